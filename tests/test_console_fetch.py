"""
A person steers a trained Fetch learner with words typed in the console (issue 25).

``attention_train`` runs the graph a person would (``--no-synthetic --console``, task fetch,
condition language_input) with the learner started from a trained model
(``tests/data/fetch_language_input.pt``). Every episode starts paused; in a real browser the
test reads the new room, types "get the <colour> <kind>" for an object that is not the episode's
own target, resumes, and sees which object the agent picks up.
"""

import asyncio
from pathlib import Path
import re
import subprocess
import sys

from attention_common import qos, topics
from attention_tasks.fetch.world import decode_grid, phrase, state_from_status
from cdp import Browser
from diagnostic_msgs.msg import DiagnosticArray
from env_node.status import parse_status
from harness import wait_until
import pytest
from test_trainer_console import free_port, needs_chromium

LAUNCHER = str(Path(sys.executable).parent / 'attention_train')
MODEL = Path(__file__).parent / 'data' / 'fetch_language_input.pt'
"""H of the study's language_input trial, seed 1 (every-step teacher, 10,000 steps; 0.93 of
held-out rooms solved): its final checkpoint without the buffer and the optimiser."""
EPISODES = 6
SEED = 4242
"""A layout seed no study trial trains on."""
STALL_S = 3.0
"""--stall-timeout: the test waits longer than this at one pause (a pause is no stall)."""


def status_of(msg):
    return msg.status[0].message, parse_status((kv.key, kv.value) for kv in msg.status[0].values)


def objects_in(values) -> list:
    """Return the '<colour> <kind>' of every object in the room the status describes."""
    grid = decode_grid(state_from_status(values)).grid
    return sorted(phrase(cell.color, cell.type) for cell in grid.grid if cell is not None
                  and cell.type in ('key', 'ball', 'box'))


def episode_status(statuses, episode: int, message: str):
    for msg in statuses.snapshot():
        text, values = status_of(msg)
        if text == message and values['episode'] == episode:
            return values
    return None


@pytest.mark.topics
@needs_chromium
def test_typed_words_steer_a_trained_learner_to_the_object_they_name(probe, tmp_path):
    statuses = probe.subscribe(DiagnosticArray, topics.ENV_STATUS, qos.STEP_DATA)
    port = free_port()
    # Each step is acted on with its mask: a busy machine must not make the learner act on the
    # frame alone (after saliency_timeout_s, 0.5 s by default, it would).
    patient = tmp_path / 'patient.yaml'
    patient.write_text('tamer_node:\n  ros__parameters:\n    saliency_timeout_s: 10.0\n')
    err_file = open(tmp_path / 'launcher.err', 'w')
    launcher = subprocess.Popen(
        [LAUNCHER, '--task', 'fetch', '--condition', 'language_input', '--no-synthetic',
         '--console', '--console-port', str(port), '--initial-model', str(MODEL),
         '--seed', str(SEED), '--steps', '500', '--no-record',
         '--stall-timeout', str(STALL_S), '--params-file', str(patient),
         '--run-dir', str(tmp_path / 'run')],
        stdout=subprocess.DEVNULL, stderr=err_file)
    typed, carried = [], []
    try:
        assert wait_until(lambda: episode_status(statuses, 0, 'paused') is not None
                          or launcher.poll() is not None, 180.0, interval=0.1)
        assert launcher.poll() is None, (tmp_path / 'launcher.err').read_text()[-3000:]
        url = f'http://127.0.0.1:{port}/'

        async def session():
            async with Browser(url, tmp_path / 'chromium') as page:
                assert await page.wait_for("document.getElementById('connection').textContent"
                                           " === 'connected'")
                # A person speaks once the page says the learner hears words.
                assert await page.wait_for("document.getElementById('listeners').textContent"
                                           ".split('/')[1].includes('tamer_node')", 60.0), (
                    await page.evaluate('document.body.innerText'))
                for episode in range(EPISODES):
                    # The episode starts paused: the page says so and shows the new room.
                    assert wait_until(
                        lambda: episode_status(statuses, episode, 'paused') is not None, 60.0,
                        interval=0.1)
                    assert await page.wait_for(
                        "document.getElementById('pause').textContent === 'resume'")
                    room = episode_status(statuses, episode, 'paused')
                    others = [name for name in objects_in(room) if name != room['target']]
                    assert len(others) == 3, room
                    target = others[episode % len(others)]  # never the env's own
                    if episode == 0:
                        await asyncio.sleep(STALL_S + 2.0)  # a person thinks: no stall
                    await page.evaluate("document.getElementById('utterance').focus()")
                    await page.type_text(f'get the {target}')
                    await page.press('Enter')
                    assert await page.wait_for(
                        "document.getElementById('confirmed_utterances').textContent"
                        f" === '{episode + 1}'"), await page.evaluate('document.body.innerText')
                    assert await page.wait_for(
                        "document.getElementById('named').textContent"
                        f".includes('{target.split()[1]}')")
                    await page.evaluate("document.getElementById('utterance').blur()")
                    await page.evaluate("document.getElementById('pause').click()")
                    assert wait_until(
                        lambda: episode_status(statuses, episode, 'episode over') is not None,
                        60.0, interval=0.1), f'episode {episode} did not end'
                    typed.append(target)
                    carried.append(episode_status(statuses, episode, 'episode over')['carrying'])
        asyncio.run(session())
    finally:
        launcher.terminate()
        launcher.wait(timeout=60)
        err_file.close()
    err = (tmp_path / 'launcher.err').read_text()
    assert 'stalled' not in err and 'no new step' not in err, err[-2000:]
    assert re.search(rf'Trainer console: {re.escape(url)}', err), err[-2000:]
    # Words never given with these rooms pick the object they name (by chance: 1 in 4 per room;
    # 4 or more of 6 by chance: 0.04). The learner explores a tenth of its decisions.
    hits = sum(t == c for t, c in zip(typed, carried))
    assert len(typed) == EPISODES and hits >= 4, list(zip(typed, carried))
