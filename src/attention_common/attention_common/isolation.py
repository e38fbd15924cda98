"""
Keep DDS on this machine, in a domain of our own.

Every process this project starts (nodes, tests, benchmarks, the launcher) runs with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ``ROS_DOMAIN_ID`` reserved for the run, so no
DDS traffic leaves loopback and parallel runs never hear each other. A user who wants the LAN
sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` in their own shell and runs the nodes with
``ros2 run`` (see the README).
"""

import contextlib
import ipaddress
import itertools
import os
import random
import socket
from typing import Dict, Iterator, Mapping, Optional

from domain_coordinator import domain_id as _coordinated_domain_id

DISCOVERY_RANGE = 'LOCALHOST'


def isolated_environ(domain_id: int,
                     base: Optional[Mapping[str, str]] = None) -> Dict[str, str]:
    """Return a copy of ``base`` (default ``os.environ``) with localhost discovery in a domain."""
    env = dict(os.environ if base is None else base)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = DISCOVERY_RANGE
    env['ROS_DOMAIN_ID'] = str(int(domain_id))
    env.pop('ROS_LOCALHOST_ONLY', None)  # deprecated in Jazzy; the range above replaces it
    env.pop('ROS_STATIC_PEERS', None)
    return env


@contextlib.contextmanager
def reserved_domain() -> Iterator[int]:
    """
    Reserve a free ROS domain (1..100) on this machine for the duration of the block.

    Uses ``domain_coordinator``, which holds a local port per domain, starting from a random
    domain so that concurrent runs spread out.
    """
    start = random.randrange(100)
    counter = itertools.count()

    def selector() -> int:
        return (start + next(counter)) % 100 + 1

    with _coordinated_domain_id(selector) as domain:
        yield domain


def apply_to_this_process(domain_id: int) -> None:
    """Isolate this process (call before ``rclpy.init``)."""
    os.environ.update(isolated_environ(domain_id, base={}))
    os.environ.pop('ROS_LOCALHOST_ONLY', None)


def is_loopback_host(host: str) -> bool:
    """Tell whether a server bound to ``host`` is reachable from this machine only."""
    try:
        return ipaddress.ip_address(socket.gethostbyname(host)).is_loopback
    except (OSError, ValueError):
        return False
