"""
A rosbag2 bag with MCAP storage, written from Python: Foxglove's ``mcap`` writer. Pure (no node).

The bag is a folder: ``<name>_0.mcap`` and ``metadata.yaml``, as ``ros2 bag record -s mcap``
leaves it. The MCAP file follows rosbag2's conventions (profile ``ros2``, schemas ``ros2msg``,
messages ``cdr``, each channel's ``offered_qos_profiles`` and ``topic_type_hash``), so ``ros2 bag
info/play`` and Foxglove open it. Chunks are zstd-compressed (the images compress well).

Crash safety: ``flush()`` closes the chunk being filled, hands everything to the OS and rewrites
``metadata.yaml``; the recorder calls it every ``flush_period_s``. A process killed with SIGKILL
loses what came after the last flush; the file then lacks MCAP's summary and footer, which
``repair.py`` (``attention_bag repair``) writes back; the stream reader reads it as it is.
"""

import os
from pathlib import Path
from typing import Dict, List, Mapping, Optional

from mcap.writer import CompressionType, Writer
from session_bag import metadata
from session_bag.schema import definition

COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}
CHUNK_SIZE = 4 * 1024 * 1024
"""Bytes of messages per chunk at most (a flush closes the chunk sooner)."""
LIBRARY = 'language-attention-tamer session_bag (mcap)'


def storage_file_name(bag_dir: Path) -> str:
    """Return the MCAP file of a bag folder as rosbag2 names it: bag/ -> bag_0.mcap."""
    return f'{Path(bag_dir).name}_0.mcap'


class BagWriter:
    """Writes one bag; not thread-safe (the recorder calls it from one thread)."""

    def __init__(self, bag_dir: Path, compression: str = 'zstd',
                 custom_data: Optional[Mapping[str, str]] = None,
                 chunk_size: int = CHUNK_SIZE, sync: bool = False):
        if compression not in COMPRESSIONS:
            raise ValueError(f'compression {compression!r}: one of {", ".join(COMPRESSIONS)}')
        self.bag_dir = Path(bag_dir)
        if self.bag_dir.exists() and any(self.bag_dir.iterdir()):
            raise FileExistsError(f'{self.bag_dir} already holds files: a bag is never '
                                  'overwritten; choose another folder')
        self.bag_dir.mkdir(parents=True, exist_ok=True)
        self.storage_file = storage_file_name(self.bag_dir)
        self.path = self.bag_dir / self.storage_file
        self.custom_data = {str(k): str(v) for k, v in (custom_data or {}).items()}
        self.sync = sync
        """Each flush also fdatasyncs the MCAP file: what was flushed survives a power cut."""
        self.syncs = 0
        self._stream = open(self.path, 'xb')
        self._writer = Writer(self._stream, chunk_size=chunk_size,
                              compression=COMPRESSIONS[compression])
        self._writer.start(profile='ros2', library=LIBRARY)
        self._schemas: Dict[str, int] = {}
        self._channels: Dict[str, int] = {}
        self.topics: List[dict] = []
        """Channel order: {'name', 'type', 'offered_qos_profiles', 'type_hash'}."""
        self.counts: Dict[str, int] = {}
        self.start_ns: Optional[int] = None
        self.end_ns: Optional[int] = None
        self.closed = False
        self.write_metadata()

    def has_topic(self, name: str) -> bool:
        return name in self._channels

    def add_topic(self, name: str, type_name: str, qos_profiles: List[dict]) -> None:
        """Add a channel: ``name`` (absolute), its type, its publishers' QoS (``qos_dict``)."""
        if name in self._channels:
            raise ValueError(f'topic {name} is in the bag already')
        found = definition(type_name)
        schema = self._schemas.get(type_name)
        if schema is None:
            schema = self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding='ros2msg', data=found.text.encode())
        self._channels[name] = self._writer.register_channel(
            topic=name, message_encoding='cdr', schema_id=schema,
            metadata={'offered_qos_profiles': metadata.qos_yaml(qos_profiles),
                      'topic_type_hash': found.type_hash})
        self.topics.append({'name': name, 'type': type_name,
                            'offered_qos_profiles': qos_profiles, 'type_hash': found.type_hash})
        self.counts[name] = 0

    def write(self, name: str, log_time_ns: int, data: bytes,
              publish_time_ns: Optional[int] = None, sequence: int = 0) -> None:
        """Write one serialized (CDR) message of topic ``name``, received at ``log_time_ns``."""
        self._writer.add_message(channel_id=self._channels[name], log_time=int(log_time_ns),
                                 data=data, sequence=int(sequence) & 0xFFFFFFFF,
                                 publish_time=int(publish_time_ns if publish_time_ns
                                                  is not None else log_time_ns))
        self.counts[name] += 1
        if self.start_ns is None or log_time_ns < self.start_ns:
            self.start_ns = int(log_time_ns)
        if self.end_ns is None or log_time_ns > self.end_ns:
            self.end_ns = int(log_time_ns)

    @property
    def message_count(self) -> int:
        return sum(self.counts.values())

    def metadata(self) -> dict:
        return metadata.metadata(self.storage_file, self.topics, self.counts, self.start_ns,
                                 self.end_ns, self.custom_data)

    def write_metadata(self) -> None:
        metadata.write(self.bag_dir, self.metadata())

    def flush(self) -> None:
        """Close the open chunk, pass everything to the OS and rewrite metadata.yaml."""
        if self.closed:
            return
        self._writer.flush()
        if self.sync:
            self._stream.flush()
            os.fdatasync(self._stream.fileno())
            self.syncs += 1
        self.write_metadata()

    def close(self) -> None:
        """Write MCAP's summary and footer, close the file, write the final metadata.yaml."""
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        finally:
            self._stream.close()
            self.write_metadata()
