"""The Fetch room as env_node steps it (``attention_tasks.gridworld``: a layout per episode)."""

from dataclasses import dataclass
from typing import Optional

from attention_tasks.fetch.world import FetchConfig, FetchLevel, state_of
from attention_tasks.gridworld import GridWorld, Stepping


@dataclass
class FetchEnvConfig(FetchConfig, Stepping):
    """The room's settings; each field is a ROS parameter of env_node with ``task:=fetch``."""

    def validate(self) -> None:
        FetchConfig.validate(self)
        Stepping.validate(self)


class FetchEnv(GridWorld):
    """The room, stepped by action index 0..5; call ``reset`` or ``warm_up`` once first."""

    def __init__(self, config: Optional[FetchEnvConfig] = None):
        config = config or FetchEnvConfig()
        config.validate()
        super().__init__(config, FetchLevel(config, render_mode='rgb_array', highlight=False),
                         state_of)
