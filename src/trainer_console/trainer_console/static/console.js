// The trainer console's page: frames in, key presses and words out, over one websocket.
'use strict';
const token = new URLSearchParams(location.search).get('token');
const $ = (id) => document.getElementById(id);
let socket = null;
let nextId = 1;
let lastSnapshot = null;
const urls = {F: null, S: null};
window.framesShown = {F: 0, S: 0};  // images shown so far, by kind (tests and the benchmark read it)

function connect() {
  const query = token ? `?token=${encodeURIComponent(token)}` : '';
  socket = new WebSocket(`ws://${location.host}/ws${query}`);
  socket.binaryType = 'arraybuffer';
  socket.onopen = () => { $('connection').textContent = 'connected'; $('connection').className = 'good'; };
  socket.onclose = () => {
    $('connection').textContent = 'disconnected, retrying'; $('connection').className = 'bad';
    setTimeout(connect, 1000);
  };
  socket.onmessage = (event) => {
    if (event.data instanceof ArrayBuffer) { showImage(event.data); return; }
    let message;
    try { message = JSON.parse(event.data); } catch (error) { note(`unreadable state: ${error}`, 'bad'); return; }
    if (message.type === 'state') { showState(message); }
    if (message.type === 'reply' && !message.ok) { note(`not sent: ${message.error}`, 'bad'); }
  };
}

function showImage(buffer) {
  const kind = String.fromCharCode(new Uint8Array(buffer, 0, 1)[0]);
  const url = URL.createObjectURL(new Blob([buffer.slice(1)], {type: 'image/jpeg'}));
  const img = kind === 'F' ? $('frame') : $('saliency');
  img.src = url;
  if (urls[kind]) { URL.revokeObjectURL(urls[kind]); }
  urls[kind] = url;
  window.framesShown[kind] += 1;
}

function fmt(value, digits) {
  return value === null || value === undefined || Number.isNaN(value) ? '-' : Number(value).toFixed(digits);
}

function showState(s) {
  $('given').textContent = s.given.feedback;
  $('confirmed').textContent = s.confirmed.feedback;
  $('given_utterances').textContent = s.given.utterance;
  $('confirmed_utterances').textContent = s.confirmed.utterance;
  $('waiting').textContent = s.unconfirmed.length ? s.unconfirmed.map((p) => `${p.kind} #${p.seq}`).join(', ') : 'nothing';
  $('said').textContent = s.utterance || '-';
  const heard = (kind) => (s.listeners[kind] || []).join(', ') || 'nobody yet';
  $('listeners').textContent = `${heard('feedback')} / ${heard('utterance')}`;
  $('named').textContent = s.named.length ? s.named.join(', ') : '-';
  const l = s.learner;
  $('learner_feedback').textContent = `${fmt(l['feedback/received'], 0)}, ${fmt(l['feedback/count'], 0)}`;
  $('learner_training').textContent = `${fmt(l['train/loss'], 4)}, ${fmt(l['train/updates'], 0)}`;
  $('step').textContent = `${s.step ?? '-'}, ${s.episode ?? '-'}, ${s.lives ?? '-'}`;
  lastSnapshot = s;
  $('furthest').textContent = s.furthest >= 0 ? `${s.furthest} (${(s.milestones || [])[s.furthest] || ''})` : '-';
  $('pause').textContent = s.paused ? 'resume' : 'pause';
  $('log').innerHTML = s.last.slice().reverse().map((p) =>
    `<li class="${p.confirmed ? 'good' : 'pending'}">${p.kind} ${escapeHtml(String(p.value))}` +
    `${p.confirmed ? ` logged (${p.status})` : ' waiting'}</li>`).join('');
  plot(s.history);
}

function escapeHtml(text) {
  return text.replace(/[&<>"]/g, (c) => ({'&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;'}[c]));
}

function plot(points) {
  const canvas = $('plot');
  const g = canvas.getContext('2d');
  g.clearRect(0, 0, canvas.width, canvas.height);
  if (points.length < 2) { return; }
  const t0 = points[0][0], t1 = points[points.length - 1][0];
  const maxFeedback = Math.max(1, ...points.map((p) => p[3]));
  const x = (t) => (t - t0) / Math.max(1, t1 - t0) * (canvas.width - 4) + 2;
  const line = (value, colour) => {
    g.strokeStyle = colour; g.beginPath();
    points.forEach((p, i) => { const y = canvas.height - 4 - value(p) * (canvas.height - 8); i ? g.lineTo(x(p[0]), y) : g.moveTo(x(p[0]), y); });
    g.stroke();
  };
  const count = Math.max(1, (lastSnapshot && lastSnapshot.milestones || []).length);
  line((p) => (p[2] + 1) / count, '#4af');      // furthest milestone (critical position, sub-goal)
  line((p) => p[3] / maxFeedback, '#fa4');      // feedback logged by the learner
}

function send(command) {
  if (!socket || socket.readyState !== WebSocket.OPEN) { note('not connected: nothing sent', 'bad'); return; }
  command.id = nextId++;
  socket.send(JSON.stringify(command));
}

function note(text, kind) {
  const item = document.createElement('li');
  item.textContent = text; item.className = kind;
  $('log').prepend(item);
}

document.addEventListener('keydown', (event) => {
  if (event.target === $('utterance')) { return; }  // typing words, not judging
  if (event.key === '+' || event.key === 'ArrowUp') { send({type: 'feedback', h: 1}); event.preventDefault(); }
  if (event.key === '-' || event.key === 'ArrowDown') { send({type: 'feedback', h: -1}); event.preventDefault(); }
});
$('say').addEventListener('submit', (event) => {
  event.preventDefault();
  const text = $('utterance').value.trim();
  if (text) { send({type: 'utterance', text}); $('utterance').value = ''; }
});
$('pause').addEventListener('click', () => send({type: $('pause').textContent === 'pause' ? 'pause' : 'resume'}));
connect();
