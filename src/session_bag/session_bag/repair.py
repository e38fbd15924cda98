"""
Make a bag cut short (its recorder was killed) whole again, like ``ros2 bag reindex``. Pure.

Every message of every complete chunk is copied, with its schemas and channels, into a new
MCAP file with summary and footer, which then replaces the old one; ``metadata.yaml`` is
rewritten with the true counts. What is lost is only what the killed recorder had not flushed
(at most ``flush_period_s``); the half-written chunk at the end was unreadable anyway.
"""

import os
from pathlib import Path
from typing import Dict, NamedTuple

from mcap.writer import CompressionType, Writer
from session_bag import metadata
from session_bag.reader import BagReader, ends_whole
from session_bag.writer import LIBRARY


class Repaired(NamedTuple):
    was_complete: bool
    messages: int
    counts: Dict[str, int]
    problem: str


def repair(bag_dir: Path) -> Repaired:
    """Rewrite a cut-short bag whole (a complete one only gets its metadata.yaml checked)."""
    bag_dir = Path(bag_dir)
    reader = BagReader(bag_dir)
    if ends_whole(reader.path):  # only its counts are read (a whole file has its footer)
        for _ in reader.messages():
            pass
        if reader.complete:
            _rewrite_metadata(bag_dir, reader)
            return Repaired(True, sum(reader.counts.values()), dict(reader.counts), '')
        reader = BagReader(bag_dir)
    temporary = reader.path.with_suffix('.mcap.repairing')
    with open(temporary, 'wb') as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile='ros2', library=LIBRARY)
        schema_ids: Dict[str, int] = {}
        channel_ids: Dict[str, int] = {}
        for message in reader.messages():
            channel = channel_ids.get(message.topic)
            if channel is None:
                topic = reader.topics[message.topic]
                schema = schema_ids.get(topic.type_name)
                if schema is None:
                    schema = schema_ids[topic.type_name] = writer.register_schema(
                        topic.type_name, 'ros2msg', reader.schemas[topic.type_name])
                channel = channel_ids[message.topic] = writer.register_channel(
                    message.topic, 'cdr', schema, topic.metadata)
            writer.add_message(channel, message.log_time, message.data, message.publish_time)
        writer.finish()
    os.replace(temporary, reader.path)
    _rewrite_metadata(bag_dir, reader)
    return Repaired(False, sum(reader.counts.values()), dict(reader.counts),
                    reader.problem or '')


def _rewrite_metadata(bag_dir: Path, reader: BagReader) -> None:
    """metadata.yaml with the counts and times of the MCAP file as it now is."""
    try:
        old = metadata.read(bag_dir)
    except ValueError:
        old = {}
    qos = {entry['topic_metadata']['name']: entry['topic_metadata'].get('offered_qos_profiles')
           for entry in old.get('topics_with_message_count') or []}
    topics = []
    for topic in reader.topics.values():
        profiles = qos.get(topic.name)
        if profiles is None:
            profiles = _yaml_list(topic.metadata.get('offered_qos_profiles', ''))
        topics.append({'name': topic.name, 'type': topic.type_name,
                       'offered_qos_profiles': profiles,
                       'type_hash': topic.metadata.get('topic_type_hash', '')})
    metadata.write(bag_dir, metadata.metadata(reader.path.name, topics, reader.counts,
                                              reader.start_ns, reader.end_ns,
                                              old.get('custom_data')))


def _yaml_list(text: str) -> list:
    import yaml
    try:
        loaded = yaml.safe_load(text)
    except yaml.YAMLError:
        return []
    return loaded if isinstance(loaded, list) else []
