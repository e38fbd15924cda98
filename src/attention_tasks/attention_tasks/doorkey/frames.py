"""
DoorKey frames for pretraining the encoder (``tamer_pretrain --task doorkey``).

The expert's routes with random detours, as Room 1's are collected, on layouts of their own (the
pretraining seeds are offset by ``PRETRAIN_SEED_OFFSET``; no held-out layout of a trial is among
them).
"""

from typing import Tuple

from attention_tasks import gridworld
from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.expert import next_action
import numpy as np

PRETRAIN_SEED_OFFSET = 1_000_000


def collect_frames(count: int, seed: int = 0, **options) -> Tuple[np.ndarray, str]:
    """Return (frames of the agent's view, the policy's name): ``gridworld.collect_frames``."""
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=PRETRAIN_SEED_OFFSET + seed))
    return gridworld.collect_frames(env, lambda step: next_action(env.world), count, seed,
                                    **options)
