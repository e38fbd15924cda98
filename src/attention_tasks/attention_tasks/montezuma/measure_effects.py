"""
``teacher_effects``: measure with the emulator which actions do the same where.

Writes the teacher's table (``attention_tasks/montezuma/data/action_effects.json``).

States come from real play: the scripted expert from random warm-ups, mixed with random actions
held for a few steps (as a learner's greedy policy holds them), so that the agent walks into
walls, falls, dies and respawns too. In each state every one of the 18 actions is applied from
a saved emulator state (``cloneState`` / ``restoreState``) and followed by
``FOLLOW_STEPS`` steps of each probe (NOOPs; a RIGHTFIRE press then NOOPs, which tells whether
the action left the button held); actions whose position, room, lives and inventory agree at
every one of those steps are equivalent there. ``tests/test_action_effects.py`` checks the table on
states of other seeds.

Usage: ``teacher_effects [--seeds 0 1 2 3 4 5] [--steps 500] [--out PATH]``.
"""

import argparse
import collections
import json
from pathlib import Path
import sys
from typing import Iterator, List, Sequence, Tuple

from attention_common.joy_actions import NUM_ACTIONS
from attention_tasks.montezuma.action_effects import (
    AGREEMENT, build_table, FOLLOW_STEPS, Measured, MIN_STATES, MOOT_SHARE, partition_of,
    place_of, Situation, TABLE_PATH)
from attention_tasks.montezuma.env import (
    EnvConfig, MontezumaEnv, RAM_INVENTORY, RAM_LIVES, RAM_ROOM, RAM_X, RAM_Y)
from attention_tasks.montezuma.expert import FIRE_ACTIONS, NOOP, phase_of, RIGHTFIRE, RoomOneExpert
import numpy as np

DEFAULT_SEEDS = (0, 1, 2, 3, 4, 5)
EXPLORATION = (0.0, 0.2, 0.4, 0.6)
"""Share of steps (by seed, in turn) on which a random action replaces the expert's."""
MAX_HOLD = 8
"""A random action is held for 1..MAX_HOLD steps."""
PROBES = (NOOP, RIGHTFIRE)
"""What follows the action at the next step: nothing, or a press of the button (an action
that leaves the button held makes that press do nothing, one that releases it does not)."""


def outcome(ale, action: int, frameskip: int, probe: int) -> bytes:
    """Apply ``action`` for one agent step, then ``probe`` and NOOPs; return what happened."""
    trace = []
    for step in range(FOLLOW_STEPS + 1):
        for _ in range(frameskip):
            ale.act(action if step == 0 else probe if step == 1 else NOOP)
        ram = ale.getRAM()
        trace.append(bytes(ram[[RAM_X, RAM_Y, RAM_ROOM, RAM_LIVES, RAM_INVENTORY]]))
    return b''.join(trace)


def measure_partition(env) -> Measured:
    """
    Measure which actions are equivalent in the env's current state (which it keeps).

    ``effect``: by the NOOP probe alone (what the action does to the game); ``classes``: by
    both probes (also whether it leaves the button held).
    """
    ale = env.ale
    saved = ale.cloneState()
    effect, classes = collections.OrderedDict(), collections.OrderedDict()
    try:
        for action in range(NUM_ACTIONS):
            traces = []
            for probe in PROBES:
                ale.restoreState(saved)
                traces.append(outcome(ale, action, env.config.frameskip, probe))
            effect.setdefault(traces[0], []).append(action)
            classes.setdefault(b''.join(traces), []).append(action)
    finally:
        ale.restoreState(saved)
    return Measured(partition_of(effect.values()), partition_of(classes.values()))


def play_states(seed: int, steps: int, exploration: float) -> Iterator[Tuple[object, object]]:
    """
    Yield ``(env, step)`` along a mixed expert/random trajectory (the env is live).

    ``step.action`` is the action applied to reach the step (-1 after a reset).
    """
    env = MontezumaEnv(EnvConfig(seed=seed, warmup_steps=100))
    rng = np.random.default_rng(seed)
    try:
        step = env.warm_up()
        expert = RoomOneExpert()
        expert.reset()
        held, hold = 0, 0
        for _ in range(steps):
            yield env, step
            action = expert.act(step.state, step.state.skull_x)
            if hold > 0:
                action, hold = held, hold - 1
            elif rng.random() < exploration:
                held, hold = int(rng.integers(NUM_ACTIONS)), int(rng.integers(MAX_HOLD))
                action = held
            step = env.step(action)
            if step.done:
                step = env.reset()
                expert.reset()
    finally:
        env.close()


def situation_of(step) -> Situation:
    """Return what the teacher sees of a step (the teacher sees it from topics)."""
    state = step.state
    return Situation(phase_of(state).name, place_of(state.x, state.y), state.pose,
                     step.action in FIRE_ACTIONS)


def measure(seeds: Sequence[int], steps: int) -> List[Tuple[Situation, Measured]]:
    """Return ``(situation, measured)`` of every state played."""
    samples = []
    for index, seed in enumerate(seeds):
        for env, step in play_states(seed, steps, EXPLORATION[index % len(EXPLORATION)]):
            samples.append((situation_of(step), measure_partition(env)))
    return samples


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='teacher_effects',
                                     description=__doc__.split('\n')[1].strip('`'))
    parser.add_argument('--seeds', type=int, nargs='+', default=list(DEFAULT_SEEDS))
    parser.add_argument('--steps', type=int, default=500, help='states per seed')
    parser.add_argument('--out', type=Path, default=TABLE_PATH)
    parser.add_argument('--samples', type=Path, default=None,
                        help='JSON file of measured states: read if it exists, else written')
    parser.add_argument('--agreement', type=float, default=AGREEMENT,
                        help=f'share of states two actions must agree in (default {AGREEMENT})')
    parser.add_argument('--noop-probe-only', action='store_true',
                        help='judge equivalence by the NOOP probe alone (for comparison: it '
                             'cannot tell holding the button from releasing it)')
    args = parser.parse_args(argv)
    if args.samples is not None and args.samples.exists():
        samples = [(Situation(*s), Measured(*(partition_of(p) for p in m)))
                   for s, m in json.loads(args.samples.read_text())]
    else:
        samples = measure(args.seeds, args.steps)
        if args.samples is not None:
            args.samples.write_text(json.dumps(
                [(list(s), [[sorted(c) for c in p] for p in m]) for s, m in samples]))
    if args.noop_probe_only:
        samples = [(s, Measured(m.effect, m.effect)) for s, m in samples]
    table = build_table(samples, agreement=args.agreement, info={
        'seeds': args.seeds, 'states_per_seed': args.steps, 'follow_steps': FOLLOW_STEPS,
        'exploration': list(EXPLORATION), 'agreement': args.agreement, 'moot_share': MOOT_SHARE,
        'min_states': MIN_STATES, 'noop_probe_only': args.noop_probe_only,
        'command': 'teacher_effects'})
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(table.to_json(), indent=1) + '\n')
    print(f'{len(samples)} states, {len(table.partitions)} situations -> {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
