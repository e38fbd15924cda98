"""
``attention_replay BAG``: a recorded session replayed into a fresh saliency_node and tamer_node.

Offline TAMER from a person's session: the new learner sees the session's observations and
hears its feedback and utterances in recorded order (and timing, unless ``--fast``), learns the
feedback on the actions the session's agent took (``action_taken``), and answers every
observation with its own greedy action, which is compared with the session's. The run folder
holds the learner's files (feedback log, metrics, checkpoints), ``replay_steps.csv``,
``learning_curve.png`` and ``summary.json``.

``--all-conditions`` replays the same session once per study condition and prints a table: the
learner changes, the person's teaching does not. It is the ``replay`` experiment spec run by the
experiment engine with this bag, seed and ``--out`` (resumable: ``OUT/trials/`` holds each
finished replay's result file, ``OUT/<condition>/seed<k>/`` its run folder); ``--conditions``
names fewer (or other) conditions, ``--parallel`` runs several replays side by side.

Exit code: 0 when every item was sent and both nodes exited cleanly; 1 when a node died or did
not start; 2 for bad options, bags or files; 130 on Ctrl-C.
"""

import csv
import dataclasses
import datetime
import json
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Optional

from attention_bringup import report
from attention_bringup.driver import Driver
from attention_bringup.experiment import engine, runner, spec as specs
from attention_bringup.experiment.plugins.replay import bag_steps
from attention_bringup.experiment.runner import Backend
from attention_bringup.experiment.spec import Arm
from attention_bringup.graph import THESIS_CONDITIONS
from attention_bringup.params import ParamsFileError
from attention_bringup.plan import chosen_domain
from attention_bringup.processes import (
    executables_found, node_environ, NodeGroup, run_graph)
from attention_bringup.replay.output import plot_replay, study_table, summary_lines
from attention_bringup.replay.plan import (
    build_plan, OPTIONS_FILE, PARAMS_FILE, parse_options, ReplayPlan, STEPS_FILE)
from attention_bringup.replay.player import (
    feedback_receipt, ReplayPlayer, sleep_until, task_action_of_bytes)
from attention_bringup.replay.session import Agreement, RECEIPTED, replay_items
from attention_common import topics
from attention_common.node_main import unblock_stop_signals
from attention_common.run_files import LEARNING_CURVE_FILE, LOGS_DIR, REPLAY_LOG, SUMMARY_FILE
from attention_tasks.task import load_task
from session_bag.reader import BagReader

STARTUP_TIMEOUT_S = 300.0
ANSWER_TIMEOUT_S = 10.0
"""Longest wait for the learner's answer to one observation (then the step counts unanswered)."""
RESEND_S = 1.0
"""Without an answer by then, the observation goes again (same stamp), as the env re-sends its
first step: a DDS match is per side, and a reader that matched late drops what came before."""
RECEIPT_TIMEOUT_S = 10.0
METRICS_TIMEOUT_S = 5.0
STOP_TIMEOUT_S = 30.0
PROGRESS_PERIOD_S = 15.0
EXIT_INTERRUPTED = 130


def send_until_answered(send, wait, timeout_s: float = ANSWER_TIMEOUT_S,
                        resend_s: float = RESEND_S) -> int:
    """
    ``send()`` an observation, then again every ``resend_s`` until ``wait(s)`` sees its answer.

    Return how many times it was sent; after ``timeout_s`` it stops (the step is unanswered).
    """
    deadline = time.monotonic() + timeout_s
    sent = 0
    while True:
        send()
        sent += 1
        left = deadline - time.monotonic()
        if wait(max(0.0, min(resend_s, left))) or left <= resend_s:
            return sent


class Replay:
    """One replay: start the two nodes, send the bag, stop them, write the run folder."""

    def __init__(self, plan: ReplayPlan, domain_id: int, out=sys.stdout, err=sys.stderr):
        self.plan = plan
        self.domain_id = domain_id
        self.out, self.err = out, err
        self.task = load_task(plan.task)
        self.interrupted = threading.Event()
        self.agreement = Agreement()
        self.counts = {}
        self.session_receipts = []  # the session's feedback stamps, in logged order

    def _say(self, text: str) -> None:
        if not self.plan.options.quiet:
            self.err.write(text + '\n')
            self.err.flush()

    def run(self) -> int:
        run_dir = self.plan.run_dir
        # (an experiment's runner writes this replay's output in REPLAY_LOG before it starts)
        if run_dir.exists() and any(p.name != REPLAY_LOG for p in run_dir.iterdir()):
            raise FileExistsError(f'{run_dir} is not empty; choose another --run-dir')
        (run_dir / LOGS_DIR).mkdir(parents=True)
        (run_dir / PARAMS_FILE).write_text(self.plan.params_text())
        report.write_json(run_dir / OPTIONS_FILE, self.plan.options_dict())
        previous = {sig: signal.signal(sig, lambda *_: self.interrupted.set())
                    for sig in (signal.SIGINT, signal.SIGTERM)}
        unblock_stop_signals()
        try:
            return self._run()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    def _run(self) -> int:
        with Driver(self.domain_id, lambda context: ReplayPlayer(self.task, context=context),
                    self.err) as driver:
            player = driver.node
            group = NodeGroup(node_environ(self.domain_id, self.plan.run_dir / LOGS_DIR))
            started = time.monotonic()
            self._say(f'Replaying {self.plan.bag_dir} into {self.plan.run_dir} (ROS domain '
                      f'{self.domain_id}); {self.plan.task}, {self.plan.condition}, seed '
                      f'{self.plan.seed}, '
                      f'{"fast" if self.plan.options.fast else "recorded timing"}')
            status = 'completed'
            try:
                for command in self.plan.commands:
                    group.start(command)
                status = self._wait_ready(group, player)
                if status is None:
                    status = self._send(group, player)
                exit_codes = group.stop(STOP_TIMEOUT_S)
            finally:
                if group.running():
                    group.stop(sigint_timeout=10.0)
            if status == 'completed' and any(code != 0 for code in exit_codes.values()):
                status = 'unclean_exit'
            driver.exit_code = self._finish(status, exit_codes, player,
                                            time.monotonic() - started)
            return driver.exit_code

    def _wait_ready(self, group: NodeGroup, player: ReplayPlayer) -> Optional[str]:
        failure = group.wait_ready(player.nodes_listen, STARTUP_TIMEOUT_S,
                                   lambda: self._ended(group))
        if failure == ('stalled', None):
            self.err.write(f'attention_replay: the nodes do not listen after '
                           f'{STARTUP_TIMEOUT_S:.0f} s; logs in {self.plan.run_dir / LOGS_DIR}\n')
        return failure and failure[0]

    def _ended(self, group: NodeGroup) -> Optional[tuple]:
        """Return ('interrupted', None) after Ctrl-C, ('node_failed', node) (said), else None."""
        return group.interrupted_or_dead(self.interrupted.is_set(), self.err.write,
                                         'attention_replay')

    def _send(self, group: NodeGroup, player: ReplayPlayer) -> str:
        """Send every item of the bag in order; return the run's status."""
        fast = self.plan.options.fast
        reader = BagReader(self.plan.bag_dir)
        receipts_expected = 0
        first_log = start = None
        last_line = time.monotonic()
        for item in replay_items(self._watch_session(reader.messages())):
            ended = self._ended(group)
            if ended:
                return ended[0]
            if first_log is None:
                first_log, start = item.log_time, time.monotonic()
            if not fast:
                sleep_until(start + (item.log_time - first_log) / 1e9)
            self.counts[item.topic] = self.counts.get(item.topic, 0) + 1
            if item.topic == topics.OBSERVATION:
                self._step(player, item)
            else:
                player.send(item.topic, item.data)
                if item.topic in RECEIPTED:
                    receipts_expected += 1
                    if fast:  # the learner has it before the next observation, as it had
                        player.wait_receipts(receipts_expected, RECEIPT_TIMEOUT_S)
            if not self.plan.options.quiet and time.monotonic() - last_line > PROGRESS_PERIOD_S:
                last_line = time.monotonic()
                fraction = self.agreement.fraction()
                self._say(f'  {len(self.agreement.rows)} steps replayed, agreement '
                          f'{"-" if fraction is None else f"{fraction:.3f}"}, '
                          f'{player.receipts} feedback/utterances logged')
        if not player.wait_receipts(receipts_expected, RECEIPT_TIMEOUT_S):
            self.err.write(f'attention_replay: {receipts_expected - player.receipts} of '
                           f'{receipts_expected} feedback/utterances not logged by the learner '
                           f'within {RECEIPT_TIMEOUT_S:.0f} s\n')
        # The learner's metrics once they count every step sent (the summary's numbers).
        player.wait_metrics('act/count', len(self.agreement.rows), METRICS_TIMEOUT_S)
        self.complete = reader.complete
        self.problem = reader.problem
        return 'completed'

    def _step(self, player: ReplayPlayer, item) -> None:
        """Send one step: what the world executed on it, then its observation; await the answer."""
        session = item.executed
        if session is None and item.answered is not None:  # (a bag without env_status)
            session = task_action_of_bytes(item.answered, self.task)
        if session is not None:
            player.send_taken(item.stamp, session)
        send_until_answered(lambda: player.send(topics.OBSERVATION, item.data),
                            lambda wait_s: player.wait_answer(item.stamp, wait_s))
        self.agreement.add(item.stamp, session, player.answer(item.stamp))

    def _watch_session(self, messages):
        """Pass the bag's messages on; note the session's own feedback receipts on the way."""
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.serialization import deserialize_message
        for message in messages:
            if message.topic.endswith('/' + topics.FEEDBACK_LOGGED):
                for status in deserialize_message(message.data, DiagnosticArray).status:
                    receipt = feedback_receipt(status)
                    if receipt is not None:
                        self.session_receipts.append(receipt)
            yield message

    def _finish(self, status, exit_codes, player, wall_s) -> int:
        run_dir = self.plan.run_dir
        rows = self.agreement.rows
        with open(run_dir / STEPS_FILE, 'w', newline='') as file:
            writer = csv.DictWriter(file, fieldnames=list(rows[0]) if rows else ['step'])
            writer.writeheader()
            writer.writerows(rows)
        # The k-th feedback each learner logged (a resumed session's seq does not start at 1).
        session = [stamp for _, stamp in sorted(self.session_receipts)]
        replayed = [stamp for _, stamp in sorted(player.receipt_stamps.items())]
        compared = list(zip(session, replayed))
        same = [1 for a, b in compared if a == b]
        summary = {
            'kind': 'replay',
            'status': status,
            'bag': str(self.plan.bag_dir),
            'bag_complete': getattr(self, 'complete', None),
            'bag_problem': getattr(self, 'problem', None),
            'task': self.plan.task,
            'condition': self.plan.condition,
            'session_condition': self.plan.session.options.get('condition'),
            'seed': self.plan.seed,
            'fast': self.plan.options.fast,
            'wall_time_s': round(wall_s, 2),
            'sent': self.counts,
            'receipts': player.receipts,
            'feedback_same_step': {'same': len(same), 'compared': len(compared)},
            **self.agreement.summary(),
            'chance_agreement': round(1.0 / self.task.num_actions, 4),
            'metrics': dict(player.metrics),
            'exit_codes': exit_codes,
            'domain_id': self.domain_id,
            'finished_at': datetime.datetime.now().isoformat(timespec='seconds'),
            'files': {'params': PARAMS_FILE, 'steps': STEPS_FILE, 'logs': LOGS_DIR},
        }
        summary['files']['learning_curve'] = plot_replay(
            summary, run_dir / LEARNING_CURVE_FILE,
            f'replay of {self.plan.bag_dir.parent.name}: {self.plan.condition}, seed '
            f'{self.plan.seed}') and LEARNING_CURVE_FILE
        report.write_json(run_dir / SUMMARY_FILE, summary)
        self.out.write(f'Run folder: {run_dir}\n')
        for line in summary_lines(summary):
            self.out.write(f'  {line}\n')
        self.out.flush()
        if status == 'completed':
            return 0
        return EXIT_INTERRUPTED if status == 'interrupted' else 1


def replay_study(options, plan: ReplayPlan) -> int:
    """``--all-conditions``: the ``replay`` spec on the engine, with this bag, seed and folder."""
    out = Path(options.out or Path('runs') / f'{datetime.datetime.now():%Y%m%d-%H%M%S}'
               '-replay-study').resolve()
    bag_args = [str(plan.bag_dir)] + (['--fast'] if options.fast else []) + [
        word for path in options.params_files
        for word in ('--params-file', str(Path(path).resolve()))]
    if options.task:
        bag_args += ['--task', options.task]
    if options.domain is not None:
        bag_args += ['--domain', str(options.domain)]
    spec = dataclasses.replace(
        specs.load('replay'), source='attention_replay --all-conditions',
        arms=tuple(Arm(c, c) for c in options.conditions or THESIS_CONDITIONS),
        seeds=(plan.seed,), budget=bag_steps(plan.bag_dir), out=str(out),
        report=str(out / 'replay_study.md'), runs_dir=str(out), launcher_args=tuple(bag_args))
    code, result = engine.main_flow(spec, Backend(parallel=options.parallel),
                                    engine.sayer('attention_replay'))
    if code == runner.EXIT_INTERRUPTED:
        sys.stderr.write(f'attention_replay: interrupted; run it again with --out {out} to go '
                         'on\n')
    if code != 0:
        return code
    rows = result['summaries']
    report.write_json(out / 'replay_study.json', rows)
    sys.stdout.write(study_table(rows) + f'\nReplay study: {out}\n')
    completed = [row for row in rows if row.get('status') == 'completed']
    return 0 if len(completed) == len(spec.arms) else 1


def main(argv: Optional[list] = None) -> int:
    options = parse_options(argv)
    try:
        plan = build_plan(options, Path(sys.executable).parent, Path.cwd())
        chosen = chosen_domain(options, os.environ)
    except (ParamsFileError, ValueError, json.JSONDecodeError) as error:
        sys.stderr.write(f'attention_replay: {error}\n')
        return 2
    if not executables_found('attention_replay', plan.commands):
        return 2
    if options.all_conditions or options.conditions:
        if options.parallel > 1 and options.domain is not None:
            sys.stderr.write('attention_replay: --domain runs one replay at a time; drop it or '
                             '--parallel\n')
            return 2
        return replay_study(options, plan)  # (each replay reserves its own domain)
    return run_graph('attention_replay', plan.commands, chosen,
                     lambda domain_id: Replay(plan, domain_id).run())


if __name__ == '__main__':
    sys.exit(main())
