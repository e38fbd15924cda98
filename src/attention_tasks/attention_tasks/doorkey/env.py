"""
The DoorKey level as env_node steps it: ``reset`` / ``warm_up`` / ``step`` give ``Step``s.

Layouts: episode k of a trial draws its layout from seed ``SeedSequence([seed, split, k])``,
split 0 while training and 1 (the held-out seeds, never trained on) once the agent has taken
``heldout_after`` steps; ``env_status`` says which (``heldout``, ``layout``). Simulation time
runs ``STEP_S`` per step, the period a person watches at (``REALTIME_HZ``), so seconds mean
the same in lockstep and in real time (the teacher's delays, the utterances' lifetime).
"""

from dataclasses import dataclass
from typing import Optional

from attention_common.stamps import NS_PER_S
from attention_tasks.doorkey.world import DistractorDoorKeyEnv, DoorKeyConfig, observe, state_of
from attention_tasks.stepping import SteppedWorld
from attention_tasks.task import Step
import numpy as np

REALTIME_HZ = 1.0
"""Steps per second when a person watches: one move a second, time to see it and judge it (a
person's feedback comes 0.3-1.5 s late: at 1 Hz it is about one of the last 2-3 moves, at 4 Hz
one of the last 6)."""
STEP_S = 1.0 / REALTIME_HZ
NUM_ACTIONS = 6
"""MiniGrid's: left, right, forward, pickup, drop, toggle (``expert.LEFT`` ...)."""


def layout_seed(seed: int, heldout: bool, episode: int) -> int:
    """Return the level generator's seed of ``episode``: training and held-out never meet."""
    return int(np.random.SeedSequence([seed, int(heldout), episode]).generate_state(1)[0])


@dataclass
class DoorKeyEnvConfig(DoorKeyConfig):
    """The level's settings; each field is a ROS parameter of env_node with ``task:=doorkey``."""

    seed: int = 0
    """Seeds the layouts (and the random warm-up actions)."""
    warmup_steps: int = 0
    """Random steps at the start of the trial, not published."""
    heldout_after: int = 0
    """Agent steps after which every new episode has a held-out layout (0: never)."""

    def validate(self) -> None:
        super().validate()
        if self.warmup_steps < 0 or self.heldout_after < 0:
            raise ValueError('warmup_steps and heldout_after must be >= 0, got '
                             f'{self.warmup_steps} and {self.heldout_after}')


class DoorKeyEnv(SteppedWorld):
    """The level, stepped by action index 0..5; call ``reset`` or ``warm_up`` once first."""

    num_actions = NUM_ACTIONS

    def __init__(self, config: Optional[DoorKeyEnvConfig] = None):
        self.config = config or DoorKeyEnvConfig()
        self.config.validate()
        self._env = DistractorDoorKeyEnv(self.config, render_mode='rgb_array',
                                         highlight=False)  # no view cone: tiles look the same
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
    def world(self) -> DistractorDoorKeyEnv:
        """Return the MiniGrid env (for tests and tools)."""
        return self._env

    def reset(self) -> Step:
        """Start the next episode on its layout."""
        self._episode += 1
        after = self.config.heldout_after
        self._heldout = after > 0 and self._agent_step >= after
        self._layout = layout_seed(self.config.seed, self._heldout, self._episode)
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
        return Step(observation=observe(self._env),
                    state=state_of(self._env, self._layout, self._heldout), reward=reward,
                    terminated=terminated, truncated=truncated, life_lost=False,
                    episode=self._episode, episode_step=self._episode_step,
                    agent_step=self._agent_step,
                    sim_time_ns=int(round(self._ticks * STEP_S * NS_PER_S)),
                    episode_return=self._return)

    def close(self) -> None:
        self._env.close()
