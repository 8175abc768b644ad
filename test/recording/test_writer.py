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

"""Tests of ring_gyro_sim.recording.writer, read back with independent readers."""

import collections
import gc
import math
import pathlib
import tracemalloc

import mcap.reader
import mcap_ros2.decoder
import pytest
import rclpy.serialization
import recording_samples as samples
from ring_gyro_sim.recording import writer as writer_module
from ring_gyro_sim.recording.errors import OutputExistsError, RecordingError
from ring_gyro_sim.recording.schemas import message_definition, type_description_hash
from ring_gyro_sim.recording.writer import BagWriter
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosHistory, QosLiveliness, QosReliability
from yaml import safe_load

# The offered_qos_profiles channel metadata of a reliable, volatile, keep-last-10 publisher as
# rosbag2 Jazzy serializes it (string enums, RMW_DURATION_INFINITE, no trailing newline).
RELIABLE_VOLATILE_10 = """\
- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false"""

BAG_METADATA_KEYS = [
    'version', 'storage_identifier', 'duration', 'starting_time', 'message_count',
    'topics_with_message_count', 'compression_format', 'compression_mode',
    'relative_file_paths', 'files', 'custom_data', 'ros_distro']
QOS_KEYS = [
    'history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan', 'liveliness',
    'liveliness_lease_duration', 'avoid_ros_namespace_conventions']


def assert_same_message(actual, expected):
    """Compare a message decoded by another library field by field with an rclpy message."""
    for field in expected.get_fields_and_field_types():
        want = getattr(expected, field)
        got = getattr(actual, field)
        if isinstance(want, bytes) and len(want) == 1:  # rclpy's 'byte' fields
            want = want[0]
        if hasattr(want, 'get_fields_and_field_types'):
            assert_same_message(got, want)
        elif isinstance(want, (list, tuple)) or hasattr(want, 'tolist'):
            assert len(got) == len(want), field
            for got_item, want_item in zip(got, want):
                if hasattr(want_item, 'get_fields_and_field_types'):
                    assert_same_message(got_item, want_item)
                else:
                    assert got_item == want_item, field
        else:
            assert got == want, field


def summary_of(path):
    with open(path, 'rb') as stream:
        reader = mcap.reader.make_reader(stream)
        return reader.get_header(), reader.get_summary()


def rosbag2_document(path):
    with open(path, 'rb') as stream:
        reader = mcap.reader.make_reader(stream)
        records = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
    assert len(records) == 1
    assert set(records[0].metadata) == {'serialized_metadata'}
    return safe_load(records[0].metadata['serialized_metadata'])


def assert_decodable_like_rosbag2(document):
    """Check the fields and types rosbag2_storage's convert<BagMetadata>::decode (v9) needs."""
    assert list(document) == BAG_METADATA_KEYS
    assert document['version'] == 9
    assert isinstance(document['storage_identifier'], str)
    assert document['duration']['nanoseconds'] >= 0
    assert document['starting_time']['nanoseconds_since_epoch'] >= 0
    assert isinstance(document['message_count'], int)
    for entry in document['topics_with_message_count']:
        assert list(entry) == ['topic_metadata', 'message_count']
        topic = entry['topic_metadata']
        assert list(topic) == ['name', 'type', 'serialization_format', 'offered_qos_profiles',
                               'type_description_hash']
        for profile in topic['offered_qos_profiles']:
            assert list(profile) == QOS_KEYS
            for key in ('deadline', 'lifespan', 'liveliness_lease_duration'):
                assert set(profile[key]) == {'sec', 'nsec'}
        assert isinstance(entry['message_count'], int)
    assert isinstance(document['compression_format'], str)
    assert isinstance(document['compression_mode'], str)
    assert all(isinstance(name, str) for name in document['relative_file_paths'])
    for entry in document['files']:
        assert list(entry) == ['path', 'starting_time', 'duration', 'message_count']
    custom = document['custom_data']
    assert custom is None or all(
        isinstance(k, str) and isinstance(v, str) for k, v in custom.items())
    assert isinstance(document['ros_distro'], str)


def test_header_schemas_and_channels(sample_bag):
    path, _ = sample_bag
    header, summary = summary_of(path)
    assert header.profile == 'ros2'
    schemas = {schema.name: schema for schema in summary.schemas.values()}
    assert len(schemas) == len(summary.schemas) == len(set(samples.TOPIC_TYPES.values()))
    for name, schema in schemas.items():
        assert schema.encoding == 'ros2msg'
        assert schema.data.decode() == message_definition(name)
    channels = {channel.topic: channel for channel in summary.channels.values()}
    assert set(channels) == set(samples.TOPIC_TYPES)
    for topic, channel in channels.items():
        assert channel.message_encoding == 'cdr'
        assert summary.schemas[channel.schema_id].name == samples.TOPIC_TYPES[topic]
        assert set(channel.metadata) == {'offered_qos_profiles', 'topic_type_hash'}
        type_hash = type_description_hash(samples.TOPIC_TYPES[topic])
        assert channel.metadata['topic_type_hash'] == type_hash
    assert channels[samples.BLOCK_TOPIC].metadata['offered_qos_profiles'] == RELIABLE_VOLATILE_10
    (diagnostics_qos,) = safe_load(channels[samples.DIAGNOSTICS_TOPIC].metadata[
        'offered_qos_profiles'])
    assert diagnostics_qos['reliability'] == 'best_effort'


def test_statistics_chunks_and_indexes(sample_bag):
    path, messages = sample_bag
    _, summary = summary_of(path)
    statistics = summary.statistics
    assert statistics.message_count == len(messages)
    topic_of = {cid: channel.topic for cid, channel in summary.channels.items()}
    assert {topic_of[cid]: n for cid, n in statistics.channel_message_counts.items()
            if n} == collections.Counter(topic for topic, _, _ in messages)
    assert statistics.message_start_time == min(t for _, _, t in messages)
    assert statistics.message_end_time == max(t for _, _, t in messages)
    assert statistics.chunk_count == len(summary.chunk_indexes) >= 1
    for chunk_index in summary.chunk_indexes:
        assert chunk_index.compression == 'zstd'
        assert chunk_index.message_index_offsets
    names = [index.name for index in summary.metadata_indexes]
    assert sorted(names) == ['ring_gyro_sim', 'rosbag2']
    rosbag2_offset = next(i.offset for i in summary.metadata_indexes if i.name == 'rosbag2')
    assert rosbag2_offset > max(c.chunk_start_offset for c in summary.chunk_indexes)


def test_small_chunks_split_the_data(tmp_path):
    path = tmp_path / 'chunked.mcap'
    with BagWriter(path, chunk_size=1024) as bag:
        bag.add_topic(samples.BLOCK_TOPIC, 'std_msgs/msg/Float64MultiArray')
        for b in range(200):
            bag.write(samples.BLOCK_TOPIC, samples.block_message(b * 40_000), b * 40_000)
    _, summary = summary_of(path)
    assert summary.statistics.chunk_count > 10
    assert summary.statistics.message_count == 200


CHUNK_INDEX_RECORD_BYTES = 77
"""A chunk index record of a zstd chunk without its channels (MCAP specification)."""


def write_chunks(bag, topics, chunks, first_ns=0):
    """Write ``chunks`` chunks of 4 kB (chunk_size 4096) touching every topic of ``topics``."""
    payload = bytes(range(256)) * 4
    for k in range(chunks):
        for i, topic in enumerate(topics):
            bag.write(topic, payload if i < 4 else payload[:64], first_ns + k * 1000 + i)


def test_a_chunk_keeps_only_its_index_record_in_memory(tmp_path):
    # A recording node must not grow with its file. What a writer keeps per chunk
    # until finish() is the chunk's index for the summary: mcap's ChunkIndex objects took
    # ~1.5 kB each for 15 channels, their records take 77 + 10 per channel bytes.
    topics = [f'/ring_gyro/t{i}' for i in range(15)]
    with BagWriter(tmp_path / 'long.mcap', chunk_size=4096, compression='none') as bag:
        for topic in topics:
            bag.add_topic(topic, 'std_msgs/msg/Float64')
        write_chunks(bag, topics, 50)
        gc.collect()
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            write_chunks(bag, topics, 2000, first_ns=10**9)
            gc.collect()
            kept = tracemalloc.get_traced_memory()[0] - before
        finally:
            tracemalloc.stop()
    record = CHUNK_INDEX_RECORD_BYTES + 10 * len(topics)  # 227 B
    _, summary = summary_of(tmp_path / 'long.mcap')
    assert summary.statistics.chunk_count == len(summary.chunk_indexes) >= 2000
    # bytearray over-allocation and the few objects of the chunk in progress: at most 1.3x.
    assert kept / 2000 < 1.3 * record, f'{kept / 2000:.0f} B per chunk'


@pytest.mark.parametrize('compression', ['zstd', 'none'])
def test_the_compact_chunk_indexes_write_what_mcap_writes(tmp_path, monkeypatch, compression):
    topics = [f'/ring_gyro/t{i}' for i in range(6)]
    paths = [tmp_path / 'compact' / 'run.mcap', tmp_path / 'mcap' / 'run.mcap']
    for path in paths:
        if path.parent.name == 'mcap':
            monkeypatch.setattr(writer_module, '_keep_chunk_indexes_compact', lambda w: False)
        with BagWriter(path, chunk_size=4096, compression=compression) as bag:
            for topic in topics:
                bag.add_topic(topic, 'std_msgs/msg/Float64')
            write_chunks(bag, topics, 30)
    compact, plain = (p.read_bytes() for p in paths)
    assert compact == plain
    assert len(summary_of(paths[0])[1].chunk_indexes) >= 30


def test_mcap_ros2_decodes_the_original_values(sample_bag):
    path, messages = sample_bag
    with open(path, 'rb') as stream:
        reader = mcap.reader.make_reader(
            stream, decoder_factories=[mcap_ros2.decoder.DecoderFactory()])
        decoded = [(channel.topic, message.log_time, message.publish_time, value)
                   for _, channel, message, value in reader.iter_decoded_messages()]
    assert [(topic, t) for topic, t, _, _ in decoded] == [(topic, t) for topic, _, t in messages]
    for (_, log_time_ns, publish_time_ns, value), (_, original, _) in zip(decoded, messages):
        assert publish_time_ns == log_time_ns
        assert_same_message(value, original)
    block = next(value for topic, _, _, value in decoded if topic == samples.BLOCK_TOPIC)
    assert [d.label for d in block.layout.dim] == ['sample', 't,q1,q2,q3']
    assert [(d.size, d.stride) for d in block.layout.dim] == [(4, 16), (4, 4)]


def test_rosbags_reads_the_bare_mcap(sample_bag):
    path, messages = sample_bag
    with AnyReader([pathlib.Path(path)]) as reader:
        connections = {c.topic: c for c in reader.connections}
        assert {t: c.msgtype for t, c in connections.items()} == samples.TOPIC_TYPES
        counts = collections.Counter(topic for topic, _, _ in messages)
        assert {t: c.msgcount for t, c in connections.items()} == {
            t: counts.get(t, 0) for t in samples.TOPIC_TYPES}
        for topic, connection in connections.items():
            (qos,) = connection.ext.offered_qos_profiles
            assert qos.history == QosHistory.KEEP_LAST and qos.depth == 10
            best_effort = topic == samples.DIAGNOSTICS_TOPIC
            assert qos.reliability == (QosReliability.BEST_EFFORT if best_effort
                                       else QosReliability.RELIABLE)
            assert qos.durability == QosDurability.VOLATILE
            assert qos.liveliness == QosLiveliness.AUTOMATIC
        read = [(c.topic, t, reader.deserialize(raw, c.msgtype))
                for c, t, raw in reader.messages()]
    assert [(topic, t) for topic, t, _ in read] == [(topic, t) for topic, _, t in messages]
    for (_, _, value), (_, original, _) in zip(read, messages):
        assert_same_message(value, original)


def test_rosbag2_metadata_is_complete(sample_bag):
    path, messages = sample_bag
    document = rosbag2_document(path)
    assert_decodable_like_rosbag2(document)
    times = [t for _, _, t in messages]
    assert document['storage_identifier'] == 'mcap'
    assert document['message_count'] == len(messages)
    assert document['starting_time'] == {'nanoseconds_since_epoch': min(times)}
    assert document['duration'] == {'nanoseconds': max(times) - min(times)}
    assert document['compression_format'] == document['compression_mode'] == ''
    assert document['relative_file_paths'] == ['run.mcap']
    assert document['files'] == [{
        'path': 'run.mcap', 'starting_time': document['starting_time'],
        'duration': document['duration'], 'message_count': len(messages)}]
    assert document['custom_data'] == samples.CUSTOM_DATA
    assert document['ros_distro'] == 'jazzy'
    counts = collections.Counter(topic for topic, _, _ in messages)
    _, summary = summary_of(path)
    channels = {channel.topic: channel for channel in summary.channels.values()}
    topics = document['topics_with_message_count']
    assert [entry['topic_metadata']['name'] for entry in topics] == list(samples.TOPIC_TYPES)
    for entry in topics:
        metadata = entry['topic_metadata']
        name = metadata['name']
        assert entry['message_count'] == counts.get(name, 0)
        assert metadata['type'] == samples.TOPIC_TYPES[name]
        assert metadata['serialization_format'] == 'cdr'
        assert metadata['offered_qos_profiles'] == safe_load(
            channels[name].metadata['offered_qos_profiles'])
        assert metadata['type_description_hash'] == channels[name].metadata['topic_type_hash']
    assert counts[samples.IDLE_TOPIC] == 0


def test_empty_bag_metadata(tmp_path):
    path = tmp_path / 'empty.mcap'
    with BagWriter(path) as bag:
        bag.add_topic(samples.CLOCK_TOPIC, 'rosgraph_msgs/msg/Clock')
    document = rosbag2_document(path)
    assert_decodable_like_rosbag2(document)
    assert document['message_count'] == 0
    assert document['duration'] == {'nanoseconds': 0}
    assert document['custom_data'] is None
    assert document['topics_with_message_count'][0]['message_count'] == 0


def test_user_metadata_round_trip(sample_bag):
    path, _ = sample_bag
    with open(path, 'rb') as stream:
        records = {m.name: m.metadata for m in mcap.reader.make_reader(stream).iter_metadata()}
    assert records['ring_gyro_sim'] == samples.RUN_METADATA


def test_transient_local_best_effort_qos(tmp_path):
    path = tmp_path / 'qos.mcap'
    with BagWriter(path) as bag:
        bag.add_topic('/latched', 'std_msgs/msg/Float64MultiArray', reliable=False,
                      durability='transient_local', depth=1)
    _, summary = summary_of(path)
    (channel,) = summary.channels.values()
    (profile,) = safe_load(channel.metadata['offered_qos_profiles'])
    assert profile['reliability'] == 'best_effort'
    assert profile['durability'] == 'transient_local'
    assert profile['depth'] == 1


def test_publish_time_and_serialized_bytes(tmp_path):
    path = tmp_path / 'times.mcap'
    cdr = {t: rclpy.serialization.serialize_message(samples.clock_message(t)) for t in (5, 9)}
    with BagWriter(path) as bag:
        bag.add_topic(samples.CLOCK_TOPIC, 'rosgraph_msgs/msg/Clock')
        bag.write(samples.CLOCK_TOPIC, samples.clock_message(5), 5, publish_time_ns=7)
        bag.write(samples.CLOCK_TOPIC, cdr[9], 9)
        assert bag.message_count == 2
    with open(path, 'rb') as stream:
        read = [(m.log_time, m.publish_time, m.sequence, m.data)
                for _, _, m in mcap.reader.make_reader(stream).iter_messages()]
    assert read == [(5, 7, 1, cdr[5]), (9, 9, 2, cdr[9])]


def test_missing_parent_directories_are_created(tmp_path):
    path = tmp_path / 'no' / 'such' / 'dir' / 'run.mcap'
    with BagWriter(path) as bag:
        bag.add_topic(samples.SHOCK_TOPIC, 'geometry_msgs/msg/Vector3Stamped')
        bag.write(samples.SHOCK_TOPIC, samples.shock_message(0, 1.0), 0)
    assert rosbag2_document(path)['message_count'] == 1


def test_unwritable_path_is_reported_at_construction(tmp_path):
    # Tests run as root, for whom permissions do not stop a write: a path through a regular
    # file cannot be created by anyone.
    blocker = tmp_path / 'plain_file'
    blocker.write_text('not a directory')
    missing = blocker / 'dir' / 'run.mcap'
    with pytest.raises(RecordingError) as info:
        BagWriter(missing)
    assert str(missing) in str(info.value)
    assert 'Not a directory' in str(info.value)
    assert isinstance(info.value, RuntimeError)
    with pytest.raises(OutputExistsError, match='a directory of that name exists'):
        BagWriter(tmp_path)
    with pytest.raises(RecordingError, match='Is a directory'):
        BagWriter(tmp_path, overwrite=True)
    assert blocker.read_text() == 'not a directory'


def test_finish_runs_on_exception_and_is_idempotent(tmp_path):
    path = tmp_path / 'aborted.mcap'
    with pytest.raises(ZeroDivisionError):
        with BagWriter(path) as bag:
            bag.add_topic(samples.SHOCK_TOPIC, 'geometry_msgs/msg/Vector3Stamped')
            bag.write(samples.SHOCK_TOPIC, samples.shock_message(0, 1.0), 0)
            math.sqrt(1 / 0)
    assert bag.closed
    bag.finish()
    assert rosbag2_document(path)['message_count'] == 1
    with pytest.raises(RecordingError, match='already finished'):
        bag.write(samples.SHOCK_TOPIC, samples.shock_message(1, 1.0), 1)
    with pytest.raises(RecordingError, match='already finished'):
        bag.add_topic(samples.CLOCK_TOPIC, 'rosgraph_msgs/msg/Clock')


def test_invalid_calls(tmp_path):
    with BagWriter(tmp_path / 'invalid.mcap') as bag:
        bag.add_topic(samples.SHOCK_TOPIC, 'geometry_msgs/msg/Vector3Stamped')
        bag.add_topic(samples.SHOCK_TOPIC, 'geometry_msgs/Vector3Stamped')  # same again: no-op
        with pytest.raises(RecordingError, match='already registered'):
            bag.add_topic(samples.SHOCK_TOPIC, 'std_msgs/msg/Float64MultiArray')
        with pytest.raises(RecordingError, match='already registered'):
            bag.add_topic(samples.SHOCK_TOPIC, 'geometry_msgs/msg/Vector3Stamped', depth=3)
        with pytest.raises(RecordingError, match='unknown message type'):
            bag.add_topic('/x', 'std_msgs/msg/NoSuchType')
        with pytest.raises(ValueError, match='durability'):
            bag.add_topic('/x', 'std_msgs/msg/Float64', durability='persistent')
        with pytest.raises(ValueError, match='topic'):
            bag.add_topic('relative', 'std_msgs/msg/Float64')
        with pytest.raises(ValueError, match='depth'):
            bag.add_topic('/x', 'std_msgs/msg/Float64', depth=0)
        with pytest.raises(RecordingError, match='not registered'):
            bag.write('/unknown', samples.clock_message(0), 0)
        with pytest.raises(TypeError, match='Vector3Stamped'):
            bag.write(samples.SHOCK_TOPIC, samples.clock_message(0), 0)
        with pytest.raises(ValueError, match='log_time_ns'):
            bag.write(samples.SHOCK_TOPIC, samples.shock_message(0, 1.0), -1)
        with pytest.raises(TypeError, match='log_time_ns'):
            bag.write(samples.SHOCK_TOPIC, samples.shock_message(0, 1.0), 0.5)
        with pytest.raises(ValueError, match='reserved'):
            bag.add_metadata('rosbag2', {'a': 'b'})
        with pytest.raises(TypeError, match='dict'):
            bag.add_metadata('run', {'a': 1})
        assert bag.message_count == 0
    with pytest.raises(ValueError, match='chunk_size'):
        BagWriter(tmp_path / 'never.mcap', chunk_size=0)
