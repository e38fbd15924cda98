"""
What a replay runs: the bag, the task and condition, the two nodes' parameters. Pure.

The nodes get the session's own parameters (the bag's ``custom_data`` holds the run's
params.yaml) with the chosen condition's file on top, then the user's files, then the replay's
overrides (a fresh learner in the replay's run folder). A bag without them (recorded by
another tool) gets the graph's defaults, the task's and the condition's.
"""

import argparse
from dataclasses import asdict, dataclass, field
import datetime
import json
from pathlib import Path
from typing import List, Optional, Sequence

from attention_bringup.graph import base_params_files, CONDITIONS
from attention_bringup.params import (
    dump_params, GraphParams, load_params_file, merge_params, node_params, parse_params)
from attention_bringup.plan import BAG_DIR, domain_id, NodeCommand, positive_int
from attention_common.run_files import node_log
from attention_tasks.task import DEFAULT_TASK, task_names
from session_bag import metadata
from session_bag.reader import BagReader

REPLAYED_NODES = ('saliency_node', 'tamer_node')
PARAMS_FILE = 'replay_params.yaml'
OPTIONS_FILE = 'replay_options.json'
STEPS_FILE = 'replay_steps.csv'
SESSION_KEYS = ('run_dir', 'resume', 'wait_for_recorder')
"""Session parameters a replay never takes over (its learner is a fresh one, elsewhere, and
nothing records it)."""


@dataclass
class ReplayOptions:
    bag: str = ''
    """The bag folder, or a run folder holding one (``bag/``)."""
    fast: bool = False
    """As fast as the learner answers, instead of the recorded timing."""
    condition: Optional[str] = None
    """The learner's study condition (None: the session's)."""
    task: Optional[str] = None
    """The task (None: the session's; Room 1 for a bag without it)."""
    seed: Optional[int] = None
    params_files: List[str] = field(default_factory=list)
    run_dir: Optional[str] = None
    domain: Optional[int] = None
    quiet: bool = False
    all_conditions: bool = False
    """Replay once per study condition, each into ``out/<condition>``."""
    out: Optional[str] = None
    """With ``all_conditions``: the study's folder (default runs/<timestamp>-replay-study)."""
    conditions: Optional[List[str]] = None
    """A replay study of these conditions only (``all_conditions``: every thesis condition)."""
    parallel: int = 1
    """Replays of the study side by side."""


def argument_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='attention_replay',
        description="Replay a recorded session's observations, feedback and utterances into a "
                    'fresh saliency_node and tamer_node (offline TAMER from a session), write a '
                    "run folder, and report how the new learner's greedy actions agree with "
                    "the session's.")
    parser.add_argument('bag', help='the bag folder (with metadata.yaml), or the run folder of '
                                    'attention_train that holds it in bag/')
    parser.add_argument('--fast', action='store_true',
                        help='as fast as the learner answers (default: the recorded timing)')
    parser.add_argument('--condition', choices=CONDITIONS, default=None,
                        help="the new learner's condition (default: the session's)")
    parser.add_argument('--task', choices=task_names(), default=None,
                        help="the task (default: the session's, from the bag)")
    parser.add_argument('--seed', type=int, default=None,
                        help="the new learner's seed (default: the session's)")
    parser.add_argument('--params-file', dest='params_files', action='append', default=[],
                        metavar='YAML', help='ROS 2 parameter file on top (repeatable)')
    parser.add_argument('--run-dir', default=None,
                        help='run folder (default runs/<timestamp>-replay-<condition>-seed<n>)')
    parser.add_argument('--domain', type=domain_id, default=None, metavar='ID',
                        help='ROS_DOMAIN_ID (default: ROS_DOMAIN_ID if set, else a free one)')
    parser.add_argument('--quiet', action='store_true', help='no progress lines')
    parser.add_argument('--all-conditions', dest='all_conditions', action='store_true',
                        help='replay the same session once per study condition (the learner '
                             "changes, the person's teaching does not), each into "
                             'OUT/<condition>/seed<k>/; a replay already done there is kept')
    parser.add_argument('--conditions', nargs='+', choices=CONDITIONS, default=None,
                        metavar='CONDITION',
                        help='a replay study of these conditions (as --all-conditions, fewer '
                             'or others)')
    parser.add_argument('--parallel', type=positive_int, default=1,
                        help='with --all-conditions: replays side by side (default 1)')
    parser.add_argument('--out', default=None,
                        help='with --all-conditions: the folder (default '
                             'runs/<timestamp>-replay-study)')
    return parser


def parse_options(argv: Optional[Sequence[str]] = None) -> ReplayOptions:
    return ReplayOptions(**vars(argument_parser().parse_args(argv)))


def bag_folder(path: Path) -> Path:
    """Return the bag folder ``path`` names: itself, or a run folder's ``bag/``."""
    path = Path(path)
    if (path / metadata.METADATA_FILE).is_file():
        return path
    if (path / BAG_DIR / metadata.METADATA_FILE).is_file():
        return path / BAG_DIR
    raise ValueError(f'{path} is neither a bag folder (no {metadata.METADATA_FILE}) nor a run '
                     f'folder with a bag in {BAG_DIR}/ (record with attention_train --record)')


@dataclass
class Session:
    """What the bag says of the session it recorded."""

    options: dict
    """attention_train's options ({} for a bag of another tool)."""
    params: GraphParams
    """The session's parameters, per node ({} if unknown)."""


def read_session(bag_dir: Path) -> Session:
    custom = BagReader(bag_dir).custom_data()
    options = json.loads(custom['attention.launch_options']) if (
        'attention.launch_options' in custom) else {}
    params = parse_params(custom['attention.params'], f'{bag_dir} custom_data') if (
        'attention.params' in custom) else {}
    return Session(options, params)


@dataclass
class ReplayPlan:
    options: ReplayOptions
    bag_dir: Path
    session: Session
    task: str
    condition: str
    seed: int
    run_dir: Path
    params: GraphParams
    """The two nodes' parameters, as written to ``replay_params.yaml``."""
    commands: List[NodeCommand]

    def params_text(self) -> str:
        return dump_params(self.params, header=f'attention_replay of {self.bag_dir}: the '
                                               "session's parameters, the condition's, yours.")

    def options_dict(self) -> dict:
        return asdict(self.options)


def build_plan(options: ReplayOptions, bin_dir: Path, cwd: Path,
               now: Optional[datetime.datetime] = None) -> ReplayPlan:
    """Decide the replay; ValueError (or ParamsFileError) for a bad bag, file or name."""
    bag_dir = bag_folder((cwd / options.bag).resolve())
    session = read_session(bag_dir)
    task = options.task or session.options.get('task') or DEFAULT_TASK
    condition = options.condition or session.options.get('condition') or 'language'
    base = base_params_files(condition, task=task)
    session_layer = {node: {k: v for k, v in node_params(session.params, node).items()
                            if k not in SESSION_KEYS}
                     for node in REPLAYED_NODES if node in session.params}
    layers = [load_params_file(base[0]), *[load_params_file(p) for p in base[1:-1]],
              session_layer, load_params_file(base[-1]),
              *[load_params_file((cwd / p).resolve()) for p in options.params_files]]
    merged = merge_params(layers)
    seed = options.seed if options.seed is not None else int(
        node_params(merged, 'tamer_node').get('seed', 0))
    if options.run_dir is not None:
        run_dir = (cwd / options.run_dir).resolve()
    else:
        stamp = f'{now or datetime.datetime.now():%Y%m%d-%H%M%S}'
        named = '' if task == DEFAULT_TASK else f'{task}-'
        run_dir = cwd / 'runs' / f'{stamp}-replay-{named}{condition}-seed{seed}'
    # It learns on the session's actions; its own answers, compared with them, are greedy.
    overrides = {'tamer_node': {'run_dir': str(run_dir), 'resume': False, 'seed': seed,
                                'task': task, 'explore': 0.0, 'await_taken': True},
                 'saliency_node': {'task': task}}
    merged = merge_params([merged, overrides])
    params = {node: node_params(merged, node) for node in REPLAYED_NODES}
    commands = [NodeCommand(node, [str(bin_dir / node), '--ros-args', '--params-file',
                                   str(run_dir / PARAMS_FILE)], run_dir / node_log(node))
                for node in REPLAYED_NODES]
    return ReplayPlan(options, bag_dir, session, task, condition, seed, run_dir, params,
                      commands)
