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

"""Tests of ring_gyro_sim.recording.reader, including files cut short by a killed recorder."""

import io
import logging
import os
import signal
import struct
import subprocess
import sys
import textwrap

import mcap.data_stream
import mcap.reader
import mcap.records
import mcap.stream_reader
import pytest
import rclpy.serialization
import recording_samples as samples

import ring_gyro_sim
from ring_gyro_sim.recording.errors import RecordingError
from ring_gyro_sim.recording.reader import (
    BagMessage, decode, read_messages, read_metadata, read_topics)
from ring_gyro_sim.recording.writer import BagWriter

REPOSITORY = os.path.dirname(os.path.dirname(os.path.abspath(ring_gyro_sim.__file__)))
BLOCK_PERIOD_NS = 40_000


def write_blocks(path, count, chunk_size=2048):
    """Record ``count`` blocks at increasing log times, in several chunks."""
    with BagWriter(path, chunk_size=chunk_size) as bag:
        bag.add_topic(samples.BLOCK_TOPIC, 'std_msgs/msg/Float64MultiArray')
        bag.add_metadata('ring_gyro_sim', samples.RUN_METADATA)
        for b in range(count):
            time_ns = b * BLOCK_PERIOD_NS
            bag.write(samples.BLOCK_TOPIC, samples.block_message(time_ns), time_ns)
    return path


def chunk_layout(path):
    """Return [(start offset, end offset, message count)] of the chunks of a finished file."""
    with open(path, 'rb') as stream:
        summary = mcap.reader.make_reader(stream).get_summary()
        layout = []
        for index in sorted(summary.chunk_indexes, key=lambda i: i.chunk_start_offset):
            stream.seek(index.chunk_start_offset + 1 + 8)
            chunk = mcap.records.Chunk.read(mcap.data_stream.ReadDataStream(stream))
            records = mcap.stream_reader.breakup_chunk(chunk)
            count = sum(isinstance(record, mcap.records.Message) for record in records)
            layout.append((index.chunk_start_offset,
                           index.chunk_start_offset + index.chunk_length, count))
    return layout


def test_messages_in_log_time_order(sample_bag):
    path, messages = sample_bag
    read = list(read_messages(path))
    assert all(isinstance(message, BagMessage) for message in read)
    assert [(m.topic, m.log_time_ns) for m in read] == [(t, n) for t, _, n in messages]
    for message, (topic, original, log_time_ns) in zip(read, messages):
        assert message.type_name == samples.TOPIC_TYPES[topic]
        # rclpy's CDR serializer leaves alignment padding uninitialised, so the bytes of two
        # serializations of one message can differ: compare what the bytes decode to.
        assert rclpy.serialization.deserialize_message(message.data, type(original)) == original
        assert message.publish_time_ns == log_time_ns
        assert decode(message) == original


def test_out_of_order_writes_come_back_sorted(tmp_path):
    path = tmp_path / 'unordered.mcap'
    with BagWriter(path, chunk_size=256) as bag:
        bag.add_topic(samples.CLOCK_TOPIC, 'rosgraph_msgs/msg/Clock')
        bag.add_topic(samples.SHOCK_TOPIC, 'geometry_msgs/msg/Vector3Stamped')
        for time_ns in (50, 10, 40):
            bag.write(samples.CLOCK_TOPIC, samples.clock_message(time_ns), time_ns)
        bag.write(samples.SHOCK_TOPIC, samples.shock_message(20, 9.81), 20)
    read = list(read_messages(path))
    assert [m.log_time_ns for m in read] == [10, 20, 40, 50]
    assert decode(read[1]) == samples.shock_message(20, 9.81)


def test_topic_filter(sample_bag):
    path, messages = sample_bag
    expected = [t for topic, _, t in messages if topic == samples.BLOCK_TOPIC]
    assert [m.log_time_ns for m in read_messages(path, samples.BLOCK_TOPIC)] == expected
    both = {samples.BLOCK_TOPIC, samples.SHOCK_TOPIC}
    assert {m.topic for m in read_messages(path, topics=sorted(both))} == both
    assert list(read_messages(path, topics=[])) == []


def test_read_metadata(sample_bag):
    path, _ = sample_bag
    assert read_metadata(path, 'ring_gyro_sim') == samples.RUN_METADATA
    assert 'serialized_metadata' in read_metadata(path, 'rosbag2')
    with pytest.raises(RecordingError, match="no metadata record 'missing'"):
        read_metadata(path, 'missing')


def test_multi_chunk_file_cut_mid_chunk(tmp_path):
    path = write_blocks(tmp_path / 'full.mcap', 300)
    layout = chunk_layout(path)
    assert len(layout) >= 5
    start, end, _ = layout[3]
    cut = start + (end - start) // 2
    expected = sum(count for _, chunk_end, count in layout if chunk_end <= cut)
    truncated = tmp_path / 'cut.mcap'
    truncated.write_bytes(path.read_bytes()[:cut])
    read = list(read_messages(truncated))
    assert len(read) == expected > 0
    assert [m.log_time_ns for m in read] == [b * BLOCK_PERIOD_NS for b in range(expected)]
    assert decode(read[-1]) == samples.block_message((expected - 1) * BLOCK_PERIOD_NS)
    assert read_metadata(truncated, 'ring_gyro_sim') == samples.RUN_METADATA
    with pytest.raises(RecordingError, match='rosbag2'):
        read_metadata(truncated, 'rosbag2')


@pytest.mark.parametrize('where', ['header', 'before_first_chunk_end', 'chunk_end',
                                   'summary', 'footer'])
def test_any_cut_reads_the_complete_chunks(tmp_path, where):
    path = write_blocks(tmp_path / 'full.mcap', 120)
    layout = chunk_layout(path)
    size = path.stat().st_size
    cut = {
        'header': 20,
        'before_first_chunk_end': layout[0][1] - 1,
        'chunk_end': layout[1][1],
        'summary': size - 60,
        'footer': size - 3,
    }[where]
    expected = sum(count for _, chunk_end, count in layout if chunk_end <= cut)
    truncated = tmp_path / 'cut.mcap'
    truncated.write_bytes(path.read_bytes()[:cut])
    read = list(read_messages(truncated, samples.BLOCK_TOPIC))
    assert [m.log_time_ns for m in read] == [b * BLOCK_PERIOD_NS for b in range(expected)]


def test_killed_writer_leaves_completed_chunks_readable(tmp_path):
    path = tmp_path / 'killed.mcap'
    script = textwrap.dedent(f"""
        import os, signal
        from std_msgs.msg import Float64MultiArray
        from ring_gyro_sim.recording.writer import BagWriter
        bag = BagWriter({str(path)!r}, chunk_size=4096)
        bag.add_topic({samples.BLOCK_TOPIC!r}, 'std_msgs/msg/Float64MultiArray')
        bag.add_metadata('ring_gyro_sim', {samples.RUN_METADATA!r})
        for i in range(1000):
            bag.write({samples.BLOCK_TOPIC!r}, Float64MultiArray(data=[float(i)] * 16), i * 1000)
            if i == 700:
                os.kill(os.getpid(), signal.SIGKILL)
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        filter(None, [REPOSITORY, os.environ.get('PYTHONPATH')])))
    result = subprocess.run([sys.executable, '-c', script], env=env, timeout=120,
                            capture_output=True, text=True)
    assert result.returncode == -signal.SIGKILL, result.stderr
    read = list(read_messages(path))
    # Each message is ~ 200 B uncompressed: a 4 KiB chunk holds ~ 20 of them.
    assert 600 < len(read) <= 701
    assert [m.log_time_ns for m in read] == [i * 1000 for i in range(len(read))]
    assert list(decode(read[-1]).data) == [float(len(read) - 1)] * 16
    assert read_metadata(path, 'ring_gyro_sim') == samples.RUN_METADATA
    with pytest.raises(RecordingError, match='rosbag2'):
        read_metadata(path, 'rosbag2')


def test_flush_bounds_the_loss(tmp_path):
    path = tmp_path / 'flushed.mcap'
    bag = BagWriter(path, chunk_size=1 << 20)
    bag.add_topic(samples.CLOCK_TOPIC, 'rosgraph_msgs/msg/Clock')
    for time_ns in range(5):
        bag.write(samples.CLOCK_TOPIC, samples.clock_message(time_ns), time_ns)
    assert list(read_messages(path)) == []  # still in the chunk in progress
    bag.flush()
    assert [m.log_time_ns for m in read_messages(path)] == list(range(5))
    bag.finish()


def test_unreadable_inputs(tmp_path):
    with pytest.raises(RecordingError, match='No such file'):
        read_messages(tmp_path / 'missing.mcap')
    text = tmp_path / 'notes.mcap'
    text.write_text('definitely not an MCAP file')
    with pytest.raises(RecordingError, match='not an MCAP file'):
        read_messages(text)
    with pytest.raises(RecordingError, match='not an MCAP file'):
        read_metadata(text, 'rosbag2')
    empty = tmp_path / 'empty.mcap'
    empty.write_bytes(b'')
    assert list(read_messages(empty)) == []


def test_decode_errors(sample_bag):
    path, _ = sample_bag
    message = next(iter(read_messages(path, samples.BLOCK_TOPIC)))
    broken = BagMessage(message.topic, message.type_name, message.data[:6],
                        message.log_time_ns, message.publish_time_ns)
    with pytest.raises(RecordingError, match='cannot decode'):
        decode(broken)
    with pytest.raises(RecordingError, match='no schema'):
        decode(BagMessage('/x', '', b'', 0, 0))


def summary_start(data):
    """Return the offset of the summary section of a finished MCAP file (from its footer)."""
    footer = len(data) - 8 - (1 + 8 + 8 + 8 + 4)  # magic; opcode, length, 2 offsets, crc
    return struct.unpack_from('<Q', data, footer + 1 + 8)[0]


def contents(messages):
    return [(m.topic, m.log_time_ns, m.data) for m in messages]


VALUE_TOPIC = '/ring_gyro/value'


def value_data(value):
    """
    Return the CDR of a std_msgs/Float64, built here: the same bytes on every run.

    rclpy leaves alignment padding uninitialised, so the bytes of serialized blocks, the
    compressed chunks holding them and their offsets in a file differ from one process to the
    next: a test that damages given offsets would damage other fields on every run.
    """
    return struct.pack('<4sd', b'\x00\x01\x00\x00', value)  # encapsulation: CDR, little endian


def write_values(path, count, chunk_size):
    """Record ``count`` values at increasing log times, in small chunks, as a run is recorded."""
    with BagWriter(path, chunk_size=chunk_size) as bag:
        bag.add_topic(VALUE_TOPIC, 'std_msgs/msg/Float64')
        bag.add_metadata('ring_gyro_sim', samples.RUN_METADATA)
        for b in range(count):
            bag.write(VALUE_TOPIC, value_data(0.5 * b), b * BLOCK_PERIOD_NS)
    return path


def killed_before_finish(data):
    """Return the bytes of a finished file up to its rosbag2 record: a killed recorder's."""
    summary = mcap.reader.make_reader(io.BytesIO(data)).get_summary()
    return data[:next(index.offset for index in summary.metadata_indexes
                      if index.name == 'rosbag2')]


def test_corrupt_bytes_give_a_clean_end_or_a_recording_error(tmp_path):
    """Two recorders on one file, a damaged disk: never another exception."""
    path = write_values(tmp_path / 'full.mcap', 16, chunk_size=160)
    data = path.read_bytes()
    original = contents(read_messages(path))
    assert len(chunk_layout(path)) == 5
    assert decode(next(read_messages(path))).data == 0.0  # a std_msgs/Float64
    damaged = tmp_path / 'damaged.mcap'
    outcomes = {'clean': 0, 'error': 0}
    # Read linearly: a killed recorder's file, every byte after the magic, so every field of
    # every record whatever its offset (1 600 positions). Read through the index: the finished
    # file, every byte of the summary, which the index read relies on, and the data section
    # (its chunks CRC-checked) at a prime step (1 600 positions): about 3.5 s in all.
    killed = killed_before_finish(data)
    summary = summary_start(data)
    variants = {
        'killed': (killed, range(8, len(killed))),
        'finished': (data, [*range(8, summary, 97), *range(summary, len(data))]),
    }
    for variant, (source, positions) in variants.items():
        for position in positions:
            corrupt = bytearray(source)
            corrupt[position] ^= 0xFF
            damaged.write_bytes(bytes(corrupt))
            try:
                read = contents(read_messages(damaged))
                read_topics(damaged)
                read_metadata(damaged, 'ring_gyro_sim')
            except RecordingError:
                outcomes['error'] += 1
                continue
            outcomes['clean'] += 1
            # Reading stopped at the damaged record (or did not need it): what came back is
            # what was written, in order, nothing skipped.
            assert read == original[:len(read)], (variant, position)
    assert outcomes['clean'] > 0 and outcomes['error'] > 0, outcomes


@pytest.mark.parametrize('damage', ['opcode', 'length', 'index_as_message'])
def test_a_damaged_record_ends_a_linear_read(tmp_path, caplog, damage):
    # A killed file, damaged after its second chunk: the third chunk's opcode (unknown now), the
    # length of the index record after the second chunk (reaching the fourth chunk now), or one
    # bit of that record's opcode (a message record now, that the index's fields fill). mcap's
    # StreamReader skipped the third chunk or returned a message never written.
    path = write_values(tmp_path / 'full.mcap', 16, chunk_size=160)
    layout = chunk_layout(path)
    assert len(layout) == 5
    data = bytearray(killed_before_finish(path.read_bytes()))
    if damage == 'opcode':
        stop = layout[2][0]
        data[stop] ^= 0xFF
    else:
        stop = layout[1][1]  # the first message index record after the second chunk
        assert data[stop] == 0x07
        if damage == 'length':
            struct.pack_into('<Q', data, stop + 1, layout[3][0] - stop - 9)
        else:
            data[stop] ^= 0x02
    killed = tmp_path / 'killed.mcap'
    killed.write_bytes(bytes(data))
    expected = layout[0][2] + layout[1][2]
    with caplog.at_level(logging.WARNING, logger='ring_gyro_sim.recording.reader'):
        read = list(read_messages(killed))
    assert contents(read) == contents(read_messages(path))[:expected]
    assert f'read up to byte {stop} of {len(data)}' in caplog.records[0].getMessage()


@pytest.mark.parametrize('damage', ['opcode', 'start_time', 'offset'])
def test_a_damaged_summary_is_not_trusted(tmp_path, caplog, damage):
    # mcap does not check the summary's CRC: it skipped a chunk index whose opcode is damaged
    # (that chunk's messages were missing), read the chunks in the order of a damaged start
    # time (messages out of order) and seeked to a damaged offset (OSError). Checked, the
    # summary is not used and the intact data section is read linearly.
    path = write_values(tmp_path / 'full.mcap', 16, chunk_size=160)
    original = contents(read_messages(path))
    data = bytearray(path.read_bytes())
    with open(path, 'rb') as stream:
        index = mcap.reader.make_reader(stream).get_summary().chunk_indexes[1]
    fields = data.index(struct.pack('<QQQ', index.message_start_time, index.message_end_time,
                                    index.chunk_start_offset), summary_start(data))
    if damage == 'opcode':
        data[fields - 9] ^= 0xFF
    elif damage == 'start_time':
        struct.pack_into('<Q', data, fields, original[-1][1] + 1)
    else:
        data[fields + 16 + 6] ^= 0xFF
    damaged = tmp_path / 'damaged.mcap'
    damaged.write_bytes(bytes(data))
    with caplog.at_level(logging.WARNING, logger='ring_gyro_sim.recording.reader'):
        assert contents(read_messages(damaged)) == original
    # The warning says what is wrong: the summary is there but fails its CRC (it said "has no
    # summary" before).
    assert 'has a summary that fails its CRC' in caplog.records[0].getMessage()
    assert read_metadata(damaged, 'ring_gyro_sim') == samples.RUN_METADATA


def test_invalid_utf8_in_an_indexed_file_is_a_recording_error(tmp_path):
    # Uncompressed chunks, so the topic name of the channel record inside the chunk is there
    # to damage; mcap's own reader (no CRC check by default) then raises UnicodeDecodeError,
    # which is what our reader let through before.
    path = tmp_path / 'plain.mcap'
    with BagWriter(path, compression='none') as bag:
        bag.add_topic(samples.BLOCK_TOPIC, 'std_msgs/msg/Float64MultiArray')
        for b in range(3):
            bag.write(samples.BLOCK_TOPIC, samples.block_message(b), b)
    data = bytearray(path.read_bytes())
    where = data.index(samples.BLOCK_TOPIC.encode())  # the first copy: inside the chunk
    data[where + 1] = 0xFF
    path.write_bytes(bytes(data))
    with open(path, 'rb') as stream:
        with pytest.raises(UnicodeDecodeError):
            list(mcap.reader.make_reader(stream).iter_messages())
    with pytest.raises(RecordingError, match='is corrupt'):
        list(read_messages(path))


def test_a_file_without_summary_says_once_that_recover_completes_it(tmp_path, caplog):
    path = write_blocks(tmp_path / 'full.mcap', 60)
    with caplog.at_level(logging.WARNING, logger='ring_gyro_sim.recording.reader'):
        list(read_messages(path))
        read_metadata(path, 'ring_gyro_sim')
    assert caplog.records == []  # a finished file needs nothing
    killed = tmp_path / 'killed.mcap'
    data = path.read_bytes()
    killed.write_bytes(data[:summary_start(data) - 5])
    with caplog.at_level(logging.WARNING, logger='ring_gyro_sim.recording.reader'):
        list(read_messages(killed))
        read_metadata(killed, 'ring_gyro_sim')
        read_topics(killed)
    assert len(caplog.records) == 1
    line = caplog.records[0].getMessage()
    assert '\n' not in line and 'has no summary' in line
    assert f'`ring_gyro recover {killed}`' in line
    assert 'read up to byte' in line
