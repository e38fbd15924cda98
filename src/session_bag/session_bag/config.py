"""The recorder's parameters, in one dataclass (each field is a ROS parameter of that name)."""

from dataclasses import dataclass
import datetime
from pathlib import Path
from typing import List

from session_bag.recorded import RECORDED
from session_bag.writer import COMPRESSIONS

SYNC_MODES = ('off', 'grouped')
"""The recorder's sync choices (a bag is synced per flush, never per message: 30 frames/s)."""


@dataclass
class RecorderConfig:
    """Where the bag goes and how it is written."""

    bag_dir: str = ''
    """The bag's folder (it must not hold files yet); '' = bags/<date-time> here."""
    run_dir: str = ''
    """attention_train's run folder: its launch options and parameters go into the bag's
    custom_data, so that the bag alone tells how the session was run."""
    compression: str = 'zstd'
    """MCAP chunk compression: zstd, lz4 or none."""
    flush_period_s: float = 0.5
    """Wall seconds between flushes: a killed recorder loses at most this much of the bag."""
    sync: str = 'grouped'
    """'grouped': every flush also fdatasyncs the bag, so a power cut loses at most one
    flush_period_s of it, as a kill does; 'off': flushed to the OS only."""
    topics: str = ''
    """Comma-separated topics to record ('' = every topic of the graph, session_bag.recorded)."""
    nice: int = 5
    """Niceness the recorder adds to every thread of its own at start (DDS's too; later ones
    inherit it): the graph's nodes get the CPU first, and the frame writers hold 100 frames
    while it catches up (0: as the other nodes)."""

    def validate(self) -> None:
        """Raise ValueError naming the first impossible value."""
        if self.compression not in COMPRESSIONS:
            raise ValueError(f'compression must be one of {", ".join(COMPRESSIONS)}, got '
                             f'{self.compression!r}')
        if not 0.05 <= self.flush_period_s <= 1.0:
            raise ValueError('flush_period_s must be within 0.05..1.0 s (a crash loses at most '
                             f'this much), got {self.flush_period_s}')
        if self.sync not in SYNC_MODES:
            raise ValueError(f'sync must be one of {", ".join(SYNC_MODES)}, got {self.sync!r}')
        if not 0 <= self.nice <= 19:
            raise ValueError(f'nice must be within 0..19, got {self.nice}')
        unknown = set(self.topic_names()) - {t.name for t in RECORDED}
        if unknown:
            raise ValueError(f'topics {", ".join(sorted(unknown))} are not topics of the graph '
                             f'(known: {", ".join(t.name for t in RECORDED)})')

    def topic_names(self) -> List[str]:
        chosen = [name.strip() for name in self.topics.split(',') if name.strip()]
        return chosen or [t.name for t in RECORDED]

    def bag_path(self, cwd: Path, now: datetime.datetime) -> Path:
        if self.bag_dir:
            return (cwd / self.bag_dir).resolve()
        return cwd / 'bags' / f'{now:%Y%m%d-%H%M%S}'
