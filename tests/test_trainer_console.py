"""
The trainer console with a real browser (headless Chromium over CDP) and the real graph.

A person's key presses and words go out on ``feedback`` and ``utterance``; the page confirms a
press only once the learner's receipt names it; it shows the learner's H of the frame on screen
and the steps a press was credited to; pause stops the real-time env.
"""

import asyncio
import contextlib
import json
import os
import re
import signal
import urllib.error
import urllib.request

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy, numpy_to_image
from attention_common.stamps import ns_to_stamp, stamp_to_ns
from attention_tasks.task import load_task
from cdp import Browser, CHROMIUM
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Vector3Stamped
from harness import free_port, wait_until
import numpy as np
import pytest
from sensor_msgs.msg import Image
from std_msgs.msg import Float32
from trainer_console.config import ConsoleConfig
from trainer_console.press_time import frame_stamp, MAX_AFTER_MS, press_moment
from trainer_console.state import ConsoleState
from trainer_console.web import ConsoleServer, Frames

STARTUP_S = 60.0
CI = bool(os.environ.get('CI'))


def log_lines(run_dir):
    path = run_dir / 'feedback_log.jsonl'
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def credit_of(messages, seq):
    """Return {stamp: weight} and h that the learner published on feedback_credit for seq."""
    for msg in messages:
        values = [(kv.key, kv.value) for kv in msg.status[0].values]
        if dict(values).get('seq') == str(seq):
            return ({int(k): float(v) for k, v in values if k not in ('seq', 'h')},
                    float(dict(values)['h']), msg.status[0].message)
    return None


# What the page shows of the learner, read at once (one frame's view, not two).
PAGE_VIEW = """(() => {
  const $ = (id) => document.getElementById(id), strip = $('strip');
  const texts = (q) => [...document.querySelectorAll(q)].map((e) => e.textContent);
  return {
    frame: window.frameStamp, h_stamp: $('h_panel').dataset.stamp,
    exact: $('h_panel').dataset.exact, taken: $('taken') && $('taken').textContent,
    names: texts('#h_bars .bar .name'), h: texts('#h_bars .bar .h'),
    highlighted: texts('#h_bars .bar.taken .name'),
    seq: $('credit_seq').textContent, press_h: $('credit_h').textContent,
    mode: $('credit_mode').textContent, steps: $('credit_steps').textContent,
    shown: $('credit_shown').textContent, sum: $('credit_sum').textContent,
    newest: [...strip.querySelectorAll('i.newest')].map((c) => [c.dataset.stamp, c.dataset.seq]),
  };
})()"""

needs_chromium = pytest.mark.skipif(
    CHROMIUM is None and not CI, reason='no chromium: apt-get install chromium (CI installs it)')


@pytest.mark.topics
@needs_chromium
def test_a_person_teaches_from_the_browser(probe, start_node, tmp_path):
    run_dir = tmp_path / 'run'
    statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    masks = probe.subscribe(Image, topics.SALIENCY_MASK, qos.FRAMES)
    action_values = probe.subscribe(DiagnosticArray, topics.ACTION_VALUES, qos.ACTION_VALUES)
    credits = probe.subscribe(DiagnosticArray, topics.FEEDBACK_CREDIT, qos.HUMAN)
    someone_else = probe.publisher(Float32, topics.FEEDBACK, qos.HUMAN)
    # Window credit: a press is credited to the steps 0.2-4 s before the moment it was given.
    tamer = start_node('tamer_node', {'run_dir': str(run_dir), 'credit': 'window',
                                      'metrics_period_s': 0.3})
    start_node('saliency_node', {})
    port = free_port()
    console = start_node('trainer_console', {'port': port})
    assert console.wait_for_log('trainer console at', STARTUP_S), console.log_text()[-2000:]
    url = re.search(r'trainer console at (\S+)', console.log_text()).group(1)
    assert url == f'http://127.0.0.1:{port}/'
    env = start_node('env_node', {'rate_hz': 15.0, 'warmup_steps': 0,
                                  'wait_observation_subscribers': 3})
    assert statuses.wait_count(5, STARTUP_S), env.log_text()[-2000:]
    assert tamer.wait_for_log('ready', STARTUP_S), tamer.log_text()[-2000:]  # a person waits too

    async def session():
        async with Browser(url, tmp_path / 'chromium') as page:
            assert await page.wait_for("document.getElementById('connection').textContent"
                                       " === 'connected'")
            assert await page.wait_for("document.getElementById('frame').naturalWidth === 160")
            assert await page.wait_for("document.getElementById('listeners').textContent"
                                       ".startsWith('tamer_node')"), (  # the page says who hears
                await page.evaluate('document.body.innerText'))
            shown = await page.evaluate('window.framesShown.F')
            assert await page.wait_for(f'window.framesShown.F >= {shown + 5}')  # it plays
            assert await page.evaluate("document.getElementById('paused_hint').hidden")
            # Seven judgements from the keyboard: five +, then ArrowUp and -.
            for key in ('+',) * 5 + ('ArrowUp', '-'):
                await page.press(key)
            assert await page.wait_for(
                "document.getElementById('confirmed').textContent === '7'"), (
                await page.evaluate('document.body.innerText'))
            # Words: typed into the box, sent with Enter; a '+' typed there is not feedback.
            await page.evaluate("document.getElementById('utterance').focus()")
            await page.type_text('climb down the ladder +')
            await page.press('Enter')
            assert await page.wait_for(
                "document.getElementById('confirmed_utterances').textContent === '1'")
            assert await page.wait_for(
                "document.getElementById('named').textContent.includes('ladder')")
            assert await page.wait_for(
                "document.getElementById('saliency').naturalWidth === 160")
            assert await page.evaluate("document.getElementById('given').textContent") == '7'
            # One more '+' once the strip holds 6 s of steps (the learner has a whole 4 s
            # window of them), then pause: the frame on screen and its strip stand still.
            assert await page.wait_for(
                "Number(document.getElementById('strip').dataset.steps) >= 90", 30.0)
            # Someone else's feedback first (another publisher: its own #1 and a log seq of
            # its own), so that our press's log seq is not its publication number.
            someone_else.publish(Float32(data=-0.5))
            assert wait_until(lambda: any(line.get('h') == -0.5
                                          for line in log_lines(run_dir)), 10.0)
            await page.evaluate("document.getElementById('utterance').blur()")  # judging again
            await page.press('+')
            assert await page.wait_for(
                "document.getElementById('confirmed').textContent === '8'")
            # Pause stops the real-time env; resume starts it again.
            await page.evaluate("document.getElementById('pause').click()")
            assert await page.wait_for("document.getElementById('pause').textContent"
                                       " === 'resume'")
            plus = next(line for line in log_lines(run_dir)
                        if line['kind'] == 'feedback' and line['publication_seq'] == 8)
            assert plus['seq'] != 8 and plus['h'] == 1.0, plus
            assert credits.wait_for(lambda m: credit_of(m, plus['seq']), 10.0)
            assert await page.wait_for("document.getElementById('credit_note').textContent"
                                       ".includes('not from this page')")  # the -0.5
            assert await page.wait_for(f"document.getElementById('credit_seq').textContent"
                                       f" === '{plus['seq']}'"), (
                await page.evaluate('document.body.innerText'))
            assert await page.wait_for("document.getElementById('h_panel').dataset.exact"
                                       " === '1'")
            view = await page.evaluate(PAGE_VIEW)
            assert await page.wait_for("!document.getElementById('paused_hint').hidden")
            # Paused, a press judges the step on screen: stamped with it, credited to it alone
            # (plain, the learner's window would fall 0.2 s and more before it, never on it).
            await page.press('-')
            assert await page.wait_for(
                "document.getElementById('confirmed').textContent === '9'")
            paused_frame = await page.evaluate('window.frameStamp')
            # The step button: one step with the agent's answer, still paused; then judge it.
            assert not await page.evaluate("document.getElementById('step_once').disabled")
            await page.evaluate("document.getElementById('step_once').click()")
            assert await page.wait_for(f"window.frameStamp !== '{paused_frame}'"), (
                await page.evaluate('document.body.innerText'))
            await page.press('+')
            assert await page.wait_for(
                "document.getElementById('confirmed').textContent === '10'")
            return view, plus['seq'], paused_frame, await page.evaluate('window.frameStamp')

    shown, seq, paused_frame, stepped_frame = asyncio.run(session())
    # The H panel: one bar per action of the task, the action the learner took on the frame
    # on screen highlighted, and the H it published for that very step.
    names = list(load_task('montezuma').action_names)
    assert shown['names'] == names and len(names) == 18, shown
    assert shown['h_stamp'] == shown['frame'], shown  # the H of the frame on screen
    published = next(msg for msg in action_values.snapshot()
                     if str(stamp_to_ns(msg.header.stamp)) == shown['h_stamp'])
    status = published.status[0]
    assert shown['taken'] == status.message and shown['highlighted'] == [status.message]
    assert [float(x) for x in shown['h']] == pytest.approx(
        [float(kv.value) for kv in status.values[2:]], abs=6e-4)
    # The strip: that press's credit, as the learner published it for its seq.
    weights, h, mode = credit_of(credits.snapshot(), seq)
    assert (h, mode, float(shown['press_h'])) == (1.0, 'window', 1.0), shown
    assert int(shown['steps']) == len(weights)
    assert float(shown['sum']) == pytest.approx(sum(weights.values()), abs=1.5e-3)
    assert 0.9 <= sum(weights.values()) <= 1.0 + 1e-4  # a whole window of steps
    cells = [int(stamp) for stamp, cell_seq in shown['newest'] if cell_seq == str(seq)]
    assert cells and len(cells) == len(shown['newest']) == int(shown['shown']), shown
    assert set(cells) <= set(weights), shown  # coloured: only the steps credited
    assert env.wait_for_log('paused', 10.0)
    count = len(statuses.snapshot())
    assert not statuses.wait_count(count + 3, 1.5)  # no steps while paused
    lines = log_lines(run_dir)
    feedback = [line for line in lines if line['kind'] == 'feedback']
    # Ours carry the moment given (pressed); someone else's plain -0.5 is learned from too.
    assert [(line['h'], line['source'], line['publication_seq'], line['status'])
            for line in feedback] == [
        (1.0, 'pressed', 1, 'ok'), (1.0, 'pressed', 2, 'ok'), (1.0, 'pressed', 3, 'ok'),
        (1.0, 'pressed', 4, 'ok'), (1.0, 'pressed', 5, 'ok'), (1.0, 'pressed', 6, 'ok'),
        (-1.0, 'pressed', 7, 'ok'), (-0.5, 'plain', 1, 'ok'), (1.0, 'pressed', 8, 'ok'),
        (-1.0, 'stamped', 1, 'ok'), (1.0, 'stamped', 2, 'ok')]
    for line, frame, h in ((feedback[-2], paused_frame, -1.0), (feedback[-1], stepped_frame, 1.0)):
        assert line['stamp_ns'] == int(frame), (line, frame)
        assert credits.wait_for(lambda m: credit_of(m, line['seq']), 10.0)
        assert credit_of(credits.snapshot(), line['seq']) == ({int(frame): 1.0}, h, 'step')
    assert int(stepped_frame) > int(paused_frame)
    assert env.wait_for_log('one step taken while paused', 5.0)
    # Each of ours timed on the env's clock from the frame on screen: near the newest
    # observation the learner had when it arrived (at most a step after it).
    for line in feedback[:7]:
        assert -10**9 // 15 - 10**7 <= line['stamp_ns'] - line['now_ns'] < 10**9, line
    # The utterance made saliency images whose masks keep something (the ladders, the agent).
    assert any(image_to_numpy(mask).any() for mask in masks.snapshot())
    assert [line['text'] for line in lines if line['kind'] == 'utterance'] == [
        'climb down the ladder +']
    assert wait_until(lambda: 'the person gave utterance' in console.log_text(), 5.0)
    assert tamer.alive() and console.stop(signal.SIGINT) == 0, console.log_text()[-3000:]


def test_a_console_open_beyond_loopback_needs_allow_remote_and_a_token():
    with pytest.raises(ValueError, match='allow_remote'):
        ConsoleConfig(host='0.0.0.0').validate()
    ConsoleConfig(host='0.0.0.0', allow_remote=True).validate()
    assert ConsoleConfig().loopback and not ConsoleConfig(host='0.0.0.0').loopback
    # The token check itself, on loopback (nothing here is served beyond this machine).
    server = ConsoleServer('127.0.0.1', 0, Frames(), lambda: {}, lambda c: {'ok': True}, 15.0,
                           token='s3cret')
    port = server.start()
    try:
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(f'http://127.0.0.1:{port}/', timeout=10)
        assert refused.value.code == 403
        with urllib.request.urlopen(f'http://127.0.0.1:{port}/?token=s3cret',
                                    timeout=10) as page:
            assert b'Trainer console' in page.read()
    finally:
        server.stop()


def test_a_press_is_confirmed_only_by_the_receipt_that_names_it():
    state = ConsoleState()
    t = 1_800_000_000_000_000_000
    state.sent('feedback', 1.0, 1, t)
    state.sent('feedback', -1.0, 2, t + 10**8)
    # Someone else's message (another publisher's #1, an hour earlier) confirms nothing.
    assert state.on_receipt('feedback', 1, t - 3600 * 10**9) is None
    assert state.on_receipt('utterance', 2, t) is None
    assert state.on_receipt('feedback', 2, t + 10**8 + 5 * 10**6).value == -1.0
    assert state.confirmed == {'feedback': 1, 'utterance': 0}
    assert state.on_receipt('feedback', 2, t + 10**8) is None  # once
    snapshot = state.snapshot()
    assert snapshot['given']['feedback'] == 2 and len(snapshot['unconfirmed']) == 1


@pytest.mark.topics
def test_teach_from_a_shell_reaches_the_learner_every_time(start_node, tmp_path):
    """The README's way from a shell: 10 fresh ``teach`` processes, each logged, all 10."""
    import subprocess
    from harness import BIN
    run_dir = tmp_path / 'run'
    tamer = start_node('tamer_node', {'run_dir': str(run_dir), 'credit': 'window'})
    start_node('feedback_node', {'synthetic': False})  # a second subscriber, as in person mode
    assert tamer.wait_for_log('ready', STARTUP_S)
    given = ['good', 'bad', '+', '-', '0.5', 'good', 'bad', 'good', 'bad', 'good']
    for what in given:
        result = subprocess.run([str(BIN / 'teach'), what], capture_output=True, text=True,
                                timeout=60)
        assert result.returncode == 0, (what, result.stderr)
        assert 'logged by the learner (no_observation)' in result.stdout  # no env here
    said = subprocess.run([str(BIN / 'teach'), 'say', 'jump over the skull'],
                          capture_output=True, text=True, timeout=60)
    assert said.returncode == 0, said.stderr
    assert subprocess.run([str(BIN / 'teach'), '5'], capture_output=True,
                          timeout=60).returncode == 2  # outside [-1, 1]: nothing sent
    lines = log_lines(run_dir)
    assert [line['h'] for line in lines if line['kind'] == 'feedback'] == [
        1.0, -1.0, 1.0, -1.0, 0.5, 1.0, -1.0, 1.0, -1.0, 1.0]  # all 10, in order
    assert [line['text'] for line in lines if line['kind'] == 'utterance'] == [
        'jump over the skull']


def console_alone(start_node):
    """Start a console with nothing else; return it and a function that opens its websocket."""
    import aiohttp
    port = free_port()
    console = start_node('trainer_console', {'port': port})
    assert console.wait_for_log('trainer console at', STARTUP_S)

    @contextlib.asynccontextmanager
    async def page():
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(f'http://127.0.0.1:{port}/ws') as socket:
                yield socket
    return console, page


@pytest.mark.topics
def test_nothing_is_sent_into_the_void_when_nobody_listens(start_node):
    """Without a learner a press is refused with a reason, not published and lost."""
    console, page = console_alone(start_node)

    async def press():
        async with page() as socket:
            await socket.send_json({'type': 'feedback', 'h': 1, 'id': 1})
            while True:
                message = await socket.receive_json(timeout=30)
                if message.get('type') == 'reply':
                    return message
    reply = asyncio.run(press())
    assert reply['ok'] is False and 'nobody listens to feedback' in reply['error']
    assert 'not sent: nobody subscribes' in console.log_text()
    assert console.stop(signal.SIGINT) == 0


@pytest.mark.topics
def test_the_console_stops_cleanly_while_a_page_is_still_open(start_node):
    """A person's tab is open when the run ends: the console closes it and exits 0 (was 1)."""
    import aiohttp
    console, page = console_alone(start_node)

    async def stop_while_open():
        async with page() as socket:
            assert (await socket.receive(timeout=30)).type == aiohttp.WSMsgType.TEXT
            stopping = asyncio.ensure_future(asyncio.to_thread(console.stop, signal.SIGINT))
            while (message := await socket.receive(timeout=10)).type not in (
                    aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED):
                pass  # (the page reads on while the console stops)
            return await stopping, message.data
    code, close_code = asyncio.run(stop_while_open())
    assert code == 0, console.log_text()[-3000:]
    assert close_code == aiohttp.WSCloseCode.GOING_AWAY  # told, not dropped


def test_the_state_is_valid_json_when_the_learner_has_no_loss_yet():
    state = ConsoleState()
    state.on_metrics({'train/loss': float('nan'), 'train/updates': 0.0,
                      'feedback/received': float('inf')})
    text = json.dumps(state.snapshot(), allow_nan=False)  # what the page's JSON.parse reads
    assert json.loads(text)['learner']['train/loss'] is None


def test_the_console_shows_another_tasks_milestones():
    from attention_tasks.task import load_task
    task = load_task('doorkey')
    state = ConsoleState(milestone_of=lambda values: task.milestone_of(values, 0.0),
                         milestones=task.milestones)
    for subgoals in (0, 1, 2, 1):
        state.on_status({'agent_step': 1, 'subgoals': subgoals, 'room': 0, 'x': 1, 'y': 1},
                        now=0.0)
    snapshot = state.snapshot()
    assert snapshot['furthest'] == 1 and snapshot['milestones'] == ['key', 'door', 'goal']
    assert ConsoleState().snapshot()['milestones'][5] == 'critical position 5'  # Room 1's


def test_the_page_shows_the_pause_of_an_env_that_paused_itself():
    state = ConsoleState()
    state.on_status({'agent_step': 0}, now=0.0, message='paused')  # pause_each_episode
    assert state.snapshot()['paused'] and state.snapshot()['judges_frame']  # the page's hint
    state.on_status({'agent_step': 1}, now=0.0, message='running')  # resumed from elsewhere
    assert not state.snapshot()['paused'] and not state.snapshot()['judges_frame']
    state.paused = True  # the console's own pause: a step still in flight does not undo it
    state.on_status({'agent_step': 2}, now=0.0, message='running')
    assert state.snapshot()['paused']
    assert not ConsoleState(judge_paused_frame=False, paused=True).snapshot()['judges_frame']


@pytest.mark.topics
@needs_chromium
def test_a_key_press_carries_the_frame_on_screen_and_the_time_since_it_appeared(
        probe, start_node, tmp_path):
    """
    A press goes out at the frame's stamp plus the wait; paused, at the frame's own stamp.

    Running, on feedback_pressed; paused, on feedback_stamped (the step on screen is the step
    judged).

    The frames' stamps are 1,000 s of simulation apart, so a press timed from anything but
    the frame on screen (the console's clock, the newest frame it got) would show.
    """
    frames = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
    statuses = probe.publisher(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    pressed = probe.subscribe(Vector3Stamped, topics.FEEDBACK_PRESSED, qos.HUMAN)
    on_frame = probe.subscribe(Vector3Stamped, topics.FEEDBACK_STAMPED, qos.HUMAN)
    plain = probe.subscribe(Float32, topics.FEEDBACK, qos.HUMAN)
    port = free_port()
    console = start_node('trainer_console', {'port': port})
    assert console.wait_for_log('trainer console at', STARTUP_S), console.log_text()[-2000:]
    assert probe.wait_for_subscribers(frames, timeout=STARTUP_S)
    assert probe.wait_matched(pressed, timeout=STARTUP_S) and probe.wait_matched(plain)
    assert probe.wait_matched(on_frame, timeout=STARTUP_S)

    def show(k: int) -> int:
        msg = numpy_to_image(np.full((210, 160, 3), 40 * k % 255, np.uint8), 'rgb8', Image())
        msg.header.stamp = ns_to_stamp(k * 1000 * 10**9)
        frames.publish(msg)
        return k * 1000 * 10**9

    def say(message: str) -> None:
        array = DiagnosticArray()
        array.status = [DiagnosticStatus(name='env_node', message=message)]
        statuses.publish(array)

    async def session():
        async with Browser(f'http://127.0.0.1:{port}/', tmp_path / 'chromium') as page:
            assert await page.wait_for("document.getElementById('connection').textContent"
                                       " === 'connected'")
            timings = []
            for k, wait_s in ((1, 0.1), (2, 0.6)):
                stamp = show(k)
                assert await page.wait_for(f"window.frameStamp === '{stamp}'"), k
                shown_at, before = await page.evaluate('[window.frameShownAt, performance.now()]')
                await asyncio.sleep(wait_s)
                await page.press('+')
                after = await page.evaluate('performance.now()')
                timings.append((stamp, before - shown_at, after - shown_at))
                assert pressed.wait_count(k, 10.0), console.log_text()[-2000:]
            say('paused')  # the env paused itself: the frame stands still and is judged
            assert await page.wait_for("document.getElementById('pause').textContent"
                                       " === 'resume'")
            await asyncio.sleep(0.3)
            await page.press('-')
            assert on_frame.wait_count(1, 10.0), console.log_text()[-2000:]
            assert await page.wait_for(
                "document.getElementById('confirmed').textContent === '0'")  # no learner
            return timings

    timings = asyncio.run(session())
    for (stamp, low_ms, high_ms), msg in zip(timings, pressed.snapshot()):
        # The key went down between our two looks at the page's clock.
        waited_ms = (stamp_to_ns(msg.header.stamp) - stamp) / 10**6
        assert low_ms - 1 <= waited_ms <= high_ms + 1, (waited_ms, low_ms, high_ms)
        assert msg.vector.x == 1.0
    assert stamp_to_ns(pressed.snapshot()[1].header.stamp) - timings[1][0] >= 0.55 * 10**9
    assert [(m.vector.x, stamp_to_ns(m.header.stamp)) for m in on_frame.snapshot()] == [
        (-1.0, timings[1][0])]  # the frame on screen's own stamp, not a moment after it
    assert plain.snapshot() == [] and len(pressed.snapshot()) == 2
    assert console.stop(signal.SIGINT) == 0


def test_a_press_is_timed_only_from_a_frame_that_is_the_present():
    second = 10**9
    assert press_moment('5000000000', 250.0, paused=False) == (5 * second + second // 4, '')
    assert press_moment(5 * second, 0, paused=False) == (5 * second, '')
    assert press_moment('5000000000', 250.0, paused=True) == (None, 'the env is paused')
    assert press_moment(None, None, paused=False)[0] is None  # no frame on screen yet
    for frame, after in (('-5', 1.0), ('1e9', 1.0), (True, 1.0), ('5', float('nan')),
                         ('5', -1.0), ('5', '3'), ('5', True)):
        moment, why = press_moment(frame, after, paused=False)
        assert moment is None and why.startswith('unreadable'), (frame, after)
    moment, why = press_moment('5', MAX_AFTER_MS + 1, paused=False)
    assert moment is None and 'not the present' in why
    # Paused, the frame on screen is the step judged: its stamp alone, however long it stood.
    assert frame_stamp('5000000000') == (5 * second, '')
    assert frame_stamp(None) == (None, 'the page sent no frame timing')
    for frame in ('-5', '1e9', True, 5.0):
        assert frame_stamp(frame)[0] is None and frame_stamp(frame)[1].startswith('unreadable')


def test_a_receipt_names_the_publisher_its_press_went_out_on():
    # The console's plain and pressed publishers each number from 1: the source tells them.
    state = ConsoleState()
    t = 1_800_000_000_000_000_000
    state.sent('feedback', 1.0, 1, t, 'pressed')
    state.sent('feedback', -1.0, 1, t + 10**6, 'plain')
    assert state.on_receipt('feedback', 1, t + 10**6, source='plain').value == -1.0
    assert state.on_receipt('feedback', 1, t, source='plain') is None
    assert state.on_receipt('feedback', 1, t, source='pressed').value == 1.0
    assert state.confirmed['feedback'] == 2


@pytest.mark.topics
@needs_chromium
def test_a_person_answers_the_learners_questions_on_the_frame_asked(probe, start_node, tmp_path):
    """A question pauses the env and puts the asked frame on screen; a press answers that step."""
    run_dir = tmp_path / 'run'
    statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    questions = probe.subscribe(Vector3Stamped, topics.QUESTION, qos.HUMAN)
    credits = probe.subscribe(DiagnosticArray, topics.FEEDBACK_CREDIT, qos.HUMAN)
    # Unsure of every step (gaps are at most 2): a question every other step, one at a time.
    tamer = start_node('tamer_node', {'run_dir': str(run_dir), 'ask_rate': 0.5,
                                      'ask_margin': 3.0, 'ask_burst': 1.0})
    # Hear the first question too: it comes on the second step (CI once missed it to discovery).
    assert probe.wait_matched(questions, timeout=STARTUP_S), tamer.log_text()[-2000:]
    port = free_port()
    console = start_node('trainer_console', {'port': port})
    assert console.wait_for_log('trainer console at', STARTUP_S), console.log_text()[-2000:]
    # The env steps once this probe's subscription to observations is matched too (a third),
    # made only after its status subscription is matched: no step goes unheard here. (The
    # first question, on the second step, may pause the env before a third; under a loaded
    # suite a slow discovery once missed both steps.)
    env = start_node('env_node', {'rate_hz': 15.0, 'warmup_steps': 0,
                                  'wait_observation_subscribers': 3})
    assert probe.wait_matched(statuses, timeout=STARTUP_S), env.log_text()[-2000:]
    probe.subscribe(Image, topics.OBSERVATION, qos.FRAMES)
    assert statuses.wait_count(1, STARTUP_S), env.log_text()[-2000:]
    asked_on_screen = """(() => { const q = document.getElementById('question');
      return !q.hidden && q.dataset.stamp === window.frameStamp
        && document.getElementById('h_panel').dataset.stamp === q.dataset.stamp
        ? q.dataset.stamp : null; })()"""

    async def next_question(page, after):
        assert await page.wait_for(f'{asked_on_screen} !== null && {asked_on_screen} !== '
                                   f"'{after}'", 30.0), (
            await page.evaluate('document.body.innerText'))
        stamp = await page.evaluate(asked_on_screen)
        taken = await page.evaluate("document.getElementById('question_taken').textContent")
        return stamp, taken, await page.evaluate("document.getElementById('taken')"
                                                 '.textContent')

    async def session():
        async with Browser(f'http://127.0.0.1:{port}/', tmp_path / 'chromium') as page:
            assert await page.wait_for("document.getElementById('connection').textContent"
                                       " === 'connected'")
            shown = []
            for key in ('+', '-', '0'):  # yes, no, skip
                stamp, taken, h_taken = await next_question(page, shown[-1][0] if shown else '')
                count = len(statuses.snapshot())
                paused = not statuses.wait_count(count + 3, 1.0)  # the env waits for the answer
                shown.append((stamp, taken, h_taken, paused))
                await page.press(key)
            assert await page.wait_for("document.getElementById('question_counts').textContent"
                                       ".includes('2 answered, 1 skipped')")
            return shown, await page.evaluate(
                "document.getElementById('question_counts').textContent")

    shown, counts = asyncio.run(session())
    asked = {str(stamp_to_ns(m.header.stamp)): m.vector for m in questions.snapshot()}
    names = load_task('montezuma').action_names
    for stamp, taken, h_taken, paused in shown:
        assert stamp in asked and taken == h_taken == names[int(asked[stamp].x)], (stamp, asked)
        assert paused, 'the env stepped on while a question stood on screen'
    assert int(shown[0][0]) < int(shown[1][0]) < int(shown[2][0])  # resumed in between
    assert '2 answered, 1 skipped' in counts, counts
    # The two answers: stamped with the steps asked, each credited to that step alone.
    assert wait_until(lambda: len([line for line in log_lines(run_dir)
                                   if line.get('source') == 'stamped']) >= 2, 10.0)
    answers = [line for line in log_lines(run_dir) if line['kind'] == 'feedback']
    assert [(line['h'], line['source'], str(line['stamp_ns'])) for line in answers] == [
        (1.0, 'stamped', shown[0][0]), (-1.0, 'stamped', shown[1][0])], answers
    for line in answers:
        assert credits.wait_for(lambda m: credit_of(m, line['seq']), 10.0)
        assert credit_of(credits.snapshot(), line['seq']) == (
            {line['stamp_ns']: 1.0}, line['h'], 'step')
    assert console.wait_for_log('the learner asks about step', 5.0)
    assert tamer.alive() and console.stop(signal.SIGINT) == 0, console.log_text()[-3000:]
