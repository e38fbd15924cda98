"""
Task knowledge, one home per task (issue 15).

Each task is a subpackage the nodes are to load by name (``task`` parameter): its world (env
factory and the state other nodes need), its expert, its progress measure and its teacher's
sentences. ``doorkey`` is the first: MiniGrid DoorKey with distractors, a world that changes
every episode. ``montezuma`` holds Room 1's critical positions and scripted expert (which the
launcher, the console, the teacher and the encoder's pretraining used to import from
feedback_node); Room 1's RAM state and env factory are still in env_node.
"""
