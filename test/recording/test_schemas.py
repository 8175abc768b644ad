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

"""Tests of ring_gyro_sim.recording.schemas against the installed .msg files and rclpy."""

import os
import re

import mcap.records
import mcap_ros2.decoder
import pytest
import rclpy
from rclpy.context import Context
from recording_samples import TOPIC_TYPES

from ring_gyro_sim.recording import schemas
from ring_gyro_sim.recording.errors import RecordingError
from ring_gyro_sim.recording.schemas import (
    DELIMITER,
    message_class,
    message_definition,
    message_type_name,
    normalize_type_name,
    type_description_hash,
)

SEPARATOR = '\n' + '=' * 80 + '\n'


def msg_text(package, name):
    """Return an installed .msg file verbatim."""
    share = schemas._share_directory(package)
    with open(os.path.join(share, 'msg', name + '.msg'), encoding='utf-8', newline='') as f:
        return f.read()


def msg_lines(definition):
    return re.findall(r'^MSG: (\S+)$', definition, flags=re.MULTILINE)


def test_delimiter_is_80_equal_signs():
    assert DELIMITER == '=' * 80


def test_float64_multi_array_layout_is_rosbag2s():
    definition = message_definition('std_msgs/msg/Float64MultiArray')
    expected = (msg_text('std_msgs', 'Float64MultiArray')
                + SEPARATOR + 'MSG: std_msgs/MultiArrayLayout\n'
                + msg_text('std_msgs', 'MultiArrayLayout')
                + SEPARATOR + 'MSG: std_msgs/MultiArrayDimension\n'
                + msg_text('std_msgs', 'MultiArrayDimension'))
    assert definition == expected
    assert SEPARATOR + 'MSG: std_msgs/MultiArrayLayout\n' in definition
    assert SEPARATOR + 'MSG: std_msgs/MultiArrayDimension\n' in definition


def test_vector3_stamped_dependencies_depth_first_sorted_with_time():
    definition = message_definition('geometry_msgs/msg/Vector3Stamped')
    assert msg_lines(definition) == [
        'geometry_msgs/Vector3', 'std_msgs/Header', 'builtin_interfaces/Time']
    # Comments are kept: the root text is the file verbatim.
    assert definition.startswith(msg_text('geometry_msgs', 'Vector3Stamped'))
    assert definition.startswith('# This represents a Vector3')
    assert definition.endswith(msg_text('builtin_interfaces', 'Time'))


def test_each_dependency_once():
    definition = message_definition('diagnostic_msgs/msg/DiagnosticArray')
    names = msg_lines(definition)
    assert names == ['diagnostic_msgs/DiagnosticStatus', 'diagnostic_msgs/KeyValue',
                     'std_msgs/Header', 'builtin_interfaces/Time']
    assert len(names) == len(set(names))
    assert definition.count(DELIMITER) == len(names)


def test_type_without_dependencies_is_the_file():
    assert message_definition('std_msgs/msg/Float64') == msg_text('std_msgs', 'Float64')


def test_short_and_long_type_names_agree():
    assert message_definition('std_msgs/Float64MultiArray') == message_definition(
        'std_msgs/msg/Float64MultiArray')
    assert normalize_type_name('std_msgs/Header') == 'std_msgs/msg/Header'
    assert normalize_type_name('std_msgs/msg/Header') == 'std_msgs/msg/Header'


def test_results_are_cached():
    first = message_definition('rosgraph_msgs/msg/Clock')
    assert message_definition('rosgraph_msgs/msg/Clock') is first


def test_ament_prefix_path_and_sys_prefix_find_the_same_files(monkeypatch):
    without = message_definition('geometry_msgs/msg/Vector3Stamped')
    share = schemas._share_directory('geometry_msgs')
    prefix = os.path.dirname(os.path.dirname(share))
    monkeypatch.setenv('AMENT_PREFIX_PATH', prefix)
    for cached in (schemas._share_directory, schemas._msg_spec, schemas.message_definition):
        cached.cache_clear()
    try:
        assert message_definition('geometry_msgs/msg/Vector3Stamped') == without
    finally:
        for cached in (schemas._share_directory, schemas._msg_spec,
                       schemas.message_definition):
            cached.cache_clear()


@pytest.mark.parametrize('type_name, fragment', [
    ('std_msgs/msg/NoSuchType', "'std_msgs/msg/NoSuchType'"),
    ('no_such_pkg/msg/Thing', "package 'no_such_pkg' is not installed"),
    ('not a type', "invalid message type name 'not a type'"),
])
def test_unknown_type_is_a_clear_error(type_name, fragment):
    with pytest.raises(RecordingError, match=re.escape(fragment)) as info:
        message_definition(type_name)
    assert isinstance(info.value, RuntimeError)


def test_definitions_parse_with_an_independent_parser():
    factory = mcap_ros2.decoder.DecoderFactory()
    for type_name in TOPIC_TYPES.values():
        schema = mcap.records.Schema(
            id=1, name=type_name, encoding='ros2msg',
            data=message_definition(type_name).encode())
        assert callable(factory.decoder_for('cdr', schema))


def test_type_hash_format():
    for type_name in TOPIC_TYPES.values():
        assert re.fullmatch(r'RIHS01_[0-9a-f]{64}', type_description_hash(type_name))
    assert type_description_hash('no_such_pkg/msg/Thing') == ''


def test_type_hash_matches_what_rclpy_discovers():
    """The hash rosbag2 stores is the publisher's (TopicEndpointInfo.topic_type_hash)."""
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('type_hash_probe', context=context)
        try:
            for index, type_name in enumerate(sorted(set(TOPIC_TYPES.values()))):
                topic = f'/type_hash_probe_{index}'
                node.create_publisher(message_class(type_name), topic, 10)
                (info,) = node.get_publishers_info_by_topic(topic)
                assert str(info.topic_type_hash) == type_description_hash(type_name)
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_message_type_name_and_class_round_trip():
    for type_name in TOPIC_TYPES.values():
        cls = message_class(type_name)
        assert message_type_name(cls) == type_name
        assert message_type_name(cls()) == type_name
    with pytest.raises(TypeError):
        message_type_name(3.0)
    with pytest.raises(RecordingError, match='cannot import'):
        message_class('no_such_pkg/msg/Thing')


def test_imu_schema_is_rosbag2s_with_every_dependency():
    """~/rate (sensor_msgs/Imu): Quaternion, Vector3 (once, used twice), Header, Time."""
    definition = message_definition('sensor_msgs/msg/Imu')
    # rosbag2 sorts the direct dependencies (geometry_msgs/* before std_msgs/Header) and walks
    # them depth first, each once (Imu uses Vector3 twice).
    expected = (msg_text('sensor_msgs', 'Imu')
                + SEPARATOR + 'MSG: geometry_msgs/Quaternion\n'
                + msg_text('geometry_msgs', 'Quaternion')
                + SEPARATOR + 'MSG: geometry_msgs/Vector3\n'
                + msg_text('geometry_msgs', 'Vector3')
                + SEPARATOR + 'MSG: std_msgs/Header\n'
                + msg_text('std_msgs', 'Header')
                + SEPARATOR + 'MSG: builtin_interfaces/Time\n'
                + msg_text('builtin_interfaces', 'Time'))
    assert definition == expected
    factory = mcap_ros2.decoder.DecoderFactory()
    schema = mcap.records.Schema(id=1, name='sensor_msgs/msg/Imu', encoding='ros2msg',
                                 data=definition.encode())
    assert callable(factory.decoder_for('cdr', schema))
    assert re.fullmatch(r'RIHS01_[0-9a-f]{64}', type_description_hash('sensor_msgs/msg/Imu'))
    assert message_type_name(message_class('sensor_msgs/msg/Imu')) == 'sensor_msgs/msg/Imu'


def test_imu_type_hash_matches_what_rclpy_discovers():
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('imu_hash_probe', context=context)
        try:
            node.create_publisher(message_class('sensor_msgs/msg/Imu'), '/imu_hash_probe', 10)
            (info,) = node.get_publishers_info_by_topic('/imu_hash_probe')
            assert str(info.topic_type_hash) == type_description_hash('sensor_msgs/msg/Imu')
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
