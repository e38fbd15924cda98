"""
QoS profiles of the graph, chosen on purpose and named once.

- Frames and actions are RELIABLE: in lockstep the env waits for the action that answers each
  observation, so a lost frame would stall a step until ``action_timeout``.
- A person's words (``utterance``, ``feedback``) are RELIABLE and VOLATILE, which is exactly what
  ``ros2 topic pub`` offers by default; KEEP_ALL history keeps bursts whole.
- Status and metrics are for viewers: reliable, shallow. The launcher watches with a deep
  queue (``WATCH_STEPS``) and samples images best effort (``WATCH_IMAGES``).
- ``/clock`` follows rclpy's own time source (best-effort subscriber, depth 1); a reliable
  publisher serves both kinds of subscriber.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def _reliable(depth: int) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


FRAMES = _reliable(10)
"""observation, saliency, saliency_mask: their readers."""

FRAMES_WRITER = _reliable(100)
"""Their writers: a reliable writer gives a reader that fell behind only what it still holds,
and the session recorder may fall behind for a moment (a chunk to compress, a busy core) where
the learners never do in lockstep; 100 frames (10 MB of Room 1's) cover 0.4 s at 250 steps/s.
Depth does not take part in QoS matching, so every reader matches as before."""

ACTIONS = _reliable(10)
"""action (sensor_msgs/Joy)."""

STEP_DATA = _reliable(1000)
"""agent_position, env_status: one small message per step; a burst must not be lost. Lockstep
waits for the learner only, so the teacher may fall behind the env (a busy core): a reliable
KEEP_LAST writer overwrites what a slow reader has not taken yet, and each step lost leaves two
actions unjudged. 1000 steps are 4 s at 250 steps/s."""

LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""trainer_status: the newest state only, given to a reader that comes late."""

HUMAN = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""utterance, feedback and their stamped companions: a person's words are never dropped.

KEEP_ALL on both sides: a reliable writer keeps each message until every reader has it, and a
reader keeps every message until its node takes it, so a burst waits instead of being
overwritten (a depth of 100 lost 9,534 of 10,000 feedback sent at once)."""

METRICS = _reliable(10)
"""metrics."""

ACTION_VALUES = _reliable(10)
"""action_values: a viewer's; one per step, the newest matter."""

CLOCK = _reliable(1)
"""/clock publisher (rclpy's time source subscribes best-effort, depth 1)."""

WATCH_STEPS = _reliable(1000)
"""The launcher's monitor on env_status and the trainer's topics: reliable like the publishers,
with a deep queue, so a busy launcher falls behind and loses nothing."""

WATCH_IMAGES = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.VOLATILE)
"""The launcher's image samples (counting, the gallery): best effort, a late one may go."""

NEWEST = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                    reliability=ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.VOLATILE)
"""A viewer's: the newest message only, best effort (a frame not drawn is no loss). The
``<topic>/preview`` writers (``attention_common.preview``) and the Foxglove bridge's readers of
images and per-step topics."""
