"""The task contract: tasks load by name, their tables agree, both worlds step the same way."""

from attention_common.joy_actions import action_to_joy, joy_to_action
from attention_tasks.gridworld import layout_seed
from attention_tasks.task import load_task, NO_ACTION, task_names, UnknownTask
import numpy as np
import pytest


def test_the_installed_tasks_load_by_name_and_an_unknown_one_is_named():
    assert task_names() == ('doorkey', 'fetch', 'montezuma')
    with pytest.raises(UnknownTask, match="unknown task 'pong'; installed tasks: doorkey, "
                                          'fetch, montezuma'):
        load_task('pong')


@pytest.mark.parametrize('name', ['montezuma', 'doorkey'])
def test_every_task_action_travels_as_one_joystick_action_and_back(name):
    task = load_task(name)
    assert len(task.action_names) == task.num_actions
    for action in range(task.num_actions):
        axes, buttons = action_to_joy(task.joy_action(action))
        assert task.action_of_joy(joy_to_action(axes, buttons)) == action
    with pytest.raises(ValueError):
        task.joy_action(task.num_actions)


def test_doorkey_leaves_joystick_actions_that_carry_nothing():
    task = load_task('doorkey')
    assert task.num_actions == 6
    carried = {task.joy_action(a) for a in range(6)}
    assert [task.action_of_joy(j) for j in range(18) if j not in carried] == [None] * 12
    assert task.action_names[task.action_of_joy(1)] == 'toggle'  # FIRE opens the door


@pytest.mark.parametrize('name', ['montezuma', 'doorkey'])
def test_each_world_steps_with_the_tasks_frames_and_state(name):
    task = load_task(name)
    env = task.make_env(task.env_config(seed=1, warmup_steps=0))
    try:
        step = env.warm_up()
        assert step.observation.shape == task.frame_shape + (3,)
        assert step.action == NO_ACTION and step.episode == 0
        status = step.state.status()
        assert {'x', 'y', 'has_key', 'lives', 'room'} <= set(status)
        assert len(step.state.position()) == 3
        stamps = [step.sim_time_ns]
        for action in range(task.num_actions):
            step = env.step(action)
            assert step.action == action and step.observation.dtype == np.uint8
            stamps.append(step.sim_time_ns)
        assert stamps == sorted(set(stamps))  # simulation time strictly increases
        assert task.milestone_of(status, 8.0) >= -1
    finally:
        env.close()


def test_doorkey_holds_out_layouts_after_heldout_after_steps():
    task = load_task('doorkey')
    env = task.make_env(task.env_config(seed=2, heldout_after=30, max_episode_steps=10))
    layouts = {False: set(), True: set()}
    step = env.reset()
    for _ in range(80):
        layouts[step.state.heldout].add(step.state.layout)
        step = env.step(2)
        if step.done:
            step = env.reset()
    assert len(layouts[False]) >= 3 and len(layouts[True]) >= 3
    assert not layouts[False] & layouts[True]
    again = task.make_env(task.env_config(seed=2, heldout_after=30, max_episode_steps=10))
    assert again.reset().state.layout == layout_seed(2, False, 0) in layouts[False]  # the same
    assert layout_seed(3, False, 0) != layout_seed(2, False, 0)  # draws for the same seed
