"""
Montezuma's Revenge, Room 1, as a plain Python object (no rclpy).

Wraps ``ALE/MontezumaRevenge-v5`` (gymnasium + ale-py) and adds what the study needs: agent
position, room, lives and key read from RAM; random warm-up steps at the start of a trial; the
episode ends on game over or when the agent leaves the start room; simulation time counted in
emulator frames (60 Hz), so that seconds mean the same in lockstep and real time.

RAM coordinates and the frame: one RAM unit is one pixel on both axes; x grows to the right,
y grows upwards. The agent's sprite (8 columns, 20 rows while standing) spans columns
``x - 1 .. x + 6`` and rows ``308 - y .. 327 - y`` (its feet on row ``327 - y``), give or take
up to three pixels while it walks, jumps or dies (tests/test_env_core.py checks this).
"""

from dataclasses import dataclass
from typing import ClassVar, NamedTuple, Optional

import ale_py
from attention_common.joy_actions import NUM_ACTIONS
from attention_common.stamps import frames_to_ns
from attention_tasks.stepping import SteppedWorld
from attention_tasks.task import NO_ACTION, Step  # noqa: F401 (NO_ACTION: for callers)
import gymnasium as gym
import numpy as np

gym.register_envs(ale_py)

# RAM addresses (checked against rendered frames; see tests/test_env_core.py).
RAM_X, RAM_Y, RAM_ROOM, RAM_LIVES, RAM_INVENTORY = 42, 43, 3, 58, 65
KEY_BIT = 0x02  # inventory bit set while the agent carries the key
RAM_POSE = 53
"""The sprite the game draws for the agent (what a person sees it doing): 8 standing, 18
walking, 10 and 0 climbing a ladder, 6 jumping or falling, 4 and 14 on the rope, 22 and 30
dying (read off the expert's route; ``action_effects`` measures what it means)."""
STANDING_POSES = frozenset((8, 18, 10, 0, 4, 14))
"""Poses of an agent held by something: the ground (standing, walking), a ladder, the rope."""
RAM_SKULL_X = 47
"""The rolling skull's x (one pixel per step between 22 and 72 in Room 1)."""

FRAME_HEIGHT, FRAME_WIDTH = 210, 160


@dataclass
class EnvConfig:
    """The game's settings; each field is a ROS parameter of env_node (``config.py``)."""

    env_id: ClassVar[str] = 'ALE/MontezumaRevenge-v5'
    """Gymnasium id; ale-py ships the ROM. Fixed, not a parameter: the RAM addresses are its."""
    start_room: ClassVar[int] = 1
    """The episode ends when the agent leaves this room (RAM room number; Room 1 is 1). Fixed."""
    frameskip: int = 4
    """Emulator frames per agent step; the action is repeated on each."""
    sticky_actions: float = 0.0
    """ALE repeat_action_probability (0 keeps a study reproducible)."""
    seed: int = 0
    """Seeds the emulator and the random warm-up actions."""
    warmup_steps: int = 100
    """Random steps at the start of the trial (the thesis's 100), not published."""
    end_on_room_exit: bool = True
    """End the episode (truncated) when the agent leaves Room 1."""
    end_on_life_loss: bool = False
    """End the episode at every life lost instead of at game over."""


class RamState(NamedTuple):
    """What the study reads from the Atari's RAM."""

    x: int
    y: int
    room: int
    lives: int
    has_key: bool
    pose: int = -1
    """``RAM_POSE``: the agent's sprite (standing, walking, climbing, jumping, dying, ...)."""
    skull_x: int = -1
    """``RAM_SKULL_X``: where the skull is (a person sees it on screen)."""

    def status(self) -> dict:
        """Return the env_status values of the state (``env_node.status``)."""
        return {'lives': self.lives, 'has_key': self.has_key, 'room': self.room, 'x': self.x,
                'y': self.y, 'pose': self.pose, 'skull_x': self.skull_x}

    def position(self):
        """Return agent_position's (x, y, z): RAM coordinates and the room."""
        return float(self.x), float(self.y), float(self.room)


def read_ram_state(ram: np.ndarray) -> RamState:
    """Decode the study's variables from the 128 bytes of Atari RAM."""
    return RamState(x=int(ram[RAM_X]), y=int(ram[RAM_Y]), room=int(ram[RAM_ROOM]),
                    lives=int(ram[RAM_LIVES]), has_key=bool(ram[RAM_INVENTORY] & KEY_BIT),
                    pose=int(ram[RAM_POSE]), skull_x=int(ram[RAM_SKULL_X]))


class MontezumaEnv(SteppedWorld):
    """The game, stepped by action index; call ``reset`` once, then ``step``."""

    num_actions = NUM_ACTIONS

    def __init__(self, config: Optional[EnvConfig] = None):
        self.config = config or EnvConfig()
        if self.config.frameskip < 1:
            raise ValueError(f'frameskip must be >= 1, got {self.config.frameskip}')
        if not 0.0 <= self.config.sticky_actions <= 1.0:
            raise ValueError(f'sticky_actions must be in [0, 1], got {self.config.sticky_actions}')
        if self.config.warmup_steps < 0:
            raise ValueError(f'warmup_steps must be >= 0, got {self.config.warmup_steps}')
        self._env = gym.make(self.config.env_id, frameskip=self.config.frameskip,
                             repeat_action_probability=self.config.sticky_actions,
                             full_action_space=True)
        self._rng = np.random.default_rng(self.config.seed)
        self._frames = 0
        self._episode = -1
        self._episode_step = 0
        self._agent_step = 0
        self._lives = 0
        self._episode_return = 0.0
        self._needs_reset = True
        self._seeded = False

    @property
    def ale(self):
        """Return the ALEInterface (RAM access for tests and tools)."""
        return self._env.unwrapped.ale

    def ram_state(self) -> RamState:
        """Read the study's variables from the current RAM."""
        return read_ram_state(self.ale.getRAM())

    def reset(self) -> Step:
        """Start a new episode (the first reset seeds the emulator)."""
        seed = None if self._seeded else self.config.seed
        observation, info = self._env.reset(seed=seed)
        self._seeded = True
        self._episode += 1
        self._episode_step = 0
        self._episode_return = 0.0
        self._needs_reset = False
        self._frames += self.config.frameskip  # keeps stamps strictly increasing
        state = self.ram_state()
        self._lives = state.lives
        return self._make_step(observation, state, 0.0, False, False, False)

    def _advance(self, action: int) -> Step:
        observation, reward, terminated, truncated, info = self._env.step(action)
        self._frames += self.config.frameskip
        self._episode_step += 1
        state = self.ram_state()
        # The game's last death does not decrement lives (0 stays 0); game over marks it.
        life_lost = state.lives < self._lives or bool(terminated)
        self._lives = state.lives
        if self.config.end_on_life_loss and life_lost:
            terminated = True
        left_room = self.config.end_on_room_exit and state.room != self.config.start_room
        self._episode_return += float(reward)
        step = self._make_step(observation, state, float(reward), bool(terminated),
                               bool(truncated or left_room), life_lost)
        self._needs_reset = step.done
        return step

    def _make_step(self, observation, state, reward, terminated, truncated, life_lost) -> Step:
        return Step(observation=observation, state=state, reward=reward, terminated=terminated,
                    truncated=truncated, life_lost=life_lost, episode=self._episode,
                    episode_step=self._episode_step, agent_step=self._agent_step,
                    sim_time_ns=frames_to_ns(self._frames),
                    episode_return=self._episode_return)

    def close(self) -> None:
        """Release the emulator."""
        self._env.close()
