"""
Which of the 18 ALE actions do the same thing where: the teacher's measured table (pure).

Two actions are *equivalent* in a state when, applied there for one agent step and followed by
the same ``FOLLOW_STEPS`` steps (NOOPs, or a press of the button and NOOPs: holding the button
is not releasing it), they leave the agent at the same positions, with the same room, lives and
inventory, step by step (measured with the emulator by ``teacher_effects``,
``measure_effects.py``). On the floor LEFT, UPLEFT and DOWNLEFT walk alike; on a ladder they do
not (only UP and DOWN move there); in the air or while dying every action does
the same to the game (the button an action leaves held aside): the action cannot matter.

A person judging the agent cannot see the emulator's state, only the screen. The table is
therefore keyed by what is seen (``Situation``): the stage of the route (``expert.Phase``
from the position), whether the agent stands at a ladder's end, its sprite (``RamState.pose``:
standing, walking, climbing, jumping, on the rope, dying) and whether the button was pressed at
the step before (fire acts on a press). For each situation it holds the partition its
measured states share (two actions are one class when they were equivalent in at least 95 % of
them: ``AGREEMENT``), and how many states it was measured on. A situation measured in fewer
than ``MIN_STATES`` states falls back to fewer details, down to the phase alone, then to
"every action is its own class" (strict: only the expert's very action is right).
"""

import json
from pathlib import Path
from typing import Dict, FrozenSet, Iterable, List, Mapping, NamedTuple, Optional, Sequence, Tuple

from attention_common.joy_actions import NUM_ACTIONS

TABLE_PATH = Path(__file__).resolve().parent / 'data' / 'action_effects.json'
TABLE_FORMAT = 'feedback_node.action_effects/1'
FOLLOW_STEPS = 8
"""NOOP steps after the action over which its effect is compared (a jump lasts ~8 steps)."""

Partition = Tuple[FrozenSet[int], ...]


class Situation(NamedTuple):
    """What a person sees of the state an action is taken in, most telling first."""

    phase: str
    """The stage of the route (``expert.Phase`` name), from the position and the key."""
    place: str
    """``'ladder'`` at either end of a ladder (UP or DOWN may take it), else ``'open'``."""
    pose: int
    """The agent's sprite (``attention_tasks.montezuma.env.RAM_POSE``)."""
    held: bool
    """The button was pressed at the step before (fire acts on a press, so a second press in
    a row does nothing)."""

    def keys(self) -> List[str]:
        """Table keys from the most detailed to the phase alone."""
        parts = [self.phase, self.place, str(int(self.pose)), 'held' if self.held else 'free']
        return ['/'.join(parts[:n]) for n in range(len(parts), 0, -1)]


LADDER_ENDS = ((77, 235), (77, 192), (133, 192), (133, 148), (21, 148), (21, 192))
"""RAM (x, y) of the top and the foot of the middle, right and left ladders."""
LADDER_REACH = 4
"""How far in x from a ladder's end UP or DOWN still takes it (the expert's snap is 3-4)."""


def place_of(x: int, y: int) -> str:
    """``'ladder'`` when the agent stands at a ladder's end, else ``'open'``."""
    at_end = any(y == end_y and abs(x - end_x) <= LADDER_REACH for end_x, end_y in LADDER_ENDS)
    return 'ladder' if at_end else 'open'


def partition_of(classes: Iterable[Iterable[int]]) -> Partition:
    """Normalise classes of action indices (each class sorted, classes by smallest action)."""
    normal = sorted((frozenset(int(a) for a in c) for c in classes), key=min)
    seen = sorted(a for c in normal for a in c)
    if seen != list(range(NUM_ACTIONS)):
        raise ValueError(f'classes must cover each of the {NUM_ACTIONS} actions once')
    return tuple(normal)


class Measured(NamedTuple):
    """What was measured in one state."""

    effect: Partition
    """Equivalent by what the action does to the game (position, room, lives, inventory)."""
    classes: Partition
    """Equivalent also by what it leaves for the next step (the button held or not)."""


STRICT: Partition = tuple(frozenset((a,)) for a in range(NUM_ACTIONS))
"""Every action its own class: what a situation never measured is judged by."""


class EffectTable:
    """The measured partitions; ``classes(phase, pose)`` for a situation."""

    def __init__(self, partitions: Mapping[str, Partition], counts: Mapping[str, int],
                 moot: Iterable[str] = (), info: Optional[dict] = None):
        self.partitions = dict(partitions)
        self.counts = dict(counts)
        self.moot = frozenset(moot)
        """Keys of the situations where no action changes what happens (in the air, dying)."""
        self.info = dict(info or {})

    @classmethod
    def load(cls, path: Path = TABLE_PATH) -> 'EffectTable':
        data = json.loads(Path(path).read_text())
        if data.get('format') != TABLE_FORMAT:
            raise ValueError(f'{path} is not a {TABLE_FORMAT} file')
        partitions = {key: partition_of(entry['classes'])
                      for key, entry in data['situations'].items()}
        counts = {key: int(entry['states']) for key, entry in data['situations'].items()}
        moot = [key for key, entry in data['situations'].items() if entry['cannot_matter']]
        return cls(partitions, counts, moot, data.get('info'))

    def to_json(self) -> dict:
        return {'format': TABLE_FORMAT, 'info': self.info, 'situations': {
            key: {'states': self.counts.get(key, 0), 'cannot_matter': key in self.moot,
                  'classes': [sorted(c) for c in self.partitions[key]]}
            for key in sorted(self.partitions)}}

    def _key(self, situation: Situation) -> Optional[str]:
        return next((key for key in situation.keys() if key in self.partitions), None)

    def classes(self, situation: Situation) -> Partition:
        """Return the partition for a situation (fewer details when unmeasured, then strict)."""
        key = self._key(situation)
        return STRICT if key is None else self.partitions[key]

    def equivalent(self, situation: Situation, a: int, b: int) -> bool:
        """Whether actions ``a`` and ``b`` do the same in this situation."""
        return any(a in c and b in c for c in self.classes(situation))

    def cannot_matter(self, situation: Situation) -> bool:
        """Whether every action does the same here (in the air, dying, respawning)."""
        return self._key(situation) in self.moot


AGREEMENT = 0.95
"""Two actions are one class of a situation when they were equivalent in this share of its
measured states. High on purpose: an action counted as the expert's when it is not (RIGHT as
NOOP where RIGHT walks) pays the learner for standing still, a trap; the other error (-1 for
an action that did the same after all) only makes the teacher stricter than needed."""
MOOT_SHARE = 0.9
"""A situation cannot matter when in this share of its states every action did the same to the
game. Lower than ``AGREEMENT`` on purpose: silence where an action did matter (the step a jump
lands) only loses a judgement; in the air and while dying, 92-94 % of the measured states are
moot."""
MIN_STATES = 5
"""A situation measured in fewer states is judged by a less detailed one."""


def agreed_partition(partitions: Sequence[Partition], agreement: float = AGREEMENT) -> Partition:
    """
    Return the partition of a situation from the partitions measured in its states.

    a and b share a class when they were equivalent in at least ``agreement`` of the states;
    classes are the connected groups of that relation (so the result is always a partition).
    """
    together = [[0] * NUM_ACTIONS for _ in range(NUM_ACTIONS)]
    for partition in partitions:
        for c in partition:
            for a in c:
                for b in c:
                    together[a][b] += 1
    parent = list(range(NUM_ACTIONS))

    def root(a: int) -> int:
        while parent[a] != a:
            a = parent[a]
        return a

    for a in range(NUM_ACTIONS):
        for b in range(a + 1, NUM_ACTIONS):
            if together[a][b] >= agreement * len(partitions):
                parent[root(b)] = root(a)
    groups: Dict[int, List[int]] = {}
    for a in range(NUM_ACTIONS):
        groups.setdefault(root(a), []).append(a)
    return partition_of(groups.values())


def build_table(samples: Iterable[Tuple[Situation, Measured]], min_states: int = MIN_STATES,
                agreement: float = AGREEMENT, moot_share: float = MOOT_SHARE,
                info: Optional[dict] = None) -> EffectTable:
    """
    Build the table from measured ``(situation, measured)`` samples.

    A situation's classes come from ``Measured.classes``; it cannot matter when in
    ``moot_share`` of its states every action is one class by ``Measured.effect`` (the button
    an action leaves held is judged at the next step, whose situation knows it).
    """
    by_key: Dict[str, List[Measured]] = {}
    for situation, measured in samples:
        for key in situation.keys():
            by_key.setdefault(key, []).append(measured)
    kept = {key: found for key, found in by_key.items() if len(found) >= min_states}
    partitions = {key: agreed_partition([m.classes for m in found], agreement)
                  for key, found in kept.items()}
    moot = [key for key, found in kept.items()
            if sum(len(m.effect) == 1 for m in found) >= moot_share * len(found)]
    return EffectTable(partitions, {key: len(found) for key, found in kept.items()}, moot, info)
