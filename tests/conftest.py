"""
Session-wide test setup: DDS on loopback, in a ROS domain reserved for this pytest session.

This runs when pytest imports it, before any test module imports rclpy, so every node a test
starts, in this process or as a child process, inherits the isolation.
"""

import os

from attention_common.dds_memory import use_freed_payloads
from attention_common.isolation import isolated_environ, reserved_domain
import pytest

_domain_reservation = reserved_domain()
TEST_DOMAIN_ID = _domain_reservation.__enter__()
os.environ.update(isolated_environ(TEST_DOMAIN_ID, base={}))
os.environ.pop('ROS_LOCALHOST_ONLY', None)
use_freed_payloads()  # the probe talks DDS as the graph's nodes do (attention_common.dds_memory)


def pytest_report_header(config):
    return (f'ROS_DOMAIN_ID={TEST_DOMAIN_ID} '
            f'ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]}')


LONGEST_FIRST = (
    'test_launcher.py', 'test_study_ray.py', 'test_session_graph.py', 'test_tamer_node.py',
    'test_trainer_console.py', 'test_graph_viewer.py', 'test_human_bursts.py',
    'test_bad_input.py', 'test_console_fetch.py', 'test_env_topics.py', 'test_action_effects.py',
)
"""The files that take longest (140 s down to 17 s of their tests' time in one run of the suite
on 2 cores), run first: ``make test`` gives each pytest-xdist worker whole files
(``--dist loadfile``), and a long file started last keeps one worker busy while the others
idle."""


def pytest_collection_modifyitems(config, items):
    """Put the longest files first (each file's tests stay together and in order)."""
    rank = {name: index for index, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def pytest_unconfigure(config):
    _domain_reservation.__exit__(None, None, None)


@pytest.fixture
def probe():
    """Give a node in a private rclpy context, spinning on its own thread (harness.TopicProbe)."""
    from harness import TopicProbe
    with TopicProbe() as topic_probe:
        yield topic_probe


@pytest.fixture
def start_node(tmp_path):
    """Start real node executables as processes; every one still running is stopped after."""
    from harness import NodeProcess
    started = []

    def start(executable, params=None, ros_args=(), name=None):
        process = NodeProcess(executable, params or {}, tmp_path, ros_args=ros_args, name=name)
        started.append(process)
        return process

    yield start
    for process in started:
        process.kill_if_running()
