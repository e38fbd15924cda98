"""Fetch frames for pretraining an encoder (``tamer_pretrain --task fetch``), as DoorKey's."""

from typing import Tuple

from attention_tasks import gridworld
from attention_tasks.doorkey.frames import PRETRAIN_SEED_OFFSET
from attention_tasks.fetch.env import FetchEnv, FetchEnvConfig
from attention_tasks.fetch.expert import next_action
import numpy as np


def collect_frames(count: int, seed: int = 0, **options) -> Tuple[np.ndarray, str]:
    """Return (frames of the agent's view, the policy's name): ``gridworld.collect_frames``."""
    env = FetchEnv(FetchEnvConfig(seed=PRETRAIN_SEED_OFFSET + seed))
    return gridworld.collect_frames(env, lambda step: next_action(step.state), count, seed,
                                    **options)
