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
Tests of replay.py (``ring_gyro replay``) with the real rclpy across processes.

A short run is recorded offline; ``ring_gyro replay`` publishes it from its own process and a
subscriber node in this process receives it. The subscriber has its own rclpy context in a
ROS domain of its own (215-232, apart from the node tests' 100-199), discovery limited to this
machine, so that it neither disturbs nor is disturbed by other sessions.

Timing is judged on the publication times (the DDS source timestamps, taken by the replaying
process as it publishes), not on when this process's executor got round to a message: on a
loaded 2-core host the latter trailed the publication by up to 47 ms while the replay itself
was within 14 ms of its schedule. The replay's contract (replay.py, "Timing"): absolute
deadlines, a stall of the host costs lateness once and is caught up, nothing accumulates.
"""

import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from ring_gyro_sim import cli
from ring_gyro_sim.core.params import paper_config
from ring_gyro_sim.offline import run_offline
from ring_gyro_sim.recording.reader import decode, read_messages, read_topics
from ring_gyro_sim.recording.schemas import message_class
from ring_gyro_sim.recording.writer import BagWriter
from ring_gyro_sim.replay import MAX_GAP_S
import ros_domains
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
DOMAIN_ID = ros_domains.claim('replay tests')
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
NS = '/ring_gyro'
BLOCK_TOPICS = [f'{NS}/modal_displacement', f'{NS}/radial_gap', f'{NS}/sense_electrodes']
TOPIC_TYPES = {**{t: Float64MultiArray for t in BLOCK_TOPICS}, f'{NS}/shock': Vector3Stamped,
               '/diagnostics': DiagnosticArray, '/clock': Clock}
BLOCK_S = 0.05
"""Log-time spacing of the recorded blocks, s."""
DURATION_S = 0.6
JITTER_S = 0.025
"""Allowed deviation of one publication from its schedule (scheduling), s."""
ON_TIME_S = 0.005
"""
A publication counts as on schedule within this of its deadline, s: a wake-up and a publish
(on an idle host the median lag is 0.1 ms, on a loaded one the largest 14 ms).
"""


def replay_command():
    """Return the ``ring_gyro`` console script next to this Python, else ``python -m``."""
    exe = pathlib.Path(sys.executable).parent / 'ring_gyro'
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'ring_gyro_sim.cli']


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """Record 0.6 s: a 2000 g shock at t = 0, blocks every 50 ms (12 per block topic)."""
    path = tmp_path_factory.mktemp('replay') / 'run.mcap'
    config = paper_config({'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                           'output.rate': 20000.0, 'output.block_duration': BLOCK_S,
                           'scenario.shock_times': [0.0], 'scenario.shock_peaks': [19613.3]})
    run_offline(config, DURATION_S, output=str(path), progress=False)
    return path


class Received:
    """
    What one replay delivered: [(wall arrival, topic, message)] and the replay's output.

    ``published`` maps each topic to the source timestamps of its messages (ns, the
    publisher's system clock), in the order they arrived.
    """

    def __init__(self, items, result, published):
        self.items = items
        self.returncode, self.stderr = result
        self._published = published

    def topic(self, name):
        return [(wall, msg) for wall, topic, msg in self.items if topic == name]

    def published_ns(self, name):
        """Publication times of the messages of topic ``name`` (ns, the replay's clock)."""
        return np.array(self._published.get(name, []), dtype=np.int64)

    def schedule(self, path):
        """Return (publication ns, log time ns) of every received message of the recording."""
        published, log = [], []
        for topic in read_topics(path):
            times = [m.log_time_ns for m in read_messages(path, topic)]
            sent = self.published_ns(topic)
            assert len(sent) == len(times), topic
            published.extend(sent)
            log.extend(times)
        order = np.argsort(log, kind='stable')
        return np.array(published, dtype=np.int64)[order], np.array(log, dtype=np.int64)[order]

    def count(self, name):
        return len(self.topic(name))


def replay_and_receive(path, *args, timeout=60.0, during=None):
    """
    Run ``ring_gyro replay path *args`` in its own process and receive what it publishes.

    ``during(proc, items)``, if given, is called between the spins while the replay runs.
    """
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    node = rclpy.create_node(f'replay_probe_{os.getpid()}', context=context)
    items = []
    published = {}

    def received(msg, info, name):
        items.append((time.monotonic(), name, msg))
        published.setdefault(name, []).append(info['source_timestamp'])
    # Every topic of the recording (channels without messages too: the replay waits until
    # each of its publishers has a subscriber), and /clock.
    types = {**{t: message_class(name) for t, name in read_topics(path).items()},
             **TOPIC_TYPES} if pathlib.Path(path).stat().st_size else dict(TOPIC_TYPES)
    for name, msg_type in types.items():
        node.create_subscription(
            msg_type, name, lambda msg, info, name=name: received(msg, info, name), 2000)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(REPO_ROOT)] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    err_path = pathlib.Path(path).with_suffix(f'.{len(args)}.{time.monotonic_ns()}.stderr')
    try:
        with open(err_path, 'wb') as err:
            # Start once our subscriptions are matched (a fixed discovery wait lost the
            # first 4 to 7 of 12 blocks on a loaded machine).
            proc = subprocess.Popen(replay_command() + ['replay', str(path), *args,
                                                        '--wait-for-subscribers', '60'],
                                    env=env, stdout=subprocess.DEVNULL, stderr=err)
            end = time.monotonic() + timeout
            while proc.poll() is None:
                if time.monotonic() > end:
                    proc.kill()
                    proc.wait()
                    pytest.fail(f'replay did not finish within {timeout} s')
                executor.spin_once(timeout_sec=0.005)
                if during is not None:
                    during(proc, items)
        end = time.monotonic()
        tail = time.monotonic() + 0.5
        while time.monotonic() < tail:
            executor.spin_once(timeout_sec=0.01)
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    got = Received(items, (proc.returncode, err_path.read_text(errors='replace')), published)
    got.end = end
    return got


def recorded_blocks(path, topic=f'{NS}/modal_displacement'):
    """Return [(log_time_ns, data array)] of one block topic of the recording."""
    return [(m.log_time_ns, np.array(decode(m).data)) for m in read_messages(path, topic)]


def publication_lags(published_ns, log_ns, rate):
    """
    Return how late each message was published against the replay's schedule, s.

    The schedule is the log times divided by ``rate`` from an origin the publisher does not
    tell: the earliest publication relative to it (the replay never publishes early, so that
    one was at most a wake-up late) is taken as on time.
    """
    lag = (published_ns - published_ns[0]) * 1e-9 - (log_ns - log_ns[0]) * 1e-9 / rate
    return lag - lag.min()


def check_schedule(published_ns, log_ns, rate, what):
    """
    Messages (sorted by log time) were published on the schedule of their log times / rate.

    Most messages are published on time (within ON_TIME_S), in each half of the replay: a
    replay that publishes in bursts (every message of a block at once), ignores the timing
    or drifts (a lag that grows by more than about ON_TIME_S over the replay) fails. A stall
    of the host makes the messages due during it late, and does not fail the check unless it
    covers half of either half (the replay catches up: test_a_stall_is_caught_up).
    """
    lag = publication_lags(published_ns, log_ns, rate)
    half = len(lag) // 2
    medians = [float(np.median(lag[:half])), float(np.median(lag[half:]))]
    print(f'{what} at rate {rate}: {len(lag)} messages, median lag '
          f'{medians[0] * 1e3:.2f} / {medians[1] * 1e3:.2f} ms (first / second half), '
          f'largest {lag.max() * 1e3:.1f} ms, {np.mean(lag > JITTER_S) * 100:.0f} % later '
          f'than {JITTER_S * 1e3:.0f} ms')
    assert max(medians) < ON_TIME_S, what


def check_spacing(got, topic, recorded, rate):
    """Check that the blocks of ``topic`` were published on the schedule of log times / rate."""
    published = got.published_ns(topic)
    log_ns = np.array([t for t, _ in recorded], dtype=np.int64)
    assert len(published) == len(log_ns)
    median = float(np.median(np.diff(published))) * 1e-9
    print(f'rate {rate}: median spacing of the publications {median * 1e3:.1f} ms (expected '
          f'{BLOCK_S / rate * 1e3:.1f} ms)')
    assert median == pytest.approx(BLOCK_S / rate, rel=0.1)
    check_schedule(published, log_ns, rate, topic)


@pytest.fixture(scope='module')
def at_rate_1(recording):
    return replay_and_receive(recording)


def test_replay_delivers_everything_in_order_with_its_spacing(recording, at_rate_1):
    got = at_rate_1
    assert got.returncode == 0, got.stderr
    assert 'replayed 38 messages' in got.stderr
    for topic in BLOCK_TOPICS:
        assert got.count(topic) == round(DURATION_S / BLOCK_S) == 12, topic
    assert got.count(f'{NS}/shock') == 1 and got.count('/diagnostics') == 1
    assert got.count('/clock') == 0
    recorded = recorded_blocks(recording)
    received = got.topic(f'{NS}/modal_displacement')
    # Same messages, same order, values unchanged (published as recorded, bit for bit).
    for (_, msg), (_, data) in zip(received, recorded):
        assert np.array_equal(np.array(msg.data), data)
    check_spacing(got, f'{NS}/modal_displacement', recorded, 1.0)
    check_schedule(*got.schedule(recording), 1.0, 'every topic')
    # The shock (log time 0) comes first, 50 ms before the first block.
    assert got.items[0][1] == f'{NS}/shock'
    first_block = got.published_ns(f'{NS}/modal_displacement')[0]
    shock = got.published_ns(f'{NS}/shock')[0]
    assert (first_block - shock) * 1e-9 == pytest.approx(BLOCK_S, abs=JITTER_S)
    # Across topics, arrivals keep the log-time order (blocks of one time arrive together).
    times = {BLOCK_TOPICS[0]: [t for t, _ in recorded]}
    order = []
    for wall, topic, msg in got.items:
        if topic in BLOCK_TOPICS:
            order.append(int(round(msg.data[-msg.layout.dim[1].size] * 1e9)))
    assert order == sorted(order)
    assert sorted(set(order)) == times[BLOCK_TOPICS[0]]


def test_rate_2_halves_the_spacing(recording, at_rate_1):
    got = replay_and_receive(recording, '--rate', '2')
    assert got.returncode == 0, got.stderr
    received = got.topic(f'{NS}/modal_displacement')
    assert len(received) == 12
    check_spacing(got, f'{NS}/modal_displacement', recorded_blocks(recording), 2.0)
    span_1 = at_rate_1.published_ns(f'{NS}/modal_displacement')
    span_1 = (span_1[-1] - span_1[0]) * 1e-9
    span_2 = got.published_ns(f'{NS}/modal_displacement')
    span_2 = (span_2[-1] - span_2[0]) * 1e-9
    print(f'first to last block: {span_1 * 1e3:.0f} ms at rate 1, {span_2 * 1e3:.0f} ms at 2')
    assert span_2 == pytest.approx(0.5 * span_1, abs=JITTER_S)


def test_clock_and_topic_filter(recording):
    topic = f'{NS}/modal_displacement'
    got = replay_and_receive(recording, '--clock', '--topics', topic)
    assert got.returncode == 0, got.stderr
    assert 'replayed 12 messages' in got.stderr
    assert got.count(topic) == 12
    for other in BLOCK_TOPICS[1:] + [f'{NS}/shock', '/diagnostics']:
        assert got.count(other) == 0, other
    clock = got.topic('/clock')
    stamps = [c.clock.sec * 1_000_000_000 + c.clock.nanosec for _, c in clock]
    log_times = [t for t, _ in recorded_blocks(recording)]
    # One /clock per published message, with its log time, in order, before it.
    assert stamps == log_times
    blocks = got.topic(topic)
    for (clock_wall, _), (block_wall, _) in zip(clock, blocks):
        assert clock_wall <= block_wall + 0.005


def test_bad_arguments_fail_before_ros(recording, tmp_path, capsys):
    assert cli.main(['replay', str(recording), '--rate', '0']) != 0
    assert 'rate' in capsys.readouterr().err
    assert cli.main(['replay', str(recording), '--wait-for-subscribers', '-1']) != 0
    assert 'wait_for_subscribers' in capsys.readouterr().err
    missing = tmp_path / 'missing.mcap'
    assert cli.main(['replay', str(missing)]) != 0
    assert 'missing.mcap' in capsys.readouterr().err


# ------------------------------------------------------------------ hardening

FAR_FUTURE_NS = 2_145_916_800 * 1_000_000_000
"""2038-01-01T00:00:00Z in ns: an input stamped in 2038."""


class SignalAfter:
    """Send ``sig`` once ``count`` messages of ``topic`` have arrived (plus ``wait_s``)."""

    def __init__(self, sig, count, topic=f'{NS}/modal_displacement', wait_s=0.0):
        self.sig, self.count, self.topic, self.wait_s = sig, count, topic, wait_s
        self.reached = None
        self.sent = None
        self.received_before = None

    def __call__(self, proc, items):
        if self.sent is not None:
            return
        if self.reached is None and sum(t == self.topic for _, t, _ in items) >= self.count:
            self.reached = time.monotonic()
        if self.reached is not None and time.monotonic() >= self.reached + self.wait_s:
            self.received_before = len(items)
            proc.send_signal(self.sig)
            self.sent = time.monotonic()


def ended_after_signal(got, signaller):
    """Seconds from the signal to the end of the replay process (as this test saw it)."""
    return got.end - signaller.sent


@pytest.fixture(scope='module')
def long_recording(tmp_path_factory):
    """Record 2 s without a shock: 40 blocks per block topic, so replay takes 5 s in all."""
    path = tmp_path_factory.mktemp('replay_long') / 'long.mcap'
    config = paper_config({'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                           'output.rate': 20000.0, 'output.block_duration': BLOCK_S})
    run_offline(config, 2.0, output=str(path), progress=False)
    return path


@pytest.fixture(scope='module')
def far_future_recording(recording, tmp_path_factory):
    """Copy the 0.6 s recording and add one shock stamped (logged) in 2038, as a node would."""
    path = tmp_path_factory.mktemp('replay_2038') / 'far.mcap'
    with BagWriter(path) as bag:
        topics = set()
        for m in read_messages(recording):
            if m.topic not in topics:
                bag.add_topic(m.topic, m.type_name)
                topics.add(m.topic)
            bag.write(m.topic, m.data, m.log_time_ns)
        shock = Vector3Stamped()
        shock.header.stamp.sec = FAR_FUTURE_NS // 1_000_000_000
        shock.vector.x = 9806.65
        bag.write(f'{NS}/shock', shock, FAR_FUTURE_NS)
    return path


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_a_signal_during_replay_ends_it_cleanly(long_recording, sig):
    # After 5 of the 40 blocks: well inside the replay (the first block comes after the 3 s
    # discovery wait, the last 2 s later).
    signaller = SignalAfter(sig, 5)
    got = replay_and_receive(long_recording, during=signaller)
    assert signaller.sent is not None, got.stderr
    assert 'Traceback' not in got.stderr and 'RCLError' not in got.stderr, got.stderr
    assert got.returncode == 0, got.stderr
    note = re.search(rf'stopped by {sig.name}: replayed (\d+) of (\d+) messages', got.stderr)
    assert note, got.stderr
    published, total = int(note.group(1)), int(note.group(2))
    # 40 blocks on each of 3 topics and /diagnostics once per simulated second (at 1 and 2 s).
    assert total == 122
    assert signaller.received_before <= published < total
    assert got.count(f'{NS}/modal_displacement') < 40
    # One sleep slice (50 ms) plus the shutdown of rclpy, generously under load.
    assert ended_after_signal(got, signaller) < 5.0


def test_a_signal_during_the_discovery_wait_ends_at_once(recording):
    state = {}

    def during(proc, items):
        state.setdefault('start', time.monotonic())
        if 'sent' not in state and time.monotonic() - state['start'] > 1.0:
            proc.send_signal(signal.SIGINT)
            state['sent'] = time.monotonic()
    start = time.monotonic()
    got = replay_and_receive(recording, during=during)
    assert got.returncode == 0, got.stderr
    assert 'Traceback' not in got.stderr
    assert 'stopped by SIGINT: replayed 0 of 38 messages' in got.stderr
    assert not got.items
    # The 3 s discovery wait is cut short (signal after 1 s plus start-up).
    assert got.end - start < 1.0 + DISCOVERY_AND_START_S


DISCOVERY_AND_START_S = 8.0
"""Start-up of the replay process (imports) before its discovery wait, generously."""


def test_a_2038_input_does_not_make_replay_wait_until_2038(far_future_recording):
    # Before the fix this waited 12 years: the timeout ends it (30 s >> 3 s discovery +
    # 0.6 s + 1 s shortened gap + 0.5 s tail).
    got = replay_and_receive(far_future_recording, timeout=30.0)
    assert got.returncode == 0, got.stderr
    assert 'replayed 39 messages (1 gap(s) shortened' in got.stderr
    assert re.search(r'warning: a gap of [0-9.e+]+ s in the log times before the message on '
                     rf'{NS}/shock at 2\.14592e\+09 s: shortened to 1 s', got.stderr), got.stderr
    shocks = got.topic(f'{NS}/shock')
    assert len(shocks) == 2
    assert shocks[-1][1].header.stamp.sec == FAR_FUTURE_NS // 1_000_000_000
    last_block = got.published_ns(f'{NS}/modal_displacement')[-1]
    # The gap after the last block (log time 0.55 s) is cut to MAX_GAP_S.
    gap_s = (got.published_ns(f'{NS}/shock')[-1] - last_block) * 1e-9
    assert gap_s == pytest.approx(MAX_GAP_S, abs=JITTER_S)


def test_sigterm_ends_a_long_gap_kept_by_max_gap_inf(far_future_recording):
    # --max-gap inf keeps the 12-year gap: the replay then waits, but a SIGTERM ends it.
    signaller = SignalAfter(signal.SIGTERM, 12, wait_s=0.5)
    got = replay_and_receive(far_future_recording, '--max-gap', 'inf', timeout=60.0,
                             during=signaller)
    assert signaller.sent is not None, got.stderr
    assert got.returncode == 0, got.stderr
    assert 'Traceback' not in got.stderr
    assert 'stopped by SIGTERM: replayed 38 of 39 messages' in got.stderr
    assert got.count(f'{NS}/shock') == 1
    assert ended_after_signal(got, signaller) < 5.0


def run_replay(*args, timeout=60.0):
    """Run ``ring_gyro replay *args``; return (exit code, stderr, wall time)."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(REPO_ROOT)] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    start = time.monotonic()
    proc = subprocess.run(replay_command() + ['replay', *map(str, args)], env=env,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, timeout=timeout)
    return proc.returncode, proc.stderr.decode(errors='replace'), time.monotonic() - start


@pytest.mark.parametrize('kind, reason', [
    ('empty', 'is empty (0 bytes)'),
    ('short', 'is not an MCAP file (3 bytes'),
    ('yaml', 'is not an MCAP file'),
    ('truncated', 'is incomplete: it has no summary'),
])
def test_a_file_that_cannot_be_replayed_is_refused(recording, tmp_path, kind, reason):
    path = tmp_path / f'{kind}.mcap'
    content = {'empty': b'', 'short': b'abc',
               'yaml': (REPO_ROOT / 'config' / 'demo.yaml').read_bytes(),
               # half the file: every chunk before the cut is complete, the summary is gone
               'truncated': recording.read_bytes()[:recording.stat().st_size // 2]}[kind]
    path.write_bytes(content)
    code, err, wall = run_replay(path)
    assert code == 1, err
    assert 'Traceback' not in err
    assert 'ring_gyro replay: error: ' in err and str(path) in err and reason in err, err
    assert 'replayed' not in err
    # Refused before ROS starts: no discovery wait (3 s).
    assert wall < DISCOVERY_AND_START_S


def test_topics_not_in_the_recording_are_refused(recording):
    code, err, _ = run_replay(recording, '--topics', '/nope')
    assert code == 1, err
    assert '--topics: /nope not in recording' in err and f'{NS}/radial_gap' in err


# ------------------------------------------------------------------ gyroscope topics

GYRO_BLOCKS = 20
"""
Blocks of BLOCK_S in the gyro recording (1 s, 1000 rate samples at 1 kHz): long enough that
one stall of a loaded host (100 ms seen in CI) holds up a small share of the samples.
"""


@pytest.fixture(scope='module')
def gyro_recording(tmp_path_factory):
    """
    Record a gyroscope run whose blocks carry synthetic rate and demodulator samples.

    The sense electronics are not what is tested here (they fill Block.rate / Block.demod);
    the sink and recorder write what a gyroscope run writes, including an angular rate. The
    drive is the closed loop, so the blocks also carry the loops' updates (``~/control``, the
    simulator's own rows, 50 per block of 50 ms at 1 kHz).
    """
    from ring_gyro_sim import run as run_mod
    from ring_gyro_sim.core.gyro.control import update_rows
    from ring_gyro_sim.core.gyro.electronics import DemodSamples, RateSamples
    from ring_gyro_sim.core.engine.full import Simulator
    from ring_gyro_sim.ros.recorder import RunRecorder
    from ring_gyro_sim.ros.sinks import RosSink
    path = tmp_path_factory.mktemp('replay_gyro') / 'gyro.mcap'
    config = paper_config({'drive.start_on': 'rest', 'modes.companions': True,
                           'gyro.enabled': True, 'output.rate': 20000.0,
                           'output.block_duration': BLOCK_S, 'control.mode': 'closed_loop'})
    sim = Simulator(config)
    sink = RosSink(sim.channel_names, NS,
                   recorder=RunRecorder(str(path), config, sim.channel_names, NS),
                   frame_id='gyro_link')
    sink.input(run_mod.AngularRate(z=0.174533, at_ns=0))
    for k in range(GYRO_BLOCKS):
        first = sim.sample_index
        s = sim.advance_samples(1000)
        rate_t = s.t[19::20]  # every 20th sample of 50 us: 1 kHz
        rate = RateSamples(t=rate_t, rate=0.17 + 1e-5 * np.arange(50 * k, 50 * k + 50),
                           quadrature=np.zeros(50))
        demod = DemodSamples(t=s.t, values=np.full((1000, 4), float(k)))
        control = update_rows(first, s.t, s.control, sim.loop.window, sim.period_s)
        sink.block(run_mod.Block(samples=s, end_ns=sim.time_ns, first_index=first,
                                 rate=rate, demod=demod, control=control))
    sink.close()
    return path


def test_replay_publishes_the_gyro_topics_with_their_timing(gyro_recording):
    got = replay_and_receive(gyro_recording)
    assert got.returncode == 0, got.stderr
    recorded = [(m.log_time_ns, decode(m)) for m in read_messages(gyro_recording,
                                                                  f'{NS}/rate')]
    assert len(recorded) == 50 * GYRO_BLOCKS
    received = got.topic(f'{NS}/rate')
    assert len(received) == len(recorded)
    for (_, msg), (log_ns, original) in zip(received, recorded):
        assert msg.angular_velocity.z == original.angular_velocity.z
        assert msg.header.stamp == original.header.stamp
        assert msg.header.frame_id == 'gyro_link'
        assert msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec == log_ns
    # Each rate sample is published at its own log time (1 ms apart), not in block bursts,
    # and the block topics at theirs, without drift.
    check_schedule(got.published_ns(f'{NS}/rate'), np.array([t for t, _ in recorded]), 1.0,
                   f'{NS}/rate')
    check_schedule(*got.schedule(gyro_recording), 1.0, 'every topic')
    assert got.count(f'{NS}/demodulator') == GYRO_BLOCKS
    # The closed loop's block topic, as the other block topics: every block, as recorded.
    control = [(m.log_time_ns, decode(m)) for m in read_messages(gyro_recording,
                                                                 f'{NS}/control')]
    received = got.topic(f'{NS}/control')
    assert len(control) == len(received) == GYRO_BLOCKS
    for (_, msg), (_, original) in zip(received, control):
        assert msg.layout == original.layout
        assert np.array_equal(np.array(msg.data), np.array(original.data))
    assert sum(msg.layout.dim[0].size for _, msg in received) == 50 * GYRO_BLOCKS - 1
    assert got.count(f'{NS}/angular_rate') == 1
    (_, acted), = got.topic(f'{NS}/angular_rate')
    assert acted.vector.z == 0.174533


# ------------------------------------------------------------------ a stall of the host

STALL_S = 0.3
"""How long test_a_stall_is_caught_up stops the replay process (SIGSTOP), s."""


class Stall:
    """Stop the replay process for ``STALL_S`` once ``count`` messages of ``topic`` arrived."""

    def __init__(self, count, topic=f'{NS}/modal_displacement'):
        self.count, self.topic = count, topic
        self.done = False

    def __call__(self, proc, items):
        if self.done or sum(t == self.topic for _, t, _ in items) < self.count:
            return
        proc.send_signal(signal.SIGSTOP)
        try:
            time.sleep(STALL_S)
        finally:
            proc.send_signal(signal.SIGCONT)
        self.done = True


def test_a_stall_is_caught_up(long_recording):
    # What a loaded host does to the replay, on purpose: the process does not run for 0.3 s
    # in the middle of the 2 s replay. The messages due meanwhile are published late, at
    # once when it runs again; the ones after that on the original schedule, not 0.3 s late.
    stall = Stall(10)
    got = replay_and_receive(long_recording, during=stall)
    assert stall.done, got.stderr
    assert got.returncode == 0, got.stderr
    assert 'replayed 122 messages' in got.stderr  # nothing dropped to catch up
    published, log_ns = got.schedule(long_recording)
    # The stall shows in the publication times (else this test tested nothing).
    gaps = np.diff(np.sort(published)) * 1e-9
    resumed = np.sort(published)[np.argmax(gaps) + 1]
    assert gaps.max() > 0.9 * STALL_S
    lag = publication_lags(published, log_ns, 1.0)
    deadline = published - np.round(lag * 1e9).astype(np.int64)
    overdue = deadline < resumed
    after = deadline > resumed + round(2 * BLOCK_S * 1e9)
    print(f'stall of {gaps.max() * 1e3:.0f} ms; lag of the overdue messages up to '
          f'{lag[overdue].max() * 1e3:.0f} ms, median lag after '
          f'{np.median(lag[after]) * 1e3:.2f} ms ({np.sum(after)} messages)')
    assert lag[overdue].max() > 0.9 * STALL_S - BLOCK_S
    # Back on schedule: the stall was not carried on to the rest of the replay.
    assert np.sum(after) >= 40
    assert np.median(lag[after]) < ON_TIME_S
    # The replay says how late it was.
    note = re.search(r'latest publication ([0-9.e+]+) ms after its deadline', got.stderr)
    assert note, got.stderr
    assert float(note.group(1)) * 1e-3 > 0.9 * STALL_S - BLOCK_S


def test_replay_in_a_process_that_runs_ros_leaves_its_context_alone(
        recording, monkeypatch, capsys):
    # replay() called from a process whose global context is up (a test session, an
    # application) refused with 'Context.init() must only be called once', and its
    # try_shutdown would have shut the caller's context down: it has a context of its own.
    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    started = not rclpy.ok()
    if started:
        rclpy.init()
    try:
        assert cli.main(['replay', str(recording), '--rate', '1000', '--topics',
                         f'{NS}/modal_displacement']) == 0
        assert json.loads(capsys.readouterr().out)['published'] > 0
        assert rclpy.ok()
    finally:
        if started:
            rclpy.try_shutdown()
