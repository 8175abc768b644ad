# Copyright 2025 ring_gyro_sim developers
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
Node tests of the gyroscope's ROS plumbing.

``~/angular_rate`` in, ``~/rate`` (sensor_msgs/Imu) and ``~/demodulator`` out, all recorded.
Real rclpy across processes (``node_harness``): topics, types, QoS, the input accepted or
refused and counted, the recording's channels, the contents of ``~/rate``; and the node as a
user meets it first, with no parameter file (the gyroscope) or config/default.yaml under
another name.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import json
import math
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

from geometry_msgs.msg import Vector3Stamped
from mcap.reader import make_reader
from node_harness import (connected, MATCH_TIMEOUT_S, node_env, NodeProcess, Probe, REPO_ROOT,
                          start_node)
import numpy as np
import pytest
from rclpy.qos import ReliabilityPolicy
from ring_gyro_sim.recording.reader import decode, read_messages, read_rate
from ring_gyro_sim.ros import conversions
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float64MultiArray
# isort: on

NS = '/ring_gyro'
# 20 kHz output (a whole multiple of the 1 kHz rate output), paced, from rest.
GYRO = {'drive.start_on': 'rest', 'modes.companions': True, 'gyro.enabled': True,
        'output.rate': 20000.0, 'gyro.frame_id': 'gyro_link', 'duration': 0.0}
TEN_DEG_S = math.radians(10.0)  # 0.174533 rad/s: the gyroscope's test rate


class GyroProbe(Probe):
    """The harness probe, also on ``~/rate``, ``~/demodulator`` and ``~/angular_rate``."""

    def __init__(self):
        super().__init__()
        self.rate = []
        self.demod = []
        self.create_subscription(Imu, f'{NS}/rate', self.rate.append, 1000)
        self.create_subscription(Float64MultiArray, f'{NS}/demodulator', self.demod.append,
                                 200)
        self.angular_rate_pub = self.create_publisher(Vector3Stamped, f'{NS}/angular_rate', 10)

    def angular_rate(self, z, at_ns=0, x=0.0):
        msg = conversions.angular_rate_message(at_ns, z, x=x)
        self.angular_rate_pub.publish(msg)


def counted(probe, key, value, timeout=30.0):
    """Wait until a diagnostics snapshot says ``key == value``."""
    probe.spin_until(lambda: (probe.latest_diagnostics() or {}).get(key) == str(value),
                     timeout, f'{key} = {value} on /diagnostics')


def stop(node):
    node.signal(signal.SIGINT)
    assert node.wait(30.0) == 0, node.output()[-3000:]


def test_gyro_node_offers_the_gyro_topics_and_records_them(ros, tmp_path):
    path = tmp_path / 'gyro.mcap'
    node = start_node(tmp_path, {**GYRO, 'record.path': str(path)})
    with connected(node, GyroProbe) as probe:
        probe.spin_until(lambda: probe.angular_rate_pub.get_subscription_count() > 0, 20.0,
                         'the ~/angular_rate subscription')
        types = dict(probe.get_topic_names_and_types())
        assert types[f'{NS}/rate'] == ['sensor_msgs/msg/Imu']
        assert types[f'{NS}/demodulator'] == ['std_msgs/msg/Float64MultiArray']
        (rate_info,) = probe.get_publishers_info_by_topic(f'{NS}/rate')
        assert rate_info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        # Open loop (config/gyro.yaml): no ~/control (test_node_control).
        assert not probe.get_publishers_info_by_topic(f'{NS}/control')
        probe.angular_rate(TEN_DEG_S, x=0.5)
        # Accepted (x ignored, with a warning) or refused: either way once, and counted.
        probe.spin_for(1.0)
        stop(node)
    log = node.output()
    acted = list(read_messages(path, f'{NS}/angular_rate'))
    diagnostics = [decode(m) for m in read_messages(path, '/diagnostics')]
    rejected = {kv.key: kv.value for kv in diagnostics[-1].status[0].values}['rejected_inputs']
    assert len(acted) + int(rejected) == 1, log[-3000:]
    if acted:
        assert decode(acted[0]).vector.z == TEN_DEG_S
        assert 'the x and y components are ignored' in log
    else:
        assert 'rejected ~/angular_rate' in log
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert types[f'{NS}/rate'] == 'sensor_msgs/msg/Imu'
    assert types[f'{NS}/demodulator'] == 'std_msgs/msg/Float64MultiArray'
    assert types[f'{NS}/angular_rate'] == 'geometry_msgs/msg/Vector3Stamped'
    assert f'{NS}/control' not in types


def test_a_resonator_node_refuses_angular_rates_and_has_no_rate_output(ros, tmp_path):
    node = start_node(tmp_path, {**GYRO, 'gyro.enabled': False})
    with connected(node, GyroProbe) as probe:
        probe.spin_until(lambda: probe.angular_rate_pub.get_subscription_count() > 0, 20.0,
                         'the ~/angular_rate subscription')
        # The probe subscribes to both, so the topics exist; nobody publishes them.
        assert not probe.get_publishers_info_by_topic(f'{NS}/rate')
        assert not probe.get_publishers_info_by_topic(f'{NS}/demodulator')
        assert not probe.get_publishers_info_by_topic(f'{NS}/control')
        for _ in range(3):
            probe.angular_rate(TEN_DEG_S)
        counted(probe, 'rejected_inputs', 3)
        stop(node)
    log = node.output()
    # One warning for the three (throttled per topic and kind of reason).
    assert log.count('rejected ~/angular_rate') == 1, log[-3000:]
    assert not probe.rate and not probe.demod


class ThermalProbe(Probe):
    """The harness probe, also publishing ``~/temperature``, on ``~/die_temperature``."""

    def __init__(self):
        super().__init__()
        self.die = []
        self.create_subscription(Temperature, f'{NS}/die_temperature', self.die.append, 100)
        self.temperature_pub = self.create_publisher(Temperature, f'{NS}/temperature', 10)

    def ambient(self, celsius):
        self.temperature_pub.publish(Temperature(temperature=float(celsius)))


def test_the_ambient_on_its_topic_moves_the_die_sensor_and_is_recorded(ros, tmp_path):
    # thermal.time_constant 0: the die is the ambient (T1), so the die's sensor reads the
    # step at the next block. -200 degrees C (73.15 K) is outside 150-500 K: refused, counted.
    path = tmp_path / 'thermal.mcap'
    node = start_node(tmp_path, {**GYRO, 'thermal.time_constant': 0.0,
                                 'record.path': str(path)})
    with connected(node, ThermalProbe) as probe:
        probe.spin_until(lambda: probe.temperature_pub.get_subscription_count() > 0
                         and probe.die, 20.0, 'the ~/temperature subscription and the die')
        assert probe.die[0].temperature == pytest.approx(25.0, abs=1e-9)  # the reference
        assert probe.die[0].header.frame_id == 'gyro_link'
        probe.ambient(35.0)
        probe.ambient(-200.0)
        probe.spin_until(lambda: abs(probe.die[-1].temperature - 35.0) < 1e-9, 20.0,
                         'the die at 35 degrees C')
        counted(probe, 'rejected_temperature', 1)
        stop(node)
    acted = [decode(m) for m in read_messages(path, f'{NS}/temperature')]
    assert [m.temperature for m in acted] == [pytest.approx(35.0, abs=1e-12)]
    die = [(m.log_time_ns, decode(m).temperature)
           for m in read_messages(path, f'{NS}/die_temperature')]
    step_ns = next(m.log_time_ns for m in read_messages(path, f'{NS}/temperature'))
    assert all(c == pytest.approx(25.0 if t <= step_ns else 35.0, abs=1e-9) for t, c in die)
    assert die[-1][1] == pytest.approx(35.0, abs=1e-9)


def test_rate_output_end_to_end(ros, tmp_path):
    """
    ``~/rate`` of a node turning at 10 deg/s: stamps, frame, REP-145 fields, value within 1 %.

    The node starts on the orbit with the sense mode's steady response to the rate
    (``nnm._add_sense_response``) and the filters settled, so the first 1.0 s discarded is a
    margin, not a settling time (the offline reading is within 0.04 % from the first
    sample: doc/gyroscope.md).
    """
    path = tmp_path / 'rate.mcap'
    # config/gyro.yaml's operating point (a tenth of the paper's drive at 15 800 Hz, started
    # on its orbit with the sense mode's steady response to the rate: doc/gyroscope.md).
    # The node runs until SIGINT, sent once 1 500 rate samples arrived live: with a fixed
    # duration of 1.5 s it could finish before the probe had discovered it (beside one CPU
    # hog: 'timed out waiting for the node to be up and matched', 1 run in 4).
    node = start_node(tmp_path, {**GYRO, 'scenario.rate_times': [0.0],
                                 'drive.amplitude': 0.0065, 'drive.frequency': 15800.0,
                                 'drive.start_on': 'upper_branch',
                                 'scenario.rate_values': [TEN_DEG_S], 'duration': 0.0,
                                 'record.path': str(path)})
    with connected(node, GyroProbe) as probe:
        # Spin while the node runs: the rate messages must not wait in the reader's history
        # (1 000 deep) while nobody takes them.
        probe.spin_until(lambda: len(probe.rate) >= 1500, 120.0, '1 500 rate samples live')
        node.signal(signal.SIGINT)
        probe.spin_until(lambda: node.proc.poll() is not None, 60.0, 'the node to finish')
        assert node.wait(10.0) == 0, node.output()[-3000:]
        probe.spin_for(0.5)
    stamps = [m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec for m in probe.rate]
    # 1 kHz on the simulation clock: consecutive stamps 1 ms apart, none lost or repeated.
    assert np.all(np.diff(stamps) == 1_000_000)
    for m in probe.rate:
        assert m.header.frame_id == 'gyro_link'
        assert m.orientation_covariance[0] == -1.0
        assert m.linear_acceleration_covariance[0] == -1.0
    series = read_rate(path)
    # recorded whole, from the first sample at 1 ms to the last one the node published
    assert np.array_equal(series.t_ns, (np.arange(len(series.t_ns)) + 1) * 1_000_000)
    assert len(series.t_ns) >= 1500
    settled = series.rate[series.t_ns > 1_000_000_000]
    assert np.mean(settled) == pytest.approx(TEN_DEG_S, rel=0.01)
    # and what subscribers got live, with the electronics' predicted variance on z (REP-145):
    # the recording's last samples from the moment the probe was discovered.
    live = np.array([m.angular_velocity.z for m in probe.rate])
    assert len(live) >= 1500, len(live)
    assert stamps[-1] == series.t_ns[-1]
    assert np.array_equal(live, series.rate[-len(live):])
    cov = probe.rate[-1].angular_velocity_covariance
    assert cov[8] > 0.0 and cov[0] == cov[4] == 1e6  # x, y not measured, finite
    # /diagnostics carries the rate channel's state
    diag = probe.latest_diagnostics()
    assert diag is not None
    for key in ('rate_scale_factor_v_per_rad_s', 'rate_quadrature_rad_s', 'noise_seed',
                'temperature_k', 'input_noise_density_v_per_sqrt_hz',
                'predicted_arw_deg_per_sqrt_h', 'scale_factor_valid'):
        assert key in diag, sorted(diag)
    assert float(diag['rate_scale_factor_v_per_rad_s']) > 0.0


class NamedRateProbe(Probe):
    """The harness probe for a node of another name: its ``~/rate`` and ``~/angular_rate``."""

    def __init__(self, target):
        super().__init__(target)
        self.rate = []
        self.create_subscription(Imu, f'{target}/rate', self.rate.append, 1000)
        self.angular_rate_pub = self.create_publisher(Vector3Stamped, f'{target}/angular_rate',
                                                      10)


def test_the_default_node_is_the_gyroscope_under_any_name(ros, tmp_path):
    # What a user meets first: with no parameter file the node is the gyroscope (~/rate out).
    bare = NodeProcess(None, tmp_path)
    with connected(bare, lambda: NamedRateProbe('/ring_gyro')) as probe:
        probe.spin_until(lambda: len(probe.rate) >= 100, 60.0, '~/rate of the default node')
    assert bare.wait(10.0) == 0
    # config/default.yaml (`/**:`) configures a node of any name, as the README runs it.
    (tmp_path / 'left').mkdir()
    left = NodeProcess(REPO_ROOT / 'config' / 'default.yaml', tmp_path / 'left',
                       '-r', '__node:=gyro_left')
    with connected(left, lambda: NamedRateProbe('/gyro_left')) as probe:
        probe.spin_until(lambda: probe.angular_rate_pub.get_subscription_count() > 0, 20.0,
                         '/gyro_left/angular_rate')
        probe.spin_until(lambda: probe.rate, 20.0, '/gyro_left/rate')
        msg = Vector3Stamped()
        msg.vector.z = TEN_DEG_S  # stamp 0: now
        probe.angular_rate_pub.publish(msg)
        # force-to-rebalance reads within ~20 ms (20 Hz); 0.5 s after the step, 0.5 s kept
        probe.spin_until(lambda: len([m for m in probe.rate if m.angular_velocity.z > 0.5
                                      * TEN_DEG_S]) >= 1000, 60.0, '1 s of the 10 deg/s')
    assert left.wait(10.0) == 0
    turning = [m.angular_velocity.z for m in probe.rate if m.angular_velocity.z > 0.5
               * TEN_DEG_S]
    settled = np.mean(turning[500:1000])
    print(f'/gyro_left/rate at 10 deg/s: {math.degrees(settled):.4f} deg/s')
    assert settled == pytest.approx(TEN_DEG_S, rel=0.01)
    assert 'gyro_left' in left.output()


RATE_FLOOD_HZ = 5000
RATE_FLOOD_S = 2.0


class RateFloodProbe(Probe):
    """A probe on ``~/modal_displacement`` alone, with a deep ``~/angular_rate`` publisher."""

    def __init__(self):
        super().__init__(topics=('modal_displacement',))
        self.flood_pub = self.create_publisher(Vector3Stamped, f'{NS}/angular_rate', 1000)


def caught_up(probe):
    """Spin until the probe has taken what waits for it: its last block is the node's now."""
    blocks = probe.blocks['modal_displacement']
    while True:
        before = len(blocks)
        probe.spin_for(0.05)
        if len(blocks) - before <= 10:  # ~5 blocks in 50 ms at the live rate
            return


def test_a_rate_flood_keeps_the_node_paced_and_every_message_counted(ros, tmp_path):
    # 5 kHz of ~/angular_rate stamped ahead for 2 s: the node keeps its pace (a rate that
    # read the whole profile would cost 49 us with 1 000 pending, 245 us with 8 000) and
    # counts every message (doc/performance.md, "The node under an angular-rate flood").
    # Stamps 1 to 2 s ahead,
    # 100 us apart: the first 1 000 are held, the next refused until the first of them act.
    # What the flood costs, not the physics: the cheapest step (Strang, one 50 us step per
    # sample) and the node at nice -10, so that others' load on two shared cores does
    # not decide its pace (a bm6 node without priority ran at x0.50 without a flood at load 5).
    node = start_node(tmp_path, {**GYRO, 'integrator.method': 'strang',
                                 'integrator.max_step': 5e-5}, nice=-10)
    with connected(node, RateFloodProbe) as probe:
        probe.spin_until(lambda: probe.flood_pub.get_subscription_count() > 0, 20.0,
                         'the ~/angular_rate subscription')
        keys = ('accepted_angular_rate', 'rejected_angular_rate', 'lost_inputs')
        wall = time.monotonic()
        probe.spin_until(lambda: probe.latest_diagnostics(wall) is not None, 10, 'diagnostics')
        before = {k: int(probe.latest_diagnostics(wall).get(k, 0)) for k in keys}
        batch = RATE_FLOOD_HZ // 100
        messages = [conversions.angular_rate_message(0, 0.01 * (k % 7))
                    for k in range(int(RATE_FLOOD_HZ * RATE_FLOOD_S))]
        sent = [0]

        def flood():
            start = time.monotonic()
            for b in range(0, len(messages), batch):
                for msg in messages[b:b + batch]:
                    probe.flood_pub.publish(msg)
                sent[0] += batch
                delay = start + 0.01 * (b // batch + 1) - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
        # Stamped from the node's now once the probe has caught up (building the messages
        # takes a good part of a second on a slow host: stamped before, the first ones were
        # late and all 10 000 refused as in the past)
        caught_up(probe)
        base_ns = probe.last_time_ns() + 1_000_000_000
        for k, msg in enumerate(messages):
            msg.header.stamp = conversions.ns_to_stamp(base_ns + k * 100_000)
        sim0, wall0 = probe.last_time_ns(), time.monotonic()
        thread = threading.Thread(target=flood)
        thread.start()
        probe.spin_until(lambda: not thread.is_alive(), 30.0, 'the flood to end')
        wall = time.monotonic() - wall0
        caught_up(probe)
        progress = (probe.last_time_ns() - sim0) * 1e-9 / wall

        def counts():
            latest = probe.latest_diagnostics() or {}
            return {k: int(latest.get(k, 0)) - before[k] for k in keys}
        # Until every message is counted, or 10 s (a node behind on a loaded host drains late).
        end = time.monotonic() + 10.0
        while sum(counts().values()) < sent[0] and time.monotonic() < end:
            probe.spin_for(0.2)
        counted = counts()
        print(f'\n{sent[0]} rates in {wall:.2f} s ({sent[0] / wall:.0f}/s); the node simulated '
              f'x{progress:.2f} real time meanwhile; counted {counted}')
        assert sent[0] / wall > 0.8 * RATE_FLOOD_HZ
        assert progress > 0.5
        # Every message accepted, refused or reported lost, but for what a keep-last queue of
        # 1 000 (0.2 s of this flood) overwrites unreported while the node is held up by
        # others' load (5 % once in 7 runs on two shared cores), as in the shock flood.
        assert sum(counted.values()) >= 0.95 * sent[0]
        assert counted['accepted_angular_rate'] >= 1000 and counted['rejected_angular_rate'] > 0


RATE_WARM_UP_S = 4.0
"""How long the rate test lets the node settle after its subscriber started, s: starting it
(imports, discovery) takes two shared cores from the node, which then catches up (up to 0.5 s
behind for the first 3.3 s once, at a load of 6.6)."""
RATE_LISTEN_S = 4.0
"""How long the best-effort subscriber listens to ``~/rate`` after that, s."""


def test_a_sensor_data_subscriber_gets_every_rate_message(ros, tmp_path):
    # ~/rate goes out paced, not in bursts of 10 per 10 ms block, of which a subscriber with
    # rclpy's qos_profile_sensor_data (best effort, keep last 5) gets 79-80 % of the messages.
    # The subscriber runs in its own process (rate_listener.py), as a user's node would, and
    # notes when each message was sent (the middleware's source timestamp).
    # The plumbing, not the physics: the cheapest step (Strang, one 50 us step per sample), and
    # the node's process at nice -10, so that the node keeps real time on two shared cores
    # (x0.56-0.82 with bm6 and no priority under others' load): pacing is the contract of
    # a node that keeps its pace, as receiving everything is that of a subscriber keeping up.
    node = start_node(tmp_path, {**GYRO, 'integrator.method': 'strang',
                                 'integrator.max_step': 5e-5}, nice=-10)
    with connected(node, lambda: Probe(topics=('modal_displacement',))) as probe:
        with open(tmp_path / 'listener.log', 'wb') as log:
            # A subscriber that keeps up: on shared cores its process gets the priority
            # of one (nice -10, ~10 % of a core), so that what it misses is the node's doing.
            listener = subprocess.Popen(
                [sys.executable, str(pathlib.Path(__file__).with_name('rate_listener.py')),
                 f'{NS}/rate'], env=node_env(), stdout=subprocess.PIPE, stderr=log,
                preexec_fn=lambda: os.nice(-10))
            try:
                probe.spin_until(lambda: probe.count_subscribers(f'{NS}/rate') > 0,
                                 MATCH_TIMEOUT_S, 'the listener on ~/rate')
                probe.spin_for(RATE_WARM_UP_S + RATE_LISTEN_S)
            finally:
                listener.send_signal(signal.SIGINT)
                out, _ = listener.communicate(timeout=30)
    got = json.loads(out.decode().strip().splitlines()[-1])
    stamps, sent = np.array(got['stamps_ns']), np.array(got['sent_ns'])
    listened = sent >= sent[0] + RATE_WARM_UP_S * 1e9
    stamps, sent = stamps[listened], sent[listened]
    # Judged while the node kept its pace: in 100 ms windows of sample time whose messages
    # all went out less than 50 ms later than the promptest (the node's own jitter is a few
    # ms). On shared cores even a node at nice -10 stalls for 250 ms at times, and a
    # stall longer than rate_pacer.MAX_LATE_S makes a burst by design.
    late = (sent - stamps) * 1e-6
    late -= late.min()  # ms
    window = (stamps - stamps.min()) // 100_000_000
    on_pace = [w for w in np.unique(window) if late[window == w].max() < 50.0]
    got = expected = in_bursts = 0
    for w in on_pace:
        mine = window == w
        got += int(np.count_nonzero(mine))
        expected += int((stamps[mine].max() - stamps[mine].min()) // 1_000_000 + 1)
        # bursts: runs of messages sent less than 0.2 ms apart (a pair is paced: GROUP)
        runs = np.bincount(np.concatenate([[0], np.cumsum(np.diff(sent[mine]) >= 200_000)]))
        in_bursts += int(runs[runs > 3].sum())
    fraction = got / max(expected, 1)
    print(f'\n{len(on_pace)} of {len(np.unique(window))} windows of 100 ms on pace; there '
          f'{got} of {expected} rate messages received ({100 * fraction:.1f} %), '
          f'{in_bursts} in bursts of more than 3; late by at most {late.max():.1f} ms overall')
    assert np.all(np.diff(stamps) > 0)  # in order, none twice
    assert len(on_pace) >= 10 and expected >= 1000
    assert in_bursts <= 0.01 * got  # paced: one per period, two together (GROUP)
    assert fraction >= 0.98
