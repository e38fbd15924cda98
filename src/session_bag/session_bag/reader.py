"""
Reading a session bag in recorded order, whole or cut short. Pure (no node).

The MCAP file is read as a stream (``mcap.stream_reader``), which needs no summary or footer:
a bag whose recorder was killed reads up to its last complete chunk, and ``complete`` tells
whether the file ended properly. Messages stay serialized (CDR): a replay publishes them as
they were; ``rclpy.serialization.deserialize_message`` opens the ones a program looks into.
"""

from pathlib import Path
from typing import Dict, Iterator, NamedTuple, Optional

from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader
from session_bag import metadata


class BagMessage(NamedTuple):
    topic: str
    type_name: str
    log_time: int
    """When the recorder received it (ns since the epoch)."""
    publish_time: int
    """When its publisher sent it (ns since the epoch, DDS source time)."""
    data: bytes
    """The serialized message (CDR)."""


class BagTopic(NamedTuple):
    name: str
    type_name: str
    metadata: Dict[str, str]
    """The channel's metadata: ``offered_qos_profiles``, ``topic_type_hash``."""


MCAP_MAGIC = b'\x89MCAP0\r\n'


def ends_whole(path: Path) -> bool:
    """Tell cheaply whether an MCAP file ends as a finished one does (with the magic)."""
    try:
        with open(path, 'rb') as stream:
            stream.seek(0, 2)
            if stream.tell() < 2 * len(MCAP_MAGIC):
                return False
            stream.seek(-len(MCAP_MAGIC), 2)
            return stream.read() == MCAP_MAGIC
    except OSError:
        return False


def storage_path(bag_dir: Path) -> Path:
    """Return the MCAP file of a bag folder (from its metadata.yaml, else the only .mcap)."""
    bag_dir = Path(bag_dir)
    if not bag_dir.is_dir():
        raise ValueError(f'{bag_dir} is not a bag folder')
    try:
        names = metadata.read(bag_dir).get('relative_file_paths') or []
    except ValueError:
        names = []
    files = [bag_dir / name for name in names] or sorted(bag_dir.glob('*.mcap'))
    if len(files) != 1 or not files[0].is_file():
        raise ValueError(f'{bag_dir} holds no single MCAP file (found: '
                         f'{", ".join(f.name for f in files) or "none"})')
    return files[0]


class BagReader:
    """One pass over a bag's messages, in the order they were written."""

    def __init__(self, bag_dir: Path):
        self.bag_dir = Path(bag_dir)
        self.path = storage_path(self.bag_dir)
        self.topics: Dict[str, BagTopic] = {}
        """The channels seen so far (all of them once ``messages()`` is done)."""
        self.schemas: Dict[str, bytes] = {}
        """Schema data by type name."""
        self.complete: Optional[bool] = None
        """After ``messages()``: True if the file ended with its footer, False if cut short."""
        self.problem: Optional[str] = None
        """Why a cut-short file ended where it did."""
        self.counts: Dict[str, int] = {}
        self.start_ns: Optional[int] = None
        self.end_ns: Optional[int] = None

    def custom_data(self) -> Dict[str, str]:
        """Return the bag's ``custom_data`` (metadata.yaml), {} if none."""
        try:
            return dict(metadata.read(self.bag_dir).get('custom_data') or {})
        except ValueError:
            return {}

    def messages(self) -> Iterator[BagMessage]:
        schemas: Dict[int, Schema] = {}
        channels: Dict[int, Channel] = {}
        self.complete = False
        with open(self.path, 'rb') as stream:
            records = StreamReader(stream, validate_crcs=True).records
            try:
                for record in records:
                    if isinstance(record, Schema):
                        schemas[record.id] = record
                        self.schemas[record.name] = record.data
                    elif isinstance(record, Channel):
                        channels[record.id] = record
                        schema = schemas.get(record.schema_id)
                        self.topics[record.topic] = BagTopic(
                            record.topic, schema.name if schema else '', dict(record.metadata))
                    elif isinstance(record, Message):
                        channel = channels[record.channel_id]
                        self.counts[channel.topic] = self.counts.get(channel.topic, 0) + 1
                        self._span(record.log_time)
                        yield BagMessage(channel.topic, self.topics[channel.topic].type_name,
                                         record.log_time, record.publish_time,
                                         bytes(record.data))
                    elif isinstance(record, Footer):
                        self.complete = True
            except Exception as error:  # noqa: B902 - a cut or torn file ends the reading
                # (McapError, EOFError, struct.error half-way through a field, a torn chunk's
                # zstd or lz4 error, KeyError for a record of an unknown channel)
                self.problem = f'{type(error).__name__}: {error}' if str(error) else (
                    type(error).__name__)

    def _span(self, log_time: int) -> None:
        if self.start_ns is None or log_time < self.start_ns:
            self.start_ns = log_time
        if self.end_ns is None or log_time > self.end_ns:
            self.end_ns = log_time
