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
Tests of ``ring_gyro_sim.ros.recorder``: the run recorder, its controls and its files.

Recordings are read back with readers that share no code with ours (``mcap`` with the
``mcap_ros2`` decoder, and ``rosbags``) wherever the layout is what is tested.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import dataclasses
import json
import os
import pathlib
import signal
import subprocess
import sys
import textwrap
import time

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from node_harness import NodeProcess, params_yaml, Probe
import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from ring_gyro_sim import cli
from ring_gyro_sim.core.engine.full import Samples, Simulator
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import paper_config, STANDARD_GRAVITY
from ring_gyro_sim.recording.errors import OutputBusyError, OutputExistsError, RecordingError
from ring_gyro_sim.recording.reader import (
    block_end_times_ns, block_sample_counts, decode, read_messages, read_metadata)
from ring_gyro_sim.recording.writer import BagWriter
from ring_gyro_sim.ros import conversions, qos
from ring_gyro_sim.ros.recorder import (
    ALWAYS_RECORDED, METADATA_NAME, RECORDABLE_TOPICS, recorded_topic_names, RunRecorder)
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml
# isort: on

NS = '/ring_gyro'
REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
# 100 kHz output (10 us period) in blocks of 1 ms = 100 samples: small, fast recordings, of
# every sample (the default record.decimation keeps one in 200).
FAST = {'drive.start_on': 'rest', 'output.rate': 100000.0, 'output.block_duration': 0.001,
        'record.decimation': 1}
PERIOD_NS = 10_000
#: The inputs a run without gyro.enabled records (~/angular_rate cannot act there).
RESONATOR_INPUTS = [name for name in ALWAYS_RECORDED if name != 'angular_rate']


def record(path, threaded):
    config = paper_config({'drive.start_on': 'rest', 'output.rate': 100000.0})
    sim = Simulator(config)
    with RunRecorder(str(path), config, sim.channel_names, threaded=threaded) as rec:
        rec.shock(1_000_000, 2000 * STANDARD_GRAVITY)
        sim.shock(2000 * STANDARD_GRAVITY, at_ns=1_000_000)
        for _ in range(12):
            samples = sim.advance(0.005)
            rec.outputs(conversions.output_blocks(samples, sim.channel_names), sim.time_ns)
            rec.drive(sim.time_ns, amplitude=0.01)
    return [(m.topic, m.log_time_ns, m.type_name, decode(m)) for m in read_messages(path)]


def channels(path):
    """Return {topic: channel} of a finished recording, read by mcap."""
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    return {c.topic: c for c in summary.channels.values()}


def decoded_blocks(path, topic):
    """Return [(log time, (K, C) array)] of a block topic, decoded by mcap_ros2."""
    out = []
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, _, message, msg in reader.iter_decoded_messages(topics=[topic]):
            rows, columns = msg.layout.dim[0].size, msg.layout.dim[1].size
            out.append((message.log_time, np.array(msg.data, dtype=np.float64).reshape(
                rows, columns)))
    return out


def sliced(samples, start, stop):
    """Return the samples ``start:stop`` of a Samples (rows of every array)."""
    def rows(value):
        if value is None or np.ndim(value) == 0:  # drive_phase, rate: gyro only
            return value  # die_temperature: one value per block
        return value[start:stop]
    return Samples(**{f.name: rows(getattr(samples, f.name))
                      for f in dataclasses.fields(Samples)})


def record_cut(path, config, samples, cut, diagnostics=False, **kwargs):
    """Record ``samples`` (from t = 1 period) cut into blocks of the sizes ``cut``."""
    names = Simulator(config).channel_names
    with RunRecorder(str(path), config, names, **kwargs) as rec:
        done = 0
        for size in cut:
            t_ns = (done + size) * config.run.output_period_ns
            rec.outputs(conversions.output_blocks(sliced(samples, done, done + size), names),
                        t_ns)
            rec.clock(t_ns)
            done += size
        if diagnostics:
            rec.diagnostics(conversions.diagnostics_message(
                t_ns, 'ring_gyro: simulator', 'ring_gyro_sim', 'OK', 'test', {}), t_ns)
    return path


@pytest.fixture(scope='module')
def shocked_samples():
    """Return (config values, 300 samples of a 2000 g shock at 0.5 ms from rest)."""
    sim = Simulator(paper_config(FAST))
    sim.shock(2000 * STANDARD_GRAVITY, at_ns=500_000)
    return sim.advance_samples(300)


# ------------------------------------------------------------------ writer thread


def test_threaded_recording_equals_the_direct_one(tmp_path):
    direct = record(tmp_path / 'direct.mcap', threaded=False)
    threaded = record(tmp_path / 'threaded.mcap', threaded=True)
    assert len(threaded) == len(direct) == 1 + 12 * 4
    for a, b in zip(direct, threaded):
        assert a[:3] == b[:3]
        if a[2] == 'std_msgs/msg/Float64MultiArray':
            assert np.array_equal(np.asarray(a[3].data), np.asarray(b[3].data))
            assert a[3].layout == b[3].layout
        else:
            assert a[3] == b[3]


def test_a_write_error_in_the_thread_reaches_the_caller(tmp_path):
    config = paper_config({})
    rec = RunRecorder(str(tmp_path / 'x.mcap'), config, Simulator(config).channel_names)
    rec._write('/not/a/registered/topic', conversions.float_message(1.0), 0)
    with pytest.raises(RecordingError):
        rec.close()
    rec.close()  # idempotent once the error was reported
    assert (tmp_path / 'x.mcap').read_bytes().endswith(b'\x89MCAP0\r\n')


# ------------------------------------------------------------------ order and QoS


def test_messages_are_written_in_log_time_order(tmp_path, shocked_samples):
    """A shock scheduled ahead (recorded at the start) lands between the blocks around it."""
    config = paper_config(FAST)
    path = tmp_path / 'order.mcap'
    names = Simulator(config).channel_names
    with RunRecorder(str(path), config, names, threaded=True) as rec:
        rec.shock(1_550_000, 1.0)  # inside the 16th block (1.5 .. 1.6 ms)
        rec.shock(9_000_000, 2.0)  # after the end: still recorded, at the end
        for k in range(3):
            rec.outputs(conversions.output_blocks(sliced(shocked_samples, 100 * k,
                                                         100 * k + 100), names),
                        (k + 1) * 1_000_000)
        rec.drive(3_000_000, amplitude=0.5)  # "now": right away
    with open(path, 'rb') as stream:
        in_file_order = [(channel.topic, message.log_time) for _, channel, message in
                         make_reader(stream).iter_messages(log_time_order=False)]
    times = [t for _, t in in_file_order]
    assert times == sorted(times), in_file_order
    shocks = [t for topic, t in in_file_order if topic == f'{NS}/shock']
    assert shocks == [1_550_000, 9_000_000]
    assert in_file_order[-1] == (f'{NS}/shock', 9_000_000)


def qos_of_channel(channel):
    """Return (depth, reliability, durability) of the recorded offered QoS of a channel."""
    profiles = yaml.safe_load(channel.metadata['offered_qos_profiles'])
    assert len(profiles) == 1
    return profiles[0]['depth'], profiles[0]['reliability'], profiles[0]['durability']


# The gyroscope's topics exist only with gyro.enabled (which needs the companions), the closed
# loop's (~/control) only with a closed control.mode.
GYRO = {'gyro.enabled': True, 'modes.companions': True, 'control.mode': 'rebalance'}


def test_recorded_qos_is_the_qos_module(tmp_path):
    config = paper_config({**FAST, **GYRO, 'publish_clock': True})
    path = tmp_path / 'qos.mcap'
    with RunRecorder(str(path), config, Simulator(config).channel_names, NS,
                     publish_clock=True):
        pass
    recorded = channels(path)
    assert sorted(recorded) == sorted(
        name if name.startswith('/') else f'{NS}/{name}' for name in RECORDABLE_TOPICS)
    # The depths the node uses (ros/node.py takes them from qos.py; the input queues hold 1000
    # shocks so that a flood is taken and counted, not overwritten in the middleware).
    expected_depths = {'modal_displacement': 50, 'radial_gap': 50, 'sense_electrodes': 50,
                       '/diagnostics': 10, '/clock': 10, 'shock': 1000,
                       'base_acceleration': 1000, 'drive/amplitude': 10,
                       'drive/frequency': 10, 'events/reset': 10, 'events/parameters': 10,
                       # Gyroscope: a block topic; 50 blocks of 10 rate samples (1 kHz rate
                       # output in 10 ms blocks); a rate profile streamed like base_acceleration.
                       'demodulator': 50, 'rate': 500, 'angular_rate': 1000,
                       # The die's sensor, one per block; the ambient, a few steps at once.
                       'die_temperature': 10, 'temperature': 100,
                       # Closed loop: a block topic (its updates in each block).
                       'control': 50}
    assert sorted(expected_depths) == sorted(RECORDABLE_TOPICS)
    for name, depth in expected_depths.items():
        topic = name if name.startswith('/') else f'{NS}/{name}'
        assert qos_of_channel(recorded[topic]) == (depth, 'reliable', 'volatile'), name
        assert qos.TOPIC_QOS[name].depth == depth


def test_recorded_qos_is_what_the_live_node_offers(tmp_path, ros):
    """A real node records; its publishers and subscriptions are asked for their QoS live."""
    # A best-effort or transient-local mutation of a qos.py profile that node.py does not use
    # (as node.py stands: all of them) makes this fail; the depth is checked by the two tests
    # above.
    path = tmp_path / 'live.mcap'
    params = tmp_path / 'live.yaml'
    params.write_text(params_yaml({'drive.start_on': 'rest', 'duration': 0.0, **GYRO,
                                   'publish_clock': True, 'record.path': str(path)}))
    node = NodeProcess(params, tmp_path)
    probe = Probe()
    live = {}
    try:
        def discovered():
            for name in RECORDABLE_TOPICS:
                topic = name if name.startswith('/') else f'{NS}/{name}'
                if name in ('events/reset', 'events/parameters') or name in live:
                    continue
                infos = (probe.get_subscriptions_info_by_topic(topic) if name in ALWAYS_RECORDED
                         else probe.get_publishers_info_by_topic(topic))
                ours = [i for i in infos if i.node_name == 'ring_gyro']
                if ours:
                    profile = ours[0].qos_profile
                    live[name] = ({ReliabilityPolicy.RELIABLE: 'reliable',
                                   ReliabilityPolicy.BEST_EFFORT: 'best_effort'}[
                                       profile.reliability],
                                  {DurabilityPolicy.VOLATILE: 'volatile',
                                   DurabilityPolicy.TRANSIENT_LOCAL: 'transient_local'}[
                                       profile.durability])
            return len(live) == len(RECORDABLE_TOPICS) - 2
        probe.spin_until(discovered, 60.0, 'the node topics in the graph')
        node.signal(signal.SIGINT)
        assert node.wait(30.0) == 0, node.output()
    finally:
        node.stop()
        probe.destroy_node()
    recorded = channels(path)
    for name, offered in live.items():
        topic = name if name.startswith('/') else f'{NS}/{name}'
        # The graph tells reliability and durability; the depth is local to the endpoint (it
        # comes back as 0), which the constants test above checks.
        assert qos_of_channel(recorded[topic])[1:] == offered, (name, node.output())


# ------------------------------------------------------------------ record.topics


def test_record_topics_selects_topics_and_keeps_the_inputs(tmp_path, shocked_samples):
    config = paper_config({**FAST, 'record.topics': ['radial_gap', '/diagnostics',
                                                     f'{NS}/shock']})
    path = record_cut(tmp_path / 'some.mcap', config, shocked_samples, [100, 100, 100],
                      diagnostics=True, namespace=NS, publish_clock=True)
    kept = ['radial_gap', '/diagnostics', *RESONATOR_INPUTS]
    topics = sorted(n if n.startswith('/') else f'{NS}/{n}' for n in kept)
    assert sorted(channels(path)) == topics
    meta = read_metadata(path, METADATA_NAME)
    assert sorted(json.loads(meta['record_topics'])) == topics
    assert json.loads(meta['block_topics']) == [f'{NS}/radial_gap']
    counts = {}
    for m in read_messages(path):
        counts[m.topic] = counts.get(m.topic, 0) + 1
    assert counts == {f'{NS}/radial_gap': 3, '/diagnostics': 1}
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([pathlib.Path(path)], default_typestore=store) as reader:
        assert sorted(c.topic for c in reader.connections) == topics


def test_empty_record_topics_means_every_topic():
    assert recorded_topic_names([], NS, gyro=True, control=True) == list(RECORDABLE_TOPICS)
    assert '/clock' not in recorded_topic_names([], NS, publish_clock=False)
    # Without gyro.enabled the node has no gyroscope topics, so no recording holds them; nor
    # ~/control without the closed loop.
    gyro_only = ('demodulator', 'rate', 'angular_rate', 'die_temperature')
    assert recorded_topic_names([], NS) == [
        n for n in RECORDABLE_TOPICS if n not in (*gyro_only, 'control')]
    assert recorded_topic_names([], NS, gyro=True) == [n for n in RECORDABLE_TOPICS
                                                       if n != 'control']
    assert recorded_topic_names([], NS, control=True) == [
        n for n in RECORDABLE_TOPICS if n not in gyro_only]
    assert recorded_topic_names(['control', '~/radial_gap'], NS) == [
        'radial_gap', *RESONATOR_INPUTS]
    assert recorded_topic_names([f'{NS}/control'], NS, control=True) == [
        'control', *RESONATOR_INPUTS]
    assert recorded_topic_names(['~/sense_electrodes'], NS) == [
        'sense_electrodes', *RESONATOR_INPUTS]
    assert recorded_topic_names(['~/sense_electrodes'], NS, gyro=True) == [
        'sense_electrodes', *ALWAYS_RECORDED]


@pytest.mark.parametrize('name', ['modal', '/modal_displacement', 'diagnostics',
                                  '/other_ns/radial_gap', 'drive/*'])
def test_unknown_record_topic_is_refused_naming_the_parameter(tmp_path, name):
    config = paper_config({**FAST, 'record.topics': ['radial_gap', name]})
    path = tmp_path / 'never.mcap'
    with pytest.raises(ParameterError) as info:
        RunRecorder(str(path), config, Simulator(config).channel_names, NS)
    text = str(info.value)
    assert text.startswith('record.topics: ') and repr(name) in text
    assert 'modal_displacement' in text  # the valid names are listed
    assert not path.exists()


# ------------------------------------------------------------------ record.decimation


@pytest.mark.parametrize('decimation', [7, 150])
def test_decimation_keeps_every_nth_global_sample_whatever_the_cut(
        tmp_path, shocked_samples, decimation):
    # 7 does not divide the block sizes, so each block starts at another offset; 150 is longer
    # than the blocks, so some blocks keep no sample at all.
    full = record_cut(tmp_path / 'full.mcap', paper_config(FAST), shocked_samples,
                      [100, 100, 100])
    config = paper_config({**FAST, 'record.decimation': decimation})
    cuts = [[100, 100, 100], [37, 100, 63, 41, 59]]
    for k, cut in enumerate(cuts):
        path = record_cut(tmp_path / f'decimated{k}.mcap', config, shocked_samples, cut)
        meta = read_metadata(path, METADATA_NAME)
        assert meta['record_decimation'] == str(decimation)
        assert meta['output_period_ns'] == str(PERIOD_NS)
        assert meta['block_samples'] == '100'  # 1 ms blocks of 10 us samples
        for name in conversions.OUTPUT_TOPICS:
            topic = f'{NS}/{name}'
            original = np.concatenate([a for _, a in decoded_blocks(full, topic)])
            blocks = decoded_blocks(path, topic)
            # Every block is still there, at its end time, with the layout of the original.
            assert [t for t, _ in blocks] == list(np.cumsum(cut) * PERIOD_NS)
            assert all(a.shape[1] == original.shape[1] for _, a in blocks)
            kept = np.concatenate([a for _, a in blocks])
            index = np.rint(original[:, 0] / (PERIOD_NS * 1e-9)).astype(int)
            assert index[0] == 1  # the first sample is one period after the start
            assert np.array_equal(kept, original[index % decimation == 0]), (topic, cut)
        assert block_end_times_ns(path) == list(np.cumsum(cut) * PERIOD_NS)
        assert block_sample_counts(path) == cut
    if decimation > 37:
        assert any(a.shape[0] == 0 for _, a in decoded_blocks(path, f'{NS}/radial_gap'))


def test_block_ends_without_block_topics(tmp_path, shocked_samples):
    cut = [100, 100, 60]  # a run with a duration: the last block is shorter
    ends = list(np.cumsum(cut) * PERIOD_NS)
    config = paper_config({**FAST, 'record.topics': ['/diagnostics']})
    path = record_cut(tmp_path / 'diag.mcap', config, shocked_samples, cut, diagnostics=True)
    assert block_end_times_ns(path) == ends
    config = paper_config({**FAST, 'record.topics': ['/clock'], 'publish_clock': True})
    path = record_cut(tmp_path / 'clock.mcap', config, shocked_samples, cut,
                      publish_clock=True)
    assert block_end_times_ns(path) == ends
    config = paper_config({**FAST, 'record.topics': ['shock']})
    path = record_cut(tmp_path / 'inputs.mcap', config, shocked_samples, cut)
    with pytest.raises(RecordingError, match='no block topic'):
        block_end_times_ns(path)


# ------------------------------------------------------------------ record.compression


@pytest.mark.parametrize('compression, in_file', [('zstd', 'zstd'), ('lz4', 'lz4'),
                                                  ('none', '')])
def test_compression(tmp_path, shocked_samples, compression, in_file):
    reference = record_cut(tmp_path / 'reference.mcap', paper_config(FAST), shocked_samples,
                           [100, 100, 100])
    config = paper_config({**FAST, 'record.compression': compression})
    path = record_cut(tmp_path / f'{compression}.mcap', config, shocked_samples,
                      [100, 100, 100])
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    assert summary.chunk_indexes
    assert {index.compression for index in summary.chunk_indexes} == {in_file}
    assert read_metadata(path, METADATA_NAME)['compression'] == compression
    for name in conversions.OUTPUT_TOPICS:
        a, b = decoded_blocks(reference, f'{NS}/{name}'), decoded_blocks(path, f'{NS}/{name}')
        assert [t for t, _ in a] == [t for t, _ in b]
        assert all(np.array_equal(x, y) for (_, x), (_, y) in zip(a, b))
    store = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([pathlib.Path(path)], default_typestore=store) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts[f'{NS}/modal_displacement'] == 3
        assert sum(1 for _ in reader.messages()) == 9
    if compression == 'none':
        assert path.stat().st_size > reference.stat().st_size


# ------------------------------------------------------------------ files


def small_recording(path, **values):
    config = paper_config({**FAST, **values})
    with RunRecorder(str(path), config, Simulator(config).channel_names) as rec:
        rec.shock(0, 1.0)
    return path


def test_an_existing_file_is_refused_unless_overwrite(tmp_path):
    path = small_recording(tmp_path / 'run.mcap')
    before = path.read_bytes()
    with pytest.raises(OutputExistsError) as info:
        small_recording(path)
    text = str(info.value)
    assert text.startswith('record.path: ') and str(path) in text
    assert 'exists' in text and 'record.overwrite' in text
    assert path.read_bytes() == before
    small_recording(path, **{'record.overwrite': True, 'record.compression': 'none'})
    assert path.read_bytes() != before
    assert read_metadata(path, METADATA_NAME)['compression'] == 'none'


def test_a_file_that_is_not_a_recording_is_never_replaced(tmp_path):
    scenario = tmp_path / 'scenario.yaml'
    scenario.write_text('ring_gyro:\n  ros__parameters:\n    duration: 1.0\n')
    with pytest.raises(OutputExistsError, match='not an MCAP recording'):
        small_recording(scenario, **{'record.overwrite': True})
    assert scenario.read_text() == 'ring_gyro:\n  ros__parameters:\n    duration: 1.0\n'


@pytest.mark.parametrize('same', ['scenario', 'record_path_in_the_scenario', 'from'])
def test_ring_gyro_run_never_writes_over_its_input(tmp_path, capsys, same):
    scenario = tmp_path / 's.yaml'
    values = {'drive.start_on': 'rest', 'duration': 0.001, 'record.overwrite': True}
    if same == 'record_path_in_the_scenario':
        values['record.path'] = str(scenario)
    scenario.write_text(params_yaml(values))
    text = scenario.read_text()
    if same == 'from':
        source = tmp_path / 'a.mcap'
        assert cli.main(['run', str(scenario), '-o', str(source), '--no-progress']) == 0
        before = source.read_bytes()
        argv = ['run', '--from', str(source), '-o', str(source), '--no-progress']
    else:
        before = None
        argv = ['run', str(scenario), '--no-progress']
        if same == 'scenario':
            argv += ['-o', str(scenario)]
    capsys.readouterr()
    assert cli.main(argv) == 1
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'record.path' in err and 'is the input file' in err
    assert scenario.read_text() == text
    if before is not None:
        assert source.read_bytes() == before


def test_parent_directories_are_created_and_an_unwritable_path_is_refused(tmp_path):
    path = small_recording(tmp_path / 'out' / 'deeper' / 'run.mcap')
    assert [m.topic for m in read_messages(path)] == [f'{NS}/shock']
    blocker = tmp_path / 'plain_file'
    blocker.write_text('')
    with pytest.raises(RecordingError) as info:
        small_recording(blocker / 'run.mcap')
    assert str(info.value).startswith('record.path: ')
    assert 'is not a directory' in str(info.value)


def test_initial_state_can_be_given_after_construction(tmp_path):
    config = paper_config(FAST)
    names = Simulator(config).channel_names
    n = len(names['modal_displacement'])
    with RunRecorder(str(tmp_path / 'late.mcap'), config, names) as rec:
        rec.set_initial_state(np.full(n, 1e-7), np.full(n, 0.25))
        rec.shock(0, 1.0)
        with pytest.raises(RecordingError, match='before the first message'):
            rec.set_initial_state(np.zeros(n), np.zeros(n))
    state = json.loads(read_metadata(tmp_path / 'late.mcap', METADATA_NAME)['initial_state'])
    assert state == {'q': [1e-7] * n, 'v': [0.25] * n}


HOLDER = textwrap.dedent("""
    import sys
    from ring_gyro_sim.recording.writer import BagWriter
    bag = BagWriter(sys.argv[1], overwrite=True)
    print('recording', flush=True)
    sys.stdin.read()
    bag.finish()
""")


def test_a_second_recorder_on_the_same_file_is_refused(tmp_path):
    path = tmp_path / 'one.mcap'
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT)] + sys.path))
    holder = subprocess.Popen([sys.executable, '-c', HOLDER, str(path)], env=env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == 'recording\n'
        for overwrite in (False, True):
            with pytest.raises(OutputBusyError) as info:
                small_recording(path, **{'record.overwrite': overwrite})
            assert str(info.value).startswith('record.path: ')
            assert 'another recorder is writing it' in str(info.value)
        in_process = BagWriter(tmp_path / 'two.mcap')
        with pytest.raises(OutputBusyError):
            BagWriter(tmp_path / 'two.mcap', overwrite=True)
        in_process.finish()
    finally:
        holder.communicate('', timeout=60)
    assert holder.returncode == 0
    small_recording(path, **{'record.overwrite': True})  # free once the other has finished
    assert [m.topic for m in read_messages(path)] == [f'{NS}/shock']


@pytest.fixture
def tiny_disk(tmp_path):
    """Mount a 200 kB tmpfs for the test and remove it after (needs root)."""
    mount = tmp_path / 'tiny'
    mount.mkdir()
    result = subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=200k', 'tmpfs', str(mount)],
                            capture_output=True, text=True, check=False)
    if result.returncode != 0:
        pytest.skip(f'cannot mount a small tmpfs to fill (not root?): {result.stderr.strip()}')
    try:
        yield mount
    finally:
        subprocess.run(['umount', '-l', str(mount)], check=False)


def test_a_full_disk_gives_one_error_and_a_quiet_close(tiny_disk, shocked_samples):
    config = paper_config({**FAST, 'record.compression': 'none'})
    names = Simulator(config).channel_names
    blocks = conversions.output_blocks(sliced(shocked_samples, 0, 100), names)
    rec = RunRecorder(str(tiny_disk / 'full.mcap'), config, names)
    errors = []
    for k in range(200):  # 200 blocks of ~40 kB uncompressed: far more than 200 kB
        try:
            rec.outputs(blocks, (k + 1) * 1_000_000)
        except RecordingError as exc:
            errors.append(str(exc))
    try:
        rec.close()
    except RecordingError as exc:
        errors.append(str(exc))
    rec.close()
    assert len(errors) == 1, errors
    assert 'No space left on device' in errors[0] and 'full.mcap' in errors[0]
    # What reached the disk reads like a killed recording.
    assert [m.log_time_ns for m in read_messages(tiny_disk / 'full.mcap')] == sorted(
        m.log_time_ns for m in read_messages(tiny_disk / 'full.mcap'))


def test_ring_gyro_run_on_a_full_disk_prints_one_error_line(tiny_disk, tmp_path):
    scenario = tmp_path / 's.yaml'
    scenario.write_text(params_yaml({**FAST, 'duration': 1.0, 'real_time_factor': 0.0}))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO_ROOT)] + sys.path))
    start = time.monotonic()
    result = subprocess.run([sys.executable, '-m', 'ring_gyro_sim.cli', 'run', str(scenario),
                             '-o', str(tiny_disk / 'run.mcap'), '--no-progress'],
                            capture_output=True, text=True, env=env, timeout=600, check=False)
    assert result.returncode == 1, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith('ring_gyro run: error: ')
    assert 'No space left on device' in lines[0] and 'Traceback' not in result.stderr
    assert time.monotonic() - start < 600


def test_the_node_on_a_full_disk_logs_one_fatal_line(tiny_disk, tmp_path):
    """A full disk gives one FATAL line, and no traceback from close() after it."""
    params = tmp_path / 'full.yaml'
    params.write_text(params_yaml({**FAST, 'duration': 1.0, 'real_time_factor': 0.0,
                                   'drive.start_on': 'rest',
                                   'record.path': str(tiny_disk / 'node.mcap')}))
    node = NodeProcess(params, tmp_path)
    try:
        code = node.wait(120.0)
    finally:
        node.stop()
    log = node.output()
    print(log[-2000:])
    assert code == 1, log
    assert 'Traceback' not in log
    fatal = [line for line in log.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and 'No space left on device' in fatal[0], fatal


def test_a_decimated_recording_resimulates_with_its_original_block_sizes(tmp_path):
    """offline.load_recording takes block sizes from block_sample_counts, not the layouts."""
    from ring_gyro_sim import offline
    config = paper_config({**FAST, 'record.decimation': 10, 'duration': 0.0035,
                           'scenario.shock_times': [0.001], 'scenario.shock_peaks': [1e4]})
    first = tmp_path / 'first.mcap'
    offline.run_offline(config, output=str(first), progress=False)
    loaded, start, inputs, sizes, namespace = offline.load_recording(str(first))
    counts = block_sample_counts(first)
    assert counts == sizes == [100, 100, 100, 50]  # 3.5 ms in blocks of 1 ms
    rows = [len(x) for _, x in decoded_blocks(first, f'{NS}/modal_displacement')]
    assert rows == [10, 10, 10, 5]  # the decimated rows: not the original cut
    again = tmp_path / 'again.mcap'
    offline.run_offline(loaded, sum(counts) * PERIOD_NS * 1e-9, output=str(again),
                        progress=False, namespace=namespace, start_state=start,
                        inputs=inputs, block_sizes=counts)
    for name in conversions.OUTPUT_TOPICS:
        a, b = decoded_blocks(first, f'{NS}/{name}'), decoded_blocks(again, f'{NS}/{name}')
        assert [t for t, _ in a] == [t for t, _ in b]
        assert all(np.array_equal(x, y) for (_, x), (_, y) in zip(a, b)), name
