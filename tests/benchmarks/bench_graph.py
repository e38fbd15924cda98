"""
Benchmark: the whole graph (four processes over DDS) against the same loop in one process.

1. Graph: ``attention_train --condition language --trainer thesis`` (the study's set-up, and
   the trainer the in-process loop runs) with learning on, for ``--graph-steps``
   agent steps (default 10,000, so the memory column is "after 10,000 steps"). Numbers come
   from the run's ``summary.json``: steps/s while training, the observation-to-action latency
   env_node measures (publishing observation T to receiving the action stamped T: the closed
   loop), the tamer's own acting time, saliency images/s, learner updates/s, each node's
   resident memory and CPU time at the end.
2. In process: the same cores without ROS (env core, synthetic trainer, saliency maker,
   TamerAgent with its learner thread), one step after the other, for ``--inprocess-steps``.
   Both agents wait for their learner before acting when it owes more than ``pace_updates``
   minibatch updates (tamer_node's default): without it the faster loop outran its learner,
   which dropped owed updates (0.30 updates per step in process against the graph's 0.62 in
   one run), and the comparison was with an agent that learned less.

``--foxglove N``: instead, the cost of watching in Foxglove: the graph alone against the graph with
``--foxglove`` and one client of the Foxglove protocol subscribed to every channel (the worst
case: images, raw topics and plots), alternating, N pairs of ``--graph-steps`` (target: at most
5 % slower). ``--foxglove-interleaved SECONDS``: one long run with the bridge, a client
watching for SECONDS and gone for SECONDS, in turns; each watched phase's steps/s (from
metrics.csv) against the phases alone on either side of it, which leaves out the drift between
runs that makes pairs of runs too noisy to tell 5 % (``--viewer nice=0``: a lever).

The graph's nodes use the executor ``ATTENTION_EXECUTOR`` names (``events`` unless set; see
``attention_common/executors.py``). Prints a markdown table (targets: graph >= 0.8 x
in-process; observation-to-action p50 < 2 ms, p99 < 5 ms).
"""

import argparse
import asyncio
import csv
import json
import os
from pathlib import Path
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from attention_bringup.experiment.stats import mean_ci, median_ci
from attention_common.executors import executor_name
from machine_info import machine
from tamer_node.config import TamerConfig

BIN = Path(sys.executable).parent
RATIO_TARGET = 0.8  # issue 26 (issue 14's was 0.7)
P50_TARGET_MS = 2.0
P99_TARGET_MS = 5.0


FOXGLOVE_COST_TARGET = 0.05


def graph_run(steps: int, workdir: Path, pace_updates: float, name: str = 'graph',
              extra: tuple = (), viewer: str = '', tamer: dict = None) -> dict:
    """``viewer``: graph_viewer's parameters, as YAML lines (with ``--foxglove``)."""
    run_dir = workdir / name
    params = workdir / 'bench_params.yaml'
    tamer_lines = ''.join(f'    {key}: {json.dumps(value)}\n'
                          for key, value in (tamer or {}).items())
    params.write_text(f'tamer_node:\n  ros__parameters:\n    pace_updates: {pace_updates!r}\n'
                      + tamer_lines
                      + (f'graph_viewer:\n  ros__parameters:\n{viewer}' if viewer else ''))
    started = time.monotonic()
    result = subprocess.run(
        [str(BIN / 'attention_train'), '--steps', str(steps), '--condition', 'language',
         '--trainer', 'thesis', '--quiet', '--run-dir', str(run_dir),
         '--params-file', str(params), *extra],
        capture_output=True, text=True)
    wall = time.monotonic() - started
    if result.returncode != 0:
        sys.stderr.write(result.stdout[-3000:] + result.stderr[-3000:])
        raise SystemExit(f'attention_train failed with exit code {result.returncode}')
    summary = json.loads((run_dir / 'summary.json').read_text())
    training_s = summary['training_time_s']
    metrics = summary['metrics']
    return {
        'steps': summary['steps'],
        'wall_s': wall,
        'startup_s': summary['startup_s'],
        'steps_per_s': summary['steps_per_s'],
        'latency_p50_ms': summary['latency_ms']['p50'],
        'latency_p99_ms': summary['latency_ms']['p99'],
        'latency_n': summary['latency_ms']['n'],
        'act_p50_ms': metrics.get('act/latency_p50_ms'),
        'act_p99_ms': metrics.get('act/latency_p99_ms'),
        'saliency_per_s': summary['message_counts']['saliency'] / training_s,
        'updates_per_s': float(metrics.get('train/updates', 0)) / training_s,
        'skipped_updates': metrics.get('train/skipped_updates'),
        **paced(metrics, summary['steps']),
        'cpu_ms_per_step': {node: 1000.0 * seconds / summary['steps']
                            for node, seconds in summary.get('cpu_s', {}).items() if seconds},
        'rss_mb': {node: values.get('VmRSS', 0) / 1024.0
                   for node, values in summary['rss_kb'].items()},
        'peak_mb': {node: values.get('VmHWM', 0) / 1024.0
                    for node, values in summary['rss_kb'].items()},
    }


def in_process_run(steps: int, workdir: Path, pace_updates: float, tamer: dict = None) -> dict:
    """Do the graph's work, one step after the other in this process (no ROS, no copies)."""
    import torch
    torch.set_num_threads(1)
    from attention_common.stamps import NS_PER_S
    from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
    from feedback_node.trainer import SyntheticTrainer, TrainerConfig
    from saliency_node.grounding import Grounder
    from saliency_node.manifest import load_manifest, load_template_images
    from saliency_node.matching import build_objects, method_from_name
    from saliency_node.saliency import SaliencyConfig, SaliencyMaker
    from saliency_node.timeline import Timeline
    from tamer_node.agent import TamerAgent

    env = MontezumaEnv(EnvConfig(seed=0))
    trainer = SyntheticTrainer(TrainerConfig(utterance_interval=10.0))
    manifest = load_manifest()
    maker = SaliencyMaker(build_objects(manifest, load_template_images(manifest)),
                          manifest.search_region, manifest.background,
                          method_from_name('TM_CCORR_NORMED'))
    grounder = Grounder.from_manifest(manifest)
    timeline = Timeline(int(10.0 * NS_PER_S), capacity=64, require_utterance=True)
    saliency_config = SaliencyConfig(mode='language')
    run_dir = workdir / 'in_process'
    config = TamerConfig(alpha=1e-4, run_dir=str(run_dir), pace_updates=pace_updates,
                         **(tamer or {}))
    agent = TamerAgent(config, str(run_dir),
                       log=lambda level, text: None)
    agent.start()
    saliency_images = 0

    def render(released) -> None:
        nonlocal saliency_images
        for release in released:
            frame, scene = release.item
            named = release.utterance.payload if release.utterance else ()
            image, _ = maker.render(frame, scene, named, saliency_config)
            if image is not None:
                saliency_images += 1
                agent.on_saliency(release.stamp_ns, image)

    def judge(step) -> None:
        output = trainer.on_position(step.sim_time_ns, step.state.x, step.state.y)
        for feedback in output.feedback:
            agent.on_feedback(feedback.h, 'stamped', feedback.stamp_ns)
        if output.utterance is not None:
            text = output.utterance.text
            _, released = timeline.add_utterance(text, step.sim_time_ns,
                                                 grounder.ground(text).objects)
            render(released)

    step = env.warm_up()
    started, cpu_started = time.monotonic(), time.process_time()
    for _ in range(steps):
        judge(step)
        render(timeline.add_observation(step.sim_time_ns,
                                        (step.observation, maker.observe(step.observation))))
        action = agent.on_observation(step.sim_time_ns, step.observation)
        step = env.step(action)
        if step.done:
            judge(step)  # the last action is judged; then the episode starts again
            step = env.reset()
    elapsed = time.monotonic() - started
    cpu = time.process_time() - cpu_started
    metrics = agent.metrics()
    agent.close()
    env.close()
    return {
        'steps': steps,
        'steps_per_s': steps / elapsed,
        'cpu_ms_per_step': 1000.0 * cpu / steps,
        'act_p50_ms': metrics.get('act/latency_p50_ms'),
        'act_p99_ms': metrics.get('act/latency_p99_ms'),
        'saliency_per_s': saliency_images / elapsed,
        'updates_per_s': float(metrics.get('train/updates', 0)) / elapsed,
        'skipped_updates': metrics.get('train/skipped_updates'),
        **paced(metrics, steps),
    }


def paced(metrics: dict, steps: int) -> dict:
    """How often, and how long per step, the actor waited for its learner (pace_updates)."""
    return {'paced_share': float(metrics.get('act/paced', 0)) / max(steps, 1),
            'paced_ms_per_step': float(metrics.get('act/paced_ms', 0)) / max(steps, 1)}


def _lever(item: str) -> tuple:
    """Return (name, value) of a ``--tamer NAME=VALUE``: the value as JSON if it reads so."""
    name, _, text = item.partition('=')
    try:
        return name, json.loads(text)
    except ValueError:
        return name, text


def _fmt(value, digits=1) -> str:
    return '-' if value is None else f'{value:.{digits}f}'


def table(graph: dict, local: dict) -> str:
    ratio = graph['steps_per_s'] / local['steps_per_s'] if local['steps_per_s'] else 0.0
    ratio_ok = 'ok' if ratio >= RATIO_TARGET else 'MISSED'
    p50_ok = 'ok' if (graph['latency_p50_ms'] or 1e9) < P50_TARGET_MS else 'MISSED'
    p99_ok = 'ok' if (graph['latency_p99_ms'] or 1e9) < P99_TARGET_MS else 'MISSED'
    rows = [
        ('closed-loop env steps/s, learning on', _fmt(graph['steps_per_s']),
         _fmt(local['steps_per_s']), ''),
        ('graph / in-process', _fmt(ratio, 2), '', f'>= {RATIO_TARGET} {ratio_ok}'),
        ('observation -> action p50 (ms), at env_node', _fmt(graph['latency_p50_ms'], 2),
         '', f'< {P50_TARGET_MS:g} {p50_ok}'),
        ('observation -> action p99 (ms), at env_node', _fmt(graph['latency_p99_ms'], 2),
         '', f'< {P99_TARGET_MS:g} {p99_ok}'),
        ('tamer acting time p50 / p99 (ms)',
         f'{_fmt(graph["act_p50_ms"], 2)} / {_fmt(graph["act_p99_ms"], 2)}',
         f'{_fmt(local["act_p50_ms"], 2)} / {_fmt(local["act_p99_ms"], 2)}', ''),
        ('saliency images/s', _fmt(graph['saliency_per_s']), _fmt(local['saliency_per_s']), ''),
        ('learner updates/s', _fmt(graph['updates_per_s']), _fmt(local['updates_per_s']), ''),
        ('learner updates per step', _fmt(graph['updates_per_s'] / graph['steps_per_s'], 2),
         _fmt(local['updates_per_s'] / local['steps_per_s'], 2), ''),
        ('steps the actor waited for its learner (share); wait per step (ms)',
         f'{_fmt(graph["paced_share"], 2)}; {_fmt(graph["paced_ms_per_step"], 2)}',
         f'{_fmt(local["paced_share"], 2)}; {_fmt(local["paced_ms_per_step"], 2)}', ''),
        ('minibatch updates skipped (the learner fell behind)', graph['skipped_updates'],
         local['skipped_updates'], ''),
    ]
    for node in sorted(graph['rss_mb']):
        rows.append((f'{node} resident memory after {graph["steps"]} steps (MB; peak)',
                     f'{graph["rss_mb"][node]:.0f} ({graph["peak_mb"][node]:.0f})', '', ''))
    cpu = graph['cpu_ms_per_step']
    rows.append(('CPU time per step (ms): ' + ', '.join(sorted(cpu)),
                 ' + '.join(f'{cpu[n]:.1f}' for n in sorted(cpu)),
                 _fmt(local['cpu_ms_per_step']), ''))
    lines = ['| measure | graph (4 processes) | in process | target |',
             '|---|---:|---:|---|']
    lines += [f'| {a} | {b} | {c} | {d} |' for a, b, c, d in rows]
    return '\n'.join(lines)


class Watcher(threading.Thread):
    """
    A Foxglove client on its own thread: connects when the bridge serves, takes everything.

    ``period_s``: instead of watching to the end, watch for ``period_s``, leave for
    ``period_s``, and so on (``phases``: (wall time from, to, watched)).
    """

    def __init__(self, port: int, channels: str, legacy: bool, period_s: float = 0.0):
        super().__init__(daemon=True)
        self.channels, self.legacy, self.period_s = channels, legacy, period_s
        self.url = f'ws://127.0.0.1:{port}'
        self.stop = threading.Event()
        self.received = 0
        self.by_topic = {}
        self.phases = []

    def run(self) -> None:
        asyncio.run(self._watch())

    async def _watch(self) -> None:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
        from foxglove_client import FoxgloveClient, SDK_SUBPROTOCOL, SUBPROTOCOL
        protocols = (SUBPROTOCOL,) if self.legacy else (SDK_SUBPROTOCOL, SUBPROTOCOL)
        left = time.time()
        while not self.stop.is_set():
            try:
                async with FoxgloveClient(self.url, protocols) as client:
                    await client.read_for(1.0)  # the advertisements
                    await client.subscribe(self._chosen(client.channels))
                    joined = time.time()
                    while not self.stop.is_set() and not (
                            self.period_s and time.time() - joined >= self.period_s):
                        await client.read_for(0.5)
                        for message in client.received:
                            self.by_topic[message.topic] = self.by_topic.get(message.topic, 0) + 1
                        self.received += len(client.received)
                        client.received.clear()
                if not self.period_s:
                    return
                self.phases += [(left, joined, False), (joined, time.time(), True)]
                left = time.time()
                await asyncio.sleep(self.period_s)
            except (OSError, asyncio.TimeoutError):  # not serving yet (or gone: then stopped)
                await asyncio.sleep(0.2)

    def _chosen(self, advertised) -> list:
        if self.channels == 'all':
            return sorted(advertised)
        if self.channels == 'layout':
            from graph_viewer.layout import layout_topics
            return sorted(set(layout_topics()) & set(advertised))
        return []


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def phase_rates(timeline, phases, settle_s: float) -> list:
    """
    Return (watched, steps/s) of each phase the graph stepped through from end to end.

    ``timeline``: (wall time, steps acted) rows, as metrics.csv has them (one a second; the
    learner goes on writing them, with no new steps, while the graph stops); ``phases``: (from,
    to, watched); the first ``settle_s`` of a phase is left out (the bridge takes or drops its
    readers within a poll, DDS matches them within a moment). A phase that began before the
    first step or ended after the last is left out: its idle seconds are not the graph's speed.
    """
    def steps_at(when):
        for (t0, n0), (t1, n1) in zip(timeline, timeline[1:]):
            if t0 <= when <= t1:
                return n0 + (n1 - n0) * (when - t0) / (t1 - t0) if t1 > t0 else n0
        return None

    moving = [(t0, t1) for (t0, n0), (t1, n1) in zip(timeline, timeline[1:]) if n1 > n0]
    if not moving:
        return []
    began, stopped = moving[0][0], moving[-1][1]
    rates = []
    for start, end, watched in phases:
        start += settle_s
        if end - start < 1.0 or start < began or end > stopped:
            continue
        first, last = steps_at(start), steps_at(end)
        rates.append((watched, (last - first) / (end - start)))
    return rates


def paired_slowdowns(rates) -> list:
    """
    Return each watched phase's slowdown (%) against the mean of the phases alone beside it.

    Neighbours on both sides cancel a drift that is linear over the three phases.
    """
    slowdowns = []
    for index, (watched, rate) in enumerate(rates):
        if not watched:
            continue
        beside = [r for w, r in rates[max(index - 1, 0):index + 2:2] if not w]
        if beside:
            slowdowns.append(100.0 * (1.0 - rate / statistics.mean(beside)))
    return slowdowns


def foxglove_interleaved(steps: int, period_s: float, workdir: Path, pace_updates: float,
                         channels: str, viewer: dict) -> int:
    """One graph run with the bridge; a client watches and leaves in turns; print the cost."""
    port = _free_port()
    toggler = Watcher(port, channels, legacy=False, period_s=period_s)
    toggler.start()
    run = graph_run(steps, workdir, pace_updates, 'interleaved',
                    ('--foxglove', '--foxglove-port', str(port)),
                    viewer=''.join(f'    {key}: {json.dumps(value)}\n'
                                   for key, value in viewer.items()))
    toggler.stop.set()
    toggler.join(10.0)
    with (workdir / 'interleaved' / 'metrics.csv').open() as handle:
        timeline = [(float(row['wall_time']), float(row['act/count']))
                    for row in csv.DictReader(handle) if row.get('act/count')]
    settle_s = min(2.0, period_s / 3.0)  # the bridge takes or drops its readers within a poll
    rates = phase_rates(timeline, toggler.phases, settle_s)
    alone = [rate for watched, rate in rates if not watched]
    watched = [rate for watched, rate in rates if watched]
    slowdowns = paired_slowdowns(rates)
    slowdown = mean_ci(slowdowns)
    print(f'one lockstep run of {run["steps"]} steps ({run["steps_per_s"]:.1f} steps/s), a '
          f'client on the {channels} channels for {period_s:g} s, then none for {period_s:g} s, '
          f'in turns ({toggler.received} messages to it); the first {settle_s:.2g} s of a phase '
          f'left out; '
          f'graph_viewer {viewer or "defaults"}\n')
    print('| phases | n | steps/s (mean) |\n|---|---|---|')
    print(f'| alone | {len(alone)} | {statistics.mean(alone):.1f} |')
    print(f'| watched | {len(watched)} | {statistics.mean(watched):.1f} |')
    print(f'\nslowdown of each watched phase (%): {", ".join(f"{v:.1f}" for v in slowdowns)}')
    median = median_ci(slowdowns)
    if slowdown.high is not None:
        print(f'\n| slowdown of a watched phase against the phases alone beside it | {slowdown.n} '
              f'phases |\n|---|---|\n| mean [95 % CI] | {slowdown.mean:.1f} % '
              f'[{slowdown.low:.1f}, {slowdown.high:.1f}] (sd {slowdown.sd:.1f}): target <= '
              f'{100 * FOXGLOVE_COST_TARGET:g} % {_verdict(slowdown.low, slowdown.high)} |')
    if median.high is not None:  # robust to the odd wild phase (a busy core elsewhere)
        print(f'| median [95 % CI, sign test] | {median.median:.1f} % [{median.low:.1f}, '
              f'{median.high:.1f}]: target <= {100 * FOXGLOVE_COST_TARGET:g} % '
              f'{_verdict(median.low, median.high)} |')
    return 0


def _verdict(low: float, high: float) -> str:
    target = 100 * FOXGLOVE_COST_TARGET
    return 'met' if high <= target else 'missed' if low > target else 'neither shown'


def foxglove_cost(pairs: int, steps: int, workdir: Path, pace_updates: float,
                  channels: str, legacy: bool, relay: bool, image_rate_hz: float = 0.0) -> int:
    """Run the graph alone and watched in Foxglove, alternating; print both and the cost."""
    viewer = '' if relay else '    legacy_subprotocol: false\n'
    if image_rate_hz:
        viewer += f'    max_image_rate_hz: {image_rate_hz}\n'
    alone, watched, received = [], [], []
    cpu = {'graph alone': [], 'graph watched': [], 'graph_viewer': [], 'the client': []}
    for pair in range(pairs):
        run = graph_run(steps, workdir, pace_updates, f'alone{pair}')
        alone.append(run['steps_per_s'])
        cpu['graph alone'].append(sum(run['cpu_ms_per_step'].values()))
        port = _free_port()
        watcher = Watcher(port, channels, legacy)
        client_cpu = time.process_time()  # this process: the client's thread (the rest waits)
        watcher.start()
        run = graph_run(steps, workdir, pace_updates, f'watched{pair}',
                        ('--foxglove', '--foxglove-port', str(port)), viewer=viewer)
        watcher.stop.set()
        watcher.join(10.0)
        cpu['the client'].append(1000.0 * (time.process_time() - client_cpu) / run['steps'])
        nodes = dict(run['cpu_ms_per_step'])
        cpu['graph_viewer'].append(nodes.pop('graph_viewer', 0.0))
        cpu['graph watched'].append(sum(nodes.values()))
        watched.append(run['steps_per_s'])
        received.append(watcher.received)
        print(f'pair {pair}: alone {alone[-1]:.1f} steps/s, watched {watched[-1]:.1f} steps/s '
              f'({watcher.received} messages to the client: '
              f'{json.dumps(dict(sorted(watcher.by_topic.items())))})', flush=True)
    cost = 1.0 - statistics.mean(watched) / statistics.mean(alone)
    verdict = 'ok' if cost <= FOXGLOVE_COST_TARGET else 'MISSED'
    print(f'\n| lockstep, {steps} steps x {pairs} | steps/s (mean; runs) |\n|---|---|')
    print(f'| graph alone | {statistics.mean(alone):.1f} '
          f'({", ".join(f"{v:.1f}" for v in alone)}) |')
    client = ('foxglove.websocket.v1 only' if legacy else 'as Foxglove') + (
        ', through the relay' if relay else ', no relay')
    print(f'| with --foxglove, one client ({client}) on {channels} channels | '
          f'{statistics.mean(watched):.1f} '
          f'({", ".join(f"{v:.1f}" for v in watched)}) |')
    print('\nCPU time per step (ms, mean of the runs; steps/s on 2 busy cores swing 10-20 % '
          'from run to run, CPU per step much less):')
    for name, values in cpu.items():
        print(f'- {name}: {statistics.mean(values):.2f} ({", ".join(f"{v:.2f}" for v in values)})')
    extra = (statistics.mean(cpu['graph watched']) + statistics.mean(cpu['graph_viewer'])
             - statistics.mean(cpu['graph alone']))
    print(f'- the bridge costs the graph {extra:.2f} ms of CPU per step, '
          f'{100 * extra / statistics.mean(cpu["graph alone"]):.1f} % of its own '
          f'(the client, another {statistics.mean(cpu["the client"]):.2f} ms: Foxglove runs '
          'where you choose)')
    print(f'\n| cost of watching | {100 * cost:.1f} % (target <= '
          f'{100 * FOXGLOVE_COST_TARGET:g} %: {verdict}) |')
    # Each pair ran back to back, so its own slowdown leaves out the drift between pairs.
    paired = mean_ci([100.0 * (1.0 - w / a) for a, w in zip(alone, watched)])
    if paired.high is not None:
        shown = ('met' if paired.high <= 100 * FOXGLOVE_COST_TARGET else
                 'missed' if paired.low > 100 * FOXGLOVE_COST_TARGET else 'neither shown')
        print(f'| slowdown per pair, mean [95 % CI] | {paired.mean:.1f} % [{paired.low:.1f}, '
              f'{paired.high:.1f}] over {paired.n} pairs (sd {paired.sd:.1f}): target {shown} |')
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--graph-steps', type=int, default=10_000)
    parser.add_argument('--inprocess-steps', type=int, default=3_000)
    parser.add_argument('--pace-updates', type=float, default=TamerConfig.pace_updates,
                        help="tamer_node's pace_updates for both (0: the actor never waits "
                             'for its learner, which then drops owed updates)')
    parser.add_argument('--foxglove', type=int, default=0, metavar='PAIRS',
                        help='measure the cost of watching in Foxglove instead: PAIRS runs '
                             'alone and watched, alternating')
    parser.add_argument('--foxglove-interleaved', type=float, default=0.0, metavar='SECONDS',
                        help='measure the cost of watching within one run instead: a client '
                             'watches for SECONDS and leaves for SECONDS, in turns, and each '
                             'watched phase is compared with the phases alone beside it')
    parser.add_argument('--foxglove-channels', choices=('all', 'layout', 'none'), default='layout',
                        help='with --foxglove, what the client subscribes to (default: the '
                             "shipped layout's channels, as Foxglove with it open does)")
    parser.add_argument('--foxglove-legacy', action='store_true',
                        help='the client offers only foxglove.websocket.v1 (old Lichtblick: '
                             "through the bridge's relay) instead of both names, as Foxglove")
    parser.add_argument('--foxglove-no-relay', action='store_true',
                        help="graph_viewer's legacy_subprotocol false: the SDK serves the port "
                             'itself (clients of foxglove.sdk.v1 only)')
    parser.add_argument('--foxglove-image-rate', type=float, default=0.0, metavar='HZ',
                        help="graph_viewer's max_image_rate_hz (default: the node's)")
    parser.add_argument('--viewer', action='append', default=[], metavar='NAME=VALUE',
                        help='a graph_viewer parameter for --foxglove-interleaved (repeatable; '
                             'a lever to measure, as nice=0)')
    parser.add_argument('--tamer', action='append', default=[], metavar='NAME=VALUE',
                        help='a tamer_node parameter for both runs (repeatable; a lever to '
                             'measure, as learner_nice=0)')
    parser.add_argument('--acting-first', action='store_true',
                        help="the graph run with attention_train's --acting-first (the nodes "
                             'off the acting path in the idle scheduling class)')
    args = parser.parse_args()
    tamer = dict(_lever(item) for item in args.tamer)
    with tempfile.TemporaryDirectory(prefix='bench_graph_') as tmp:
        workdir = Path(tmp)
        if args.foxglove_interleaved:
            print(f'Machine: {machine()}; executor {executor_name()}')
            return foxglove_interleaved(args.graph_steps, args.foxglove_interleaved, workdir,
                                        args.pace_updates, args.foxglove_channels,
                                        dict(_lever(item) for item in args.viewer))
        if args.foxglove:
            print(f'Machine: {machine()}; executor {executor_name()}')
            return foxglove_cost(args.foxglove, args.graph_steps, workdir, args.pace_updates,
                                 args.foxglove_channels, args.foxglove_legacy,
                                 not args.foxglove_no_relay, args.foxglove_image_rate)
        load_before = os.getloadavg()[0]
        local = in_process_run(args.inprocess_steps, workdir, args.pace_updates, tamer)
        graph = graph_run(args.graph_steps, workdir, args.pace_updates, tamer=tamer,
                          extra=('--acting-first',) if args.acting_first else ())
        load_after = os.getloadavg()[0]
    print(f'Machine: {machine()}; load average {load_before:.1f} before, '
          f'{load_after:.1f} after (1 min); executor {executor_name()}')
    print(f'pace_updates {args.pace_updates:g}; tamer_node {tamer or "defaults"}; '
          f'acting first: {"yes" if args.acting_first else "no"}. '
          f'Graph run: {graph["steps"]} steps in {graph["wall_s"]:.0f} s wall '
          f'(start-up {graph["startup_s"]:.1f} s), {graph["latency_n"]} latency samples; '
          f'in process: {local["steps"]} steps\n')
    print(table(graph, local))
    return 0


if __name__ == '__main__':
    sys.exit(main())
