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
Tests of ring_gyro_sim.recording.recover and ``ring_gyro recover``.

The recovered files are read with readers that share no code with ours: ``mcap``'s
``make_reader`` with the ``mcap_ros2`` decoder, and rosbags.
"""

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

from mcap.exceptions import McapError
import mcap.reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
import recording_samples as samples

import ring_gyro_sim
from ring_gyro_sim import cli
from ring_gyro_sim.recording.errors import OutputBusyError, OutputExistsError, RecordingError
from ring_gyro_sim.recording.reader import read_messages, read_metadata
from ring_gyro_sim.recording.recover import default_output, recover
from ring_gyro_sim.recording.writer import BagWriter
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml

REPOSITORY = pathlib.Path(ring_gyro_sim.__file__).resolve().parents[1]
NS = '/ring_gyro'
BLOCK_TOPICS = [f'{NS}/modal_displacement', f'{NS}/radial_gap', f'{NS}/sense_electrodes']


def many_chunks(path, blocks=200):
    """Record the sample topics in small chunks; return the path."""
    with BagWriter(path, chunk_size=2048, custom_data=samples.CUSTOM_DATA) as bag:
        for topic, type_name in samples.TOPIC_TYPES.items():
            bag.add_topic(topic, type_name, reliable=topic != samples.DIAGNOSTICS_TOPIC,
                          depth=50 if topic == samples.BLOCK_TOPIC else 10)
        bag.add_metadata('ring_gyro_sim', samples.RUN_METADATA)
        for topic, message, log_time_ns in samples.sample_messages(blocks):
            bag.write(topic, message, log_time_ns)
    return path


def independent(path):
    """Return [(topic, log time, decoded message)] and {topic: count} by mcap and rosbags."""
    with open(path, 'rb') as stream:
        reader = mcap.reader.make_reader(stream, decoder_factories=[DecoderFactory()])
        decoded = [(channel.topic, message.log_time, msg) for _, channel, message, msg in
                   reader.iter_decoded_messages()]
        summary = reader.get_summary()
    assert summary is not None and summary.statistics.message_count == len(decoded)
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([pathlib.Path(path)], default_typestore=store) as bag:
        counts = {c.topic: c.msgcount for c in bag.connections}
        assert sum(1 for _ in bag.messages()) == len(decoded)
    return decoded, counts


def rosbag2(path):
    return yaml.safe_load(read_metadata(path, 'rosbag2')['serialized_metadata'])


def chunk_ends(path):
    """Return the end offsets of the chunks of a file, read linearly."""
    ends = []
    with open(path, 'rb') as stream:
        try:
            for record in StreamReader(stream, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    ends.append(stream.tell())
        except Exception:  # noqa: B902 - a cut file ends inside a record
            pass
    return ends


@pytest.mark.parametrize('keep', [0.3, 0.55, 0.8, 'summary'])
def test_a_cut_file_recovers_every_complete_chunk(tmp_path, keep):
    full = many_chunks(tmp_path / 'full.mcap')
    data = full.read_bytes()
    if keep == 'summary':  # cut inside the summary: every chunk is complete
        with open(full, 'rb') as stream:
            end = mcap.reader.make_reader(stream).get_summary().chunk_indexes[-1]
        cut = end.chunk_start_offset + end.chunk_length + end.message_index_length + 40
    else:
        cut = int(len(data) * keep)
    killed = tmp_path / 'killed.mcap'
    killed.write_bytes(data[:cut])
    ours = list(read_messages(killed))
    assert 0 < len(ours) <= len(list(read_messages(full)))
    with open(killed, 'rb') as stream:  # what a user meets: the other readers see nothing
        try:
            summary = mcap.reader.make_reader(stream).get_summary()
        except McapError:  # what the footer position holds is not a footer
            summary = None
        assert summary is None

    result = recover(killed)
    assert result.output == tmp_path / 'killed.recovered.mcap'
    assert result.message_count == len(ours) and not result.was_complete
    assert result.chunk_count == len([e for e in chunk_ends(full) if e <= cut])
    decoded, counts = independent(result.output)
    assert [(t, lt) for t, lt, _ in decoded] == [(m.topic, m.log_time_ns) for m in ours]
    assert sum(counts.values()) == len(ours)
    assert sorted(counts) == sorted(samples.TOPIC_TYPES)  # the idle topic too
    # Decoded values are the original ones.
    originals = {(t, lt): m for t, m, lt in samples.sample_messages(200)}
    for topic, log_time, msg in decoded:
        if topic == samples.BLOCK_TOPIC:
            assert list(msg.data) == list(originals[topic, log_time].data)
    # Metadata: the run's record as it was, and a complete rosbag2 record of what is there.
    assert read_metadata(result.output, 'ring_gyro_sim') == samples.RUN_METADATA
    document = rosbag2(result.output)
    assert document['message_count'] == len(ours)
    assert document['relative_file_paths'] == ['killed.recovered.mcap']
    recorded = {t['topic_metadata']['name']: t for t in document['topics_with_message_count']}
    assert {name: t['message_count'] for name, t in recorded.items()} == counts
    qos = recorded[samples.BLOCK_TOPIC]['topic_metadata']['offered_qos_profiles'][0]
    assert (qos['depth'], qos['reliability']) == (50, 'reliable')
    qos = recorded[samples.DIAGNOSTICS_TOPIC]['topic_metadata']['offered_qos_profiles'][0]
    assert qos['reliability'] == 'best_effort'
    with open(result.output, 'rb') as stream:
        summary = mcap.reader.make_reader(stream).get_summary()
    assert summary.chunk_indexes and summary.metadata_indexes
    assert all(index.message_index_offsets for index in summary.chunk_indexes)


def test_a_damaged_opcode_ends_the_recovery_where_the_reader_stops(tmp_path):
    # A killed file whose third chunk's opcode is damaged (0x06 -> 0xF9, unknown): mcap's
    # StreamReader, which recover used before, skipped that chunk and copied the ones after
    # it, so the copy had a hole the report did not mention. Now the copy ends where the
    # project's reader stops, and the report says where and why.
    full = many_chunks(tmp_path / 'full.mcap', blocks=30)
    with open(full, 'rb') as stream:
        summary = mcap.reader.make_reader(stream).get_summary()
        third = sorted(index.chunk_start_offset for index in summary.chunk_indexes)[2]
        rosbag2_record = next(index.offset for index in summary.metadata_indexes
                              if index.name == 'rosbag2')
    data = bytearray(full.read_bytes()[:rosbag2_record])  # killed before the summary
    assert data[third] == 0x06
    data[third] ^= 0xFF
    killed = tmp_path / 'killed.mcap'
    killed.write_bytes(bytes(data))
    ours = [(m.topic, m.log_time_ns, m.data) for m in read_messages(killed)]
    assert 0 < len(ours) < len(list(read_messages(full)))
    result = recover(killed)
    assert result.chunk_count == 2
    assert result.stopped_at == third and 'opcode' in result.reason, result.reason
    assert [(m.topic, m.log_time_ns, m.data) for m in read_messages(result.output)] == ours
    decoded, _ = independent(result.output)
    assert len(decoded) == len(ours)


def test_a_complete_file_is_copied_as_it_is(tmp_path):
    full = many_chunks(tmp_path / 'full.mcap', blocks=30)
    result = recover(full, tmp_path / 'copy.mcap')
    assert result.was_complete and result.stopped_at is None
    assert [(m.topic, m.log_time_ns, m.data) for m in read_messages(result.output)] == [
        (m.topic, m.log_time_ns, m.data) for m in read_messages(full)]
    a, b = rosbag2(full), rosbag2(result.output)
    for document in (a, b):
        del document['relative_file_paths'], document['files']
    assert a == b  # ros_distro and custom_data kept from the original record
    assert b['custom_data'] == samples.CUSTOM_DATA


def test_refusals(tmp_path):
    full = many_chunks(tmp_path / 'full.mcap', blocks=10)
    with pytest.raises(OutputExistsError, match='exists'):
        recover(full, full)
    existing = tmp_path / 'existing.mcap'
    existing.write_bytes(b'keep me')
    with pytest.raises(OutputExistsError, match='refusing to replace it'):
        recover(full, existing)
    assert existing.read_bytes() == b'keep me'
    text = tmp_path / 'notes.mcap'
    text.write_text('not a recording')
    with pytest.raises(RecordingError, match='not an MCAP file'):
        recover(text)
    short = tmp_path / 'short.mcap'
    short.write_bytes(b'\x89MCA')
    with pytest.raises(RecordingError, match='nothing to recover'):
        recover(short)
    with pytest.raises(RecordingError, match='No such file'):
        recover(tmp_path / 'missing.mcap')
    busy = BagWriter(tmp_path / 'busy.mcap')
    try:
        with pytest.raises(OutputBusyError, match='being recorded right now'):
            recover(tmp_path / 'busy.mcap')
    finally:
        busy.finish()
    # Nothing half-written is left behind.
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        'busy.mcap', 'existing.mcap', 'full.mcap', 'notes.mcap', 'short.mcap']


def test_default_output():
    assert default_output('/a/run.mcap') == pathlib.Path('/a/run.recovered.mcap')
    assert default_output('run') == pathlib.Path('run.recovered.mcap')


def test_the_recover_verb(tmp_path, capsys):
    full = many_chunks(tmp_path / 'full.mcap')
    killed = tmp_path / 'k.mcap'
    killed.write_bytes(full.read_bytes()[:full.stat().st_size // 2])
    assert cli.main(['recover', str(killed), '-o', str(tmp_path / 'out' / 'r.mcap')]) == 0
    captured = capsys.readouterr()
    assert 'written to' in captured.err and 'reading stopped at byte' in captured.err
    printed = json.loads(captured.out)
    assert printed['output'] == str(tmp_path / 'out' / 'r.mcap') and printed['stopped_at'] > 0
    assert (tmp_path / 'out' / 'r.mcap').exists()
    assert cli.main(['recover', str(killed), '-o', str(tmp_path / 'out' / 'r.mcap')]) == 1
    err = capsys.readouterr().err
    assert err.startswith('ring_gyro recover: error: ') and 'exists' in err


# ------------------------------------------------------------------ a killed real run


def ring_gyro(*args, **kwargs):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        filter(None, [str(REPOSITORY), os.environ.get('PYTHONPATH')])))
    return [sys.executable, '-m', 'ring_gyro_sim.cli', *args], env


def complete_chunks(path):
    return len(chunk_ends(path)) if path.exists() else 0


def block_values(path, topic):
    """Return [(log time, data array)] of a block topic, decoded by mcap_ros2."""
    with open(path, 'rb') as stream:
        reader = mcap.reader.make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(message.log_time, np.array(msg.data, dtype=np.float64))
                for _, _, message, msg in reader.iter_decoded_messages(topics=[topic])]


@pytest.mark.ci
def test_a_sigkilled_run_recovers_and_resimulates_bit_for_bit(tmp_path):
    scenario = tmp_path / 'scenario.yaml'
    # Driven from rest with a shock at 5 ms, as fast as possible for far longer than the test
    # lets it run: it is killed once a few chunks are on disk.
    scenario.write_text(yaml.safe_dump({'ring_gyro': {'ros__parameters': {
        'drive': {'start_on': 'rest'}, 'real_time_factor': 0.0, 'duration': 30.0,
        'scenario': {'shock_times': [0.005], 'shock_peaks': [19613.3]}}}}))
    killed = tmp_path / 'killed.mcap'
    command, env = ring_gyro('run', str(scenario), '-o', str(killed), '--no-progress')
    run = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 300
        while complete_chunks(killed) < 4 and run.poll() is None:
            assert time.monotonic() < deadline, 'the run wrote no chunks in 300 s'
            time.sleep(0.2)
        assert run.poll() is None, run.stderr.read()
        run.send_signal(signal.SIGKILL)
        assert run.wait(60) == -signal.SIGKILL
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        run.stderr.close()
    ours = list(read_messages(killed))
    assert len(ours) > 0

    command, env = ring_gyro('recover', str(killed))
    done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    recovered = tmp_path / 'killed.recovered.mcap'
    decoded, counts = independent(recovered)
    assert len(decoded) == sum(counts.values()) == len(ours)
    assert [(t, lt) for t, lt, _ in decoded] == [(m.topic, m.log_time_ns) for m in ours]
    assert counts[f'{NS}/modal_displacement'] >= 2

    # --from on the killed file says, in one line, that recover completes it.
    command, env = ring_gyro('run', '--from', str(killed), '--no-progress')
    hint = subprocess.run(command, env=env, capture_output=True, text=True, timeout=600)
    assert hint.returncode == 0, hint.stderr
    lines = [line for line in hint.stderr.splitlines() if 'ring_gyro recover' in line]
    assert len(lines) == 1 and 'no summary' in lines[0], hint.stderr

    again = tmp_path / 'again.mcap'
    command, env = ring_gyro('run', '--from', str(recovered), '-o', str(again),
                             '--no-progress')
    resim = subprocess.run(command, env=env, capture_output=True, text=True, timeout=600)
    assert resim.returncode == 0, resim.stderr
    assert 'ring_gyro recover' not in resim.stderr  # the recovered file is complete
    modal = f'{NS}/modal_displacement'
    assert len(block_values(again, modal)) == len(block_values(recovered, modal))
    for topic in BLOCK_TOPICS:
        original, repeated = block_values(recovered, topic), block_values(again, topic)
        # A kill between the three messages of one block leaves the last block on some
        # topics only; the re-simulation has it on all three.
        assert 0 <= len(repeated) - len(original) <= 1, topic
        for (t_a, a), (t_b, b) in zip(original, repeated):
            assert t_a == t_b and np.array_equal(a, b), (topic, t_a)


def test_an_output_where_nothing_can_be_written_is_one_error(tmp_path, capsys):
    # One error line, not an OSError traceback from the temporary file beside the output;
    # /sys refuses new files to root as well.
    try:
        os.close(os.open('/sys/ring_gyro_probe', os.O_WRONLY | os.O_CREAT | os.O_EXCL))
    except OSError:
        pass
    else:
        os.unlink('/sys/ring_gyro_probe')
        pytest.skip('/sys is writable here')
    full = many_chunks(tmp_path / 'full.mcap', blocks=10)
    with pytest.raises(RecordingError, match="cannot create a file in '/sys'"):
        recover(full, '/sys/x.mcap')
    assert cli.main(['recover', str(full), '-o', '/sys/x.mcap']) == 1
    err = capsys.readouterr().err
    assert err.startswith("ring_gyro recover: error: cannot write '/sys/x.mcap': ") and \
        err.count('\n') == 1, err


@pytest.mark.parametrize('keep', ['magic', 'header'])
def test_a_file_with_nothing_after_its_header_is_refused(tmp_path, capsys, keep):
    # An 8-byte file (the MCAP magic alone) is refused, not "recovered" into an empty MCAP
    full = many_chunks(tmp_path / 'full.mcap', blocks=10)
    data = full.read_bytes()
    if keep == 'magic':
        cut = 8
    else:  # the magic and the header record: op (1), length (8), then the record
        cut = 8 + 9 + int.from_bytes(data[9:17], 'little')
    short = tmp_path / 'short.mcap'
    short.write_bytes(data[:cut])
    with pytest.raises(RecordingError, match=f'holds nothing to recover: .*{cut} bytes'):
        recover(short)
    assert not default_output(short).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ['full.mcap', 'short.mcap']
    assert cli.main(['recover', str(short)]) == 1
    assert 'nothing to recover' in capsys.readouterr().err
