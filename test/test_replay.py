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
"""

import os
import pathlib
import random
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
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.offline import run_offline
from ring_gyro_sim.recording.reader import decode, read_messages, read_topics
from ring_gyro_sim.recording.schemas import message_class
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
DOMAIN_ID = random.SystemRandom().randrange(215, 233)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
NS = '/ring_gyro'
BLOCK_TOPICS = [f'{NS}/modal_displacement', f'{NS}/radial_gap', f'{NS}/sense_electrodes']
TOPIC_TYPES = {**{t: Float64MultiArray for t in BLOCK_TOPICS}, f'{NS}/shock': Vector3Stamped,
               '/diagnostics': DiagnosticArray, '/clock': Clock}
BLOCK_S = 0.05
"""Log-time spacing of the recorded blocks, s."""
DURATION_S = 0.6
JITTER_S = 0.025
"""Allowed deviation of one arrival from its schedule (scheduling and discovery), s."""


def replay_command():
    """Return the ``ring_gyro`` console script next to this Python, else ``python -m``."""
    exe = pathlib.Path(sys.executable).parent / 'ring_gyro'
    return [str(exe)] if exe.exists() else [sys.executable, '-m', 'ring_gyro_sim.cli']


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """Record 0.6 s: a 2000 g shock at t = 0, blocks every 50 ms (12 per block topic)."""
    path = tmp_path_factory.mktemp('replay') / 'run.mcap'
    config = build_config({'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                           'output.rate': 20000.0, 'output.block_duration': BLOCK_S,
                           'scenario.shock_times': [0.0], 'scenario.shock_peaks': [19613.3]})
    run_offline(config, DURATION_S, output=str(path), progress=False)
    return path


class Received:
    """What one replay delivered: [(wall arrival, topic, message)] and the replay's output."""

    def __init__(self, items, result):
        self.items = items
        self.returncode, self.stderr = result

    def topic(self, name):
        return [(wall, msg) for wall, topic, msg in self.items if topic == name]

    def count(self, name):
        return len(self.topic(name))


def replay_and_receive(path, *args, timeout=60.0):
    """Run ``ring_gyro replay path *args`` in its own process and receive what it publishes."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=DOMAIN_ID)
    node = rclpy.create_node(f'replay_probe_{os.getpid()}', context=context)
    items = []
    # Every topic of the recording (channels without messages too: the replay waits until
    # each of its publishers has a subscriber), and /clock.
    types = {**{t: message_class(name) for t, name in read_topics(path).items()},
             **TOPIC_TYPES}
    for name, msg_type in types.items():
        node.create_subscription(
            msg_type, name,
            lambda msg, name=name: items.append((time.monotonic(), name, msg)), 200)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(REPO_ROOT)] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])
    env['ROS_DOMAIN_ID'] = str(DOMAIN_ID)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    err_path = pathlib.Path(path).with_suffix(f'.{len(args)}.stderr')
    try:
        with open(err_path, 'wb') as err:
            # Start once our subscriptions are matched (a fixed discovery wait lost the
            # first 4 to 7 of 12 blocks on a loaded machine).
            proc = subprocess.Popen(replay_command() + ['replay', str(path), *args,
                                                        '--wait-for-subscribers', '60'],
                                    env=env,
                                    stdout=subprocess.DEVNULL, stderr=err)
            end = time.monotonic() + timeout
            while proc.poll() is None:
                if time.monotonic() > end:
                    proc.kill()
                    proc.wait()
                    pytest.fail(f'replay did not finish within {timeout} s')
                executor.spin_once(timeout_sec=0.005)
        tail = time.monotonic() + 0.5
        while time.monotonic() < tail:
            executor.spin_once(timeout_sec=0.01)
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    return Received(items, (proc.returncode, err_path.read_text(errors='replace')))


def recorded_blocks(path, topic=f'{NS}/modal_displacement'):
    """Return [(log_time_ns, data array)] of one block topic of the recording."""
    return [(m.log_time_ns, np.array(decode(m).data)) for m in read_messages(path, topic)]


def check_spacing(received, recorded, rate):
    """Arrivals follow the log times divided by ``rate`` within the jitter."""
    walls = np.array([w for w, _ in received])
    log_s = np.array([t for t, _ in recorded]) * 1e-9
    expected = (log_s - log_s[0]) / rate
    actual = walls - walls[0]
    deviation = np.max(np.abs(actual - expected))
    median = float(np.median(np.diff(walls)))
    print(f'rate {rate}: median spacing {median * 1e3:.1f} ms (expected '
          f'{BLOCK_S / rate * 1e3:.1f} ms), largest deviation {deviation * 1e3:.1f} ms')
    assert median == pytest.approx(BLOCK_S / rate, rel=0.1)
    assert deviation < JITTER_S


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
    check_spacing(received, recorded, 1.0)
    # The shock (log time 0) comes first, 50 ms before the first block.
    shock_wall = got.topic(f'{NS}/shock')[0][0]
    assert got.items[0][1] == f'{NS}/shock'
    assert received[0][0] - shock_wall == pytest.approx(BLOCK_S, abs=JITTER_S)
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
    check_spacing(received, recorded_blocks(recording), 2.0)
    span_1 = at_rate_1.topic(f'{NS}/modal_displacement')
    span_1 = span_1[-1][0] - span_1[0][0]
    span_2 = received[-1][0] - received[0][0]
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
