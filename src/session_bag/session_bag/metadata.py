"""
rosbag2's ``metadata.yaml`` (version 9, Jazzy) and QoS profiles in its YAML form. Pure.

``ros2 bag info`` reads this file, ``ros2 bag play`` finds the storage files through it, and
Python readers (rosbags) need it; the recorder rewrites it (atomically) on every flush, so a
bag whose recorder was killed still has one, at most one flush behind its MCAP file.
"""

import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional

import yaml

METADATA_FILE = 'metadata.yaml'
VERSION = 9
"""rosbag2's metadata version of Jazzy."""
STORAGE = 'mcap'


def duration_dict(nanoseconds: int) -> dict:
    return {'sec': int(nanoseconds) // 10**9, 'nsec': int(nanoseconds) % 10**9}


def qos_dict(profile) -> dict:
    """Return an rclpy ``QoSProfile`` as rosbag2 v9 writes it ('keep_last', 'reliable', ...)."""
    return {
        'history': profile.history.name.lower(),
        'depth': int(profile.depth),
        'reliability': profile.reliability.name.lower(),
        'durability': profile.durability.name.lower(),
        'deadline': duration_dict(profile.deadline.nanoseconds),
        'lifespan': duration_dict(profile.lifespan.nanoseconds),
        'liveliness': profile.liveliness.name.lower(),
        'liveliness_lease_duration': duration_dict(profile.liveliness_lease_duration.nanoseconds),
        'avoid_ros_namespace_conventions': bool(profile.avoid_ros_namespace_conventions),
    }


def qos_yaml(profiles: List[dict]) -> str:
    """Return QoS profiles as the YAML text an MCAP channel's ``offered_qos_profiles`` holds."""
    return yaml.safe_dump(profiles, sort_keys=False)


def metadata(storage_file: str, topics: List[dict], counts: Mapping[str, int],
             start_ns: Optional[int], end_ns: Optional[int],
             custom_data: Optional[Mapping[str, str]] = None) -> dict:
    """
    Return the metadata of a one-file bag.

    ``topics``: [{'name', 'type', 'offered_qos_profiles' (list of qos_dict), 'type_hash'}] in
    channel order; ``counts``: messages per topic name.
    """
    start = int(start_ns or 0)
    duration = max(0, int(end_ns or 0) - start) if start_ns is not None else 0
    total = sum(counts.get(t['name'], 0) for t in topics)
    return {'rosbag2_bagfile_information': {
        'version': VERSION,
        'storage_identifier': STORAGE,
        'duration': {'nanoseconds': duration},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': total,
        'topics_with_message_count': [
            {'topic_metadata': {'name': t['name'], 'type': t['type'],
                                'serialization_format': 'cdr',
                                'offered_qos_profiles': t['offered_qos_profiles'],
                                'type_description_hash': t['type_hash']},
             'message_count': int(counts.get(t['name'], 0))}
            for t in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [storage_file],
        'files': [{'path': storage_file,
                   'starting_time': {'nanoseconds_since_epoch': start},
                   'duration': {'nanoseconds': duration},
                   'message_count': total}],
        'custom_data': dict(custom_data or {}),
        'ros_distro': 'jazzy',
    }}


def write(bag_dir: Path, data: dict) -> None:
    """Write ``metadata.yaml`` atomically (a reader never sees half a file)."""
    path = Path(bag_dir) / METADATA_FILE
    temporary = path.with_suffix('.yaml.tmp')
    temporary.write_text(yaml.safe_dump(data, sort_keys=False))
    os.replace(temporary, path)


def read(bag_dir: Path) -> dict:
    """Return the ``rosbag2_bagfile_information`` of a bag; ValueError if it has none."""
    path = Path(bag_dir) / METADATA_FILE
    try:
        data = yaml.safe_load(path.read_text())
        return data['rosbag2_bagfile_information']
    except (OSError, yaml.YAMLError, KeyError, TypeError) as error:
        raise ValueError(f'{path} is not a rosbag2 metadata file ({error})') from None


def topic_counts(info: dict) -> Dict[str, int]:
    """Return {topic: message count} of a bag's metadata."""
    return {entry['topic_metadata']['name']: int(entry['message_count'])
            for entry in info.get('topics_with_message_count') or []}
