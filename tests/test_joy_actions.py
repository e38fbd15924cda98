"""ALE actions <-> sensor_msgs/Joy (attention_common.joy_actions), table-driven."""

import math

import ale_py
from attention_common.joy_actions import (ACTION_MEANINGS, action_to_joy, DEADZONE,
                                          joy_to_action, JoyActionError, NUM_ACTIONS)
import pytest
from sensor_msgs.msg import Joy


def test_meanings_follow_ale_order():
    assert ACTION_MEANINGS == tuple(ale_py.Action(i).name for i in range(NUM_ACTIONS))
    assert NUM_ACTIONS == 18


@pytest.mark.parametrize('action', range(NUM_ACTIONS), ids=ACTION_MEANINGS)
def test_every_action_round_trips_through_a_joy_message(action):
    axes, buttons = action_to_joy(action)
    msg = Joy(axes=list(axes), buttons=list(buttons))
    assert joy_to_action(msg.axes, msg.buttons) == action


@pytest.mark.parametrize('action', range(NUM_ACTIONS), ids=ACTION_MEANINGS)
def test_joy_follows_the_ros_joystick_convention(action):
    (horizontal, vertical), (fire,) = action_to_joy(action)
    meaning = ACTION_MEANINGS[action]
    assert horizontal == (1.0 if 'LEFT' in meaning else -1.0 if 'RIGHT' in meaning else 0.0)
    assert vertical == (1.0 if 'UP' in meaning else -1.0 if 'DOWN' in meaning else 0.0)
    assert fire == int('FIRE' in meaning)


def test_actions_are_distinct():
    assert len({action_to_joy(a) for a in range(NUM_ACTIONS)}) == NUM_ACTIONS


@pytest.mark.parametrize('axes, buttons, meaning', [
    ([0.3, -0.3], [0], 'NOOP'),                   # a stick at rest drifts a little
    ([DEADZONE - 0.01, 0.0], [0], 'NOOP'),
    ([DEADZONE, 0.0], [0], 'LEFT'),
    ([0.7, 0.0], [0], 'LEFT'),
    ([-0.7, 0.0], [0], 'RIGHT'),
    ([0.0, 0.9], [1], 'UPFIRE'),
    ([-0.6, -0.8], [0], 'DOWNRIGHT'),
    ([1.0, 1.0], [1], 'UPLEFTFIRE'),
    ([0.0, -1.0, 0.2, 0.9, -1.0, 1.0], [0, 1, 1, 0], 'DOWN'),  # a gamepad's extra axes/buttons
])
def test_deadzone_and_analogue_sticks(axes, buttons, meaning):
    assert ACTION_MEANINGS[joy_to_action(axes, buttons)] == meaning


@pytest.mark.parametrize('axes, buttons', [
    ([], [0]),
    ([0.0], [0]),
    ([0.0, 0.0], []),
    ([1.5, 0.0], [0]),
    ([0.0, -1.01], [0]),
    ([math.nan, 0.0], [0]),
    ([0.0, math.inf], [0]),
    ([-math.inf, 0.0], [0]),
    ([0.0, 0.0], [2]),
    ([0.0, 0.0], [-1]),
])
def test_malformed_joy_raises(axes, buttons):
    with pytest.raises(JoyActionError):
        joy_to_action(axes, buttons)


@pytest.mark.parametrize('action', [-1, NUM_ACTIONS, 100])
def test_action_out_of_range_raises(action):
    with pytest.raises(JoyActionError):
        action_to_joy(action)
