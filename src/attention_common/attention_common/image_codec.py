"""
sensor_msgs/Image <-> numpy, without cv_bridge.

Rows are decoded by ``step`` (a row may be padded) and ``is_bigendian`` is honoured, as
cv_bridge's ``imgmsg_to_cv2`` does. Only the encodings the graph uses are supported; any other
raises ``ImageFormatError`` with a message fit for a log line.
"""

import array
import sys
from typing import NamedTuple, Optional, Tuple

import numpy as np


class ImageFormatError(ValueError):
    """An Image message that cannot be decoded as declared."""


class _Encoding(NamedTuple):
    dtype: np.dtype
    channels: int


ENCODINGS = {
    'rgb8': _Encoding(np.dtype(np.uint8), 3),
    'mono8': _Encoding(np.dtype(np.uint8), 1),
    '32FC1': _Encoding(np.dtype(np.float32), 1),
}


def image_to_numpy(msg, shape: Optional[Tuple[int, int]] = None) -> np.ndarray:
    """
    Decode a sensor_msgs/Image into an (h, w, c) array, or (h, w) for one channel.

    ``shape`` (height, width), if given, is checked before anything is decoded or copied.
    Returns a fresh, C-contiguous array that does not alias the message.
    """
    enc = ENCODINGS.get(msg.encoding)
    if enc is None:
        raise ImageFormatError(
            f'unsupported encoding {msg.encoding!r} (supported: {", ".join(ENCODINGS)})')
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if shape is not None and (height, width) != tuple(shape):
        raise ImageFormatError(f'size {width}x{height}, {shape[1]}x{shape[0]} expected')
    if height <= 0 or width <= 0:
        raise ImageFormatError(f'empty image {width}x{height}')
    row_bytes = width * enc.channels * enc.dtype.itemsize
    if step < row_bytes:
        raise ImageFormatError(
            f'step {step} is shorter than a row of {width} {msg.encoding} pixels ({row_bytes})')
    data = msg.data
    buf = data if isinstance(data, (bytes, bytearray, memoryview)) else memoryview(data)
    if len(buf) < step * height:
        raise ImageFormatError(
            f'data has {len(buf)} bytes, {step * height} expected ({height} rows of {step})')
    rows = np.frombuffer(buf, dtype=np.uint8, count=step * height).reshape(height, step)
    pixels = rows[:, :row_bytes].copy()  # drops row padding; fresh and writable
    dtype = enc.dtype.newbyteorder('>' if msg.is_bigendian else '<')
    arr = pixels.view(dtype).reshape(height, width, enc.channels)
    if not arr.dtype.isnative:
        arr = arr.astype(enc.dtype)
    return arr[:, :, 0] if enc.channels == 1 else arr


def numpy_to_image(arr: np.ndarray, encoding: str, msg) -> object:
    """
    Fill the sensor_msgs/Image ``msg`` with ``arr`` (header left to the caller) and return it.

    ``arr`` is (h, w, 3) uint8 for rgb8, (h, w) uint8 for mono8, (h, w) float32 for 32FC1.
    """
    enc = ENCODINGS.get(encoding)
    if enc is None:
        raise ImageFormatError(f'unsupported encoding {encoding!r}')
    expected_ndim = 3 if enc.channels > 1 else 2
    if arr.ndim != expected_ndim or (enc.channels > 1 and arr.shape[2] != enc.channels):
        raise ImageFormatError(f'array of shape {arr.shape} does not fit {encoding}')
    arr = np.ascontiguousarray(arr, dtype=enc.dtype)
    msg.height, msg.width = int(arr.shape[0]), int(arr.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = sys.byteorder == 'big'
    msg.step = msg.width * enc.channels * enc.dtype.itemsize
    msg.data = array.array('B', arr.tobytes())
    return msg
