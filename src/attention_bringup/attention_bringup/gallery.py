"""
Picks a few steps for the saliency gallery: frame, mask and saliency image of one stamp.

Images arrive serialized (the launcher subscribes raw, so watching costs no decoding); their
stamp is read from the CDR bytes, and only the chosen ones are decoded, at the end of the run.
Pure: no rclpy.
"""

from dataclasses import dataclass
import struct
from typing import Dict, List, Optional, Tuple

OBSERVATION, MASK, SALIENCY = 'observation', 'saliency_mask', 'saliency'

_CDR_BIG_ENDIAN = (0x00, 0x00)
_CDR_LITTLE_ENDIAN = (0x00, 0x01)


def cdr_header_stamp_ns(raw: bytes) -> int:
    """
    Stamp (ns) of a serialized message whose first field is a std_msgs/Header.

    CDR: a 4-byte encapsulation header (representation id, options), then ``stamp.sec``
    (int32) and ``stamp.nanosec`` (uint32), aligned from byte 4.
    """
    if len(raw) < 12:
        raise ValueError(f'{len(raw)} bytes is too short for a CDR header stamp')
    representation = (raw[0], raw[1])
    if representation == _CDR_LITTLE_ENDIAN:
        order = '<'
    elif representation == _CDR_BIG_ENDIAN:
        order = '>'
    else:
        raise ValueError(f'unknown CDR representation {bytes(raw[:2]).hex()}')
    sec, nanosec = struct.unpack_from(f'{order}iI', raw, 4)
    return sec * 1_000_000_000 + nanosec


@dataclass
class GallerySample:
    """One step of the gallery: serialized images (None when the graph made none)."""

    stamp_ns: int
    utterance: str
    observation: bytes
    mask: Optional[bytes]
    saliency: Optional[bytes]


class GalleryCollector:
    """
    Keeps ``capacity`` samples, taken after new utterances or, failing those, on schedule.

    After a request, the collector waits for a step whose observation, mask and saliency image
    have all arrived; if ``patience`` observations pass without one, it takes the frame alone.
    (The launcher subscribes to masks only while the collector waits: the patience covers the
    time that subscription takes to match.)
    """

    def __init__(self, capacity: int = 4, patience: int = 100, recent: int = 32):
        self.capacity = capacity
        self.patience = patience
        self.samples: List[GallerySample] = []
        self._recent_limit = recent
        self._recent: Dict[str, Dict[int, bytes]] = {OBSERVATION: {}, MASK: {}, SALIENCY: {}}
        self._utterances: List[Tuple[int, str]] = []
        self._pending: Optional[List[int]] = None  # observation stamps seen since a request

    @property
    def full(self) -> bool:
        return len(self.samples) >= self.capacity

    @property
    def waiting(self) -> bool:
        return self._pending is not None

    def request(self) -> None:
        if not self.full and self._pending is None:
            self._pending = []

    def on_utterance(self, stamp_ns: int, text: str) -> None:
        self._utterances.append((stamp_ns, text))
        del self._utterances[:-1000]
        if text not in {sample.utterance for sample in self.samples}:
            self.request()

    def on_schedule(self, step: int, budget: int) -> None:
        """Spread samples over the run when utterances alone do not fill the gallery."""
        slot = (len(self.samples) + 1) * budget / (self.capacity + 1)
        if step >= slot:
            self.request()

    def utterance_at(self, stamp_ns: int) -> str:
        """Return the newest utterance spoken at or before ``stamp_ns`` ('' if none)."""
        spoken = [text for stamp, text in self._utterances if stamp <= stamp_ns]
        return spoken[-1] if spoken else ''

    def on_image(self, kind: str, stamp_ns: int, raw: bytes) -> None:
        store = self._recent[kind]
        store[stamp_ns] = raw
        while len(store) > self._recent_limit:
            del store[min(store)]
        if self._pending is None or self.full:
            return
        if kind == OBSERVATION and stamp_ns not in self._pending:
            self._pending.append(stamp_ns)
        for stamp in self._pending:
            if all(stamp in self._recent[k] for k in (OBSERVATION, MASK, SALIENCY)):
                self._take(stamp, with_saliency=True)
                return
        if len(self._pending) > self.patience:
            self._take(self._pending[-1], with_saliency=False)

    def _take(self, stamp_ns: int, with_saliency: bool) -> None:
        observation = self._recent[OBSERVATION].get(stamp_ns)
        if observation is None:
            return
        self.samples.append(GallerySample(
            stamp_ns=stamp_ns,
            utterance=self.utterance_at(stamp_ns),
            observation=observation,
            mask=self._recent[MASK].get(stamp_ns) if with_saliency else None,
            saliency=self._recent[SALIENCY].get(stamp_ns) if with_saliency else None,
        ))
        self._pending = None
