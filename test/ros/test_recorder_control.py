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
Tests of the closed loop's block topic ``~/control`` in the sink, the recorder and the CLI.

``config/gyro.yaml`` with ``control.mode: closed_loop`` is run by ``ring_gyro run -o`` for
50 ms (5 blocks of 10 ms, the loops updated at 1 kHz) and read back with ``mcap`` +
``mcap_ros2`` and ``rosbags``, which share no code with ours, and with
:func:`~ring_gyro_sim.recording.reader.read_block_topic`; every row must equal, bit for bit,
``Block.control`` of a direct :class:`~ring_gyro_sim.run.Run` of the same configuration.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import json
import pathlib

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from ring_gyro_sim import cli
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS, ControlSamples
from ring_gyro_sim.core.params import paper_config, to_flat
from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.recording.reader import (
    block_end_times_ns, read_block_topic, read_messages, read_metadata)
from ring_gyro_sim.recording.schemas import message_definition
from ring_gyro_sim.ros import conversions
from ring_gyro_sim.ros.recorder import METADATA_NAME, RunRecorder
from ring_gyro_sim.ros.sinks import RosSink
from ring_gyro_sim.run import Run
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml
# isort: on

NS = '/ring_gyro'
TOPIC = f'{NS}/control'
REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
DURATION_S = 0.05
"""Simulated time of the runs: 5 blocks of 10 ms at 200 kHz, 49 loop updates."""
BLOCK_ENDS_NS = [10_000_000 * (k + 1) for k in range(5)]
LABELS = ['t', *CONTROL_CHANNELS]


def closed_loop_params(directory):
    """Write config/gyro.yaml with ``control.mode: closed_loop`` into ``directory``."""
    tree = yaml.safe_load((REPO_ROOT / 'config' / 'gyro.yaml').read_text(encoding='utf-8'))
    tree['/**']['ros__parameters']['control'] = {'mode': 'closed_loop'}
    path = pathlib.Path(directory) / 'gyro_closed.yaml'
    path.write_text(yaml.safe_dump(tree), encoding='utf-8')
    return path


@pytest.fixture(scope='module')
def params(tmp_path_factory):
    return closed_loop_params(tmp_path_factory.mktemp('control'))


@pytest.fixture(scope='module')
def direct(params):
    """Return the configuration and the blocks of a direct Run, cut as ``ring_gyro run`` cuts."""
    config = load_yaml(str(params))
    assert config.control.mode == 'closed_loop' and config.gyro.enabled
    run = Run(config)
    per_block = int(round(config.run.block_duration * config.run.output_rate))
    blocks = [run.advance(per_block) for _ in BLOCK_ENDS_NS]
    assert [b.end_ns for b in blocks] == BLOCK_ENDS_NS
    return config, blocks


@pytest.fixture(scope='module')
def recording(params, tmp_path_factory):
    """``ring_gyro run gyro_closed.yaml -o run.mcap --duration 0.05``."""
    path = tmp_path_factory.mktemp('control_run') / 'run.mcap'
    assert cli.main(['run', str(params), '-o', str(path), '--duration', str(DURATION_S),
                     '--no-progress']) == 0
    return path


def rows(block):
    """Return the ``t`` + CONTROL_CHANNELS rows of a block's loop updates."""
    return np.column_stack([block.control.t, block.control.values])


def test_the_recorded_rows_are_the_runs_updates_bit_for_bit(recording, direct):
    config, blocks = direct
    with open(recording, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        got = [(message.log_time, msg) for _, _, message, msg in
               reader.iter_decoded_messages(topics=[TOPIC])]
    # One message per block, logged at its end, as the other block topics.
    assert [t for t, _ in got] == BLOCK_ENDS_NS
    for (_, msg), block in zip(got, blocks):
        expected = rows(block)
        dims = msg.layout.dim
        assert (dims[0].label, dims[0].size, dims[0].stride) == (
            'sample', len(expected), len(expected) * len(LABELS))
        assert (dims[1].label, dims[1].size, dims[1].stride) == (
            ','.join(LABELS), len(LABELS), len(LABELS))
        assert np.array_equal(np.array(msg.data).reshape(expected.shape), expected)
    # The update at the end of a block is reported by the next one: 9 rows, then 10 per block.
    assert [len(rows(b)) for b in blocks] == [9, 10, 10, 10, 10]
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([pathlib.Path(recording)], default_typestore=store) as reader:
        (connection,) = [c for c in reader.connections if c.topic == TOPIC]
        assert connection.msgtype == 'std_msgs/msg/Float64MultiArray'
        assert connection.msgcount == len(blocks)
        decoded = [reader.deserialize(raw, connection.msgtype)
                   for _, _, raw in reader.messages(connections=[connection])]
    for msg, block in zip(decoded, blocks):
        assert msg.layout.dim[1].label == ','.join(LABELS)
        assert np.array_equal(np.asarray(msg.data).reshape(-1, len(LABELS)), rows(block))
    series = read_block_topic(recording, 'control')
    assert series.labels == LABELS
    assert series.end_ns == BLOCK_ENDS_NS
    assert np.array_equal(series.data, np.concatenate([rows(b) for b in blocks]))
    # Rows at the loop's 1 kHz: one per ms from 1 ms, on the ns grid.
    stamps = np.rint(series.data[:, 0] * 1e9).astype(np.int64)
    assert stamps.tolist() == [1_000_000 * (m + 1) for m in range(49)]
    assert config.control.rate == 1000.0
    # What the rows say: in lock, the NCO near the drive mode (15 800 Hz) throughout.
    values = dict(zip(LABELS, series.data.T))
    assert np.all(values['locked'] == 1.0)
    assert np.all(np.abs(values['frequency_hz'] - config.drive.frequency) < 1.0)
    assert np.all(values['amplitude_m'] > 0.0)


def test_the_recording_declares_control_a_block_topic(recording):
    meta = read_metadata(recording, METADATA_NAME)
    assert TOPIC in json.loads(meta['block_topics'])
    assert TOPIC in json.loads(meta['record_topics'])
    assert block_end_times_ns(recording) == BLOCK_ENDS_NS
    with open(recording, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    (channel,) = [c for c in summary.channels.values() if c.topic == TOPIC]
    schema = summary.schemas[channel.schema_id]
    assert (schema.name, schema.encoding) == ('std_msgs/msg/Float64MultiArray', 'ros2msg')
    assert schema.data.decode() == message_definition('std_msgs/msg/Float64MultiArray')
    (profile,) = yaml.safe_load(channel.metadata['offered_qos_profiles'])
    # The block topics' QoS (ros/qos.py): reliable, volatile, keep last 50.
    assert (profile['depth'], profile['reliability'], profile['durability']) == (
        50, 'reliable', 'volatile')


def test_resimulation_reproduces_the_control_rows(recording, tmp_path):
    again = tmp_path / 'again.mcap'
    assert cli.main(['run', '--from', str(recording), '-o', str(again), '--no-progress']) == 0
    a, b = read_block_topic(recording, 'control'), read_block_topic(again, 'control')
    assert a.end_ns == b.end_ns and np.array_equal(a.data, b.data)


def record_blocks(path, config, blocks):
    """Record ``blocks`` through a RosSink as a run with ``config`` would."""
    names = Simulator(config).channel_names
    sink = RosSink(names, NS, recorder=RunRecorder(str(path), config, names, NS),
                   frame_id=config.gyro.frame_id)
    try:
        for block in blocks:
            sink.block(block)
    finally:
        sink.close()
    return path


@pytest.mark.parametrize('decimation', [7, 400])
def test_decimation_keeps_every_update(tmp_path, direct, decimation):
    """``record.decimation`` thins the output samples, never the loop's updates."""
    config, blocks = direct
    thinned = paper_config({**to_flat(config), 'record.decimation': decimation})
    assert thinned.run.record_decimation == decimation
    path = record_blocks(tmp_path / 'decimated.mcap', thinned, blocks)
    kept = read_block_topic(path, 'control')
    assert kept.end_ns == BLOCK_ENDS_NS
    assert np.array_equal(kept.data, np.concatenate([rows(b) for b in blocks]))
    # ... while the output samples are thinned (the control that decimation is on): of the
    # samples 1 ... 10 000, those whose index is a multiple of N.
    modal = read_block_topic(path, 'modal_displacement')
    assert len(modal.data) == sum(len(b) for b in blocks) // decimation


def test_record_topics_selects_control(tmp_path, direct):
    config, blocks = direct
    only = paper_config({**to_flat(config), 'record.topics': ['control']})
    path = record_blocks(tmp_path / 'only.mcap', only, blocks)
    counts = {}
    for m in read_messages(path):
        counts[m.topic] = counts.get(m.topic, 0) + 1
    assert counts == {TOPIC: len(blocks)}
    without = paper_config({**to_flat(config), 'record.topics': ['radial_gap', 'rate']})
    path = record_blocks(tmp_path / 'without.mcap', without, blocks)
    assert TOPIC not in {m.topic for m in read_messages(path)}


def test_an_open_loop_recording_has_no_control_topic(tmp_path):
    # Open loop the run has no loop updates and the node no ~/control, whatever record.topics.
    config = paper_config({'drive.start_on': 'rest', 'modes.companions': True,
                           'gyro.enabled': True, 'output.rate': 20000.0,
                           'record.topics': ['control', 'radial_gap']})
    run = Run(config)
    block = run.advance(200)
    assert block.control is None
    path = record_blocks(tmp_path / 'open.mcap', config, [block])
    with open(path, 'rb') as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert TOPIC not in topics and f'{NS}/radial_gap' in topics


def test_control_block_layout_and_refusal():
    empty = conversions.control_block(ControlSamples(t=np.zeros(0),
                                                     values=np.zeros((0, len(CONTROL_CHANNELS)))))
    assert [(d.label, d.size, d.stride) for d in empty.layout.dim] == [
        ('sample', 0, 0), (','.join(LABELS), len(LABELS), len(LABELS))]
    assert len(empty.data) == 0
    t = np.array([1e-3, 2e-3])
    values = np.arange(2.0 * len(CONTROL_CHANNELS)).reshape(2, -1)
    labels, data = conversions.block_arrays(conversions.control_block(ControlSamples(t, values)))
    assert labels == LABELS and np.array_equal(data, np.column_stack([t, values]))
    with pytest.raises(ValueError, match='control values have shape'):
        conversions.control_block(ControlSamples(t, values[:, :-1]))
