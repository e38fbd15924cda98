"""
The DoorKey level as env_node steps it: ``reset`` / ``warm_up`` / ``step`` give ``Step``s.

A layout per episode, held-out layouts after ``heldout_after`` steps, one step a second of
simulation time: the MiniGrid tasks' shared stepping (``attention_tasks.gridworld``).
"""

from dataclasses import dataclass
from typing import Optional

from attention_tasks.doorkey.world import DistractorDoorKeyEnv, DoorKeyConfig, state_of
from attention_tasks.gridworld import GridWorld, Stepping


@dataclass
class DoorKeyEnvConfig(DoorKeyConfig, Stepping):
    """The level's settings; each field is a ROS parameter of env_node with ``task:=doorkey``."""

    def validate(self) -> None:
        DoorKeyConfig.validate(self)
        Stepping.validate(self)


class DoorKeyEnv(GridWorld):
    """The level, stepped by action index 0..5; call ``reset`` or ``warm_up`` once first."""

    def __init__(self, config: Optional[DoorKeyEnvConfig] = None, render: bool = True):
        config = config or DoorKeyEnvConfig()
        config.validate()
        super().__init__(config, DistractorDoorKeyEnv(config, render_mode='rgb_array',
                                                      highlight=False),  # no view cone
                         state_of, render)
