"""
``attention_train``: train the agent with the whole graph, in one command.

Runs in the ROS domain the user chose (``--domain``, else ``ROS_DOMAIN_ID`` when set) or else
reserves one of its own (localhost discovery either way), starts the four node executables from
this Python's bin folder as separate processes, each with the same ``--params-file`` list
(graph defaults, condition, the user's files, the launcher's overrides), watches the graph with
its own node, shows a progress bar, stops every node cleanly (SIGINT, then SIGTERM / SIGKILL
after a deadline) at the end of the budget or on Ctrl-C, and writes the run folder.

Exit code: 0 when the budget was trained and every node exited with 0; 1 when a node died,
the graph stalled or a node did not stop cleanly; 2 for bad options or files; 130 on Ctrl-C.
"""

import datetime
import functools
import os
from pathlib import Path
import re
import signal
import sys
import time
from typing import Optional

from attention_bringup import drain, report
from attention_bringup.driver import Driver
from attention_bringup.gallery import GalleryCollector
from attention_bringup.graph import NODES
from attention_bringup.params import ParamsFileError
from attention_bringup.plan import (
    build_plan, chosen_domain, CONSOLE, Continuation, FOXGLOVE, LaunchPlan, parse_options,
    RECORDER, resumed_options, save_options)
from attention_bringup.processes import (
    cpu_seconds, exit_description, idle_this_process, log_tail, node_environ, NodeGroup,
    resident_memory_kb, run_graph)
from attention_bringup.progress import format_bar, ProgressTracker
from attention_common.node_main import unblock_stop_signals
from attention_common.run_files import (
    CHECKPOINT_DIR, FEEDBACK_LOG, GALLERY_FILE, LEARNING_CURVE_FILE, LOGS_DIR, METRICS_CSV,
    of_session, OPTIONS_FILE, OVERRIDES_FILE, PARAMS_FILE, PIDS_FILE, PROGRESS_FILE, SUMMARY_FILE)
from attention_tasks.task import load_task, ROOM_1
from graph_viewer.layout import LAYOUT_FILE, LICHTBLICK_FILE
from session_bag import info as bag_info
from session_bag.reader import ends_whole, storage_path
from session_bag.repair import repair

STARTUP_TIMEOUT_S = 300.0
"""Longest wait for the first step (node start-up includes importing torch on a busy CPU)."""
ENV_MATCH_TIMEOUT_S = 60.0
"""Longest wait for the launcher's monitor to match env_node's publishers."""
STOP_TIMEOUT_S = 30.0
"""SIGINT to exit: the tamer writes its final checkpoint in this time."""
EXIT_INTERRUPTED = 130


SERVERS = (
    ('console', CONSOLE, r'trainer console at (\S+)',
     'Trainer console: {url} (open it in a browser: + or Up is good, - or Down is bad, type '
     'words and press Enter)'),
    ('foxglove', FOXGLOVE, r'Foxglove bridge at (\S+)',
     'Foxglove: {url} (in Foxglove or Lichtblick: Open connection, Foxglove WebSocket, this '
     'URL; the layout: {layout}, in Lichtblick {lichtblick_layout})'),
)
"""(option, node, what its log says once it serves, what the launcher prints)."""


class Launcher:
    """One run: start, watch, stop, report."""

    def __init__(self, plan: LaunchPlan, domain_id: int, out=sys.stdout, err=sys.stderr):
        self.plan = plan
        self.domain_id = domain_id
        self.out, self.err = out, err
        self.interrupts = 0
        self.started_wall = time.monotonic()
        self.interactive = (not plan.options.quiet) and err.isatty()
        self._gallery_steps = {}  # gallery image stamp -> agent step
        self.urls: dict = {}
        """The URL each server (``SERVERS``) printed once it served."""

    # -- set-up ---------------------------------------------------------------------------
    def _prepare_run_dir(self) -> None:
        run_dir = self.plan.run_dir
        session = self.plan.continuation.session
        summary = run_dir / SUMMARY_FILE
        if session > 1:  # the earlier session's summary is kept under its own name
            if summary.exists():
                summary.replace(run_dir / of_session(SUMMARY_FILE, session - 1))
        elif summary.exists() or (run_dir / OPTIONS_FILE).exists():
            raise FileExistsError(f'{run_dir} already holds a run; continue it with --resume '
                                  f'{run_dir}, or choose another --run-dir')
        (run_dir / LOGS_DIR).mkdir(parents=True, exist_ok=True)
        if session == 1:
            save_options(self.plan.options, run_dir)
        (run_dir / OVERRIDES_FILE).write_text(self.plan.overrides_text())
        report.write_params(run_dir / PARAMS_FILE, self.plan.effective,
                            self.plan.options_dict(), 'from the parameter files, at start')

    def _node_environ(self) -> dict:
        return node_environ(self.domain_id, self.plan.run_dir / LOGS_DIR)

    def _on_signal(self, signum, frame) -> None:
        self.interrupts += 1

    # -- the run --------------------------------------------------------------------------
    def run(self) -> int:
        self._prepare_run_dir()
        previous = {sig: signal.signal(sig, self._on_signal)
                    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
        unblock_stop_signals()  # (and its nodes, which inherit the mask, hear them too)
        try:
            return self._run()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    def _run(self) -> int:
        from attention_bringup.monitor import GraphMonitor

        radius = self.plan.critical_radius  # the feedback node's, so progress agrees with it
        task = load_task(self.plan.options.task)
        tracker = ProgressTracker(milestone_of=functools.partial(task.milestone_of,
                                                                 radius=radius),
                                  standing_poses=task.standing_poses,
                                  solved_of=task.solved)
        continuation = self.plan.continuation
        progress_file = self.plan.run_dir / PROGRESS_FILE
        if continuation.session > 1 and progress_file.exists():
            tracker.resume_from(report.read_progress_rows(progress_file))
        tracker.session = continuation.session
        options = self.plan.options

        def monitor_of(context):
            return GraphMonitor(tracker, GalleryCollector(), watch_plain=not options.synthetic,
                                context=context)

        with Driver(self.domain_id, monitor_of, self.err) as driver:
            writer = report.ProgressWriter(progress_file, append=continuation.session > 1)
            group = NodeGroup(self._node_environ())
            trainer = (f'trainer {options.trainer}' +
                       (', human-like' if options.human_like else '')
                       if options.synthetic else 'a person trains')
            resumed = (f', session {continuation.session} from step {continuation.steps_done}'
                       if continuation.session > 1 else '')
            self._say(f'Run folder {self.plan.run_dir} (ROS domain {self.domain_id}); '
                      f'{options.condition}, {trainer}, {options.steps} steps{resumed}')
            driver.exit_code = self._run_nodes(group, driver.node, writer, tracker)
            return driver.exit_code

    def _run_nodes(self, group: NodeGroup, monitor, writer, tracker) -> int:
        """Start the nodes, watch the run, stop the nodes, write the run folder."""
        try:
            status, failed = self._start_nodes(group, monitor)
            if status is None and self.plan.options.acting_first:
                idle_this_process()  # off the acting path too, once every node is up
            if status is None:
                status, failed = self._watch(group, monitor, writer)
            if status == 'completed':
                self._drain(monitor)
            rss = {node.name: resident_memory_kb(node.pid) for node in group.running()}
            cpu = {node.name: cpu_seconds(node.pid) for node in group.running()}
            cpu['attention_train'] = sum(os.times()[:2])
            queried = {}
            if self.interrupts < 2:
                alive = [node.name for node in group.running()]
                queried = monitor.query_parameters(alive)
            self._clear_bar()
            if status != 'node_failed':
                self._say('Stopping the nodes (SIGINT)...')
            exit_codes = group.stop(STOP_TIMEOUT_S, escalate=lambda: self.interrupts >= 2,
                                    last=(RECORDER,))
            with monitor.lock:
                writer.write(tracker.take_new_rows())
                self._label_gallery(tracker, monitor.gallery)
        finally:
            if group.running():  # only after an error in the launcher itself
                group.stop(sigint_timeout=10.0)
            writer.close()
        return self._finish(status, failed, group, monitor, exit_codes, rss, cpu, queried)

    def _start_nodes(self, group: NodeGroup, monitor):
        """
        Start the nodes in an order that loses no step; return (status, node) on failure.

        Lockstep: env_node first; the others once the monitor hears it (the env steps only when
        the learner answers, and the monitor must be matched with the env's publishers by
        then). Real time: the env steps on its timer from the start, so the other three go
        first and env_node starts once they listen.
        """
        env = [c for c in self.plan.commands if c.name == 'env_node']
        recorder = [c for c in self.plan.commands if c.name == RECORDER]
        learners = [c for c in self.plan.commands if c.name not in ('env_node', RECORDER)]
        if recorder:  # first: the bag holds the session from its first message
            self._start(group, recorder)
            failure = self._wait_for(
                group, lambda: monitor.node_subscribes(RECORDER, 'observation'),
                STARTUP_TIMEOUT_S, f'{RECORDER} does not subscribe')
            if failure:
                return failure
        if self.plan.options.realtime:
            self._start(group, learners)
            failure = self._wait_for(group,
                                     lambda: monitor.learners_listen(recorders=len(recorder)),
                                     STARTUP_TIMEOUT_S,
                                     'feedback_node, saliency_node and tamer_node do not listen')
            if failure:
                return failure
        self._start(group, env)
        failure = self._wait_for(group, monitor.hears_env, ENV_MATCH_TIMEOUT_S,
                                 'the launcher does not hear env_node')
        if failure:
            return failure
        monitor.watch_images()
        if not self.plan.options.realtime:
            self._start(group, learners)
        return None, None

    def _start(self, group: NodeGroup, commands) -> None:
        """Start ``commands`` and rewrite pids.json with every node started so far."""
        for command in commands:
            group.start(command)
        self._write_pids(group)

    def _wait_for(self, group: NodeGroup, ready, timeout_s: float, what: str):
        """Wait until ``ready()``; return None, or (status, node) on a death or a timeout."""
        failure = group.wait_ready(ready, timeout_s, lambda: self._interrupted_or_dead(group))
        if failure == ('stalled', None):
            self.err.write(f'attention_train: {what} after {timeout_s:.0f} s; node logs are '
                           f'in {self.plan.run_dir / LOGS_DIR}\n')
        return failure

    def _interrupted_or_dead(self, group: NodeGroup):
        """Return (status, node) after Ctrl-C or a node's death (reported), else None."""
        return group.interrupted_or_dead(bool(self.interrupts), self._say_death,
                                         'attention_train')

    def _write_pids(self, group: NodeGroup) -> None:
        report.write_json(self.plan.run_dir / PIDS_FILE,
                          {'attention_train': os.getpid(), 'domain_id': self.domain_id,
                           **group.pids()})

    def _watch(self, group: NodeGroup, monitor, writer):
        """Wait for the end of the budget, a dead node, a stall or Ctrl-C."""
        budget = self.plan.options.steps
        last_steps, last_change = -1, time.monotonic()
        last_line = 0.0
        while True:
            ended = self._interrupted_or_dead(group)
            if ended:
                return ended
            self._announce_servers()
            with monitor.lock:
                tracker = monitor.tracker
                writer.write(tracker.take_new_rows())
                self._label_gallery(tracker, monitor.gallery)
                steps, rate, finished = tracker.steps, tracker.rate(), tracker.finished
                monitor.gallery.on_schedule(steps, budget)
                bar = format_bar(steps, budget, rate, tracker.counters.feedback,
                                 tracker.furthest, tracker.latest.get('episode'),
                                 tracker.latest.get('lives'))
                started = bool(tracker.rows)
            now = time.monotonic()
            if finished:
                self._show(bar)
                return 'completed', None
            if steps != last_steps:
                last_steps, last_change = steps, now
            limit = self.plan.options.stall_timeout if started else STARTUP_TIMEOUT_S
            if now - last_change > limit:
                if self._env_paused(monitor):
                    last_change = now  # a person paused the env: waiting is no stall
                else:
                    self._report_stall(monitor, started, limit)
                    return 'stalled', None
            if self.interactive or now - last_line >= 15.0:
                self._show(bar)
                last_line = now
            time.sleep(0.2)

    def _announce_servers(self) -> None:
        """Print each server's URL once it serves (``--console``, ``--foxglove``)."""
        for option, name, pattern, text in SERVERS:
            if not getattr(self.plan.options, option) or self.urls.get(option):
                continue
            command = next(c for c in self.plan.commands if c.name == name)
            found = re.search(pattern, log_tail(command.log_path))
            if found:
                self.urls[option] = found.group(1)
                self._say(text.format(url=found.group(1), layout=LAYOUT_FILE,
                                      lichtblick_layout=LICHTBLICK_FILE.name))

    def _label_gallery(self, tracker, gallery) -> None:
        """Note the agent step of each gallery image while the tracker still knows it."""
        for sample in gallery.samples:
            step = tracker.step_at_stamp.get(sample.stamp_ns)
            if step is not None:
                self._gallery_steps.setdefault(sample.stamp_ns, step)

    def _drain(self, monitor, quiet_s: float = 0.5, timeout_s: float = 3.0) -> None:
        """After the last step, let the last feedback and metrics reach the tamer and us."""
        if self.plan.options.synthetic:
            self._wait_for_trainer(monitor)
        end = time.monotonic() + timeout_s
        previous, since = None, time.monotonic()
        while time.monotonic() < end and not self.interrupts:
            with monitor.lock:
                current = dict(monitor.counts)
            if current != previous:
                previous, since = current, time.monotonic()
            elif time.monotonic() - since >= quiet_s:
                return
            time.sleep(0.05)

    def _wait_for_trainer(self, monitor) -> None:
        """Wait until the trainer judged the last step and the learner logged all it gave."""
        end = time.monotonic() + drain.TRAINER_DRAIN_S
        while not self.interrupts:
            with monitor.lock:
                missing = drain.behind(monitor.trainer_status, monitor.tracker.last_stamp_ns,
                                       monitor.receipts, drain.logged_lines(monitor.metrics))
            if missing is None:
                return
            if time.monotonic() >= end:
                self.err.write(f'attention_train: stopping the nodes although {missing} '
                               f'after {drain.TRAINER_DRAIN_S:.0f} s\n')
                return
            time.sleep(0.05)

    # -- terminal -------------------------------------------------------------------------
    def _show(self, bar: str) -> None:
        if self.plan.options.quiet:
            return
        self.err.write('\r' + bar[:200] + '\033[K' if self.interactive else bar + '\n')
        self.err.flush()

    def _clear_bar(self) -> None:
        if self.interactive:
            self.err.write('\n')
            self.err.flush()

    def _say(self, text: str) -> None:
        if not self.plan.options.quiet:
            self._clear_bar()
            self.err.write(text + '\n')
            self.err.flush()

    def _say_death(self, text: str) -> None:
        self._clear_bar()
        self.err.write(text)
        self.err.flush()

    @staticmethod
    def _env_paused(monitor) -> bool:
        """Return whether the env is paused: at an episode's start, or by the console."""
        with monitor.lock:
            if monitor.env_message == 'paused':  # pause_each_episode
                return True
        values = monitor.query_parameters(['env_node'], timeout_s=5.0).get('env_node')
        return bool(values and values.get('paused'))

    def _report_stall(self, monitor, started: bool, limit: float) -> None:
        self._clear_bar()
        with monitor.lock:
            silent = [topic for topic, count in monitor.counts.items() if count == 0]
        what = 'no new step' if started else 'no first step'
        self.err.write(f'attention_train: {what} for {limit:.0f} s; topics never heard: '
                       f'{", ".join(silent) or "none"}. Node logs are in '
                       f'{self.plan.run_dir / LOGS_DIR}. Stopping.\n')
        self.err.flush()

    # -- the run folder -------------------------------------------------------------------
    def _finish(self, status, failed, group, monitor, exit_codes, rss, cpu, queried) -> int:
        run_dir = self.plan.run_dir
        tracker = monitor.tracker
        unclean = {name: code for name, code in exit_codes.items() if code != 0}
        if status == 'completed' and unclean:
            status = 'unclean_exit'
        exit_text = self._exit_text(status, failed, exit_codes, group)
        node_params = {name: (queried.get(name) if queried.get(name) is not None
                              else self.plan.effective[name]) for name in NODES}
        source = ('queried from the running nodes at the end of the run'
                  if queried and all(queried.get(n) is not None for n in NODES)
                  else 'queried from the nodes that answered; the others from the files')
        report.write_params(run_dir / PARAMS_FILE, node_params,
                            self.plan.options_dict(), source)
        summary = self._summary(status, failed, exit_codes, exit_text, group, monitor, rss,
                                queried)
        summary['teardown_watchdog'] = group.teardown_hangs()
        summary['cpu_s'] = {name: None if value is None else round(value, 2)
                            for name, value in cpu.items()}
        summary['learner_log'] = report.learner_log_counts(run_dir / FEEDBACK_LOG)
        title = (f'{self.plan.options.condition}, seed {self.plan.seed}, '
                 f'{summary["steps"]} steps')
        rows = report.read_rows_for_plot(run_dir / PROGRESS_FILE, tracker.row_count)
        summary['files']['learning_curve'] = report.plot_learning_curve(
            rows, run_dir / LEARNING_CURVE_FILE, title)
        samples = monitor.gallery.samples
        summary['gallery'] = {'samples': len(samples),
                              'with_saliency': sum(s.saliency is not None for s in samples)}
        summary['files']['saliency_gallery'] = report.plot_gallery(
            monitor.gallery.samples, run_dir / GALLERY_FILE, title,
            step_of=self._gallery_steps)
        summary['bag'] = self._bag(exit_codes)
        summary['files']['bag'] = summary['bag'] and summary['bag'].get('dir')
        report.write_json(run_dir / SUMMARY_FILE, summary)
        self.out.write(f'Run folder: {run_dir}\n')
        for line in report.summary_lines(summary):
            self.out.write(f'  {line}\n')
        if summary['bag'] and 'messages' in summary['bag']:
            self.out.write(f'  {bag_info.summary_line(summary["bag"])}\n')
        self.out.flush()
        if status == 'completed':
            return 0
        return EXIT_INTERRUPTED if status == 'interrupted' else 1

    def _bag(self, exit_codes) -> Optional[dict]:
        """Return what the session's bag holds; repair it first if its recorder was killed."""
        if not self.plan.options.records:
            return None
        bag_dir = self.plan.bag_dir
        try:
            repaired = None
            if exit_codes.get(RECORDER) != 0 or not ends_whole(storage_path(bag_dir)):
                repaired = repair(bag_dir)
                self.err.write(f'attention_train: {RECORDER} did not exit cleanly; the bag '
                               f'was repaired ({repaired.messages} messages kept)\n')
            summary = bag_info.bag_summary(bag_dir)
        except Exception as error:  # noqa: B902 - the run folder is written whatever the bag
            return {'dir': str(bag_dir), 'error': f'{type(error).__name__}: {error}'}
        summary['dir'] = bag_dir.name  # relative to the run folder, like the other files
        summary['repaired'] = repaired is not None
        return summary

    def _exit_text(self, status, failed, exit_codes, group) -> str:
        if status == 'completed':
            return f'all {len(group.nodes)} nodes exited cleanly'
        parts = []
        for node in group.nodes:
            code = exit_codes.get(node.name)
            text = f'{node.name} {exit_description(code)}'
            if node.name == failed:
                text += ' (died during the run)'
            elif len(node.stopped_with) > 1:
                text += f' (needed {node.stopped_with[-1]})'
            parts.append(text)
        return '; '.join(parts)

    def _summary(self, status, failed, exit_codes, exit_text, group, monitor, rss, queried):
        tracker = monitor.tracker
        with monitor.lock:
            counts = dict(monitor.counts)
            first_seen = {topic: round(t, 2) for topic, t in monitor.first_message_wall.items()}
            metrics = dict(monitor.metrics)
            trainer = dict(monitor.trainer_status) if monitor.trainer_status else None
            receipts = dict(monitor.receipts)
            first, last = tracker.first_row, (tracker.rows[-1] if tracker.rows else None)
        training_s = (last['wall_time_s'] - first['wall_time_s']
                      if tracker.row_count > 1 else 0.0)
        steps = tracker.steps
        first_steps = first['agent_step'] if first else 0
        feedback = tracker.counters.feedback

        def ms(q):
            value = tracker.latency_ms(q)
            return None if value is None else round(value, 3)

        run_dir = self.plan.run_dir
        return {
            'status': status,
            'exit_text': exit_text,
            'failed_node': failed,
            'condition': self.plan.options.condition,
            'seed': self.plan.seed,
            'budget': self.plan.options.steps,
            'steps': steps,
            'session': self.plan.continuation.session,
            'console_url': self.urls.get('console'),
            'foxglove_url': self.urls.get('foxglove'),
            'wall_time_s': round(time.monotonic() - self.started_wall, 2),
            'startup_s': first['wall_time_s'] if first else None,
            'training_time_s': round(training_s, 2),
            'steps_per_s': round((steps - first_steps) / training_s, 2) if training_s else 0.0,
            'task': self.plan.options.task,
            **task_measures(load_task(self.plan.options.task), tracker),
            'trainer': self.plan.options.trainer,
            'human_like': self.plan.options.human_like,
            'feedback_count': feedback,
            'feedback_mean': round(tracker.counters.feedback_sum / feedback, 4) if feedback
            else 0.0,
            'utterance_count': tracker.counters.utterances,
            'message_counts': counts,
            'trainer_counts': trainer,
            'receipts': receipts,
            'first_message_s': first_seen,
            'latency_ms': {'p50': ms(50), 'p99': ms(99), 'max': ms(100),
                           'n': int(tracker.latencies_ms.count)},
            'metrics': metrics,
            'rss_kb': rss,
            'exit_codes': exit_codes,
            'signals_sent': {node.name: node.stopped_with for node in group.nodes},
            'pids': group.pids(),
            'domain_id': self.domain_id,
            'parameters_queried': sorted(name for name, v in queried.items() if v is not None),
            'options': self.plan.options_dict(),
            'params_files': [str(path) for path in self.plan.params_files],
            'finished_at': datetime.datetime.now().isoformat(timespec='seconds'),
            'files': {
                'params': PARAMS_FILE,
                'progress': PROGRESS_FILE,
                'metrics': METRICS_CSV if (run_dir / METRICS_CSV).exists() else None,
                'checkpoints': CHECKPOINT_DIR if (run_dir / CHECKPOINT_DIR).is_dir() else None,
                'logs': LOGS_DIR,
            },
        }


def task_measures(task, tracker: ProgressTracker) -> dict:
    """
    Return what a run reached, in its task's terms.

    Every task: its milestones by name, the first step at each (``milestone_steps``), the
    furthest, the episodes and those solved; held-out episodes where the task has held-out
    layouts. Room 1 keeps the thesis's names beside them (critical positions by index, keys,
    lives, positions stood on).
    """
    furthest = tracker.furthest
    measures = {
        'milestones': list(task.milestones),
        'milestone_steps': tracker.milestone_steps(task.milestones),
        'furthest_milestone': task.milestones[furthest] if furthest >= 0 else None,
        'episodes': len(tracker.episodes),
        'episodes_solved': len(tracker.solved_episodes),
    }
    if task.heldout_layouts:
        measures['heldout_episodes'] = len(tracker.heldout_episodes)
        measures['heldout_episodes_solved'] = len(tracker.heldout_episodes
                                                  & tracker.solved_episodes)
    if task.name == ROOM_1:
        measures.update({
            'lives_lost': tracker.lives_lost,
            'keys': tracker.keys,
            'first_key_step': tracker.first_key_step,
            'furthest_position': furthest,
            'first_step_at_position': {str(k): v for k, v in
                                       sorted(tracker.first_step_at.items())},
            'furthest_position_stood': tracker.furthest_stood,
            'first_step_stood_at_position': {str(k): v for k, v in
                                             sorted(tracker.first_step_stood_at.items())},
        })
    return measures


def continuation_of(run_dir: Path) -> Continuation:
    """Where the run in ``run_dir`` stands: the next session, and the steps done so far."""
    last = None
    progress = run_dir / PROGRESS_FILE
    if progress.exists():
        for last in report.read_progress_rows(progress):
            pass
    if last is None:
        sessions = [int(p.stem.split('session')[1])
                    for p in run_dir.glob(of_session(SUMMARY_FILE, '*'))]
        return Continuation(session=max(sessions, default=1) + 1, steps_done=0)
    return Continuation(session=int(last.get('session') or 1) + 1,
                        steps_done=int(last['agent_step']))


def main(argv: Optional[list] = None) -> int:
    options = parse_options(argv)
    try:
        continuation = None
        if options.resume is not None:
            run_dir = Path(options.resume).resolve()
            options = resumed_options(run_dir, options.quiet)
            continuation = continuation_of(run_dir)
        plan = build_plan(options, Path(sys.executable).parent, Path.cwd(),
                          continuation=continuation)
    except (ParamsFileError, ValueError) as error:
        sys.stderr.write(f'attention_train: {error}\n')
        return 2
    try:
        chosen = chosen_domain(plan.options, os.environ)
    except ValueError as error:
        sys.stderr.write(f'attention_train: {error}\n')
        return 2
    return run_graph('attention_train', plan.commands, chosen,
                     lambda domain_id: Launcher(plan, domain_id).run())


if __name__ == '__main__':
    sys.exit(main())
