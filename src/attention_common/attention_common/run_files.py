"""
The names of what a run folder holds, in one place (pure: no torch, no rclpy).

tamer_node writes the learner's files into the folder ``attention_train`` gives it, the
launcher writes the rest; the study and the teaching experiment read them back.
"""

# -- written by tamer_node (tamer_node.persistence) ---------------------------------------------
FEEDBACK_LOG = 'feedback_log.jsonl'
METRICS_CSV = 'metrics.csv'
CHECKPOINT_DIR = 'checkpoints'
CHECKPOINT_FILE = 'checkpoint.pt'
STEPS_DIR = 'steps'

# -- written by attention_train -----------------------------------------------------------------
SUMMARY_FILE = 'summary.json'
PARAMS_FILE = 'params.yaml'
PROGRESS_FILE = 'progress.csv'
PIDS_FILE = 'pids.json'
LEARNING_CURVE_FILE = 'learning_curve.png'
GALLERY_FILE = 'saliency_gallery.png'
OPTIONS_FILE = 'launch_options.json'
"""The options a run was started with (``--resume`` continues with them)."""
OVERRIDES_FILE = 'launcher_overrides.yaml'
LOGS_DIR = 'logs'
"""One log per node (and ROS's own logs under ``ros/``)."""
LAUNCHER_LOG = 'attention_train.log'
"""The launcher's own terminal output, written by the study's runner."""
REPLAY_LOG = 'attention_replay.log'
"""A replay trial's terminal output (``LAUNCHER_LOG``'s place in a replay's run folder)."""

# -- beside the run folders: attention_study's and attention_teaching's output folder ----------
STUDY_LOG = 'study_log.json'
TEACHING_LOG = 'teaching_log.json'
ANALYSIS_FILE = 'analysis.json'


def of_session(name: str, session) -> str:
    """
    Return ``name`` as session ``session`` keeps it: 'summary.json' -> 'summary.session2.json'.

    A ``session`` of '*' gives the glob pattern of every session's.
    """
    stem, dot, suffix = name.rpartition('.')
    return f'{stem}.session{session}{dot}{suffix}' if dot else f'{name}.session{session}'


def node_log(node: str, session: int = 1) -> str:
    """Return the log of ``node`` relative to the run folder; a resumed session has its own."""
    name = f'{node}.log'
    return f'{LOGS_DIR}/{name if session == 1 else of_session(name, session)}'
