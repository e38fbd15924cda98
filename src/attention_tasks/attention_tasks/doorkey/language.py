"""
The teacher's sentences on the DoorKey level.

The sentence names the next sub-goal's (``world.SUBGOALS``) colour and object, as a person
would ("pick up the yellow key"), so the saliency node can ground it in the templates of that
object and colour.
"""

from attention_tasks.doorkey.world import DoorKeyState, progress

GOAL_COLOR = 'green'


def sentence(state: DoorKeyState) -> str:
    """Return what the teacher says for the next sub-goal."""
    done = progress(state)
    if state.carrying and not state.has_key and not state.door_open:
        return f'drop the {state.carrying} and pick up the {state.door_color} key'
    if done == 0:
        return f'pick up the {state.door_color} key'
    if done == 1:
        return f'open the {state.door_color} door'
    return f'go to the {GOAL_COLOR} square'
