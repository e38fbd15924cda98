// The trainer console's page: frames in, key presses and words out, over one websocket.
'use strict';
const token = new URLSearchParams(location.search).get('token');
const $ = (id) => document.getElementById(id);
let socket = null;
let nextId = 1;
let lastSnapshot = null;
const urls = {F: null, S: null};
window.framesShown = {F: 0, S: 0};  // images shown so far, by kind (tests and the benchmark read it)
window.frameStamp = null;  // the stamp (ns, a string: it may exceed 2**53) of the frame on screen
window.frameShownAt = null;  // when it was put on screen (performance.now(): the key events' clock)

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
    if (message.type === 'view') { showView(message); }
    if (message.type === 'reply' && !message.ok) { note(`not sent: ${message.error}`, 'bad'); }
  };
}

function showImage(buffer) {
  // One byte of kind, the image's stamp (ns, 8 bytes big-endian), then the JPEG.
  const kind = String.fromCharCode(new Uint8Array(buffer, 0, 1)[0]);
  const stamp = new DataView(buffer, 1, 8).getBigUint64(0).toString();
  const url = URL.createObjectURL(new Blob([buffer.slice(9)], {type: 'image/jpeg'}));
  const img = kind === 'F' ? $('frame') : $('saliency');
  if (kind === 'F') { window.frameStamp = stamp; window.frameShownAt = performance.now(); }
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
  showQuestion(s.questions);
  $('paused_hint').hidden = !s.judges_frame || !!s.questions.question;
  $('step_once').disabled = !s.paused;
  $('log').innerHTML = s.last.slice().reverse().map((p) =>
    `<li class="${p.confirmed ? 'good' : 'pending'}">${p.kind} ${escapeHtml(String(p.value))}` +
    `${p.confirmed ? ` logged (${p.status})` : ' waiting'}</li>`).join('');
  plot(s.history);
}

// The learner's question on screen (the frame shown is the one it asks about), and the counts.
function showQuestion(q) {
  const shown = q.question;
  $('question').hidden = !shown;
  $('question').dataset.stamp = shown ? shown.stamp : '';
  $('question_taken').textContent = shown ? shown.taken : '-';
  $('question_gap').textContent = shown ? fmt(shown.gap, 3) : '-';
  $('question_waiting').textContent = q.waiting ? `(${q.waiting} more waiting)` : '';
  const c = q.counts;
  $('question_counts').textContent = c.heard ? `the learner's questions: ${c.heard} asked, ` +
    `${c.answered} answered, ${c.skipped} skipped, ${c.lost} lost` +
    (c.not_shown ? `, ${c.not_shown} not shown (answer_questions is false)` : '') : '';
}

// What the learner made of the person, for the frame on screen (the server's view of it).
function showView(v) {
  showValues(v.values);
  showStrip(v.strip, v.newest ? v.newest.seq : null);
  showCredit(v);
}

function showValues(values) {
  const panel = $('h_panel'), bars = $('h_bars');
  if (!values) {
    $('h_title').textContent = 'H: nothing heard from the learner yet (action_values)';
    bars.replaceChildren(); bars.dataset.names = ''; panel.dataset.stamp = ''; panel.dataset.exact = '0';
    return;
  }
  if (bars.dataset.names !== values.names.join(',')) {  // the task's actions, built once
    bars.replaceChildren(...values.names.map((name) => {
      const row = document.createElement('div'); row.className = 'bar';
      const label = document.createElement('span'); label.className = 'name'; label.textContent = name;
      const track = document.createElement('span'); track.className = 'track';
      track.appendChild(document.createElement('b'));
      const number = document.createElement('span'); number.className = 'h';
      row.append(label, track, number);
      return row;
    }));
    bars.dataset.names = values.names.join(',');
  }
  const top = Math.max(1e-6, ...values.h.map((h) => Math.abs(h ?? 0)));
  Array.from(bars.children).forEach((row, i) => {
    const h = values.h[i] ?? 0, width = Math.abs(h) / top * 50;
    const bar = row.children[1].firstChild;
    bar.style.left = `${h >= 0 ? 50 : 50 - width}%`; bar.style.width = `${width}%`;
    bar.className = h >= 0 ? 'up' : 'down';
    row.children[2].textContent = fmt(values.h[i], 3);
    row.classList.toggle('taken', i === values.action);
  });
  const which = values.exact ? 'of this frame' : `of the step ${values.behind_ms} ms before this frame`;
  $('h_title').replaceChildren(`H ${which} (model v${values.version ?? '-'}), took `,
    Object.assign(document.createElement('b'), {id: 'taken', textContent: values.taken}));
  panel.dataset.stamp = values.stamp; panel.dataset.exact = values.exact ? '1' : '0';
}

function showStrip(strip, newest) {
  const el = $('strip');
  if (el.children.length !== strip.size) {
    el.replaceChildren(...Array.from({length: strip.size}, () => document.createElement('i')));
  }
  const offset = strip.size - strip.steps, cells = el.children;
  for (let i = 0; i < cells.length; i++) {
    cells[i].className = i >= offset ? 'step' : ''; cells[i].style.background = '';
    delete cells[i].dataset.stamp; delete cells[i].dataset.seq;
  }
  for (const [index, stamp, seq, sign, level] of strip.cells) {
    const cell = cells[offset + index];
    const alpha = ((0.25 + 0.75 * level) * (seq === newest ? 1 : 0.35)).toFixed(3);
    cell.style.background = sign > 0 ? `rgba(80, 220, 80, ${alpha})`
      : sign < 0 ? `rgba(240, 70, 70, ${alpha})` : `rgba(200, 200, 200, ${alpha})`;
    cell.className = seq === newest ? 'step credit newest' : 'step credit';
    cell.dataset.stamp = stamp; cell.dataset.seq = seq;
  }
  el.dataset.steps = strip.steps; el.dataset.first = strip.first || ''; el.dataset.last = strip.last || '';
}

function showCredit(v) {
  const n = v.newest;
  $('credit_seq').textContent = n ? `${n.seq}` : '-';
  $('credit_h').textContent = n ? `${n.h > 0 ? '+' : ''}${n.h}` : '-';
  $('credit_mode').textContent = n ? n.mode : '-';
  $('credit_steps').textContent = n ? n.steps : '-';
  $('credit_shown').textContent = n ? n.shown : '-';
  $('credit_sum').textContent = n ? fmt(n.sum, 3) : '-';
  const notes = [];
  if (v.waiting.length) { notes.push(`no credit yet for your press #${v.waiting.join(', #')}`); }
  if (v.others.count) { notes.push(`credit heard for ${v.others.count} feedback not from this page`); }
  const bad = v.malformed.action_values + v.malformed.feedback_credit;
  if (bad) { notes.push(`${bad} malformed messages ignored`); }
  $('credit_note').textContent = notes.join('; ');
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

// A press carries the frame on screen and how long it had been there when the key went down:
// the moment it was given, on the env's clock (press_time.py).
function judge(h, event) {
  const timing = window.frameStamp === null ? {}
    : {frame: window.frameStamp, after_ms: Math.max(0, event.timeStamp - window.frameShownAt)};
  send({type: 'feedback', h, ...timing});
  event.preventDefault();
}

document.addEventListener('keydown', (event) => {
  if (event.target === $('utterance')) { return; }  // typing words, not judging
  if (event.key === '+' || event.key === 'ArrowUp') { judge(1, event); }
  if (event.key === '-' || event.key === 'ArrowDown') { judge(-1, event); }
  if ((event.key === '0' || event.key === 'Escape') && !$('question').hidden) {
    send({type: 'skip'}); event.preventDefault();
  }
});
$('say').addEventListener('submit', (event) => {
  event.preventDefault();
  const text = $('utterance').value.trim();
  if (text) { send({type: 'utterance', text}); $('utterance').value = ''; }
});
$('pause').addEventListener('click', () => send({type: $('pause').textContent === 'pause' ? 'pause' : 'resume'}));
$('step_once').addEventListener('click', () => send({type: 'step'}));
$('skip').addEventListener('click', () => send({type: 'skip'}));
connect();
