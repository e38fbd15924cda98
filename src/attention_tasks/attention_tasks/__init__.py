"""
Task knowledge, one home per task (issue 15).

Each task is a subpackage the nodes are to load by name (``task`` parameter): its world (env
factory and the state other nodes need), its expert, its progress measure and its teacher's
sentences. ``doorkey`` is the first: MiniGrid DoorKey with distractors, a world that changes
every episode. Room 1's knowledge still lives in env_node and feedback_node (moving it here is
the rest of issue 15).
"""

TASKS = ('montezuma', 'doorkey')
"""Task names; ``montezuma`` (Room 1) is the default of every node."""
