"""
Room 1 frames for pretraining the encoder (``tamer_pretrain``).

The scripted expert's route with random detours, or a seeded random walk, from the real game (no
sticky actions, seeded).
"""

from typing import Tuple

from attention_common.joy_actions import NUM_ACTIONS
from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
from attention_tasks.montezuma.expert import RoomOneExpert, skull_x_from_ram
import numpy as np

ROOM_ONE = 1


def collect_frames(count: int, seed: int = 0, stride: int = 2, detour_probability: float = 0.05,
                   detour_steps: Tuple[int, int] = (4, 24), use_expert: bool = True,
                   episode_steps: int = 1500,
                   progress=None) -> Tuple[np.ndarray, str]:
    """
    Return ((count, 210, 160, 3) uint8 Room 1 frames, the policy's name).

    Every ``stride``-th step is kept. With probability ``detour_probability`` per step the agent
    leaves the route for a random number of steps holding one random action, then the expert
    takes over again from wherever it is. An episode ends at game over, on leaving Room 1, with
    the key, or after ``episode_steps``. ``progress(kept, count)`` is called every 200 frames.
    """
    rng = np.random.default_rng(seed)
    expert = RoomOneExpert() if use_expert else None
    policy = 'expert with random detours' if expert is not None else 'seeded random walk'
    if expert is None:
        detour_probability = 0.1  # a random walk: hold a random action for a while
    env = MontezumaEnv(EnvConfig(seed=seed, warmup_steps=0, sticky_actions=0.0))
    frames = np.empty((count,) + (210, 160, 3), np.uint8)
    kept = 0
    detour_left, detour_action = 0, 0
    try:
        step = env.reset()
        if expert is not None:
            expert.reset()
        while kept < count:
            if step.state.room == ROOM_ONE and step.episode_step % stride == 0:
                frames[kept] = step.observation
                kept += 1
                if progress is not None and kept % 200 == 0:
                    progress(kept, count)
            if detour_left == 0 and rng.random() < detour_probability:
                detour_left = int(rng.integers(detour_steps[0], detour_steps[1] + 1))
                detour_action = int(rng.integers(NUM_ACTIONS))
            if expert is not None:
                # The expert sees every step (its skull tracker keeps time) even when the
                # detour overrides its choice.
                expert_action = int(expert.act(step.state, skull_x_from_ram(env.ale.getRAM())))
            if detour_left > 0 or expert is None:
                action = detour_action
                detour_left = max(0, detour_left - 1)
            else:
                action = expert_action
            step = env.step(action)
            if step.done or step.state.has_key or step.episode_step >= episode_steps:
                step = env.reset()
                if expert is not None:
                    expert.reset()
    finally:
        env.close()
    return frames, policy
