"""
What the MiniGrid tasks share: a level stepped for env_node, a layout per episode, the view.

Layouts: episode k of a trial draws its layout from seed ``SeedSequence([seed, split, k])``,
split 0 while training and 1 (the held-out seeds, never trained on) once the agent has taken
``heldout_after`` steps; ``env_status`` says which (``heldout``, ``layout``), and the level is
told (``heldout``) before it draws, for a level that holds more than layouts out. Simulation
time runs ``STEP_S`` per step, the period a person watches at (``REALTIME_HZ``), so seconds
mean the same in lockstep and in real time (the teacher's delays, the utterances' lifetime).
Frames are the agent's own view (``observe``).
"""

from dataclasses import dataclass
from typing import Any, Callable, Optional, Tuple

from attention_common.stamps import NS_PER_S
from attention_tasks.stepping import SteppedWorld
from attention_tasks.task import Step
import numpy as np

REALTIME_HZ = 1.0
"""Steps per second when a person watches: one move a second, time to see it and judge it (a
person's feedback comes 0.3-1.5 s late: at 1 Hz it is about one of the last 2-3 moves, at 4 Hz
one of the last 6)."""
STEP_S = 1.0 / REALTIME_HZ
NUM_ACTIONS = 6
"""MiniGrid's: left, right, forward, pickup, drop, toggle."""
LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE = range(NUM_ACTIONS)
JOY_ACTIONS = (4, 3, 2, 5, 13, 1)
"""The joystick action carrying each MiniGrid action: left turns left (LEFT), right turns
right (RIGHT), forward is UP, pick up is DOWN, drop is DOWN+FIRE, toggle (open) is FIRE."""
ACTION_NAMES = ('left', 'right', 'forward', 'pickup', 'drop', 'toggle')
TILE_SIZE = 16
"""Pixels per cell of every rendered frame: large enough for template matching."""
AGENT_VIEW = 7
"""Cells per side of the agent's own view (MiniGrid's default): frames of 112 x 112."""


def layout_seed(seed: int, heldout: bool, episode: int) -> int:
    """Return the level generator's seed of ``episode``: training and held-out never meet."""
    return int(np.random.SeedSequence([seed, int(heldout), episode]).generate_state(1)[0])


def observe(env) -> np.ndarray:
    """Return the agent's view: (112, 112, 3) uint8 RGB, the agent at the bottom centre."""
    return env.get_frame(highlight=False, tile_size=TILE_SIZE, agent_pov=True)


@dataclass
class Stepping:
    """How a trial steps a level; each field is a ROS parameter of env_node."""

    seed: int = 0
    """Seeds the layouts (and the random warm-up actions)."""
    warmup_steps: int = 0
    """Random steps at the start of the trial, not published."""
    heldout_after: int = 0
    """Agent steps after which every new episode has a held-out layout (0: never)."""

    def validate(self) -> None:
        if self.warmup_steps < 0 or self.heldout_after < 0:
            raise ValueError('warmup_steps and heldout_after must be >= 0, got '
                             f'{self.warmup_steps} and {self.heldout_after}')


class GridWorld(SteppedWorld):
    """A MiniGrid level stepped by action index 0..5; call ``reset`` or ``warm_up`` once first."""

    num_actions = NUM_ACTIONS

    def __init__(self, config, level, state_of: Callable[[Any, int, bool], Any],
                 render: bool = True):
        """
        ``level``: the MiniGrid env; ``state_of(level, layout, heldout)``: a step's state.

        ``render`` False: steps carry no frame (``observation`` None), for tools that measure
        play and never look (rendering is most of a step's time).
        """
        self.config = config
        self._render = render
        self._env = level
        self._state_of = state_of
        self._rng = np.random.default_rng(self.config.seed)
        self._ticks = 0
        self._episode = -1
        self._episode_step = 0
        self._agent_step = 0
        self._return = 0.0
        self._layout = -1
        self._heldout = False
        self._needs_reset = True

    @property
    def world(self):
        """Return the MiniGrid env (for tests and tools)."""
        return self._env

    def reset(self) -> Step:
        """Start the next episode on its layout."""
        self._episode += 1
        after = self.config.heldout_after
        self._heldout = after > 0 and self._agent_step >= after
        self._layout = layout_seed(self.config.seed, self._heldout, self._episode)
        self._env.heldout = self._heldout
        self._env.reset(seed=self._layout)
        self._episode_step, self._return, self._needs_reset = 0, 0.0, False
        self._ticks += 1
        return self._make_step(0.0, False, False)

    def _advance(self, action: int) -> Step:
        _, reward, terminated, truncated, _ = self._env.step(action)
        self._ticks += 1
        self._episode_step += 1
        self._return += float(reward)
        step = self._make_step(float(reward), bool(terminated), bool(truncated))
        self._needs_reset = step.done
        return step

    def _make_step(self, reward: float, terminated: bool, truncated: bool) -> Step:
        return Step(observation=observe(self._env) if self._render else None,
                    state=self._state_of(self._env, self._layout, self._heldout),
                    reward=reward, terminated=terminated, truncated=truncated,
                    life_lost=False, episode=self._episode, episode_step=self._episode_step,
                    agent_step=self._agent_step,
                    sim_time_ns=int(round(self._ticks * STEP_S * NS_PER_S)),
                    episode_return=self._return)

    def close(self) -> None:
        self._env.close()


def collect_frames(env: GridWorld, expert: Callable[[Step], Optional[int]], count: int,
                   seed: int = 0, stride: int = 1, detour_probability: float = 0.15,
                   detour_steps: Tuple[int, int] = (1, 6), use_expert: bool = True,
                   progress=None) -> Tuple[np.ndarray, str]:
    """
    Return ((count, 112, 112, 3) uint8 frames of the agent's view, the policy's name).

    Every ``stride``-th step of ``env`` is kept. With probability ``detour_probability`` per
    step the agent takes a few random actions, then ``expert(step)`` takes over from wherever it
    is (or a random walk throughout without ``use_expert``). ``progress(kept, count)`` every
    200 frames. ``env`` is closed at the end.
    """
    rng = np.random.default_rng(seed)
    policy = 'expert with random detours' if use_expert else 'seeded random walk'
    step = env.reset()
    frames = np.empty((count,) + step.observation.shape, np.uint8)
    kept, detour_left = 0, 0
    try:
        while kept < count:
            if step.episode_step % stride == 0:
                frames[kept] = step.observation
                kept += 1
                if progress is not None and kept % 200 == 0:
                    progress(kept, count)
            if detour_left == 0 and rng.random() < detour_probability:
                detour_left = int(rng.integers(detour_steps[0], detour_steps[1] + 1))
            action = expert(step) if use_expert and detour_left == 0 else None
            if action is None:
                action = int(rng.integers(NUM_ACTIONS))
                detour_left = max(0, detour_left - 1)
            step = env.step(action)
            if step.done:
                step = env.reset()
    finally:
        env.close()
    return frames, policy
