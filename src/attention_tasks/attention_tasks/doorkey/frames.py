"""
DoorKey frames for pretraining the encoder (``tamer_pretrain --task doorkey``).

The expert's routes with random detours, as Room 1's are collected, on layouts of their own (the
pretraining seeds are offset by ``PRETRAIN_SEED_OFFSET``; no held-out layout of a trial is among
them).
"""

from typing import Tuple

from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig, NUM_ACTIONS
from attention_tasks.doorkey.expert import next_action
import numpy as np

PRETRAIN_SEED_OFFSET = 1_000_000


def collect_frames(count: int, seed: int = 0, stride: int = 1, detour_probability: float = 0.15,
                   detour_steps: Tuple[int, int] = (1, 6), use_expert: bool = True,
                   progress=None) -> Tuple[np.ndarray, str]:
    """
    Return ((count, 112, 112, 3) uint8 frames of the agent's view, the policy's name).

    Every ``stride``-th step is kept. With probability ``detour_probability`` per step the agent
    takes a few random actions, then the expert takes over from wherever it is (or a random walk
    throughout without ``use_expert``). ``progress(kept, count)`` every 200 frames.
    """
    rng = np.random.default_rng(seed)
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=PRETRAIN_SEED_OFFSET + seed))
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
            action = next_action(env.world) if use_expert and detour_left == 0 else None
            if action is None:
                action = int(rng.integers(NUM_ACTIONS))
                detour_left = max(0, detour_left - 1)
            step = env.step(action)
            if step.done:
                step = env.reset()
    finally:
        env.close()
    return frames, policy
