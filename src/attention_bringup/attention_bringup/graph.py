"""
What the graph is made of: the four node executables, the parameter files, the conditions.

The launch file (``launch/attention.launch.py``) names the same executables and files; a test
checks that both stay in step.
"""

from pathlib import Path
from typing import List

# Node names equal executable names (and package names); also the top-level keys of the YAML.
NODES = ('env_node', 'feedback_node', 'saliency_node', 'tamer_node')

CONFIG_DIR = Path(__file__).resolve().parent / 'config'
GRAPH_FILE = 'graph.yaml'
CONDITIONS_DIR = 'conditions'
TASKS_DIR = 'tasks'

# The study conditions (issue 7 and the thesis, chapter 5), one parameter file each.
THESIS_CONDITIONS = (
    'vanilla', 'language', 'blind_obs', 'blind_saliency', 'language_every_step', 'hidden_agent',
)
CONDITIONS = THESIS_CONDITIONS + ('language_input', 'text_film')
"""Every condition a run can take: the thesis's six, then those added beside them (issue 25:
language_input, H sees the saliency image (the grounded mask) beside the frame when it acts;
text_film, the peer, H's features conditioned on the utterance's words as BabyAI's agents
are)."""
DEFAULT_CONDITION = 'language'


def graph_file(config_dir: Path = CONFIG_DIR) -> Path:
    """Return the file with the defaults of every node."""
    return config_dir / GRAPH_FILE


def condition_file(condition: str, config_dir: Path = CONFIG_DIR) -> Path:
    """Return the parameter file of a study condition; ``ValueError`` for an unknown name."""
    if condition not in CONDITIONS:
        raise ValueError(f'unknown condition {condition!r} (one of: {", ".join(CONDITIONS)})')
    return config_dir / CONDITIONS_DIR / f'{condition}.yaml'


def task_file(task: str, config_dir: Path = CONFIG_DIR) -> Path:
    """Return the parameter file of a task (it need not exist: Room 1's does not)."""
    return config_dir / TASKS_DIR / f'{task}.yaml'


def person_file(task: str, config_dir: Path = CONFIG_DIR) -> Path:
    """Return a task's file for a person training it (after the condition; it need not exist)."""
    return config_dir / TASKS_DIR / f'{task}_person.yaml'


def base_params_files(condition: str, config_dir: Path = CONFIG_DIR,
                      task: str = 'montezuma') -> List[Path]:
    """Return the files every node gets: graph defaults, the task's (if any), the condition."""
    tasks = [task_file(task, config_dir)] if task_file(task, config_dir).exists() else []
    return [graph_file(config_dir), *tasks, condition_file(condition, config_dir)]
