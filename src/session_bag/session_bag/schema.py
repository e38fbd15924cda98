"""
Message definitions and type hashes as rosbag2 writes them, from rosbags' Jazzy type store.

An MCAP schema of encoding ``ros2msg`` is the type's .msg text followed by each type it uses
(``MSG: pkg/Name`` after a line of 80 '='), which is what Foxglove and ``ros2 bag`` decode
with; the RIHS01 hash is Jazzy's ``type_description_hash``. rosbags carries both for every
standard Jazzy type, so nothing here parses .msg files.
"""

import functools
from typing import NamedTuple


class Definition(NamedTuple):
    text: str
    """The concatenated message definition (MCAP schema data, encoding ``ros2msg``)."""
    type_hash: str
    """'RIHS01_<sha256>': the type description hash of ROS 2 Jazzy."""


@functools.lru_cache(maxsize=None)
def _typestore():
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


@functools.lru_cache(maxsize=None)
def definition(type_name: str) -> Definition:
    """Return the definition of ``type_name`` ('sensor_msgs/msg/Image'); KeyError if unknown."""
    store = _typestore()
    if type_name not in store.fielddefs:
        raise KeyError(f'{type_name} is not a standard ROS 2 Jazzy message type')
    text, _ = store.generate_msgdef(type_name, ros_version=2)
    return Definition(text, store.hash_rihs01(type_name))
