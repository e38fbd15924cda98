"""
When a person pressed, on the env's clock: the frame on screen and how long it had been there.

The page sends with each key press the stamp of the frame it showed (the env's simulation time)
and the milliseconds from showing it to the key going down (the browser's own clock, read
where the key was pressed). Their sum is the press on the env's clock, free of the time the
frame took to reach the screen and the press to reach the learner, and of any difference
between the browser's clock and the graph's. It holds while the env runs in real time; when it
is paused the frame on screen is what the person judges: the press is stamped with that frame
(``frame_stamp``), so the learner credits that very step. When the frame on screen has stood
still too long, or the page sent no timing, the press goes plain (the learner then measures
from its newest observation, as for ``ros2 topic pub``).
"""

import math
from typing import Optional, Tuple

MAX_AFTER_MS = 5000.0
"""A frame on screen longer than this is not the env's present (a stalled stream): plain."""


def frame_stamp(frame) -> Tuple[Optional[int], str]:
    """Return (the stamp of the frame on screen in simulation ns, '') or (None, why not)."""
    if frame is None:
        return None, 'the page sent no frame timing'
    if isinstance(frame, bool) or not isinstance(frame, (str, int)) or not str(frame).isdigit():
        return None, f'unreadable frame stamp {str(frame)[:40]!r}'
    return int(frame), ''


def press_moment(frame, after_ms, paused: bool) -> Tuple[Optional[int], str]:
    """Return (the press in simulation ns, '') or (None, why it has no moment)."""
    if paused:
        return None, 'the env is paused'
    if after_ms is None:
        return None, 'the page sent no frame timing'
    stamp, why = frame_stamp(frame)
    if stamp is None:
        return None, why
    if (isinstance(after_ms, bool) or not isinstance(after_ms, (int, float))
            or not math.isfinite(after_ms) or after_ms < 0):
        return None, f'unreadable time since the frame {str(after_ms)[:40]!r}'
    if after_ms > MAX_AFTER_MS:
        return None, (f'the frame had been on screen {after_ms / 1000:.1f} s (more than '
                      f'{MAX_AFTER_MS / 1000:g} s: not the present)')
    return stamp + round(after_ms * 1_000_000), ''
