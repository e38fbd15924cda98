"""Fetch (MiniGrid): a room of objects where only the words say which to pick up (issue 25)."""

from typing import Mapping

from attention_tasks.doorkey.task import MANIFEST
from attention_tasks.fetch.env import FetchEnv, FetchEnvConfig
from attention_tasks.fetch.frames import collect_frames
from attention_tasks.fetch.world import MILESTONES
from attention_tasks.gridworld import (
    ACTION_NAMES, AGENT_VIEW, JOY_ACTIONS, REALTIME_HZ, TILE_SIZE)
from attention_tasks.task import Task


def milestone_of(values: Mapping[str, object], radius: float = 0.0) -> int:
    """Return 1 with the target in hand, else -1 (facing it is the teacher's to judge)."""
    return 1 if values.get('fetched') else -1


def _solved(values: Mapping[str, object]) -> bool:
    return bool(values.get('fetched'))


TASK = Task(
    name='fetch', env_id='MiniGrid Fetch (the target said, not shown)',
    frame_shape=(AGENT_VIEW * TILE_SIZE,) * 2, joy_actions=JOY_ACTIONS,
    action_names=ACTION_NAMES, env_config=FetchEnvConfig, make_env=FetchEnv,
    milestones=MILESTONES, milestone_of=milestone_of,
    # The same MiniGrid objects as DoorKey's: its templates name every kind and colour, and its
    # encoder was pretrained on the same egocentric views of keys, balls and boxes.
    manifest=MANIFEST, realtime_hz=REALTIME_HZ, encoder_file='encoder_doorkey.pt',
    collect_frames=collect_frames, solved=_solved, heldout_layouts=True)
