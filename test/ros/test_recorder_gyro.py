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
Tests of the gyroscope's topics in the sink and the recorder.

``~/rate``, ``~/demodulator`` and ``~/angular_rate``.

The blocks carry synthetic :class:`RateSamples` / :class:`DemodSamples` built here (the
electronics that produce them are tested elsewhere), so what is tested is the plumbing: the
messages, their times and order in the file, decimation, topic selection and the reader.
Recordings are read back with ``mcap`` + ``mcap_ros2`` and ``rosbags``, which share no code
with ours.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import dataclasses
import functools
import math
import pathlib

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from ring_gyro_sim import run as run_mod
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.gyro.electronics import DEMOD_CHANNELS, DemodSamples, RateSamples
from ring_gyro_sim.core.gyro.validity import NOT_MEASURED_VARIANCE
from ring_gyro_sim.core.params import paper_config
from ring_gyro_sim.recording.reader import (
    block_end_times_ns, read_angular_rate, read_block_topic, read_messages, read_metadata,
    read_rate)
from ring_gyro_sim.recording.recover import recover
from ring_gyro_sim.recording.schemas import message_definition
from ring_gyro_sim.recording.writer import BagWriter
from ring_gyro_sim.ros import conversions
from ring_gyro_sim.ros import recorder as recorder_mod
from ring_gyro_sim.ros.recorder import METADATA_NAME, RunRecorder
from ring_gyro_sim.ros.sinks import Publishers, RosSink
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml
# isort: on

NS = '/ring_gyro'
# 20 kHz output in 10 ms blocks (200 samples); rate output at 1 kHz: every 20th sample, 10 rate
# samples per block; every sample recorded (the default record.decimation keeps one in 200).
GYRO = {'drive.start_on': 'rest', 'modes.companions': True, 'gyro.enabled': True,
        'output.rate': 20000.0, 'output.block_duration': 0.01, 'gyro.output_rate': 1000.0,
        'gyro.frame_id': 'gyro_link', 'record.decimation': 1}
PERIOD_NS = 50_000
RATIO = 20
BLOCKS = 4


@pytest.fixture(scope='module')
def samples():
    """Return 4 blocks of real samples of a gyroscope configuration (at rest: zeros)."""
    sim = Simulator(paper_config(GYRO))
    return [sim.advance_samples(200) for _ in range(BLOCKS)]


def gyro_block(samples, k):
    """Return block k with synthetic rate and demodulator outputs (distinct, exact values)."""
    s = samples[k]
    first = 200 * k
    rate_t = s.t[RATIO - 1::RATIO]  # the global samples 20, 40, ... (sample i at i * period)
    rate = RateSamples(t=rate_t, rate=0.1 + 1e-3 * np.arange(first, first + len(rate_t)),
                       quadrature=np.zeros(len(rate_t)))
    values = np.arange(4 * len(s.t), dtype=np.float64).reshape(len(s.t), 4) + 1e4 * k
    return run_mod.Block(samples=s, end_ns=(first + 200) * PERIOD_NS, first_index=first,
                         rate=rate, demod=DemodSamples(t=s.t, values=values * 1e-6))


def record(path, samples, values=GYRO, inputs=(), rate_variance=0.0, publishers=None):
    """Record the 4 synthetic blocks through a RosSink; ``inputs`` act before their block."""
    config = paper_config(values)
    names = Simulator(config).channel_names
    sink = RosSink(names, NS, recorder=RunRecorder(str(path), config, names, NS),
                   publishers=publishers, frame_id=config.gyro.frame_id,
                   rate_variance=rate_variance)
    pending = sorted(inputs, key=lambda e: e.at_ns)
    try:
        for k in range(BLOCKS):
            block = gyro_block(samples, k)
            while pending and pending[0].at_ns <= block.end_ns:
                sink.input(pending.pop(0))  # as Run flushes the inputs before a block
            sink.block(block)
    finally:
        sink.close()
    return path


def mcap_decoded(path, topic):
    """Return [(log time, message)] of a topic, decoded by mcap_ros2."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        return [(message.log_time, msg) for _, _, message, msg in
                reader.iter_decoded_messages(topics=[topic])]


def test_rate_is_one_imu_per_sample_stamped_and_logged_at_its_time(tmp_path, samples):
    path = record(tmp_path / 'gyro.mcap', samples)
    got = mcap_decoded(path, f'{NS}/rate')
    expected = [gyro_block(samples, k).rate for k in range(BLOCKS)]
    t_s = np.concatenate([r.t for r in expected])
    rate = np.concatenate([r.rate for r in expected])
    assert len(got) == BLOCKS * 10
    # Stamp = log time = the sample time on the output grid: samples 20, 40, ... of 50 us.
    times = [RATIO * PERIOD_NS * (i + 1) for i in range(len(got))]
    assert [t for t, _ in got] == times
    assert [m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec for _, m in got] == times
    assert np.array_equal(np.rint(t_s * 1e9).astype(int), times)
    for (_, m), z in zip(got, rate):
        assert m.header.frame_id == 'gyro_link'
        assert m.angular_velocity.z == z  # bit for bit
        assert (m.angular_velocity.x, m.angular_velocity.y) == (0.0, 0.0)
        # REP-145 / Imu.msg: -1 in element 0 = not estimated; all zeros = covariance unknown.
        assert list(m.orientation_covariance) == [-1.0] + [0.0] * 8
        assert list(m.linear_acceleration_covariance) == [-1.0] + [0.0] * 8
        assert list(m.angular_velocity_covariance) == [0.0] * 9
        assert (m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w) == (
            0.0, 0.0, 0.0, 1.0)
    series = read_rate(path)
    assert series.t_ns.tolist() == times and np.array_equal(series.rate, rate)
    assert series.frame_id == 'gyro_link' and series.covariance.shape == (40, 9)


ROTATION = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
"""A base-link-to-sensor rotation, as robot_localization applies one to a covariance."""


def test_a_known_rate_variance_fills_z_and_marks_x_y_as_unmeasured(tmp_path, samples):
    variance = 4e-6  # (rad/s)^2: any positive value
    path = record(tmp_path / 'var.mcap', samples, rate_variance=variance)
    for _, m in mcap_decoded(path, f'{NS}/rate'):
        cov = np.asarray(m.angular_velocity_covariance).reshape(3, 3)
        assert cov[2, 2] == variance
        # x and y not measured: huge but finite, so that a filter's R C R^T stays finite
        # (infinity made robot_localization's rotated covariance NaN: 0 * inf)
        assert cov[0, 0] == cov[1, 1] == NOT_MEASURED_VARIANCE == 1e6
        assert np.count_nonzero(cov) == 3
        rotated = ROTATION @ cov @ ROTATION.T
        assert np.all(np.isfinite(rotated)) and np.all(np.isfinite(np.eye(3) @ cov))
    sink = RosSink({}, NS)
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match='rate_variance'):
            sink.rate_variance = bad
    assert sink.rate_variance == 0.0


def test_demodulator_is_a_block_topic_laid_out_as_the_others(tmp_path, samples):
    path = record(tmp_path / 'demod.mcap', samples)
    got = mcap_decoded(path, f'{NS}/demodulator')
    assert [t for t, _ in got] == [200 * PERIOD_NS * (k + 1) for k in range(BLOCKS)]
    for k, (_, msg) in enumerate(got):
        dims = msg.layout.dim
        assert (dims[0].label, dims[0].size, dims[0].stride) == ('sample', 200, 200 * 5)
        assert (dims[1].label, dims[1].size, dims[1].stride) == (
            't,sense_i,sense_q,drive_i,drive_q', 5, 5)
        block = gyro_block(samples, k)
        assert np.array_equal(np.array(msg.data).reshape(200, 5),
                              np.column_stack([block.samples.t, block.demod.values]))
    series = read_block_topic(path, 'demodulator')
    assert series.labels == ['t', *DEMOD_CHANNELS]
    assert series.data.shape == (BLOCKS * 200, 5)
    assert series.end_ns == [t for t, _ in got]
    meta = read_metadata(path, METADATA_NAME)
    assert f'{NS}/demodulator' in yaml.safe_load(meta['block_topics'])
    assert block_end_times_ns(path) == [t for t, _ in got]


def test_schemas_and_qos_of_the_gyro_channels(tmp_path, samples):
    path = record(tmp_path / 'schemas.mcap', samples)
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    by_topic = {c.topic: c for c in summary.channels.values()}
    expected = {f'{NS}/rate': ('sensor_msgs/msg/Imu', 500),
                f'{NS}/demodulator': ('std_msgs/msg/Float64MultiArray', 50),
                f'{NS}/angular_rate': ('geometry_msgs/msg/Vector3Stamped', 1000)}
    for topic, (type_name, depth) in expected.items():
        channel = by_topic[topic]
        schema = summary.schemas[channel.schema_id]
        assert (schema.name, schema.encoding) == (type_name, 'ros2msg')
        assert schema.data.decode() == message_definition(type_name)
        (profile,) = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert (profile['depth'], profile['reliability'], profile['durability']) == (
            depth, 'reliable', 'volatile')


def test_rates_that_acted_are_recorded_in_log_time_order(tmp_path, samples):
    """An angular rate acting inside a block lands between the rate samples around it."""
    acted = [run_mod.AngularRate(z=0.174533, at_ns=1_234_567),  # in block 0, between samples
             run_mod.AngularRate(z=-0.174533, at_ns=25_000_000, x=0.5)]  # in block 2
    path = record(tmp_path / 'inputs.mcap', samples, inputs=acted)
    with open(path, 'rb') as stream:
        in_file = [(c.topic, m.log_time) for _, c, m in
                   make_reader(stream).iter_messages(log_time_order=False)]
    times = [t for _, t in in_file]
    assert times == sorted(times), in_file
    got = mcap_decoded(path, f'{NS}/angular_rate')
    assert [t for t, _ in got] == [1_234_567, 25_000_000]
    assert [(m.vector.z, m.vector.x) for _, m in got] == [(0.174533, 0.0), (-0.174533, 0.5)]
    assert [m.header.stamp.nanosec + m.header.stamp.sec * 10 ** 9 for _, m in got] == [
        1_234_567, 25_000_000]
    t_ns, z = read_angular_rate(path)
    assert t_ns.tolist() == [1_234_567, 25_000_000] and z.tolist() == [0.174533, -0.174533]
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([pathlib.Path(path)], default_typestore=store) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts[f'{NS}/rate'] == 40 and counts[f'{NS}/angular_rate'] == 2
        rate = [c for c in reader.connections if c.topic == f'{NS}/rate']
        first = next(iter(reader.messages(connections=rate)))
        msg = reader.deserialize(first[2], rate[0].msgtype)
        assert msg.angular_velocity.z == gyro_block(samples, 0).rate.rate[0]
        assert msg.header.frame_id == 'gyro_link'


def test_recorded_angular_rates_carry_the_sensor_frame(tmp_path, samples):
    """The recorded truth is a rate about z of the sensor frame: it names that frame."""
    acted = [run_mod.AngularRate(z=0.174533, at_ns=1_234_567)]
    path = record(tmp_path / 'frame.mcap', samples, inputs=acted)
    ((_, msg),) = mcap_decoded(path, f'{NS}/angular_rate')
    assert msg.header.frame_id == 'gyro_link'  # gyro.frame_id, as ~/rate
    ((_, imu), *_) = mcap_decoded(path, f'{NS}/rate')
    assert imu.header.frame_id == msg.header.frame_id


@pytest.mark.parametrize('decimation', [7, 300])
def test_decimation_thins_the_demodulator_never_the_rate(tmp_path, samples, decimation):
    full = record(tmp_path / 'full.mcap', samples)
    path = record(tmp_path / 'decimated.mcap', samples,
                  {**GYRO, 'record.decimation': decimation})
    original = read_block_topic(full, 'demodulator').data
    index = np.rint(original[:, 0] / (PERIOD_NS * 1e-9)).astype(int)
    kept = read_block_topic(path, 'demodulator')
    assert np.array_equal(kept.data, original[index % decimation == 0])
    assert kept.end_ns == read_block_topic(full, 'demodulator').end_ns  # every block is there
    a, b = read_rate(full), read_rate(path)
    assert np.array_equal(a.t_ns, b.t_ns) and np.array_equal(a.rate, b.rate)
    assert len(b.t_ns) == BLOCKS * 10


class _Publisher:
    """Keeps what it is given to publish; one subscriber is matched."""

    def __init__(self):
        self.messages = []

    def publish(self, msg):
        self.messages.append(msg)

    def get_subscription_count(self):
        return 1


@pytest.mark.parametrize('decimation', [1, 7, 300])
def test_published_blocks_hold_every_sample_and_record_as_offline(
        tmp_path, samples, decimation):
    # Offline nothing publishes the blocks: RosSink builds them from the recorded rows alone.
    # Published, they hold every sample and the recorder decimates its copy. One recording.
    values = {**GYRO, 'record.decimation': decimation}
    offline = record(tmp_path / 'offline.mcap', samples, values)
    blocks = {name: _Publisher() for name in conversions.OUTPUT_TOPICS + ('demodulator',)}
    publishers = Publishers(blocks, _Publisher(), rate=_Publisher())
    live = record(tmp_path / 'live.mcap', samples, values, publishers=publishers)
    for name in conversions.OUTPUT_TOPICS + ('demodulator',):
        a, b = read_block_topic(offline, name), read_block_topic(live, name)
        assert a.labels == b.labels and a.end_ns == b.end_ns, name
        assert np.array_equal(a.data, b.data), name
        assert len(a.data) == BLOCKS * 200 // decimation  # the multiples of N in 1..800
        published = [conversions.block_arrays(m)[1] for m in blocks[name].messages]
        assert [len(x) for x in published] == [200] * BLOCKS
    a, b = read_rate(offline), read_rate(live)
    assert np.array_equal(a.t_ns, b.t_ns) and np.array_equal(a.rate, b.rate)


class _Unwatched(_Publisher):
    """A publisher nobody subscribes to."""

    def get_subscription_count(self):
        return 0


def test_blocks_nobody_subscribes_to_are_not_published_and_record_as_offline(
        tmp_path, samples):
    # Publishers.publishes_blocks: no subscriber matched on any block topic, RosSink builds
    # the recorded rows only, as offline, and publishes no block; ~/rate goes out as before.
    values = {**GYRO, 'record.decimation': 7}
    offline = record(tmp_path / 'offline.mcap', samples, values)
    blocks = {name: _Unwatched() for name in conversions.OUTPUT_TOPICS + ('demodulator',)}
    rate = _Publisher()
    live = record(tmp_path / 'live.mcap', samples, values,
                  publishers=Publishers(blocks, _Publisher(), rate=rate))
    assert not any(p.messages for p in blocks.values())
    assert len(rate.messages) == BLOCKS   # one list of ~/rate messages per block
    for name in conversions.OUTPUT_TOPICS + ('demodulator',):
        a, b = read_block_topic(offline, name), read_block_topic(live, name)
        assert a.end_ns == b.end_ns and np.array_equal(a.data, b.data), name


@pytest.mark.parametrize('kept', [[], ['radial_gap'], ['demodulator', 'modal_displacement']])
def test_a_block_topic_nothing_records_or_publishes_is_not_built(
        tmp_path, samples, monkeypatch, kept):
    # Neither published (no subscriber) nor recorded (record.topics): its CDR is never
    # packed, the one the recording keeps is, and ~/rate goes out as ever.
    built = []

    def block_cdr(columns, labels):
        built.append(list(labels))
        return conversions.cdr.float64_multiarray(np.column_stack(columns), labels)

    monkeypatch.setattr(conversions, 'block_cdr', block_cdr)
    blocks = {name: _Unwatched() for name in conversions.OUTPUT_TOPICS + ('demodulator',)}
    rate = _Publisher()
    path = record(tmp_path / 'kept.mcap', samples, {**GYRO, 'record.topics': ['rate'] + kept},
                  publishers=Publishers(blocks, _Publisher(), rate=rate))
    names = Simulator(paper_config(GYRO)).channel_names
    names['demodulator'] = list(conversions.DEMOD_CHANNELS)
    assert sorted(built) == sorted(['t'] + names[name] for name in kept for _ in range(BLOCKS))
    assert len(rate.messages) == BLOCKS
    recorded = {m.topic for m in read_messages(path)}
    assert recorded == {f'{NS}/{name}' for name in ['rate'] + kept}


def test_the_sink_asks_for_the_channels_only_when_it_publishes_or_records_them(
        tmp_path, samples):
    # RosSink.needs_channels: a matched subscriber on a block topic, or radial_gap or
    # sense_electrodes recorded. A block without them (computed while nobody watched) is
    # not published to a subscriber matched meanwhile; the rest goes out as ever.
    config = paper_config(GYRO)
    names = Simulator(config).channel_names
    unwatched = {name: _Unwatched() for name in conversions.OUTPUT_TOPICS + ('demodulator',)}
    assert not RosSink(names, NS, publishers=Publishers(unwatched, _Publisher())).needs_channels
    watched = {**unwatched, 'radial_gap': _Publisher()}
    rate = _Publisher()
    publishers = Publishers(watched, _Publisher(), rate=rate)
    assert RosSink(names, NS, publishers=publishers).needs_channels
    for kept, needs in ((['rate', 'modal_displacement', 'demodulator'], False),
                        (['radial_gap'], True), (['sense_electrodes'], True)):
        path = tmp_path / f'{kept[-1]}.mcap'
        recorder = RunRecorder(str(path), paper_config({**GYRO, 'record.topics': kept}),
                               names, NS)
        sink = RosSink(names, NS, recorder=recorder,
                       publishers=Publishers(unwatched, _Publisher()))
        assert sink.needs_channels == needs, kept
        sink.close()
    path = tmp_path / 'without.mcap'
    sink = RosSink(names, NS, recorder=RunRecorder(
        str(path), paper_config({**GYRO, 'record.topics': ['rate', 'modal_displacement']}),
        names, NS), publishers=publishers, frame_id='gyro_link')
    for k in range(BLOCKS):
        block = gyro_block(samples, k)
        s = block.samples
        sink.block(dataclasses.replace(block, samples=dataclasses.replace(
            s, gap=None, min_gap=None, capacitance=None, smallest_gap=s.least_gap())))
    sink.close()
    assert not any(pub.messages for pub in watched.values())
    assert len(rate.messages) == BLOCKS
    assert len(read_block_topic(path, 'modal_displacement').data) == BLOCKS * 200


def test_gyro_topics_only_in_a_gyroscope_run(tmp_path, samples):
    # Without gyro.enabled the node has none of them, whatever record.topics says.
    config = paper_config({**GYRO, 'gyro.enabled': False,
                           'record.topics': ['rate', 'demodulator', 'radial_gap']})
    names = Simulator(config).channel_names
    path = tmp_path / 'resonator.mcap'
    with RunRecorder(str(path), config, names, NS) as rec:
        rec.outputs(conversions.output_blocks(samples[0], names), 200 * PERIOD_NS)
        with pytest.raises(Exception, match='gyro.enabled'):
            rec.angular_rate(0, 0.1)
    with open(path, 'rb') as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert not topics & {f'{NS}/rate', f'{NS}/demodulator', f'{NS}/angular_rate'}
    assert f'{NS}/radial_gap' in topics
    # With it, record.topics selects among them; the rotation input is always recorded.
    path = record(tmp_path / 'rate_only.mcap', samples, {**GYRO, 'record.topics': ['rate']})
    counts = {}
    for m in read_messages(path):
        counts[m.topic] = counts.get(m.topic, 0) + 1
    assert counts == {f'{NS}/rate': 40}
    with open(path, 'rb') as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert f'{NS}/angular_rate' in topics and f'{NS}/demodulator' not in topics


def test_a_killed_gyro_recording_recovers_its_rate(tmp_path, samples, monkeypatch):
    # Small chunks (4 kB, ~a tenth of a block), so that half a file holds complete chunks.
    monkeypatch.setattr(recorder_mod, 'BagWriter', functools.partial(BagWriter, chunk_size=4096))
    path = record(tmp_path / 'whole.mcap', samples, {**GYRO, 'record.compression': 'none'})
    data = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) // 2])  # as a kill -9 in the middle leaves it (no summary)
    fixed = tmp_path / 'fixed.mcap'
    recover(str(cut), str(fixed))
    survived = mcap_decoded(fixed, f'{NS}/rate')
    whole = mcap_decoded(path, f'{NS}/rate')
    assert 0 < len(survived) <= len(whole)
    assert [(t, m.angular_velocity.z) for t, m in survived] == [
        (t, m.angular_velocity.z) for t, m in whole[:len(survived)]]


def test_each_rate_sample_carries_its_own_variance(tmp_path, samples):
    # RateSamples.variance (core.gyro.validity): what each sample is worth, published per
    # message; a sample that is not a measurement says so with the same finite variance as
    # the unmeasured axes.
    rate = gyro_block(samples, 0).rate
    variance = np.full(len(rate), 2e-6)
    variance[3:] = NOT_MEASURED_VARIANCE
    msgs = RosSink({}, NS, frame_id='f', rate_variance=1e-6).rate_messages(
        RateSamples(t=rate.t, rate=rate.rate, quadrature=rate.quadrature, variance=variance))
    zz = [m.angular_velocity_covariance[8] for _, m in msgs]
    assert zz == variance.tolist()
    assert all(m.angular_velocity_covariance[0] == NOT_MEASURED_VARIANCE for _, m in msgs)
