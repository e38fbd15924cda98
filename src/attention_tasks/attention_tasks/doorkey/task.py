"""DoorKey with distractors (MiniGrid): a world that changes every episode (issue 15)."""

from pathlib import Path
from typing import Mapping

from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.frames import collect_frames
from attention_tasks.doorkey.world import SUBGOALS
from attention_tasks.gridworld import (
    ACTION_NAMES, AGENT_VIEW, JOY_ACTIONS, REALTIME_HZ, TILE_SIZE)
from attention_tasks.task import Task
MANIFEST = Path(__file__).resolve().parent / 'templates' / 'manifest.yaml'
"""The saliency node's templates of every object kind and colour (``doorkey_make_templates``)."""


def milestone_of(values: Mapping[str, object], radius: float = 0.0) -> int:
    """Return the sub-goal this step has done last: 0 key in hand, 1 door open, 2 goal; -1 none."""
    return int(values.get('subgoals', 0)) - 1


def _solved(values: Mapping[str, object]) -> bool:
    return bool(values.get('at_goal'))


TASK = Task(
    name='doorkey', env_id='MiniGrid DistractorDoorKey', frame_shape=(AGENT_VIEW * TILE_SIZE,) * 2,
    joy_actions=JOY_ACTIONS, action_names=ACTION_NAMES, env_config=DoorKeyEnvConfig,
    make_env=DoorKeyEnv, milestones=SUBGOALS, milestone_of=milestone_of, manifest=MANIFEST,
    realtime_hz=REALTIME_HZ, encoder_file='encoder_doorkey.pt', collect_frames=collect_frames,
    solved=_solved, heldout_layouts=True)
