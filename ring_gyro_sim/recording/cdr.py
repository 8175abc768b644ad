# Copyright 2026 ring_gyro_sim developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
CDR of the two messages a recording writes most, from numbers, without rclpy's message objects.

A recording run offline writes ``std_msgs/Float64MultiArray`` blocks and ``sensor_msgs/Imu``
rate samples that nothing publishes. Building rclpy's message objects only for
``rclpy.serialization.serialize_message`` to convert them back cost more than the rest of the
recording at the default ``record.decimation`` (a small block message ~16 us to build and
~18 us to serialise, an Imu ~9 us and ~16 us); here each is packed from its numbers in one
step, as ``serialize_message`` lays it out with rmw_fastrtps: XCDR1 little endian (the
encapsulation header ``00 01 00 00``), every primitive aligned to its size counted from the
end of that header, strings as a uint32 length with the terminating NUL, sequences as a
uint32 count. The padding bytes, which rclpy leaves as they were in its buffer, are zeros.
``test/recording/test_cdr.py`` checks the bytes against ``serialize_message`` (padding aside)
and what rclpy, mcap_ros2 and rosbags decode.

:func:`serialize` packs any other message the same way, walking its fields: rclpy's
``serialize_message`` leaves its padding bytes as they were in the buffer it allocated (bytes
of the process: ``es``, ``::``, ...), which a recording must not carry, and which made two
recordings of one run differ in their bytes.
"""

import re
import struct
from typing import Any, Optional, Sequence

import numpy as np

ENCAPSULATION = b'\x00\x01\x00\x00'
"""CDR, little endian (the first four bytes of every message rmw_fastrtps serialises)."""

_U32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')
_IMU_VALUES = struct.Struct('<37d')
_F64 = struct.Struct('<d')
_COVARIANCE = struct.Struct('<9d')


def _string(text: str) -> bytes:
    """Return a CDR string (at a 4-aligned offset): length with the NUL, the bytes, the NUL."""
    raw = text.encode('utf-8')
    return _U32.pack(len(raw) + 1) + raw + b'\x00'


def _pad(offset: int, alignment: int) -> bytes:
    return b'\x00' * (-offset % alignment)


_PRIMITIVES = {
    'boolean': '?', 'octet': 'B', 'byte': 'B', 'char': 'B', 'uint8': 'B', 'int8': 'b',
    'int16': 'h', 'uint16': 'H', 'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q',
    'float': 'f', 'double': 'd',
}
"""IDL primitive types (as rclpy's ``get_fields_and_field_types`` names them) -> struct codes."""
_SEQUENCE = re.compile(r'^sequence<(.+?)(, ?\d+)?>$')
_ARRAY = re.compile(r'^(.+)\[(\d+)\]$')
_STRING = re.compile(r'^string(<=\d+)?$')


def serialize(message: Any) -> bytes:
    """
    Return the CDR of an rclpy message as ``serialize_message`` lays it out, padding zeroed.

    XCDR1 little endian after the encapsulation header, each primitive aligned to its size
    from the end of the header; a message without fields holds one zero byte (rosidl's
    ``structure_needs_at_least_one_member``), padded to four as rmw_fastrtps sizes it.

    Raises
    ------
    TypeError
        A field of a type this packer does not know (``wstring``).

    """
    if not message.get_fields_and_field_types():
        return ENCAPSULATION + bytes(4)
    out = bytearray(ENCAPSULATION)
    _pack_message(message, out)
    return bytes(out)


def _align(out: bytearray, size: int) -> None:
    out.extend(b'\x00' * (-(len(out) - 4) % size))


def _pack_message(message: Any, out: bytearray) -> None:
    fields = message.get_fields_and_field_types()
    if not fields:
        out.append(0)
        return
    for name, kind in fields.items():
        _pack_value(kind, getattr(message, name), out)


def _pack_value(kind: str, value: Any, out: bytearray) -> None:
    code = _PRIMITIVES.get(kind)
    if code is not None:
        size = struct.calcsize(code)
        _align(out, size)
        if code == 'B' and isinstance(value, (bytes, bytearray)):
            value = value[0]
        out.extend(struct.pack('<' + code, value))
        return
    if _STRING.match(kind):
        _align(out, 4)
        out.extend(_string(value))
        return
    match = _SEQUENCE.match(kind)
    if match is not None:
        _align(out, 4)
        out.extend(_U32.pack(len(value)))
        _pack_items(match.group(1), value, out)
        return
    match = _ARRAY.match(kind)
    if match is not None:
        _pack_items(match.group(1), value, out)
        return
    if '/' in kind:
        _pack_message(value, out)
        return
    raise TypeError(f'cdr.serialize: field type {kind!r} is not supported')


def _pack_items(kind: str, values: Any, out: bytearray) -> None:
    code = _PRIMITIVES.get(kind)
    if code is not None and len(values):
        size = struct.calcsize(code)
        _align(out, size)
        out.extend(np.asarray(values, dtype=np.dtype(code).newbyteorder('<')).tobytes())
        return
    for value in values:
        _pack_value(kind, value, out)


def float64_multiarray(data: np.ndarray, labels: Sequence[str],
                       rows_label: str = 'sample') -> bytes:
    """
    Return the CDR of the ``std_msgs/Float64MultiArray`` block of ``data``.

    Laid out as ``ros.conversions.block_message`` builds it: ``layout.dim[0]`` = ``rows_label``
    with size K and stride K * C, ``layout.dim[1]`` = the labels joined by commas with size
    and stride C, ``data_offset`` 0, ``data`` the rows in order.

    Parameters
    ----------
    data : ndarray, shape (K, C)
        The block's rows (float64; any other dtype is converted).
    labels : sequence of str
        The C column names (``t`` first).
    rows_label : str
        Label of ``dim[0]``.

    """
    data = np.ascontiguousarray(data, dtype=np.float64)
    rows, columns = data.shape
    parts = [ENCAPSULATION, _U32.pack(2)]
    offset = 4
    for label, size, stride in ((rows_label, rows, rows * columns),
                                (','.join(labels), columns, columns)):
        text = _string(label)
        offset += len(text)
        parts += [text, _pad(offset, 4)]
        offset += -offset % 4
        parts.append(struct.pack('<II', size, stride))
        offset += 8
    parts.append(struct.pack('<II', 0, data.size))  # data_offset, then the data's count
    offset += 8
    parts += [_pad(offset, 8), data.tobytes()]
    return b''.join(parts)


class ImuStream:
    """
    ``sensor_msgs/Imu`` messages that differ only in their stamp and ``angular_velocity.z``.

    The gyroscope's ``~/rate``: everything else of the message is fixed for a run, so its bytes
    are packed once and each message adds its stamp and rate (~1 us). Parameters as
    :func:`imu`, without those two.
    """

    def __init__(self, frame_id: str, orientation: Sequence[float],
                 orientation_covariance: Sequence[float], angular_velocity_xy: Sequence[float],
                 angular_velocity_covariance: Sequence[float],
                 linear_acceleration: Sequence[float],
                 linear_acceleration_covariance: Sequence[float]) -> None:
        frame = _string(frame_id)
        self._frame = frame + _pad(8 + len(frame), 8)
        before = (*orientation, *orientation_covariance, *angular_velocity_xy)
        after = (*linear_acceleration, *linear_acceleration_covariance)
        count = len(before) + 1 + len(angular_velocity_covariance) + len(after)
        if count != 37 or len(angular_velocity_covariance) != 9:
            raise ValueError(f'an Imu holds 37 float64 values after its header, got {count}')
        self._before = struct.pack(f'<{len(before)}d', *before)
        self._covariance = _COVARIANCE.pack(*angular_velocity_covariance)
        self._after = struct.pack(f'<{len(after)}d', *after)

    def message(self, t_ns: int, angular_velocity_z: float,
                angular_velocity_covariance: Optional[Sequence[float]] = None) -> bytes:
        """
        Return the CDR of the message stamped ``t_ns`` (ns) with this rate (rad/s).

        ``angular_velocity_covariance`` (9 floats): this message's own; default the stream's.
        """
        covariance = (self._covariance if angular_velocity_covariance is None
                      else _COVARIANCE.pack(*angular_velocity_covariance))
        return b''.join((ENCAPSULATION, _STAMP.pack(*divmod(int(t_ns), 1_000_000_000)),
                         self._frame, self._before, _F64.pack(angular_velocity_z), covariance,
                         self._after))


def imu(t_ns: int, frame_id: str, orientation: Sequence[float],
        orientation_covariance: Sequence[float], angular_velocity: Sequence[float],
        angular_velocity_covariance: Sequence[float], linear_acceleration: Sequence[float],
        linear_acceleration_covariance: Sequence[float]) -> bytes:
    """
    Return the CDR of a ``sensor_msgs/Imu``.

    Parameters
    ----------
    t_ns : int
        ``header.stamp``, ns (>= 0, below 2**31 s).
    frame_id : str
        ``header.frame_id``.
    orientation : 4 floats
        Quaternion x, y, z, w.
    orientation_covariance, angular_velocity_covariance, linear_acceleration_covariance
        9 floats each (row-major 3 x 3).
    angular_velocity, linear_acceleration : 3 floats each
        x, y, z.

    """
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    head = ENCAPSULATION + _STAMP.pack(sec, nanosec) + _string(frame_id)
    values = (*orientation, *orientation_covariance, *angular_velocity,
              *angular_velocity_covariance, *linear_acceleration,
              *linear_acceleration_covariance)
    if len(values) != 37:
        raise ValueError(f'an Imu holds 37 float64 values after its header, got {len(values)}')
    return head + _pad(len(head) - 4, 8) + _IMU_VALUES.pack(*values)
