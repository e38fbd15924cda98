"""Montezuma's Revenge, Room 1 (the thesis's task): the default ``task``."""

from typing import Mapping

from attention_common.joy_actions import ACTION_MEANINGS, NUM_ACTIONS
from attention_tasks.montezuma.critical_positions import (
    critical_position_at, CRITICAL_POSITIONS, OUTSIDE)
from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv, STANDING_POSES
from attention_tasks.montezuma.frames import collect_frames
from attention_tasks.task import Task

REALTIME_RATE_HZ = 15.0
"""env_node ``rate_hz`` a person watches at: with frameskip 4, exactly the Atari's 60 Hz."""


def milestone_of(values: Mapping[str, object], radius: float) -> int:
    """Return the critical position within ``radius`` of the agent in Room 1; -1 elsewhere."""
    if int(values.get('room', EnvConfig.start_room)) != EnvConfig.start_room:
        return OUTSIDE
    return critical_position_at(values.get('x', 0), values.get('y', 0), radius=radius)


TASK = Task(
    name='montezuma', env_id=EnvConfig.env_id, frame_shape=(210, 160),
    joy_actions=tuple(range(NUM_ACTIONS)), action_names=ACTION_MEANINGS,
    env_config=EnvConfig, make_env=MontezumaEnv,
    milestones=tuple(f'critical position {i}' for i in range(len(CRITICAL_POSITIONS))),
    milestone_of=milestone_of, manifest=None, realtime_hz=REALTIME_RATE_HZ,
    encoder_file='encoder.pt', collect_frames=collect_frames,
    solved=lambda values: bool(values.get('has_key')), standing_poses=STANDING_POSES)
