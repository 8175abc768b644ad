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
Tests of offline.py: run summaries, recordings, re-simulation, progress bar, input errors.

Recordings are read back with readers that share no code with ours (``mcap`` with the
``mcap_ros2`` decoder, and ``rosbags``); outputs are compared as decoded float arrays, never as
CDR bytes (rclpy leaves the CDR alignment padding uninitialised).
"""

import io
import math
import pathlib
import sys
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
import numpy as np
import pytest
from ring_gyro_sim import offline, progress, run
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro.operating_point import start_state
from ring_gyro_sim.core.params import build_config, paper_config, STANDARD_GRAVITY
from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.recording.reader import read_block_topic, read_rate
from ring_gyro_sim.run import (BaseAcceleration, DriveAmplitude, DriveFrequency,
                               ParameterChange, Shock)
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores

NS = '/ring_gyro'
BLOCK_TOPICS = [f'{NS}/modal_displacement', f'{NS}/radial_gap', f'{NS}/sense_electrodes']
SHOCK_10000G = 10_000 * STANDARD_GRAVITY


def shock_from_rest(peak=SHOCK_10000G, at_s=0.0, **extra):
    """Paper configuration, drive off, one half-sine shock (x) at ``at_s``."""
    values = {'drive.amplitude': 0.0, 'drive.start_on': 'rest',
              'scenario.shock_times': [at_s], 'scenario.shock_peaks': [peak]}
    values.update(extra)
    return paper_config(values)


def decoded(path, topics=None):
    """Return {topic: [(log_time_ns, message)]} decoded by mcap_ros2 (independent of ours)."""
    out = {}
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, message, msg in reader.iter_decoded_messages(topics=topics):
            out.setdefault(channel.topic, []).append((message.log_time, msg))
    return out


def block_arrays(path):
    """Return {block topic: (labels, [log times], [(K, C) arrays])} of a recording."""
    result = {}
    for topic, items in decoded(path, BLOCK_TOPICS).items():
        labels = items[0][1].layout.dim[1].label
        arrays = [np.array(m.data, dtype=np.float64).reshape(
            m.layout.dim[0].size, m.layout.dim[1].size) for _, m in items]
        result[topic] = (labels, [t for t, _ in items], arrays)
    return result


def assert_same_outputs(path_a, path_b):
    """Both recordings hold the same blocks: labels, log times and values, bit for bit."""
    a, b = block_arrays(path_a), block_arrays(path_b)
    assert sorted(a) == sorted(b) == sorted(BLOCK_TOPICS)
    for topic in BLOCK_TOPICS:
        assert a[topic][0] == b[topic][0]
        assert a[topic][1] == b[topic][1], f'{topic}: block log times differ'
        assert len(a[topic][2]) == len(b[topic][2])
        for k, (x, y) in enumerate(zip(a[topic][2], b[topic][2])):
            assert np.array_equal(x, y), f'{topic} block {k}: values differ'


def direct_run(config, duration_s, state=None):
    """Return (sim, samples) of one Simulator advanced over the whole duration at once."""
    sim = Simulator(config)
    if state is not None:
        sim.set_state(*state)
    return sim, sim.advance(duration_s)


# ------------------------------------------------------------------ summary


def test_summary_matches_direct_simulator_run():
    # Default configuration: starts on the upper branch of the drive, a 2000 g shock at 5 ms.
    config = paper_config({'scenario.shock_times': [0.005],
                           'scenario.shock_peaks': [2000 * STANDARD_GRAVITY]})
    summary = offline.run_offline(config, 0.03, progress=False)
    sim, out = direct_run(config, 0.03, start_state(config))
    assert summary.sim_time_s == pytest.approx(0.03, abs=1e-12)
    assert summary.samples == len(out) == 6000
    assert summary.wall_time_s > 0.0
    assert summary.real_time_factor == pytest.approx(summary.sim_time_s / summary.wall_time_s)
    assert list(summary.peak_abs_m) == list(summary.final_abs_m) == ['q1', 'q2', 'q3']
    tail = int(round(run.SUMMARY_WINDOW_S / sim.period_s))
    for i, name in enumerate(sim.coordinates):
        assert summary.peak_abs_m[name] == pytest.approx(np.max(np.abs(out.q[:, i])),
                                                         rel=1e-12, abs=0.0)
        assert summary.final_abs_m[name] == pytest.approx(np.max(np.abs(out.q[-tail:, i])),
                                                          rel=1e-12, abs=0.0)
    assert summary.min_gap_m == pytest.approx(np.min(out.min_gap), rel=1e-12)
    assert summary.contact is False and summary.status == 'finished'
    # The shock did something: q1 moved by several 100 nm, q2 is still the driven ~0.43 um.
    assert summary.peak_abs_m['q1'] > 0.5e-6
    assert 0.35e-6 < summary.final_abs_m['q2'] < 0.5e-6


def test_10000g_from_rest_reaches_55_to_60_percent_of_the_gap():
    config = shock_from_rest()
    summary = offline.run_offline(config, 0.01, progress=False)
    gap = config.electrodes.gap
    peak = summary.peak_abs_m
    print(f'10 000 g from rest: peak q1 {peak["q1"] * 1e6:.3f} um '
          f'({100 * peak["q1"] / gap:.1f} % of d_g), q2 {peak["q2"] * 1e6:.3f} um, '
          f'q3 {peak["q3"] * 1e6:.3f} um, smallest gap {summary.min_gap_m * 1e6:.3f} um')
    assert 0.55 * gap < peak['q1'] < 0.60 * gap
    assert not summary.contact
    # q2 and q3 grow through the q1^2 terms and add to q1 at theta = 0: the smallest gap is
    # well below d_g - peak q1 ...
    assert summary.min_gap_m < gap - peak['q1'] - 0.3e-6
    # ... but never below what |w| <= sum |q_n| allows.
    assert summary.min_gap_m >= gap - sum(peak.values()) - 1e-12


# ------------------------------------------------------------------ recording


@pytest.fixture(scope='module')
def shock_recording(tmp_path_factory):
    """Record a 25 ms run (10 000 g from rest) to MCAP; return (path, config, summary)."""
    path = tmp_path_factory.mktemp('offline') / 'shock.mcap'
    config = shock_from_rest(**{'record.decimation': 1})  # every sample
    summary = offline.run_offline(config, 0.025, output=str(path), progress=False)
    return path, config, summary


def test_recording_is_a_ros2_bag_for_mcap_ros2(shock_recording):
    path, config, summary = shock_recording
    assert summary.output == str(path)
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        info = reader.get_summary()
        for schema in info.schemas.values():
            assert schema.encoding == 'ros2msg'
            assert schema.name.count('/msg/') == 1, schema.name
        topics = {}
        for channel_id, channel in info.channels.items():
            assert channel.message_encoding == 'cdr'
            topics[channel.topic] = info.statistics.channel_message_counts.get(channel_id, 0)
    # output.rate x duration / block size blocks per output topic (the last one partial).
    per_block = int(round(config.run.block_duration * config.run.output_rate))
    expected = math.ceil(round(0.025 * config.run.output_rate) / per_block)
    assert expected == 3
    for topic in BLOCK_TOPICS:
        assert topics[topic] == expected
    assert topics[f'{NS}/shock'] == 1  # the scheduled shock, recorded as an input
    assert topics['/diagnostics'] >= 1
    blocks = block_arrays(path)
    labels, times, arrays = blocks[f'{NS}/modal_displacement']
    assert labels == 't,q1,q2,q3'
    assert [len(a) for a in arrays] == [per_block, per_block, 1000]
    t = np.concatenate([a[:, 0] for a in arrays])
    period = 1.0 / config.run.output_rate
    # Contiguous blocks, one output period apart; log time = last sample of the block.
    np.testing.assert_allclose(np.diff(t), period, rtol=1e-9)
    assert t[0] == pytest.approx(period)
    assert times == [int(round(a[-1, 0] * 1e9)) for a in arrays]
    # The recorded samples are the Simulator's.
    _, out = direct_run(config, 0.025)
    q = np.concatenate([a[:, 1:] for a in arrays])
    assert np.array_equal(q, out.q)
    gap_labels, _, gap_arrays = blocks[f'{NS}/radial_gap']
    assert gap_labels.split(',')[-1] == 'min'
    assert np.min(np.concatenate(gap_arrays)[:, -1]) == summary.min_gap_m


def test_recording_is_readable_by_rosbags(shock_recording):
    path, config, _ = shock_recording
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([pathlib.Path(path)], default_typestore=store) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts[f'{NS}/modal_displacement'] == 3
        shocks = [c for c in reader.connections if c.topic == f'{NS}/shock']
        assert shocks[0].msgtype == 'geometry_msgs/msg/Vector3Stamped'
        (_, log_time, raw), = list(reader.messages(connections=shocks))
        msg = reader.deserialize(raw, shocks[0].msgtype)
        assert log_time == 0
        assert msg.vector.x == SHOCK_10000G and msg.vector.y == 0.0
        blocks = [c for c in reader.connections if c.topic == f'{NS}/modal_displacement']
        first = next(iter(reader.messages(connections=blocks)))
        block = reader.deserialize(first[2], blocks[0].msgtype)
        assert block.layout.dim[0].label == 'sample'
        assert block.layout.dim[0].size == 2000 and block.layout.dim[0].stride == 8000
        assert block.data.shape == (8000,)


def test_resimulation_is_bit_identical(tmp_path, shock_recording):
    path, _, summary = shock_recording
    again = offline.resimulate(str(path), str(tmp_path / 'again.mcap'), progress=False)
    assert_same_outputs(path, tmp_path / 'again.mcap')
    assert again.peak_abs_m == summary.peak_abs_m
    assert again.min_gap_m == summary.min_gap_m
    # The scheduled shock is applied once, not twice (the recording holds it as an input too).
    inputs = decoded(tmp_path / 'again.mcap', [f'{NS}/shock'])
    assert len(inputs[f'{NS}/shock']) == 1


def test_resimulation_from_the_upper_branch_with_inputs(tmp_path):
    # Drive on (start state from the metadata) plus inputs of every kind the node records.
    config = paper_config({})
    original = tmp_path / 'run.mcap'
    inputs = [Shock(2000 * STANDARD_GRAVITY, 0.0, at_ns=2_000_000),
              DriveFrequency(15790.0, at_ns=4_000_000),
              BaseAcceleration(500.0, 0.0, at_ns=6_000_000),
              BaseAcceleration(0.0, 0.0, at_ns=6_500_000),
              DriveAmplitude(0.05, at_ns=9_000_000)]
    offline.run_offline(config, 0.02, output=str(original), progress=False, inputs=inputs)
    offline.resimulate(str(original), str(tmp_path / 'again.mcap'), progress=False)
    assert_same_outputs(original, tmp_path / 'again.mcap')
    recorded = decoded(original, [f'{NS}/shock', f'{NS}/drive/frequency',
                                  f'{NS}/drive/amplitude', f'{NS}/base_acceleration'])
    assert [t for t, _ in recorded[f'{NS}/shock']] == [2_000_000]
    assert recorded[f'{NS}/drive/frequency'][0][1].data == 15790.0
    assert len(recorded[f'{NS}/base_acceleration']) == 2


def test_parameter_changes_scheduled_ahead_apply_at_their_time(tmp_path):
    # The drive is switched on (5 m/s^2) at 8 ms and off again at 12 ms by run-time parameter
    # changes; q2 is exactly zero before 8 ms and rings after.
    config = paper_config({'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                           'record.decimation': 1})
    original = tmp_path / 'params.mcap'
    inputs = [ParameterChange({'drive.amplitude': 5.0}, at_ns=8_000_000),
              ParameterChange({'drive.amplitude': 0.0}, at_ns=12_000_000)]
    offline.run_offline(config, 0.02, output=str(original), progress=False, inputs=inputs)
    events = decoded(original, [f'{NS}/events/parameters'])[f'{NS}/events/parameters']
    assert [t for t, _ in events] == [8_000_000, 12_000_000]
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert_same_outputs(original, again)
    for path in (original, again):
        _, _, arrays = block_arrays(path)[f'{NS}/modal_displacement']
        data = np.concatenate(arrays)
        t, q2 = data[:, 0], data[:, 2]
        assert np.all(q2[t <= 0.008 + 1e-12] == 0.0)
        first = t[np.nonzero(q2)[0][0]]
        assert first == pytest.approx(0.008 + 5e-6, abs=1e-9)
        # While driven, q2 grows; after 12 ms it rings down freely at about its level then.
        driven = np.max(np.abs(q2[(t > 0.011) & (t <= 0.012)]))
        free = np.max(np.abs(q2[t > 0.019]))
        assert driven > 1e-9
        assert free == pytest.approx(driven, rel=0.05)
    # Control: without the second change the drive keeps pumping q2 beyond its 12 ms level.
    pumped = offline.run_offline(config, 0.02, progress=False, inputs=inputs[:1])
    assert pumped.final_abs_m['q2'] > 1.3 * driven


def test_shock_after_a_shock_duration_change_uses_the_new_duration():
    peak = 2000 * STANDARD_GRAVITY
    rest = {'drive.amplitude': 0.0, 'drive.start_on': 'rest'}
    changed = offline.run_offline(
        paper_config(rest), 0.01, progress=False,
        inputs=[ParameterChange({'shock.duration': 20e-6}, at_ns=2_000_000),
                Shock(peak, 0.0, at_ns=5_000_000)])
    from_start = offline.run_offline(
        paper_config({**rest, 'shock.duration': 20e-6}), 0.01, progress=False,
        inputs=[Shock(peak, 0.0, at_ns=5_000_000)])
    # A 20 us pulse carries about 3x the impulse of the default 6.33 us one.
    assert changed.peak_abs_m['q1'] == pytest.approx(from_start.peak_abs_m['q1'], rel=1e-6)


# ------------------------------------------------------------------ progress bar


class _TtyBuffer(io.StringIO):
    def isatty(self):
        return True


def test_progress_bar_on_a_real_run_longer_than_its_threshold(monkeypatch):
    # The bar waits progress.DELAY_S of wall time; size the run so that it takes about 4 s.
    config = shock_from_rest(peak=0.0, **{'output.rate': 50000.0})
    probe = offline.run_offline(config, 0.2, progress=False)
    speed = probe.real_time_factor
    duration = min(60.0, round(2.0 * progress.DELAY_S * speed, 3))
    stream = _TtyBuffer()
    monkeypatch.setattr(sys, 'stderr', stream)
    start = time.perf_counter()
    summary = offline.run_offline(config, duration, progress=True)
    wall = time.perf_counter() - start
    text = stream.getvalue()
    print(f'{duration} s simulated in {wall:.2f} s; stderr: {text!r}', file=sys.__stdout__)
    assert wall > progress.DELAY_S, 'the run was too short to test the bar'
    assert '100.0%' in text
    assert f'{summary.sim_time_s:.3f}/{duration:.3f} sim s' in text
    assert text.endswith('\n')


def test_no_progress_bar_for_a_short_run(capsys):
    offline.run_offline(shock_from_rest(), 0.01)
    assert capsys.readouterr().err == ''


def test_progress_bar_lines_when_stderr_is_not_a_terminal(monkeypatch, capsys):
    # No delay: a long run seen from a pipe writes whole lines, never carriage returns.
    monkeypatch.setattr(progress, 'DELAY_S', 0.0)
    monkeypatch.setattr(progress, 'PIPE_INTERVAL_S', 0.0)
    offline.run_offline(shock_from_rest(), 0.05, progress=True)
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) >= 2, 'no progress lines for a long run'
    assert '\r' not in err
    assert '100.0%' in lines[-1] and '0.050/0.050 sim s' in lines[-1]


def test_progress_false_shows_nothing_even_for_a_long_run(monkeypatch):
    monkeypatch.setattr(progress, 'DELAY_S', 0.0)
    monkeypatch.setattr(sys, 'stderr', _TtyBuffer())
    offline.run_offline(shock_from_rest(), 0.05, progress=False)
    assert sys.stderr.getvalue() == ''


# ------------------------------------------------------------------ errors


@pytest.mark.parametrize('duration', [0.0, -0.01, math.nan, math.inf])
def test_duration_must_be_positive(duration, tmp_path):
    with pytest.raises(ParameterError, match='duration'):
        offline.run_offline(shock_from_rest(), duration, output=str(tmp_path / 'x.mcap'),
                            progress=False)
    assert not (tmp_path / 'x.mcap').exists()


def test_duration_from_the_config_defaults_to_zero_and_is_refused():
    with pytest.raises(ParameterError, match='duration'):
        offline.run_offline(shock_from_rest(), progress=False)
    # ... and is used when set.
    summary = offline.run_offline(shock_from_rest(duration=0.004), progress=False)
    assert summary.samples == 800


@pytest.mark.parametrize('text, field', [
    ('modes: {quality_factors: [-5.0, 64700.0, 170000.0]}', 'modes.quality_factors'),
    ('electrodes: {outer_voltage: abc}', 'electrodes.outer_voltage'),
    ('electrodes: {outer_voltag: 70.0}', 'electrodes.outer_voltag'),
    ('output: {rate: .nan}', 'output.rate'),
])
def test_bad_scenario_field_is_named(tmp_path, text, field):
    path = tmp_path / 'bad.yaml'
    path.write_text(f'ring_gyro:\n  ros__parameters:\n    {text}\n    duration: 0.01\n',
                    encoding='utf-8')
    with pytest.raises(ParameterError) as info:
        load_yaml(str(path))
    assert field in str(info.value)


# ------------------------------------------------------------------ gyroscope

# 20 kHz output (a whole multiple of the 1 kHz rate output), from rest: small, fast runs.
GYRO = {'drive.start_on': 'rest', 'modes.companions': True, 'gyro.enabled': True,
        'output.rate': 20000.0, 'gyro.frame_id': 'gyro_link'}
GYRO_TOPICS = [f'{NS}/rate', f'{NS}/demodulator', f'{NS}/angular_rate', f'{NS}/die_temperature']


def test_a_gyro_run_records_the_gyro_topics(tmp_path):
    path = tmp_path / 'gyro.mcap'
    offline.run_offline(paper_config(GYRO), 0.02, output=str(path), progress=False)
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert types[f'{NS}/rate'] == 'sensor_msgs/msg/Imu'
    assert types[f'{NS}/demodulator'] == 'std_msgs/msg/Float64MultiArray'
    assert types[f'{NS}/angular_rate'] == 'geometry_msgs/msg/Vector3Stamped'
    assert types[f'{NS}/die_temperature'] == 'sensor_msgs/msg/Temperature'
    assert types[f'{NS}/temperature'] == 'sensor_msgs/msg/Temperature'
    resonator = tmp_path / 'resonator.mcap'
    offline.run_offline(paper_config({**GYRO, 'gyro.enabled': False}), 0.02,
                        output=str(resonator), progress=False)
    with open(resonator, 'rb') as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert not topics & set(GYRO_TOPICS)


def test_load_recording_reads_the_angular_rates_that_acted(tmp_path):
    """--from applies the recorded rates again, except the scheduled knots (scheduled anew)."""
    from ring_gyro_sim.ros import conversions
    from ring_gyro_sim.ros.recorder import RunRecorder
    config = paper_config({**GYRO, 'scenario.rate_times': [0.0, 0.004],
                           'scenario.rate_values': [0.0, 0.174533]})
    sim = Simulator(config)
    path = tmp_path / 'rates.mcap'
    with RunRecorder(str(path), config, sim.channel_names, NS) as rec:
        rec.angular_rate(0, 0.0)  # the two knots, recorded as the run may record them
        rec.angular_rate(4_000_000, 0.174533)
        rec.angular_rate(6_000_000, -0.1, x=0.25)  # a streamed rate
        for _ in range(2):
            samples = sim.advance_samples(200)
            rec.outputs(conversions.output_blocks(samples, sim.channel_names), sim.time_ns)
    _, _, inputs, sizes, _ = offline.load_recording(str(path))
    assert sizes == [200, 200]
    assert inputs == [run.AngularRate(z=-0.1, at_ns=6_000_000, x=0.25, y=0.0)]


def test_ambient_steps_are_recorded_with_the_die_and_resimulate_bit_for_bit(tmp_path):
    """
    ~/temperature as it acted and ~/die_temperature per block; --from reproduces both.

    The die follows a step of the ambient at t_s as tau T' = T_a - T (core.thermal T1):
    T = T_a + (T_0 - T_a) exp(-(t - t_s) / tau) at each block's end, in Celsius on the topic.
    """
    tau, t_step, ambient = 0.01, 0.005, 308.15
    config = paper_config({**GYRO, 'thermal.time_constant': tau})
    t_0 = config.thermal.reference_temperature
    original = tmp_path / 'warm.mcap'
    inputs = [run.AmbientTemperature(kelvin=ambient, at_ns=int(t_step * 1e9))]
    offline.run_offline(config, 0.03, output=str(original), progress=False, inputs=inputs)
    topics = [f'{NS}/temperature', f'{NS}/die_temperature']
    a = decoded(original, topics)
    assert [(t, m.temperature + 273.15) for t, m in a[f'{NS}/temperature']] == [
        (5_000_000, ambient)]
    die = a[f'{NS}/die_temperature']
    assert [t for t, _ in die] == [10_000_000, 20_000_000, 30_000_000]
    for t_ns, m in die:
        t = t_ns * 1e-9
        expected = ambient + (t_0 - ambient) * math.exp(-(t - t_step) / tau) - 273.15
        assert m.temperature == pytest.approx(expected, abs=1e-9)
        assert m.header.frame_id == 'gyro_link' and m.variance == 0.0
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert_same_outputs(original, again)
    b = decoded(again, topics + [f'{NS}/rate'])
    assert [(t, m.temperature) for t, m in b[f'{NS}/die_temperature']] == [
        (t, m.temperature) for t, m in die]
    assert [m.angular_velocity.z for _, m in b[f'{NS}/rate']] == [
        m.angular_velocity.z for _, m in decoded(original, [f'{NS}/rate'])[f'{NS}/rate']]


def test_resimulation_with_angular_rates_is_bit_identical(tmp_path):
    """A run with streamed angular rates re-simulated from its recording: bit for bit."""
    config = paper_config(GYRO)
    original = tmp_path / 'run.mcap'
    inputs = [run.AngularRate(z=0.174533, at_ns=2_000_000),
              run.AngularRate(z=-0.174533, at_ns=11_000_000)]
    offline.run_offline(config, 0.02, output=str(original), progress=False, inputs=inputs)
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert_same_outputs(original, again)
    a, b = decoded(original, GYRO_TOPICS), decoded(again, GYRO_TOPICS)
    assert [t for t, _ in a[f'{NS}/angular_rate']] == [2_000_000, 11_000_000]
    assert len(a[f'{NS}/rate']) == 20  # 1 kHz over 20 ms
    for topic in GYRO_TOPICS:
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]], topic
    assert [m.angular_velocity.z for _, m in a[f'{NS}/rate']] == [
        m.angular_velocity.z for _, m in b[f'{NS}/rate']]
    assert all(np.array_equal(np.array(x.data), np.array(y.data)) for (_, x), (_, y) in
               zip(a[f'{NS}/demodulator'], b[f'{NS}/demodulator']))


def test_a_saturating_quantised_rate_resimulates_bit_for_bit(tmp_path):
    """The output word (gyro.range, gyro.resolution) is in the parameters: --from repeats it."""
    full_scale, lsb = math.radians(300.0), math.radians(1.0 / 80.0)
    config = build_config({'scenario.rate_times': [0.0, 0.01, 0.01],
                           'scenario.rate_values': [0.0, 0.0, math.radians(400.0)],
                           'gyro.range': full_scale, 'gyro.resolution': lsb})
    original = tmp_path / 'run.mcap'
    offline.run_offline(config, 0.06, output=str(original), progress=False)
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    a = [m for _, m in decoded(original, [f'{NS}/rate'])[f'{NS}/rate']]
    b = [m for _, m in decoded(again, [f'{NS}/rate'])[f'{NS}/rate']]
    assert len(a) == len(b) == 60
    assert [m.angular_velocity.z for m in a] == [m.angular_velocity.z for m in b]
    assert [list(m.angular_velocity_covariance) for m in a] == [
        list(m.angular_velocity_covariance) for m in b]
    z = np.array([m.angular_velocity.z for m in a])
    zz = np.array([m.angular_velocity_covariance[8] for m in a])
    at_full_scale = z == full_scale
    assert 10 < np.count_nonzero(at_full_scale) < 50  # the rise crosses the range
    assert np.all(zz[at_full_scale] == 1e6) and np.all(zz[:10] < 1e-3)
    codes = z[~at_full_scale] / lsb
    assert np.max(np.abs(codes - np.round(codes))) < 1e-9


def test_rates_replaced_or_kept_over_a_reset_resimulate_bit_for_bit(tmp_path):
    """
    The recording holds the rates as they acted, so --from reproduces a live run's arrivals.

    As a node receives them, before the first block: a rate for 25 ms, then one for 15 ms that
    replaces it (and the scheduled knot at 30 ms); before the second: a rate for 35 ms, then a
    reset, which does not stop the case turning. The 25 ms rate and the 30 ms knot never
    acted: recorded, --from applied them and diverged (as --from of a live node did).
    """
    from ring_gyro_sim.ros.recorder import RunRecorder
    from ring_gyro_sim.ros.sinks import RosSink
    config = paper_config({**GYRO, 'scenario.rate_times': [0.0, 0.03],
                           'scenario.rate_values': [0.0, 0.2]})
    original = tmp_path / 'live.mcap'
    names = Simulator(config).channel_names
    sink = RosSink(names, NS, recorder=RunRecorder(str(original), config, names, NS),
                   frame_id=config.gyro.frame_id)
    live = run.Run(config, sink=sink)
    arrivals = [[run.AngularRate(z=0.5, at_ns=25_000_000),
                 run.AngularRate(z=0.1, at_ns=15_000_000)],
                [run.AngularRate(z=-0.3, at_ns=35_000_000), run.Reset()]]
    try:
        for k in range(5):
            for event in arrivals[k] if k < len(arrivals) else ():
                live.apply(event)
            live.advance(200)
    finally:
        live.close()
    recorded = decoded(original, [f'{NS}/angular_rate'])[f'{NS}/angular_rate']
    assert [(t, m.vector.z) for t, m in recorded] == [
        (0, 0.0), (15_000_000, 0.1), (35_000_000, -0.3)]
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert_same_outputs(original, again)
    a, b = decoded(original, GYRO_TOPICS), decoded(again, GYRO_TOPICS)
    assert [m.angular_velocity.z for _, m in a[f'{NS}/rate']] == [
        m.angular_velocity.z for _, m in b[f'{NS}/rate']]


def test_a_failed_run_records_every_block_and_resimulates_bit_for_bit(tmp_path):
    """
    A run that fails on a non-finite value records every block, and --from reproduces it.

    No block after a non-finite value is withheld: a recording with holes would make --from
    fail ('reset: acts at the current simulation time only') or simulate a shorter run. Here
    the closed loops overflow at their first update (a denormal bias, 1e-320 V) and again
    after a reset at 50 ms.
    """
    from ring_gyro_sim.core.params import build_config
    from ring_gyro_sim.recording.reader import block_sample_counts
    config = build_config({'drive.start_on': 'rest', 'output.rate': 20000.0,
                           'electrodes.outer_voltage': 1e-320})
    original = tmp_path / 'failed.mcap'
    summary = offline.run_offline(config, 0.1, output=str(original), progress=False,
                                  inputs=[run.Reset(at_ns=50_000_000)])
    assert summary.status == 'failed' and summary.message.startswith('non-finite loop state')
    assert block_sample_counts(str(original)) == [200] * 10  # every block, no hole
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert_same_outputs(original, again)
    topics = GYRO_TOPICS + [f'{NS}/control', '/diagnostics']
    a, b = decoded(original, topics), decoded(again, topics)
    for topic in (f'{NS}/rate', f'{NS}/control', f'{NS}/demodulator'):
        assert [t for t, _ in a[topic]] == [t for t, _ in b[topic]], topic
    assert [m.angular_velocity.z for _, m in a[f'{NS}/rate']] == [
        m.angular_velocity.z for _, m in b[f'{NS}/rate']]
    last = {kv.key: kv.value for kv in a['/diagnostics'][-1][1].status[0].values}
    assert last['status'] == 'failed' and last['nonfinite_failures'] == '2'


# ------------------------------------------------------------------ the default recording

TEN_DEG_S = math.radians(10.0)


@pytest.fixture(scope='module')
def default_recording(tmp_path_factory):
    """Record 0.3 s of the defaults (the gyroscope, its loops), 10 deg/s, 1000 g at 0.1 s."""
    config = build_config({'scenario.rate_times': [0.0], 'scenario.rate_values': [TEN_DEG_S],
                           'scenario.shock_times': [0.1],
                           'scenario.shock_peaks': [1000 * STANDARD_GRAVITY]})
    path = tmp_path_factory.mktemp('default') / 'default.mcap'
    offline.run_offline(config, 0.3, output=str(path), progress=False)
    return path, config


def test_the_default_recording_is_small(default_recording):
    # Every 200 kHz sample of the four block topics would make 44 MB per simulated second
    # of the default gyroscope; the defaults keep ~0.35 MB of it.
    path, config = default_recording
    assert config.run.record_decimation == 200
    assert path.stat().st_size < 1e6 * 0.3, f'{path.stat().st_size / 0.3e6:.2f} MB per s'


def test_the_default_recording_keeps_rate_loops_inputs_and_diagnostics_whole(
        default_recording):
    path, config = default_recording
    ms = 1_000_000
    rate = read_rate(path)
    assert np.array_equal(rate.t_ns, (np.arange(300) + 1) * ms)  # every 1 kHz sample
    control = read_block_topic(path, 'control')
    # every loop update (the first block's reports 9, the update at its end goes with the next)
    assert np.array_equal(np.rint(control.data[:, 0] * 1e9), (np.arange(299) + 1) * ms)
    ends = [(k + 1) * 10 * ms for k in range(30)]
    for name in ('modal_displacement', 'radial_gap', 'sense_electrodes', 'demodulator'):
        blocks = read_block_topic(path, name)
        assert blocks.end_ns == ends, name  # every block message, with the kept rows
        assert np.array_equal(np.rint(blocks.data[:, 0] * 1e9), (np.arange(300) + 1) * ms)
    topics = decoded(path, [f'{NS}/shock', f'{NS}/angular_rate', '/diagnostics'])
    assert [t for t, _ in topics[f'{NS}/shock']] == [100 * ms]
    assert [t for t, _ in topics[f'{NS}/angular_rate']] == [0]
    assert topics['/diagnostics']


def test_the_default_recording_resimulates_bit_for_bit(default_recording, tmp_path):
    path, _ = default_recording
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(path), str(again), progress=False)
    assert_same_outputs(path, again)
    for name in ('demodulator', 'control'):
        a, b = read_block_topic(path, name), read_block_topic(again, name)
        assert a.end_ns == b.end_ns and np.array_equal(a.data, b.data), name
    a, b = read_rate(path), read_rate(again)
    assert np.array_equal(a.t_ns, b.t_ns) and np.array_equal(a.rate, b.rate)


def test_live_environment_changes_resimulate_bit_for_bit(tmp_path):
    """
    Environment parameters changed mid-run: recorded, and --from repeats them.

    A sine whose frequency changes (its phase runs on), a random profile whose level and band
    change, a steady acceleration switched on: the re-simulation from the recording has the
    same blocks, bit for bit, and differs from the run without the changes.
    """
    config = paper_config({'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                           'record.decimation': 1, 'scenario.vibration_frequency': 1000.0,
                           'scenario.vibration_amplitude': 50.0,
                           'scenario.vibration_psd_frequencies': [20.0, 2000.0],
                           'scenario.vibration_psd_values': [0.01, 0.01]})
    inputs = [ParameterChange({'scenario.vibration_frequency': 1700.0}, at_ns=3_000_000),
              ParameterChange({'scenario.vibration_psd_frequencies': [50.0, 500.0, 3000.0],
                               'scenario.vibration_psd_values': [0.02, 0.05, 0.01]},
                              at_ns=7_000_000),
              ParameterChange({'scenario.acceleration': [200.0, 0.0],
                               'scenario.vibration_angle': 20.0}, at_ns=11_000_000)]
    original = tmp_path / 'env.mcap'
    summary = offline.run_offline(config, 0.02, output=str(original), progress=False,
                                  inputs=inputs)
    # The summary states the rms of the profile in force at the end: the integral of the
    # log-log segments (slope log(2.5) / log(10) and log(0.2) / log(6)), by hand.
    b1, b2 = math.log(2.5) / math.log(10.0), math.log(0.2) / math.log(6.0)
    mean_square = (0.02 * 50.0 / (b1 + 1.0) * (10.0 ** (b1 + 1.0) - 1.0)
                   + 0.05 * 500.0 / (b2 + 1.0) * (6.0 ** (b2 + 1.0) - 1.0))
    assert summary.extra['random_vibration_rms_g'] == pytest.approx(
        math.sqrt(mean_square), rel=1e-12)
    events = decoded(original, [f'{NS}/events/parameters'])[f'{NS}/events/parameters']
    assert [t for t, _ in events] == [3_000_000, 7_000_000, 11_000_000]
    again = tmp_path / 'again.mcap'
    offline.resimulate(str(original), str(again), progress=False)
    assert_same_outputs(original, again)
    unchanged = tmp_path / 'unchanged.mcap'
    offline.run_offline(config, 0.02, output=str(unchanged), progress=False)
    _, _, a = block_arrays(original)[f'{NS}/modal_displacement']
    _, _, b = block_arrays(unchanged)[f'{NS}/modal_displacement']
    a, b = np.concatenate(a), np.concatenate(b)
    same = np.all(a == b, axis=1)
    assert same[a[:, 0] <= 0.003 + 1e-12].all() and not same[a[:, 0] > 0.003 + 1e-12].any()
