"""sensor_msgs/Image <-> numpy (attention_common.image_codec), table-driven, no rclpy.init."""

import sys

from attention_common.image_codec import image_to_numpy, ImageFormatError, numpy_to_image
import numpy as np
import pytest
from sensor_msgs.msg import Image

RNG = np.random.default_rng(0)

ARRAYS = {
    'rgb8': RNG.integers(0, 256, (210, 160, 3), dtype=np.uint8),
    'mono8': RNG.integers(0, 256, (7, 5), dtype=np.uint8),
    '32FC1': RNG.standard_normal((4, 6)).astype(np.float32),
}
CHANNELS = {'rgb8': 3, 'mono8': 1, '32FC1': 1}
ITEMSIZE = {'rgb8': 1, 'mono8': 1, '32FC1': 4}


def raw_image(arr, encoding, pad=0, big_endian=False, fill=0xAB):
    """Build an Image by hand: rows of ``pad`` extra bytes, data in the given byte order."""
    height, width = arr.shape[:2]
    order = '>' if big_endian else '<'
    row_bytes = arr.astype(arr.dtype.newbyteorder(order)).reshape(height, -1).view(np.uint8)
    rows = np.full((height, row_bytes.shape[1] + pad), fill, np.uint8)
    rows[:, :row_bytes.shape[1]] = row_bytes
    return Image(height=height, width=width, encoding=encoding, is_bigendian=big_endian,
                 step=rows.shape[1], data=rows.tobytes())


@pytest.mark.parametrize('encoding', ARRAYS)
def test_round_trip(encoding):
    arr = ARRAYS[encoding]
    msg = numpy_to_image(arr, encoding, Image())
    assert (msg.height, msg.width, msg.encoding) == (arr.shape[0], arr.shape[1], encoding)
    assert msg.step == arr.shape[1] * CHANNELS[encoding] * ITEMSIZE[encoding]
    assert len(msg.data) == msg.step * msg.height
    assert msg.is_bigendian == (sys.byteorder == 'big')
    decoded = image_to_numpy(msg)
    assert decoded.dtype == arr.dtype and decoded.shape == arr.shape
    np.testing.assert_array_equal(decoded, arr)


@pytest.mark.parametrize('encoding, pad', [('rgb8', 1), ('rgb8', 32), ('mono8', 3),
                                           ('32FC1', 4), ('32FC1', 1)])
def test_padded_rows_are_skipped(encoding, pad):
    arr = ARRAYS[encoding]
    decoded = image_to_numpy(raw_image(arr, encoding, pad=pad))
    np.testing.assert_array_equal(decoded, arr)


@pytest.mark.parametrize('encoding', ARRAYS)
@pytest.mark.parametrize('big_endian', [False, True])
def test_byte_order_is_honoured(encoding, big_endian):
    arr = ARRAYS[encoding]
    decoded = image_to_numpy(raw_image(arr, encoding, pad=2, big_endian=big_endian))
    assert decoded.dtype.isnative
    np.testing.assert_array_equal(decoded, arr)


def test_decoded_array_is_writable_and_does_not_alias_the_message():
    arr = ARRAYS['mono8']
    msg = numpy_to_image(arr, 'mono8', Image())
    decoded = image_to_numpy(msg)
    decoded[:] = 0
    np.testing.assert_array_equal(image_to_numpy(msg), arr)


def test_non_contiguous_input_is_encoded_by_value():
    frame = ARRAYS['rgb8']
    view = frame[::2, ::2]
    np.testing.assert_array_equal(image_to_numpy(numpy_to_image(view, 'rgb8', Image())), view)


def test_encoding_reuses_a_message_of_another_size():
    msg = numpy_to_image(ARRAYS['rgb8'], 'rgb8', Image())
    numpy_to_image(ARRAYS['mono8'], 'mono8', msg)
    np.testing.assert_array_equal(image_to_numpy(msg), ARRAYS['mono8'])


def _with(msg, **fields):
    for name, value in fields.items():
        setattr(msg, name, value)
    return msg


BAD_MESSAGES = {
    'unknown encoding': lambda: _with(raw_image(ARRAYS['rgb8'], 'rgb8'), encoding='bgr8'),
    'empty encoding': lambda: _with(raw_image(ARRAYS['mono8'], 'mono8'), encoding=''),
    '16-bit encoding': lambda: _with(raw_image(ARRAYS['mono8'], 'mono8'), encoding='mono16'),
    'truncated data': lambda: _with(raw_image(ARRAYS['rgb8'], 'rgb8'),
                                    data=bytes(160 * 3 * 209)),
    'no data': lambda: _with(raw_image(ARRAYS['mono8'], 'mono8'), data=b''),
    'step too short': lambda: _with(raw_image(ARRAYS['rgb8'], 'rgb8'), step=160 * 3 - 1),
    'float step as bytes per pixel': lambda: _with(raw_image(ARRAYS['32FC1'], '32FC1'),
                                                   step=6),
    'zero height': lambda: _with(raw_image(ARRAYS['mono8'], 'mono8'), height=0),
    'zero width': lambda: _with(raw_image(ARRAYS['mono8'], 'mono8'), width=0),
}


@pytest.mark.parametrize('case', BAD_MESSAGES)
def test_malformed_message_raises_a_clear_error(case):
    with pytest.raises(ImageFormatError) as error:
        image_to_numpy(BAD_MESSAGES[case]())
    assert str(error.value)  # fit for a log line


@pytest.mark.parametrize('arr, encoding', [
    (ARRAYS['rgb8'], 'bgr8'),
    (ARRAYS['mono8'], 'rgb8'),
    (ARRAYS['rgb8'], 'mono8'),
    (np.zeros((4, 4, 4), np.uint8), 'rgb8'),
    (np.zeros(5, np.uint8), 'mono8'),
])
def test_array_that_does_not_fit_the_encoding_raises(arr, encoding):
    with pytest.raises(ImageFormatError):
        numpy_to_image(arr, encoding, Image())
