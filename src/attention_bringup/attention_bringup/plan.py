"""
From the launcher's options to the four command lines and the parameters each node gets.

Pure (no rclpy, no processes): ``parse_options`` reads the command line, ``build_plan`` decides
the run folder, the parameter files in order (graph defaults, condition, the user's files, the
launcher's own overrides last) and the effective parameters of every node.
"""

import argparse
from dataclasses import asdict, dataclass, field, fields, replace
import datetime
import json
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

from attention_bringup.graph import (
    base_params_files, CONDITIONS, DEFAULT_CONDITION, NODES, person_file)
from attention_bringup.params import (
    dump_params, GraphParams, load_params_file, merge_params, node_params, NodeParams)
from attention_common.run_files import node_log, OPTIONS_FILE, OVERRIDES_FILE
from attention_tasks.montezuma.critical_positions import DEFAULT_RADIUS
from attention_tasks.montezuma.task import REALTIME_RATE_HZ  # noqa: F401 (Room 1's, for tests)
from attention_tasks.task import DEFAULT_TASK, load_task, task_names
from feedback_node.human_like import HUMAN_LIKE_SETTING, HumanLike
from feedback_node.judging import TRAINERS
from graph_viewer.config import DEFAULT_PORT as FOXGLOVE_PORT

DEFAULT_STEPS = 10000
"""Agent steps of a default run (the thesis's trial): about 4 minutes on 2 busy CPU cores."""


STALL_TIMEOUT_S = 120.0
"""Default of ``--stall-timeout``: the longest wait between two steps once the graph runs."""

CONSOLE = 'trainer_console'
CONSOLE_PORT = 8080
PERSON_ASK_BURST = 1.0
"""tamer_node ``ask_burst`` when a person answers (``--ask`` with the console): each question
pauses the env, so no saved-up questions come one after another."""
FOXGLOVE = 'graph_viewer'
"""The Foxglove bridge's executable and node name (package graph_viewer)."""
RECORDER = 'session_recorder'
"""The bag recorder's executable and node name (package session_bag)."""
FEEDBACK_WAITS = {'wait_feedback_nodes': 'tamer_node',
                  'wait_utterance_nodes': 'saliency_node,tamer_node',
                  'wait_utterance_stamped_nodes': 'saliency_node'}
"""What feedback_node holds its judgements and words for, by name (the recorder's added when
it records): the learner, and the saliency node that grounds the words."""
BAG_DIR = 'bag'
"""The session's rosbag2 bag in the run folder (a resumed session's: bag.session2, ...)."""

TEACHING_GREEDY_MARGIN = 0.1
"""tamer_node ``greedy_margin`` with ``--trainer teacher`` (not with ``--thesis-learner``): H
clipped to [-1, 1], actions within 0.1 of the best tied, ties broken at random. Without it one
of 10 graph trials stood 3,000 steps at the left ladder's foot never trying UP, and no
human-like trial in one process took the key (docs/teaching.md)."""


LATE_FEEDBACK_LEARNER = {'credit_loss': 'mixture', 'decision_period_s': 0.2,
                         'keep_tied_action': True}
"""tamer_node parameters of ``--late-learner`` (with late, unstamped feedback: ``--human-like``, a
person): decisions of at least 0.2 s (5 Hz, as TAMER agents act; every step of DoorKey) whose
first step takes the credit, the window's credit-weighted mean of H fitted to each feedback (the
mixture loss), and ties kept. The best of the in-process ablation on tuning seeds (the key in 3
of 8 against 0 of 4 with the plain window), it did no better through the graph on untuned seeds
(0 of 10 either way) and is not the default: docs/teaching.md."""


def human_like_window_s(step_s: float,
                        delay_max: float = HUMAN_LIKE_SETTING.feedback_delay_max) -> tuple:
    """
    Return the credit window of ``--human-like`` for steps of ``step_s`` simulation seconds.

    The teacher speaks ``feedback_delay_min``-``feedback_delay_max`` after it sees the step after
    the one it judges, so up to ``delay_max + step_s`` after that step began: Room 1 (1/15 s)
    (0.2, 1.6), DoorKey (1 s) (0.2, 2.5).
    """
    return (0.2, round(delay_max + step_s, 1))


def press_times_credit(delay_max: float = HUMAN_LIKE_SETTING.feedback_delay_max) -> dict:
    """Return tamer_node's credit with ``--press-times``, the teacher up to ``delay_max`` late."""
    return {'credit_anchor': 'effect', 'window_min_s': 0.2,
            'window_max_s': round(delay_max + 0.1, 1)}


PRESS_TIMES_CREDIT = press_times_credit()
"""tamer_node's credit with ``--press-times``: a verdict's delay counted from the moment it was
given back to when the judged step's result showed, which is the teacher's own delay (0.3-1.5 s),
whatever the step's length (DoorKey's 1 s steps no longer widen the window to 2.5 s)."""

HUMAN_LIKE_WINDOW_S = human_like_window_s(1.0 / REALTIME_RATE_HZ)
"""tamer_node ``window_min_s``, ``window_max_s`` with ``--human-like`` in Room 1: the credit window
of a learner that knows how late its trainer is. The teacher speaks 0.3-1.5 s after it sees the
step after the one it judges, so 0.37-1.63 s after that step began; Deep TAMER's [0.2, 4] s (the
default, for a person of unknown delay) spreads each feedback over 57 steps instead of 21
(measured in one process, seeds 100-103: agreement with the expert 0.24-0.46 with [0.2, 1.6],
0.11-0.38 with [0.2, 4]; docs/teaching.md)."""


def human_like_setting(knobs: Sequence[str]) -> HumanLike:
    """Return the named human-like setting with ``NAME=VALUE`` knobs changed (ValueError)."""
    known = {f.name for f in fields(HumanLike)}
    changes = {}
    for knob in knobs:
        name, _, value = knob.partition('=')
        if name not in known or not value:
            raise ValueError(f'--knob {knob!r}: expected NAME=VALUE with NAME one of '
                             f'{", ".join(sorted(known))}')
        try:
            changes[name] = float(value)
        except ValueError:
            raise ValueError(f'--knob {knob!r}: {value!r} is not a number') from None
    return replace(HUMAN_LIKE_SETTING, **changes)  # HumanLike checks the ranges


@dataclass
class LaunchOptions:
    """What the user asked for on the command line."""

    steps: int = DEFAULT_STEPS
    """Budget of agent steps (env_node ``max_steps``)."""
    task: str = DEFAULT_TASK
    """The task of every node (``attention_tasks``): 'montezuma' (Room 1) or 'doorkey'."""
    condition: str = DEFAULT_CONDITION
    """Study condition, by its name in ``graph.CONDITIONS``."""
    seed: Optional[int] = None
    """Seed of every node that has one (None: what the parameter files say)."""
    realtime: bool = False
    """Step at 15 Hz (real time) instead of lockstep."""
    synthetic: bool = True
    """Run the synthetic trainer (False: a person gives feedback with ``ros2 topic pub``)."""
    params_files: List[str] = field(default_factory=list)
    """The user's parameter files, applied in order on top of the condition."""
    run_dir: Optional[str] = None
    """Run folder (None: ``runs/<timestamp>-<condition>-seed<n>`` under the working directory)."""
    quiet: bool = False
    """No progress bar, only the final summary."""
    trainer: str = 'teacher'
    """feedback_node ``trainer``: 'teacher' (judges actions) or 'thesis' (equations 4.1/4.2)."""
    human_like: bool = False
    """The named human-like setting: feedback on a third of the steps, 0.3-1.5 s late, 10 %
    wrong (``feedback_node.human_like.HUMAN_LIKE_SETTING``), credited by the tamer's window."""
    thesis_learner: bool = False
    """Keep the thesis's learner with the teacher (no ``greedy_margin``)."""
    late_learner: bool = False
    """With late feedback, the learner for late feedback (``LATE_FEEDBACK_LEARNER``)."""
    press_times: bool = False
    """With ``human_like``: each late verdict carries the moment it was given
    (``feedback_pressed``), credited from then (``PRESS_TIMES_CREDIT``)."""
    ask: float = 0.0
    """The learner asks the teacher about the steps it is least sure of, at most this many
    questions per step (tamer_node ``ask_rate``); the teacher answers stamped. 0: never. With a
    person (``synthetic`` false) the console shows them, one at a time (``ask_burst`` 1)."""
    knobs: List[str] = field(default_factory=list)
    """With ``human_like``: ``NAME=VALUE`` changes of the named setting's knobs (``HumanLike``:
    for example ``feedback_probability=1``, a person who judges every move)."""
    resume: Optional[str] = None
    """A run folder whose nodes were killed: continue it with its own options."""
    domain: Optional[int] = None
    """ROS_DOMAIN_ID of the run (None: ``ROS_DOMAIN_ID`` if set, else a free one, reserved)."""
    console: bool = False
    """Start the trainer console too (a fifth process) and print its URL."""
    console_port: int = CONSOLE_PORT
    """The console's port on 127.0.0.1."""
    foxglove: bool = False
    """Start the Foxglove bridge too (``graph_viewer``) and print the URL to open in Foxglove."""
    foxglove_port: int = FOXGLOVE_PORT
    """The bridge's port on 127.0.0.1 (Foxglove's default, 8765; 0: any free one)."""
    record: Optional[bool] = None
    """Record the session as a rosbag2 bag (``bag/``); None: when a person trains."""
    stall_timeout: float = STALL_TIMEOUT_S
    """Seconds without a new step after which the graph counts as stalled (not while paused)."""
    initial_model: Optional[str] = None
    """A trained run (its folder or checkpoint file) whose H the learner starts from."""
    acting_first: bool = False
    """Run every process off the acting path (``off_acting_path``) and the launcher in Linux's
    idle scheduling class (SCHED_IDLE): env_node and tamer_node then take a core at once. Off
    by default: an idle-class node gets no CPU while other work fills every core."""

    @property
    def records(self) -> bool:
        """Whether the run records a bag: ``--record``/``--no-record``, else a person trains."""
        return (not self.synthetic) if self.record is None else bool(self.record)


def positive_int(text: str) -> int:
    """Parse a whole number of at least 1 (an argparse type)."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be at least 1, got {value}')
    return value


def positive_float(text: str) -> float:
    """Parse a number above 0 (an argparse type)."""
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f'must be above 0, got {text}')
    return value


MAX_DOMAIN_ID = 232
"""The largest ROS_DOMAIN_ID whose DDS ports fit (ROS 2's documented range, 0..232)."""


def domain_id(text: str) -> int:
    """Parse a ROS_DOMAIN_ID, 0..232 (an argparse type)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'a domain is a whole number, got {text!r}') from None
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise argparse.ArgumentTypeError(f'must be 0..{MAX_DOMAIN_ID}, got {value}')
    return value


def chosen_domain(options: LaunchOptions, environ) -> Optional[int]:
    """Return the domain the user chose (``--domain``, else ``ROS_DOMAIN_ID``), or None."""
    if options.domain is not None:
        return options.domain
    text = environ.get('ROS_DOMAIN_ID', '').strip()
    if not text:
        return None
    try:
        return domain_id(text)
    except argparse.ArgumentTypeError as error:
        raise ValueError(f'ROS_DOMAIN_ID: {error}') from None


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_train',
        description="Train the Deep TAMER agent on Montezuma's Revenge (Room 1) or another task: "
                    'start the four nodes, show progress, stop them at the end of the budget and '
                    'write a run folder.')
    parser.add_argument('--task', choices=task_names(), default=DEFAULT_TASK,
                        help="the task of every node (default %(default)s: Room 1; 'doorkey': "
                             'MiniGrid DoorKey with distractors, a new layout every episode)')
    parser.add_argument('--steps', type=positive_int, default=DEFAULT_STEPS,
                        help=f'budget of agent steps (default {DEFAULT_STEPS})')
    parser.add_argument('--condition', choices=CONDITIONS, default=DEFAULT_CONDITION,
                        help=f'study condition (default {DEFAULT_CONDITION})')
    parser.add_argument('--seed', type=int, default=None,
                        help='seed of every node (default: the parameter files, 0)')
    parser.add_argument('--realtime', action='store_true',
                        help=f'step in real time instead of lockstep ({REALTIME_RATE_HZ:g} Hz in '
                             "Room 1, the task's realtime_hz in another)")
    parser.add_argument('--no-synthetic', dest='synthetic', action='store_false',
                        help='no synthetic trainer: a person gives feedback with ros2 topic pub '
                             '(the tamer then credits it with the Deep TAMER window)')
    parser.add_argument('--params-file', dest='params_files', action='append', default=[],
                        metavar='YAML',
                        help='ROS 2 parameter file applied on top of the condition (repeatable, '
                             'later wins)')
    parser.add_argument('--run-dir', default=None,
                        help='run folder (default runs/<timestamp>-<condition>-seed<n>)')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    parser.add_argument('--trainer', choices=TRAINERS, default='teacher',
                        help="the synthetic trainer: 'teacher' judges each action against the "
                             "scripted expert's (default); 'thesis' gives h from the position "
                             '(equations 4.1/4.2, as in the study)')
    parser.add_argument('--human-like', dest='human_like', action='store_true',
                        help='the trainer gives feedback on a third of the steps, 0.3 to 1.5 s '
                             'late, 10%% of signs wrong; the tamer credits it with its window '
                             '(0.2-1.6 s)')
    parser.add_argument('--thesis-learner', dest='thesis_learner', action='store_true',
                        help="with the teacher, keep the thesis's greedy policy (argmax, ties "
                             'to the lowest action) instead of greedy_margin '
                             f'{TEACHING_GREEDY_MARGIN:g}')
    parser.add_argument('--late-learner', dest='late_learner', action='store_true',
                        help='with late feedback (--human-like, a person): decisions of 0.2 s '
                             'credited on the step that chose, the mixture loss and ties kept '
                             "instead of Deep TAMER's plain window (docs/teaching.md)")
    parser.add_argument('--press-times', dest='press_times', action='store_true',
                        help='with --human-like: each late verdict carries the moment the teacher '
                             'gave it (topic feedback_pressed), and the tamer credits it from '
                             'then (effect anchor, window 0.2-1.6 s), still not told the step '
                             'it judges')
    parser.add_argument('--ask', type=float, default=0.0, metavar='RATE',
                        help='the learner asks the teacher about the steps where it is least '
                             "sure (H's two best actions within ask_margin), at most RATE "
                             'questions a step; the teacher answers each stamped with its step '
                             '(tamer_node ask_rate; docs/teaching.md); with --no-synthetic '
                             '--console a person answers them in the console, the env paused '
                             'at each (try 0.02: one every 3 s at 15 Hz)')
    parser.add_argument('--knob', dest='knobs', action='append', default=[],
                        metavar='NAME=VALUE',
                        help='with --human-like: change one knob of its setting (repeatable; '
                             f'{", ".join(f.name for f in fields(HumanLike))}), for example '
                             'feedback_probability=1: a person who judges every move, late and '
                             'sometimes wrong; the credit window follows feedback_delay_max')
    parser.add_argument('--domain', type=domain_id, default=None, metavar='ID',
                        help='ROS_DOMAIN_ID of the graph, to join it from another shell (default: '
                             'ROS_DOMAIN_ID if set, else a free domain reserved for the run)')
    parser.add_argument('--console', action='store_true',
                        help='also start the trainer console (a web page on 127.0.0.1) and print '
                             'its URL: a person judges with the keyboard and types utterances')
    parser.add_argument('--console-port', dest='console_port', type=int, default=CONSOLE_PORT,
                        help=f'port of the console (default {CONSOLE_PORT}; 0: any free one)')
    parser.add_argument('--foxglove', action='store_true',
                        help='also start the Foxglove bridge (graph_viewer: the Foxglove '
                             'WebSocket protocol on 127.0.0.1) and print the URL to open in '
                             'Foxglove or Lichtblick')
    parser.add_argument('--foxglove-port', dest='foxglove_port', type=int, default=FOXGLOVE_PORT,
                        help=f'port of the Foxglove bridge (default {FOXGLOVE_PORT}; 0: any free '
                             'one)')
    parser.add_argument('--acting-first', dest='acting_first', action='store_true',
                        help='run the nodes off the acting path (feedback_node, saliency_node '
                             'unless the learner acts on its images, the recorder, console and '
                             'viewer) and the launcher in the idle scheduling class (Linux '
                             'SCHED_IDLE), so env_node and tamer_node get a core at once: '
                             'lower observation-to-action latency in lockstep; those nodes get '
                             'no CPU while other work fills every core')
    parser.add_argument('--record', dest='record', action='store_true', default=None,
                        help='record the session as a rosbag2 bag with MCAP storage in the run '
                             "folder's bag/ (every topic, for ros2 bag, Foxglove and "
                             'attention_replay; the default when a person trains, with '
                             '--no-synthetic)')
    parser.add_argument('--no-record', dest='record', action='store_false',
                        help='record no bag, even when a person trains')
    parser.add_argument('--resume', metavar='RUN_DIR', default=None,
                        help='continue a run whose nodes were killed (or that was stopped), with '
                             'the options it was started with, up to its budget: the learner '
                             'from its checkpoint and feedback log, a fresh env; other options '
                             'but --quiet are taken from the run folder')
    parser.add_argument('--stall-timeout', dest='stall_timeout', type=positive_float,
                        default=STALL_TIMEOUT_S, metavar='S',
                        help='seconds without a new step after which the run stops as stalled '
                             f'(default {STALL_TIMEOUT_S:g}; never while the env is paused)')
    parser.add_argument('--initial-model', dest='initial_model', metavar='RUN', default=None,
                        help="start the learner from a trained run's H (its run folder or its "
                             'checkpoints/checkpoint.pt): a person tries what it learned, for '
                             'example steering a Fetch learner with words in the console')
    return parser


def parse_options(argv: Optional[Sequence[str]] = None) -> LaunchOptions:
    return LaunchOptions(**vars(argument_parser().parse_args(argv)))


def save_options(options: LaunchOptions, run_dir: Path) -> None:
    """Write the options a run starts with into its folder (``OPTIONS_FILE``)."""
    (Path(run_dir) / OPTIONS_FILE).write_text(json.dumps(asdict(options), indent=2) + '\n')


def resumed_options(run_dir: Path, quiet: bool) -> LaunchOptions:
    """Return the options of the run in ``run_dir``, to continue it (ValueError: none)."""
    path = Path(run_dir) / OPTIONS_FILE
    if not path.exists():
        raise ValueError(f'{run_dir} is not a run folder of attention_train (no {OPTIONS_FILE})')
    saved = json.loads(path.read_text())
    known = {f.name for f in fields(LaunchOptions)}
    options = LaunchOptions(**{k: v for k, v in saved.items() if k in known})
    options.run_dir, options.resume, options.quiet = str(Path(run_dir).resolve()), str(
        run_dir), quiet
    return options


@dataclass
class Continuation:
    """Where a resumed run stands: its session (1 = the first start) and the steps done."""

    session: int = 1
    steps_done: int = 0


@dataclass
class NodeCommand:
    """One node process to start."""

    name: str
    argv: List[str]
    log_path: Path
    idle: bool = False
    """Start it in the idle scheduling class (``--acting-first``, Linux)."""


@dataclass
class LaunchPlan:
    """Everything the launcher starts and writes, decided before anything runs."""

    options: LaunchOptions
    run_dir: Path
    seed: int
    params_files: List[Path]
    """Files every node gets, in order, the launcher's overrides file last."""
    overrides: GraphParams
    """What the launcher itself sets (budget, run folder, seed, clock, trainer)."""
    effective: Dict[str, NodeParams]
    """Per node: the merged parameters of all files (what the files set, not the defaults)."""
    commands: List[NodeCommand]
    continuation: Continuation = field(default_factory=Continuation)
    bag_dir: Optional[Path] = None
    """The session's bag folder (``--record``), a new one: a bag is never written over."""

    def overrides_text(self) -> str:
        return dump_params(self.overrides, header='Set by attention_train from its options.')

    @property
    def critical_radius(self) -> float:
        """feedback_node's ``alpha_threshold``: how near a critical position counts as on it."""
        return float(self.effective['feedback_node'].get('alpha_threshold', DEFAULT_RADIUS))

    def options_dict(self) -> dict:
        return asdict(self.options)


def launcher_overrides(options: LaunchOptions, seed: int, run_dir: Path,
                       files_params: GraphParams,
                       continuation: Optional[Continuation] = None) -> GraphParams:
    """Return the parameters the launcher's options fix, one section per node."""
    continuation = continuation or Continuation()
    task = load_task(options.task)
    overrides: GraphParams = {node: {} for node in NODES}
    if task.name != DEFAULT_TASK:  # the default run's parameter files stay as they were
        for node in NODES:
            overrides[node]['task'] = task.name
    overrides['env_node']['max_steps'] = int(options.steps) - continuation.steps_done
    overrides['tamer_node']['run_dir'] = str(run_dir)
    if continuation.session > 1:
        overrides['tamer_node']['resume'] = True
    if options.seed is not None:
        for node in NODES:
            if node == 'env_node' or 'seed' in node_params(files_params, node):
                overrides[node]['seed'] = int(seed)
    if options.realtime:
        overrides['env_node']['rate_hz'] = task.realtime_hz
        overrides['tamer_node']['pace_updates'] = 0.0  # the env does not wait: act at once
    overrides['feedback_node']['trainer'] = options.trainer
    overrides['feedback_node']['wait_feedback_subscribers'] = 2  # the learner and the monitor
    overrides['feedback_node']['wait_utterance_subscribers'] = 2  # saliency_node, tamer_node
    # By name too: a viewer (Foxglove, the console) makes a count but learns nothing.
    overrides['feedback_node'].update(FEEDBACK_WAITS)
    if options.trainer == 'teacher' and not options.thesis_learner:
        overrides['tamer_node']['greedy_margin'] = TEACHING_GREEDY_MARGIN
    if options.human_like:
        setting = human_like_setting(options.knobs)
        overrides['feedback_node'].update(vars(setting))
        overrides['tamer_node']['credit'] = 'window'  # late and plain: the window attributes it
        overrides['tamer_node']['window_min_s'], overrides['tamer_node']['window_max_s'] = (
            human_like_window_s(1.0 / task.realtime_hz, setting.feedback_delay_max))
        if options.press_times:
            overrides['feedback_node']['press_times'] = True
            overrides['tamer_node'].update(press_times_credit(setting.feedback_delay_max))
    if not options.synthetic:
        overrides['feedback_node']['synthetic'] = False
        overrides['tamer_node']['credit'] = 'window'  # a person's feedback comes late
    late = options.human_like or not options.synthetic
    if late and options.late_learner and not options.thesis_learner:
        overrides['tamer_node'].update(LATE_FEEDBACK_LEARNER)
    if options.ask:
        overrides['tamer_node']['ask_rate'] = float(options.ask)
        if not options.synthetic:  # a person: one question at a time, never a burst of pauses
            overrides['tamer_node']['ask_burst'] = PERSON_ASK_BURST
    if node_params(files_params, 'feedback_node').get('plain_copies'):
        overrides['tamer_node']['plain_copies'] = True  # the learner knows them for copies
    if options.records:  # the env and the trainer wait for the recorder too: no step unheard
        env = node_params(files_params, 'env_node')
        overrides['env_node']['wait_observation_nodes'] = ','.join(
            filter(None, (env.get('wait_observation_nodes', ''), RECORDER)))
        overrides['env_node']['wait_observation_subscribers'] = (
            int(env.get('wait_observation_subscribers', 2)) + 1)
        overrides['env_node']['wait_position_subscribers'] = (
            int(env.get('wait_position_subscribers', 1)) + 1)
        overrides['feedback_node']['wait_feedback_subscribers'] += 1
        overrides['feedback_node']['wait_utterance_subscribers'] += 1
        for key, names in FEEDBACK_WAITS.items():
            overrides['feedback_node'][key] = f'{names},{RECORDER}'
        for node in ('saliency_node', 'tamer_node'):  # their outputs wait for it to match
            overrides[node]['wait_for_recorder'] = RECORDER
    if options.trainer == 'teacher':  # it judges from env_status: the env waits for it too
        overrides['env_node']['wait_status_subscribers'] = status_listeners(options)
    return {node: values for node, values in overrides.items() if values}


def bag_dir_name(session: int = 1) -> str:
    """Return the bag folder of a session of a run: 'bag', then 'bag.session2', ..."""
    return BAG_DIR if session == 1 else f'{BAG_DIR}.session{session}'


def off_acting_path(effective: Dict[str, NodeParams]) -> Tuple[str, ...]:
    """
    Name the processes no action waits for: every one but env_node and tamer_node.

    saliency_node is the exception when the learner acts on its images (tamer_node
    ``input_image`` 'saliency' or 'both'); otherwise the learner only learns from them.
    """
    acts_on_saliency = effective['tamer_node'].get('input_image', 'observation') != 'observation'
    return tuple(name for name in ('feedback_node', 'saliency_node', RECORDER, CONSOLE, FOXGLOVE)
                 if not (name == 'saliency_node' and acts_on_saliency))


def free_bag_dir(run_dir: Path, session: int) -> Path:
    """
    Return the session's bag folder: ``bag_dir_name(session)``, or ``.2``, ``.3``, ... after it.

    A start that never got to a step leaves a bag and no progress row, so the next one gets
    the same session number; its bag goes beside that one, never over it.
    """
    first = path = Path(run_dir) / bag_dir_name(session)
    attempt = 1
    while path.exists() and any(path.iterdir()):
        attempt += 1
        path = first.with_name(f'{first.name}.{attempt}')
    return path


def default_run_dir(cwd: Path, condition: str, seed: int, now: datetime.datetime,
                    task: str = DEFAULT_TASK) -> Path:
    named = '' if task == DEFAULT_TASK else f'{task}-'
    return cwd / 'runs' / f'{now:%Y%m%d-%H%M%S}-{named}{condition}-seed{seed}'


def status_listeners(options: LaunchOptions) -> int:
    """
    Return how many readers of env_status the env waits for before its first step.

    The launcher's monitor, the teacher, and the recorder and the console when they run: a DDS
    match is per topic, so a teacher that hears agent_position may not hear env_status yet, and
    lockstep plays a hundred steps in the time a late match takes (the teacher then judges none
    of them).
    """
    return 2 + int(options.records) + int(options.console)


def build_plan(options: LaunchOptions, bin_dir: Path, cwd: Path,
               now: Optional[datetime.datetime] = None,
               continuation: Optional[Continuation] = None) -> LaunchPlan:
    """
    Decide the run; raise ``ParamsFileError`` / ``ValueError`` for bad files or names.

    ``continuation``: a resumed run's session and steps done (the env gets the rest of the
    budget, the tamer ``resume``, and the node logs of this session names of their own).
    """
    continuation = continuation or Continuation()
    if options.trainer == 'thesis' and options.task != DEFAULT_TASK:
        raise ValueError(f"--trainer thesis measures Room 1's critical positions; task "
                         f'{options.task} is taught by the teacher (--trainer teacher)')
    if options.knobs and not options.human_like:
        raise ValueError('--knob changes the human-like setting: add --human-like')
    if options.press_times and not options.human_like:
        raise ValueError('--press-times is how the human-like teacher gives its late verdicts: '
                         'add --human-like')
    if options.ask and options.synthetic and options.trainer != 'teacher':
        raise ValueError('--ask: of the synthetic trainers only the teacher answers questions '
                         '(--trainer teacher)')
    if options.ask and not options.synthetic and not options.console:
        raise ValueError('--ask with a person: add --console, where the questions are shown '
                         'and answered')
    if not 0.0 <= options.ask <= 1.0:
        raise ValueError(f'--ask is questions per step, in [0, 1]: got {options.ask}')
    if continuation.steps_done >= options.steps:
        raise ValueError(f'the run has done its {options.steps} steps already: nothing to '
                         'resume')
    files = base_params_files(options.condition, task=options.task)
    if not options.synthetic and person_file(options.task).exists():
        files.append(person_file(options.task))  # the task's settings for a person
    files += [(cwd / path).resolve() for path in options.params_files]
    files_params = merge_params(load_params_file(path) for path in files)
    seed = options.seed
    if seed is None:
        seed = int(node_params(files_params, 'env_node').get('seed', 0))
    if options.run_dir is not None:
        run_dir = (cwd / options.run_dir).resolve()
    else:
        run_dir = default_run_dir(cwd, options.condition, seed, now or datetime.datetime.now(),
                                  options.task)
    overrides = launcher_overrides(options, seed, run_dir, files_params, continuation)
    if options.initial_model:
        model = (cwd / Path(options.initial_model).expanduser()).resolve()
        if not model.exists():
            raise ValueError(f'--initial-model {options.initial_model}: no such run folder or '
                             'checkpoint file')
        overrides['tamer_node']['initial_model'] = str(model)
    merged = merge_params([files_params, overrides])
    effective = {node: node_params(merged, node) for node in NODES}
    all_files = files + [run_dir / OVERRIDES_FILE]
    commands = []
    for node in NODES:
        argv = [str(bin_dir / node), '--ros-args']
        for path in all_files:
            argv += ['--params-file', str(path)]
        commands.append(NodeCommand(node, argv, run_dir / node_log(node, continuation.session)))
    bag_dir = free_bag_dir(run_dir, continuation.session) if options.records else None
    if bag_dir is not None:  # not a node of the study's graph: its own parameters only
        argv = [str(bin_dir / RECORDER), '--ros-args', '-p', f'bag_dir:={bag_dir}', '-p',
                f'run_dir:={run_dir}']
        commands.append(NodeCommand(RECORDER, argv,
                                    run_dir / node_log(RECORDER, continuation.session)))
    if options.console:  # not a node of the study's graph: its own parameters only
        argv = [str(bin_dir / CONSOLE), '--ros-args', '-p', f'port:={int(options.console_port)}',
                '-p', f'task:={options.task}']
        if options.synthetic:  # the trainer answers the questions: the console never pauses
            argv += ['-p', 'answer_questions:=false']
        log = run_dir / node_log(CONSOLE, continuation.session)
        commands.append(NodeCommand(CONSOLE, argv, log))
    if options.foxglove:  # a viewer: not the graph's files, but the user's (a graph_viewer: part)
        argv = [str(bin_dir / FOXGLOVE), '--ros-args']
        for path in options.params_files:
            argv += ['--params-file', str((cwd / path).resolve())]
        argv += ['-p', f'port:={int(options.foxglove_port)}', '-p', f'task:={options.task}']
        commands.append(NodeCommand(FOXGLOVE, argv,
                                    run_dir / node_log(FOXGLOVE, continuation.session)))
    if options.acting_first:
        idle = off_acting_path(effective)
        for command in commands:
            command.idle = command.name in idle
    return LaunchPlan(options=options, run_dir=run_dir, seed=seed, params_files=all_files,
                      overrides=overrides, effective=effective, commands=commands,
                      continuation=continuation, bag_dir=bag_dir)
