"""
Progress and the teacher's sentences on the DoorKey level.

Sub-goals, in order, take the place of Room 1's critical positions: the door's key in hand,
the door open, the goal reached. The sentence names the next sub-goal's colour and object, as
a person would ("pick up the yellow key"), so the saliency node can ground it in the templates
of that object and colour.
"""

from attention_tasks.doorkey.world import DoorKeyState

SUBGOALS = ('key', 'door', 'goal')
GOAL_COLOR = 'green'


def progress(state: DoorKeyState) -> int:
    """Return how many sub-goals are done (0..3); an open door counts the key as taken."""
    if state.at_goal:
        return 3
    if state.door_open:
        return 2
    return 1 if state.has_key else 0


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
