"""
Training progress as the launcher sees it, from plain values (no rclpy).

``ProgressTracker`` turns each step's ``env_status`` into one row per agent step (for
``progress.csv`` and the learning curve), keeping the furthest critical position reached so far
and the closed-loop latency env_node measured. ``format_bar`` draws the terminal line.

Its memory is bounded however long the run: rows go to the caller (``take_new_rows``, streamed
to ``progress.csv``), only the recent ones stay, and latencies go into a DDSketch (quantiles
within 1 %).
"""

import collections
from dataclasses import dataclass, field
from typing import Callable, Deque, Dict, List, Mapping, Optional, Sequence

from ddsketch import DDSketch

PROGRESS_COLUMNS = (
    'agent_step', 'sim_time_s', 'wall_time_s', 'episode', 'episode_step', 'lives', 'has_key',
    'reward', 'episode_return', 'x', 'y', 'room', 'position', 'furthest_position',
    'feedback_count', 'feedback_sum', 'utterance_count', 'saliency_count', 'pose',
    'action', 'furthest_stood', 'life_lost', 'session', 'heldout',
)

ALIVE_STEPS = 15
"""A critical position counts as stood on when no life is lost in this many steps after (1 s
of simulation time at frameskip 4)."""

START_ROOM = 1  # RAM room number of Room 1; positions elsewhere are not Room 1's coordinates.
RECENT_ROWS = 2000
"""Rows the tracker keeps (for the step rate and "now"); all rows go to progress.csv."""
RECENT_STAMPS = 4096
"""Steps whose stamp -> agent step the tracker keeps (to label images taken meanwhile)."""
LATENCY_ACCURACY = 0.01
"""Relative accuracy of the latency quantiles."""


def parse_value(text: str):
    """Turn a diagnostic KeyValue string into a bool, int, float, or keep the string."""
    lowered = text.strip().lower()
    if lowered in ('true', 'false'):
        return lowered == 'true'
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_key_values(pairs) -> Dict[str, object]:
    """``[(key, value_string)]`` -> ``{key: value}`` with values parsed."""
    return {str(key): parse_value(str(value)) for key, value in pairs}


@dataclass
class Counters:
    """Messages the launcher has seen, per kind."""

    feedback: int = 0
    feedback_sum: float = 0.0
    utterances: int = 0
    saliency: int = 0


@dataclass
class ProgressTracker:
    """One row per agent step, furthest critical position, first step at each position."""

    position_of: Callable[[float, float], int] = lambda x, y: -1
    """(x, y) in RAM coordinates -> critical position index, -1 in between (used without
    ``milestone_of``)."""
    milestone_of: Optional[Callable[[Mapping[str, object]], int]] = None
    """The task's measure (``Task.milestone_of``) on a step's env_status values: when set, it
    takes the place of ``position_of`` (DoorKey: the last sub-goal done, 0 key .. 2 goal)."""
    solved_of: Callable[[Mapping[str, object]], bool] = lambda values: False
    """The task's success (``Task.solved``) on a step's values: its episode counts as solved."""
    solved_episodes: set = field(default_factory=set)
    """(session, episode) of the episodes solved."""
    heldout_episodes: set = field(default_factory=set)
    """(session, episode) of the episodes on held-out layouts (DoorKey's last part)."""
    start_room: int = START_ROOM
    counters: Counters = field(default_factory=Counters)
    rows: Deque[dict] = field(default_factory=lambda: collections.deque(maxlen=RECENT_ROWS))
    """The newest rows (all of them went to ``take_new_rows``)."""
    row_count: int = 0
    first_row: Optional[dict] = None
    furthest: int = -1
    first_step_at: Dict[int, int] = field(default_factory=dict)
    keys: int = 0
    lives_lost: int = 0
    episodes: set = field(default_factory=set)
    step_at_stamp: 'collections.OrderedDict[int, int]' = field(
        default_factory=collections.OrderedDict)
    """stamp -> agent step of the newest ``RECENT_STAMPS`` steps."""
    latest: dict = field(default_factory=dict)
    finished: bool = False
    latencies_ms: DDSketch = field(default_factory=lambda: DDSketch(LATENCY_ACCURACY))
    """env_node's ``action_latency_ms`` of every step an answer led to (a sketch)."""
    first_key_step: Optional[int] = None
    """Agent step at which the key was first taken (None: never)."""
    standing_poses: frozenset = frozenset()
    """Poses (``env_status`` ``pose``) of an agent on the ground, a ladder or the rope; empty:
    stood-on is not measured."""
    furthest_stood: int = -1
    """Furthest critical position stood on: within alpha, held by something (a standing pose),
    alive ``ALIVE_STEPS`` steps later. ``furthest`` counts mere passing within alpha."""
    first_step_stood_at: Dict[int, int] = field(default_factory=dict)
    session: int = 1
    """The launcher's session of the run (``attention_train --resume`` starts the next)."""
    step_offset: int = 0
    """Agent steps of the earlier sessions: a resumed env counts from 1 again."""
    _had_key: bool = False
    _last_stamp: int = -1
    _candidates: List[tuple] = field(default_factory=list)
    _new_rows: List[dict] = field(default_factory=list)

    @property
    def last_stamp_ns(self) -> int:
        """Return the stamp of the newest step seen (-1: none)."""
        return self._last_stamp

    def on_status(self, stamp_ns: int, values: Mapping[str, object], wall_s: float) -> None:
        """Take one ``env_status`` (parsed key-values); a step seen twice counts once."""
        if values.get('finished'):
            self.finished = True
        if stamp_ns <= self._last_stamp:  # the first step, sent again during start-up
            return
        self._last_stamp = stamp_ns
        latency = values.get('action_latency_ms')
        if isinstance(latency, (int, float)) and latency >= 0:
            self.latencies_ms.add(float(latency))
        self._add_row(stamp_ns, values, wall_s)

    def milestone_steps(self, milestones: Sequence[str]) -> Dict[str, Optional[int]]:
        """Return the agent step at which each milestone was first reached, by name."""
        return {name: self.first_step_at.get(index) for index, name in enumerate(milestones)}

    def take_new_rows(self) -> List[dict]:
        """Return the rows added since the last call (each row is handed out once)."""
        rows, self._new_rows = self._new_rows, []
        return rows

    def latency_ms(self, q: float) -> Optional[float]:
        """Return the q-th percentile (0..100) of the steps' latency; None before any."""
        if not self.latencies_ms.count:
            return None
        return float(self.latencies_ms.get_quantile_value(q / 100.0))

    def _add_row(self, stamp_ns: int, values: Mapping[str, object], wall_s: float) -> None:
        x, y, room = (values.get(key, 0) for key in ('x', 'y', 'room'))
        if self.milestone_of is not None:
            position = self.milestone_of(values)
        else:
            position = self.position_of(x, y) if int(room) == self.start_room else -1
        step = self.step_offset + int(values.get('agent_step', self.row_count))
        if position > self.furthest:
            self.furthest = position
        if position >= 0 and position not in self.first_step_at:
            self.first_step_at[position] = step
        has_key = bool(values.get('has_key', False))
        if has_key and not self._had_key:
            self.keys += 1
            if self.first_key_step is None:
                self.first_key_step = step
        self._had_key = has_key
        if values.get('life_lost'):
            self.lives_lost += 1
        self._stand(position, step, values)
        if 'episode' in values:
            self.episodes.add((self.session, values['episode']))
            if self.solved_of(values):
                self.solved_episodes.add((self.session, values['episode']))
            if values.get('heldout'):
                self.heldout_episodes.add((self.session, values['episode']))
        self.step_at_stamp[stamp_ns] = step
        while len(self.step_at_stamp) > RECENT_STAMPS:
            self.step_at_stamp.popitem(last=False)
        row = {
            'agent_step': step,
            'sim_time_s': stamp_ns / 1e9,
            'wall_time_s': round(wall_s, 4),
            'episode': values.get('episode', ''),
            'episode_step': values.get('episode_step', ''),
            'lives': values.get('lives', ''),
            'has_key': int(has_key),
            'reward': values.get('reward', ''),
            'episode_return': values.get('episode_return', ''),
            'x': x, 'y': y, 'room': room,
            'position': position,
            'furthest_position': self.furthest,
            'feedback_count': self.counters.feedback,
            'feedback_sum': round(self.counters.feedback_sum, 4),
            'utterance_count': self.counters.utterances,
            'saliency_count': self.counters.saliency,
            'pose': values.get('pose', ''),
            'action': values.get('action', ''),
            'furthest_stood': self.furthest_stood,
            'life_lost': int(bool(values.get('life_lost'))),
            'session': self.session,
            'heldout': int(bool(values.get('heldout', False))),  # DoorKey: a held-out layout
        }
        self.rows.append(row)
        self._new_rows.append(row)
        self.row_count += 1
        if self.first_row is None:
            self.first_row = row
        self.latest = dict(values)

    def resume_from(self, rows) -> None:
        """
        Take up a run from the rows of its ``progress.csv`` (parsed).

        The furthest positions, keys, lives and counts go on, and the rows to come are the
        next session's. (Of the earlier sessions' positions stood on, the first steps of each
        new furthest are kept.)
        """
        had_key, last = False, None
        for row in rows:
            step, session = int(row['agent_step']), int(row.get('session') or 1)
            position = int(row['position'])
            self.furthest = max(self.furthest, position)
            if position >= 0:
                self.first_step_at.setdefault(position, step)
            has_key = bool(row['has_key'])
            if has_key and not had_key:
                self.keys += 1
                if self.first_key_step is None:
                    self.first_key_step = step
            had_key = has_key
            self.lives_lost += int(row.get('life_lost') or 0)
            self.episodes.add((session, row['episode']))
            if int(row.get('heldout') or 0):
                self.heldout_episodes.add((session, row['episode']))
            stood = int(row['furthest_stood'])
            if stood > self.furthest_stood:  # confirmed ALIVE_STEPS after it was stood on
                self.first_step_stood_at.setdefault(stood, step - ALIVE_STEPS)
                self.furthest_stood = stood
            self.row_count += 1
            if self.first_row is None:
                self.first_row = row
            self.rows.append(row)
            last = row
        if last is not None:
            self.step_offset = int(last['agent_step'])
            self.session = int(last.get('session') or 1) + 1
            self.counters = Counters(int(last['feedback_count']), float(last['feedback_sum']),
                                     int(last['utterance_count']), int(last['saliency_count']))

    def _stand(self, position: int, step: int, values: Mapping[str, object]) -> None:
        """Confirm the candidates that stayed alive; a life lost (or a new episode) voids all."""
        episode = values.get('episode')
        if values.get('life_lost') or any(c[2] != episode for c in self._candidates):
            self._candidates.clear()
        while self._candidates and step - self._candidates[0][1] >= ALIVE_STEPS:
            stood, at, _ = self._candidates.pop(0)
            self.first_step_stood_at.setdefault(stood, at)
            self.furthest_stood = max(self.furthest_stood, stood)
        if position >= 0 and values.get('pose') in self.standing_poses and not values.get(
                'life_lost'):
            self._candidates.append((position, step, episode))

    @property
    def steps(self) -> int:
        return int(self.rows[-1]['agent_step']) if self.rows else 0

    def rate(self, window: int = 200) -> float:
        """Agent steps per wall second over the last ``window`` rows."""
        if len(self.rows) < 2:
            return 0.0
        first = self.rows[max(0, len(self.rows) - window)]
        last = self.rows[-1]
        elapsed = last['wall_time_s'] - first['wall_time_s']
        steps = last['agent_step'] - first['agent_step']
        return steps / elapsed if elapsed > 0 else 0.0


def format_duration(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    hours, rest = divmod(seconds, 3600)
    minutes, seconds = divmod(rest, 60)
    return f'{hours}:{minutes:02d}:{seconds:02d}' if hours else f'{minutes}:{seconds:02d}'


def format_bar(steps: int, budget: int, rate: float, feedback: int, furthest: int,
               episode=None, lives=None, width: int = 24) -> str:
    """One terminal line: bar, steps, steps/s, ETA, feedback count, furthest position."""
    fraction = min(1.0, steps / budget) if budget > 0 else 0.0
    filled = int(round(fraction * width))
    eta = format_duration((budget - steps) / rate) if rate > 0 and steps < budget else '--:--'
    furthest_text = str(furthest) if furthest >= 0 else '-'
    extra = ''
    if episode is not None:
        extra += f' | episode {episode}'
    if lives is not None:
        extra += f' lives {lives}'
    return (f'[{"#" * filled}{"." * (width - filled)}] {steps}/{budget} steps '
            f'| {rate:5.1f} steps/s | ETA {eta} | feedback {feedback} '
            f'| furthest position {furthest_text}{extra}')
