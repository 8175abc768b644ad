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
Tests of ring_gyro_sim.recording.cdr against rclpy's serialize_message and three decoders.

rclpy leaves the CDR padding bytes as they were in its buffer, so the bytes are compared
outside the padding, whose positions the tests work out from the CDR rules on their own.
"""

import math

from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from ring_gyro_sim.recording import cdr
from ring_gyro_sim.recording.schemas import message_definition
from ring_gyro_sim.ros import conversions
from rosbags.typesys import get_typestore, Stores
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray


def padding(fields):
    """
    Return the byte positions of the padding of a message laid out as ``fields``.

    ``fields``: ``(alignment, size)`` of each primitive or run of bytes in order, positions
    counted from the end of the 4-byte encapsulation header.
    """
    pads, offset = set(), 0
    for alignment, size in fields:
        while offset % alignment:
            pads.add(4 + offset)
            offset += 1
        offset += size
    return pads


def string_fields(text):
    return [(4, 4), (1, len(text.encode()) + 1)]


def multiarray_fields(rows, labels):
    fields = [(4, 4)]
    for label in ('sample', ','.join(labels)):
        fields += string_fields(label) + [(4, 4), (4, 4)]
    return fields + [(4, 4), (4, 4), (8, 8 * rows * len(labels))]


def imu_fields(frame_id):
    return [(4, 4), (4, 4)] + string_fields(frame_id) + [(8, 8)] * 37


def assert_same_outside_padding(mine, reference, pads):
    assert len(mine) == len(reference)
    assert mine[:4] == cdr.ENCAPSULATION == reference[:4]
    differ = {i for i in range(len(mine)) if mine[i] != reference[i]}
    assert differ <= pads, sorted(differ - pads)
    assert all(mine[i] == 0 for i in pads)


LABEL_SETS = [['t'], ['t', 'x'], ['t', 'q1', 'q2', 'q3'], ['t'] + list(conversions.DEMOD_CHANNELS),
              ['t', 'q1', 'q2', 'q3', 'q1s', 'q2s', 'q3s'], ['t', 'abcdefg']]


@pytest.mark.parametrize('rows', [0, 1, 3, 10])
@pytest.mark.parametrize('labels', LABEL_SETS)
def test_a_block_is_what_rclpy_serialises(rows, labels):
    rng = np.random.default_rng(rows + len(labels))
    data = rng.standard_normal((rows, len(labels)))
    data[:, 0] = np.arange(1, rows + 1) * 5e-6
    message = conversions.block_message([data[:, 0], data[:, 1:]], labels)
    mine = conversions.block_cdr([data[:, 0], data[:, 1:]], labels)
    assert_same_outside_padding(mine, serialize_message(message),
                                padding(multiarray_fields(rows, labels)))
    assert deserialize_message(mine, Float64MultiArray) == message


@pytest.mark.parametrize('frame_id', ['', 'a', 'ab', 'abc', 'abcd', 'ring_gyro', 'gyro_link',
                                      'fr\u00e9quence'])
@pytest.mark.parametrize('variance', [0.0, 2.5e-9])
def test_a_rate_sample_is_what_rclpy_serialises(frame_id, variance):
    covariance = conversions.rate_covariance(variance)
    stream = conversions.imu_stream(frame_id, covariance)
    for t_ns, z in [(1_000_000, 0.17453292519943295), (1_234_567_891_011, -3.5e-7),
                    (0, 0.0), (2_000_000_000, math.pi)]:
        message = conversions.imu_message(t_ns, z, frame_id, covariance)
        mine = stream.message(t_ns, z)
        assert_same_outside_padding(mine, serialize_message(message),
                                    padding(imu_fields(frame_id)))
        assert deserialize_message(mine, Imu) == message
        assert mine == cdr.imu(t_ns, frame_id, (0.0, 0.0, 0.0, 1.0),
                               message.orientation_covariance, (0.0, 0.0, z), covariance,
                               (0.0, 0.0, 0.0), message.linear_acceleration_covariance)


@pytest.mark.parametrize('variance', [None, [2e-6, 0.0, 1e6]])
def test_the_rate_of_a_block_packs_each_sample(variance):
    # Without RateSamples.variance every message has the stream's covariance; with it, each
    # its sample's own (0: unknown), as rate_messages builds them.
    from ring_gyro_sim.core.gyro.electronics import RateSamples
    rate = RateSamples(t=np.array([0.001, 0.002, 0.003]), rate=np.array([0.5, -0.25, 0.0]),
                       quadrature=np.zeros(3),
                       variance=None if variance is None else np.array(variance))
    covariance = conversions.rate_covariance(1e-8)
    packed = conversions.rate_cdr(rate, conversions.imu_stream('g', covariance))
    built = conversions.rate_messages(rate, 'g', covariance)
    assert [t for t, _ in packed] == [t for t, _ in built] == [1_000_000, 2_000_000, 3_000_000]
    assert [deserialize_message(b, Imu) for _, b in packed] == [m for _, m in built]
    if variance is not None:
        assert [deserialize_message(b, Imu).angular_velocity_covariance[8]
                for _, b in packed] == variance


def test_independent_decoders_read_the_packed_messages():
    data = np.arange(12.0).reshape(4, 3)
    block = cdr.float64_multiarray(data, ['t', 'a', 'b'])
    rate = conversions.imu_stream('ring_gyro', conversions.rate_covariance(1e-8)).message(
        1_500_000, 0.25)
    factory = DecoderFactory()
    store = get_typestore(Stores.ROS2_JAZZY)
    for schema_id, (type_name, raw) in enumerate((('std_msgs/msg/Float64MultiArray', block),
                                                 ('sensor_msgs/msg/Imu', rate)), start=1):
        schema = Schema(id=schema_id, name=type_name, encoding='ros2msg',
                        data=message_definition(type_name).encode())
        decoded = factory.decoder_for('cdr', schema)(raw)
        theirs = store.deserialize_cdr(raw, type_name)
        if type_name.endswith('Imu'):
            assert decoded.angular_velocity.z == theirs.angular_velocity.z == 0.25
            assert decoded.header.stamp.nanosec == theirs.header.stamp.nanosec == 1_500_000
            assert decoded.header.frame_id == theirs.header.frame_id == 'ring_gyro'
            assert decoded.orientation.w == theirs.orientation.w == 1.0
        else:
            assert list(decoded.data) == list(theirs.data) == list(data.ravel())
            assert decoded.layout.dim[1].label == theirs.layout.dim[1].label == 't,a,b'
            assert decoded.layout.dim[0].size == theirs.layout.dim[0].size == 4


def test_an_imu_needs_37_values():
    with pytest.raises(ValueError, match='37'):
        cdr.imu(0, '', (0.0, 0.0, 0.0, 1.0), [0.0] * 9, (0.0, 0.0, 0.0), [0.0] * 9,
                (0.0, 0.0, 0.0), [0.0] * 8)


def _recorded_messages():
    """One message of every type the recorder serialises itself, with awkward strings."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import AccelStamped, Vector3Stamped
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Empty, Float64, String
    out = []
    for frame in ('', 'a', 'ab', 'abc', 'ring_gyro', 'fr\u00e9quence'):
        out.append(conversions.temperature_message(1_234_567_890, 301.25, frame))
        v = Vector3Stamped()
        v.header.frame_id = frame
        v.header.stamp.sec, v.header.stamp.nanosec = 3, 5
        v.vector.x, v.vector.y, v.vector.z = 1.5, -2.0, 1e-300
        out.append(v)
        a = AccelStamped()
        a.header.frame_id = frame
        a.accel.linear.x, a.accel.angular.z = 98.0665, -3.0
        out.append(a)
        status = DiagnosticStatus(level=DiagnosticStatus.WARN, name=f'{frame}: simulator',
                                  message='falling behind', hardware_id=f'ring_gyro_sim:{frame}')
        status.values = [KeyValue(key='k' * n, value=frame * n) for n in range(5)]
        array_msg = DiagnosticArray(status=[status, DiagnosticStatus()])
        array_msg.header.frame_id = frame
        out.append(array_msg)
        out.append(String(data=frame))
    out += [Clock(), Float64(data=math.pi), Empty(),
            conversions.imu_message(1_000_000, 0.25, 'ring_gyro',
                                    conversions.rate_covariance(1e-8)),
            conversions.block_message([np.arange(3.0), np.ones((3, 2))], ['t', 'a', 'b'])]
    return out


@pytest.mark.parametrize('message', _recorded_messages(),
                         ids=lambda m: type(m).__name__)
def test_serialize_lays_out_what_rclpy_does_with_the_padding_zeroed(message):
    mine = cdr.serialize(message)
    reference = serialize_message(message)
    assert len(mine) == len(reference)
    # Where the two differ, rclpy left bytes of its buffer: ours are zeros there, and the
    # message reads back the same (a value byte that differed would not).
    assert all(mine[i] == 0 for i in range(len(mine)) if mine[i] != reference[i])
    assert deserialize_message(mine, type(message)) == message
    store = get_typestore(Stores.ROS2_JAZZY)
    name = f'{type(message).__module__.split(".")[0]}/msg/{type(message).__name__}'
    decoded = store.deserialize_cdr(mine, name)
    theirs = bytes(store.serialize_cdr(decoded, name))   # rosbags writes zero padding too,
    assert mine == theirs + bytes(len(mine) - len(theirs))   # but not Empty's last three


def test_serialize_zeroes_the_padding_after_a_frame_id():
    # A Temperature stamped in frame 'ring_gyro' (9 bytes and the NUL after the 8 of the stamp
    # and the 4 of the length) has two padding bytes before its float64 temperature: rclpy's
    # are whatever its buffer held (the recordings' stray bytes), ours are zero.
    message = conversions.temperature_message(1_000_000, 300.0, 'ring_gyro')
    mine = cdr.serialize(message)
    pads = padding([(4, 4), (4, 4)] + string_fields('ring_gyro') + [(8, 8), (8, 8)])
    assert pads == {26, 27}
    assert [mine[i] for i in sorted(pads)] == [0, 0]
    control = bytearray(mine)
    control[26] = ord('e')   # what rclpy's buffer may hold there: the check sees it
    assert not all(control[i] == 0 for i in pads)
