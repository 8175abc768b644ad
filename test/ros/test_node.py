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
Tests of ring_gyro_sim.ros.node with one node process shared by the tests of this module.

The tests run in file order and build on each other (a shock, then parameter changes, a
reset, rejected inputs, a flood, and SIGTERM at the end, which also checks the recording).
The node is paced to the wall clock (real_time_factor 1); outputs at 100 kHz.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import math
import pathlib
import re
import signal
import subprocess
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticStatus
from node_harness import (connected, MATCH_TIMEOUT_S, node_env, Probe, process_cpu_seconds,
                          start_node)
import numpy as np
import pytest
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.params import paper_config, to_flat
from ring_gyro_sim.offline import resimulate
from ring_gyro_sim.paramfile import parameters_from_yaml_text
from ring_gyro_sim.recording.reader import decode, read_messages, read_metadata
from ring_gyro_sim.ros import conversions
import yaml
# isort: on

PEAK = 98066.5
"""10 000 g, m/s^2."""
PERIOD_NS = 10_000
CONFIG = {
    'drive.amplitude': 0.065,
    'drive.frequency': 15798.3,
    'drive.start_on': 'rest',
    'output.rate': 100000,  # integer literal for a float parameter
    'output.block_duration': 0.01,
    'real_time_factor': 1.0,
    'publish_clock': True,
    'modes.quality_factors': [120000, 64700, 170000],  # integers in a float list
    'scenario.shock_times': [],  # an empty list reaches the node as "not set"
    'scenario.shock_peaks': [],
}
LABELS = {
    'modal_displacement': 't,q1,q2,q3',
    'radial_gap': 't,' + ','.join(f'e{i}' for i in range(8)) + ',min',
    'sense_electrodes': 't,' + ','.join(f'e{i}' for i in range(8)),
}


class Run:
    """The shared node process, its probe and what the tests learn along the way."""

    def __init__(self, node, probe, yaml_text, record_path):
        self.node = node
        self.probe = probe
        self.yaml_text = yaml_text
        self.record_path = record_path
        self.shocks = []  # (at_ns, x) sent and expected to be accepted
        self.reset_ns = None
        self.base_acceleration = []  # (at_ns, x) sent and expected to be accepted


@pytest.fixture(scope='module')
def run(ros, tmp_path_factory):
    workdir = tmp_path_factory.mktemp('node_run')
    record = workdir / 'run.mcap'
    # every sample recorded: the recording's blocks are checked for contiguity
    node = start_node(workdir, {**CONFIG, 'record.path': str(record), 'record.decimation': 1})
    with connected(node, Probe) as probe:
        yield Run(node, probe, (workdir / 'params.yaml').read_text(), record)


def offline_config(yaml_text, **changes):
    flat = parameters_from_yaml_text(yaml_text)
    config = paper_config(flat)
    if changes:
        flat = to_flat(config)
        flat.update(changes)
        config = paper_config(flat)
    return config


def offline_samples(sim, end_index, block=1000):
    """Advance ``sim`` to sample ``end_index`` in blocks; return {index: row} arrays."""
    start = sim.sample_index + 1
    q, gap = [], []
    while sim.sample_index < end_index:
        s = sim.advance_samples(min(block, end_index - sim.sample_index))
        q.append(s.q)
        gap.append(np.column_stack([s.gap, s.min_gap]))
    return start, np.concatenate(q), np.concatenate(gap)


def while_spinning(probe, function, *args):
    """
    Return ``function(*args)``, run in a thread while the probe keeps taking messages.

    The probe keeps at most 200 blocks per topic (2 s of simulation): an offline computation
    longer than that, without spinning, loses blocks and breaks the contiguity checks. The
    kernels release the GIL, so the probe keeps up meanwhile.
    """
    result = {}

    def target():
        try:
            result['value'] = function(*args)
        except BaseException as exc:  # re-raised in the test's thread
            result['error'] = exc
    thread = threading.Thread(target=target)
    thread.start()
    probe.spin_until(lambda: not thread.is_alive(), 600, 'the offline computation')
    thread.join()
    if 'error' in result:
        raise result['error']
    return result['value']


def sample_indices(t_s):
    return np.rint(np.asarray(t_s) * 1e9 / PERIOD_NS).astype(np.int64)


def assert_contiguous(probe):
    """
    Every block received is contiguous inside, and blocks come in order, never repeated.

    That no block is ever skipped by the node is checked on its recording (which gets every
    block: test_sigterm_ends_the_node_and_finalises_the_recording). A live subscriber gets
    every block only while it keeps up (the QoS contract: keep last 50); the probe shares
    the machine with the node and the offline comparisons, and on a loaded machine it fell
    behind by more than 50 blocks, so gaps between received blocks are counted and printed
    here, not asserted.
    """
    for topic, blocks in probe.blocks.items():
        for b in blocks:
            assert np.all(np.diff(sample_indices(b.t)) == 1), f'{topic}: a block not contiguous'
        starts = sample_indices([b.t[0] for b in blocks])
        ends = sample_indices([b.t[-1] for b in blocks])
        assert np.all(starts[1:] > ends[:-1]), f'{topic}: blocks repeated or out of order'
        missed = int(np.count_nonzero(starts[1:] != ends[:-1] + 1))
        if missed:
            print(f'{topic}: {missed} gaps between the blocks received (subscriber behind)')


def compare_with_offline(probe, sim, from_ns):
    """
    Compare the node's blocks after ``from_ns`` with ``sim`` advanced over the same samples.

    Returns (peak |q1| node, offline, smallest gap node, offline, bitwise equal).
    """
    _, node_q = probe.stacked('modal_displacement', from_ns * 1e-9 - 0.05)
    _, node_gap = probe.stacked('radial_gap', from_ns * 1e-9 - 0.05)
    index = sample_indices(node_q[:, 0])
    # The subscriptions matched at different times: compare the samples both topics have.
    index, in_q, in_gap = np.intersect1d(index, sample_indices(node_gap[:, 0]),
                                         assume_unique=True, return_indices=True)
    node_q, node_gap = node_q[in_q], node_gap[in_gap]
    keep = index * PERIOD_NS > from_ns
    index, node_q, node_gap = index[keep], node_q[keep, 1:], node_gap[keep, 1:]
    start, off_q, off_gap = while_spinning(probe, offline_samples, sim, int(index[-1]))
    rows = index - start
    assert rows[0] >= 0
    off_q, off_gap = off_q[rows], off_gap[rows]
    scale = np.max(np.abs(off_q))
    assert np.max(np.abs(node_q - off_q)) <= 1e-12 * scale
    assert np.max(np.abs(node_gap - off_gap)) <= 1e-12 * np.max(off_gap)
    bitwise = np.array_equal(node_q, off_q) and np.array_equal(node_gap, off_gap)
    return (np.max(np.abs(node_q[:, 0])), np.max(np.abs(off_q[:, 0])),
            np.min(node_gap[:, -1]), np.min(off_gap[:, -1]), bitwise)


def future_stamp_ns(probe, ahead_s=0.3, not_before_ns=0):
    """Return a stamp ``ahead_s`` after the node's current time, between two samples."""
    # Take what is queued first: the last block received is then the node's "now" (to one or
    # two blocks). At the live rate (100 blocks/s) 50 ms bring ~5 blocks; more means a backlog.
    blocks = probe.blocks['modal_displacement']
    while True:
        before = len(blocks)
        probe.spin_for(0.05)
        if len(blocks) - before <= 10:
            break
    now = max(probe.last_time_ns(), not_before_ns)
    return (now // 1_000_000 + int(ahead_s * 1000)) * 1_000_000 + 3_333


def test_blocks_are_labelled_contiguous_and_finite(run):
    probe = run.probe
    probe.spin_until(lambda: all(len(b) >= 20 for b in probe.blocks.values()), 10,
                     '20 blocks per topic')
    for topic, blocks in probe.blocks.items():
        for b in blocks:
            dims = b.msg.layout.dim
            assert dims[1].label == LABELS[topic]
            assert dims[0].label == 'sample'
            assert (dims[0].size, dims[0].stride) == (b.data.shape[0], b.data.size)
            assert (dims[1].size, dims[1].stride) == (b.data.shape[1], b.data.shape[1])
            assert b.data.shape[0] == 1000  # output.block_duration * output.rate
            assert np.all(np.isfinite(b.data))
    assert_contiguous(probe)
    # The three topics carry the same samples in the same blocks. Compared by sample time
    # where all three were received: the subscriptions matched at different moments, and at
    # any instant one topic may have one block more than another (aligning the last n blocks
    # of each failed on a fresh clone).
    starts = {topic: sample_indices([b.t[0] for b in blocks])
              for topic, blocks in probe.blocks.items()}
    ends = {topic: sample_indices([b.t[-1] for b in blocks])
            for topic, blocks in probe.blocks.items()}
    lo = max(s[0] for s in starts.values())
    hi = min(e[-1] for e in ends.values())
    assert hi - lo >= 10 * 1000  # at least 10 blocks in common
    common = {topic: s[(s >= lo) & (s <= hi)] for topic, s in starts.items()}
    first = common['modal_displacement']
    assert all(np.array_equal(c, first) for c in common.values()), common
    for blocks in probe.blocks.values():
        same = [b for b in blocks if lo <= sample_indices(b.t[0]) <= hi]
        assert len(same) == len(first)
    _, gap = probe.stacked('radial_gap')
    assert np.all((gap[:, 1:] > 9e-6) & (gap[:, 1:] < 11e-6))  # driven from rest: near d_g
    _, cap = probe.stacked('sense_electrodes')
    assert np.all(cap[:, 1:] > 0.0)
    # /clock: the end of every block, in order.
    assert len(probe.clock) >= 10 and np.all(np.diff(probe.clock) == 10_000_000)
    assert probe.clock[0] % 10_000_000 == 0


def test_shock_matches_offline_simulator(run):
    probe = run.probe
    at_ns = future_stamp_ns(probe)
    probe.shock(PEAK, at_ns=at_ns)
    run.shocks.append((at_ns, PEAK))
    probe.wait_sim_time(at_ns + 20_000_000, 10)

    sim = Simulator(offline_config(run.yaml_text))
    sim.shock(PEAK, 0.0, at_ns=at_ns)
    t0 = time.monotonic()
    peak, peak_off, gap, gap_off, bitwise = compare_with_offline(probe, sim, 0)
    print(f'\nshock at {at_ns * 1e-9:.9f} s: peak |q1| node {peak:.15e} m, offline '
          f'{peak_off:.15e} m; smallest gap node {gap:.15e} m, offline {gap_off:.15e} m; '
          f'bitwise equal: {bitwise} (offline {sim.time_s:.2f} s in '
          f'{time.monotonic() - t0:.1f} s)')
    assert peak > 3e-6  # the shock arrived: a few um of q1
    assert abs(peak - peak_off) <= 1e-12 * peak_off
    assert abs(gap - gap_off) <= 1e-12 * gap_off
    _, q = probe.stacked('modal_displacement')
    before = q[sample_indices(q[:, 0]) * PERIOD_NS <= at_ns]
    assert np.max(np.abs(before[:, 1])) < 1e-3 * peak  # and it acted at its stamp, not before


def test_parameters_are_declared_with_descriptors(run):
    voltage, rate, start, quality = run.probe.remote_describe(
        'electrodes.outer_voltage', 'output.rate', 'drive.start_on', 'modes.quality_factors')
    assert voltage.description.endswith('[V]') and not voltage.read_only
    assert rate.description.endswith('[Hz]') and rate.read_only
    assert rate.floating_point_range[0].from_value == 0.0
    assert 'upper_branch' in start.additional_constraints and start.read_only
    assert not quality.read_only and 'list of numbers' in quality.additional_constraints
    assert list(run.probe.remote_get('modes.quality_factors')) == [120000, 64700, 170000]
    assert run.probe.remote_get('scenario.shock_times') is None  # [] in the file: not set


def test_invalid_parameters_are_refused_and_the_run_continues(run):
    probe = run.probe
    refused = [
        (('electrodes.outer_voltage', math.nan), 'electrodes.outer_voltage'),
        (('modes.quality_factors', [-1.0, 64700.0, 170000.0]), 'modes.quality_factors'),
        (('electrodes.outer_voltage', 'eighty'), 'electrodes.outer_voltage'),
        (('modes.quality_factors', [1e5, 6e4]), 'modes.quality_factors'),  # length 2, not 3
        (('drive.frequency', -5.0), 'drive.frequency'),
        (('real_time_factor', -1.0), 'real_time_factor'),
        (('output.rate', 50000.0), 'output.rate'),  # read-only
    ]
    before = probe.last_time_ns()
    for change, name in refused:
        result = probe.remote_set(change)[0]
        print(f'\n{change}: refused: {result.reason}')
        assert not result.successful
        assert name in result.reason
    assert probe.remote_get('electrodes.outer_voltage') == 78.0
    probe.wait_sim_time(before + 100_000_000, 5)
    assert_contiguous(probe)


def test_valid_voltage_change_takes_effect(run):
    probe = run.probe
    result = probe.remote_set(('electrodes.outer_voltage', 75))[0]  # an integer literal
    assert result.successful, result.reason
    assert probe.remote_get('electrodes.outer_voltage') == 75
    response = probe.reset()
    assert response.success
    reset_s = float(re.search(r'simulation time ([0-9.]+) s', response.message).group(1))
    run.reset_ns = int(round(reset_s * 1e9))
    at_ns = future_stamp_ns(probe, not_before_ns=run.reset_ns)
    probe.shock(PEAK, at_ns=at_ns)
    run.shocks.append((at_ns, PEAK))
    probe.wait_sim_time(at_ns + 20_000_000, 10)

    results = {}
    for volts in (75.0, 78.0):
        # After reset() the Simulator holds exactly the state of a fresh one (rest, no
        # pulses, the drive phase depends on the time only): start it at the reset's sample.
        sim = Simulator(offline_config(run.yaml_text, **{'electrodes.outer_voltage': volts}))
        sim.sample_index = run.reset_ns // PERIOD_NS
        sim.shock(PEAK, 0.0, at_ns=at_ns)
        if volts == 75.0:
            results[volts] = compare_with_offline(probe, sim, run.reset_ns)
        else:
            _, q, _ = while_spinning(probe, offline_samples, sim,
                                     probe.last_time_ns() // PERIOD_NS)
            results[volts] = (np.max(np.abs(q[:, 0])),)
    peak, peak_off, gap, gap_off, bitwise = results[75.0]
    print(f'\n75 V from {reset_s:.6f} s: peak |q1| node {peak:.15e} m, offline at 75 V '
          f'{peak_off:.15e} m, at 78 V {results[78.0][0]:.15e} m; bitwise equal: {bitwise}')
    assert abs(peak - peak_off) <= 1e-12 * peak_off
    assert abs(gap - gap_off) <= 1e-12 * gap_off
    assert abs(peak - results[78.0][0]) > 1e-4 * peak  # the voltage did change the response


def test_rejected_inputs_are_counted_and_change_nothing(run):
    probe = run.probe
    probe.spin_until(lambda: probe.latest_diagnostics() is not None, 5, 'diagnostics')
    before = probe.latest_diagnostics()
    sent = time.monotonic()
    probe.shock(math.nan)
    probe.shock(PEAK, at_ns=probe.last_time_ns() - 500_000_000)  # >= 0.5 s in the past
    accel = conversions.base_acceleration_message(0, math.inf)
    probe.accel_pub.publish(accel)
    probe.frequency_pub.publish(conversions.float_message(-5.0))
    probe.amplitude_pub.publish(conversions.float_message(math.nan))

    def counted():
        values = probe.latest_diagnostics(sent)
        return values is not None and \
            int(values['rejected_inputs']) >= int(before['rejected_inputs']) + 5
    probe.spin_until(counted, 5, 'the rejections on /diagnostics')
    values = probe.latest_diagnostics(sent)
    print('\ndiagnostics:', values)
    assert int(values['rejected_shock']) >= 2
    assert int(values['rejected_base_acceleration']) >= 1
    assert int(values['rejected_drive_frequency']) >= 1
    assert int(values['rejected_drive_amplitude']) >= 1
    assert int(values['rejected_parameter_changes']) >= 4
    assert float(values['drive_frequency_hz']) == 15798.3
    assert float(values['drive_amplitude']) == 0.065
    for key in ('real_time_factor_target', 'real_time_factor_achieved', 'lag_s',
                'sim_time_s', 'steps', 'min_gap_ratio', 'contact', 'pending_shocks'):
        assert key in values
    assert values['contact'] == 'False'
    log = run.node.output()
    assert 'rejected ~/shock: not finite' in log
    assert 'in the past' in log
    assert_contiguous(probe)
    for blocks in probe.blocks.values():
        assert all(np.all(np.isfinite(b.data)) for b in blocks)


def test_drive_and_base_acceleration_inputs_are_applied(run):
    probe = run.probe
    sent = time.monotonic()
    probe.amplitude_pub.publish(conversions.float_message(0.05))
    probe.frequency_pub.publish(conversions.float_message(15790))
    at_ns = future_stamp_ns(probe)
    for k, ax in enumerate((0.0, 500.0, 0.0)):  # a 2 ms triangle of 500 m/s^2
        probe.accel_pub.publish(conversions.base_acceleration_message(at_ns + k * 1_000_000, ax))
        run.base_acceleration.append((at_ns + k * 1_000_000, ax))

    def applied():
        values = probe.latest_diagnostics(sent)
        return values is not None and float(values['drive_amplitude']) == 0.05 \
            and float(values['drive_frequency_hz']) == 15790.0
    probe.spin_until(applied, 5, 'the new drive on /diagnostics')
    probe.wait_sim_time(at_ns + 5_000_000, 5)


FLOOD_S = 2.0
"""How long test_shock_flood_leaves_the_node_responsive floods ~/shock (10 000 per second), s."""


def flood(publisher, sent):
    """Publish 10 000 shocks per second (1 m/s^2, "now") for FLOOD_S, in batches of 100."""
    msg = conversions.shock_message(0, 1.0)
    start = time.monotonic()
    for batch in range(int(FLOOD_S * 100)):
        for _ in range(100):
            publisher.publish(msg)
        sent[0] += 100
        delay = start + 0.01 * (batch + 1) - time.monotonic()
        if delay > 0:
            time.sleep(delay)


FLOOD_PROGRESS_BOUND = 0.5
"""
Least simulated time the node must cover during the flood, as a fraction of what it covers in
the reference window, in which the same flood goes to a reference process instead
(``raw_drain.py``), so that the host carries the same load in both. Measured 1.00-1.01, both
with this node and with the node before it took the excess shocks undecoded (it decoded and
refused every shock); 0.21 with an earlier node, before it drained its queues undecoded, when a
flood starved its one thread (doc/performance.md, "The node under a shock flood").
"""

FLOOD_COST_BOUND = 3.0
"""
Most CPU time a flood message may cost the node, in units of what the same message costs the
reference process (the middleware's reliable receive plus a raw take, measured in the same
test on the same host). Measured 1.10-1.51 in five runs of this node (41-57 us per message
for the reference), 1.87 for the node that decoded and refused every shock: the ratio moves
with the scheduling of three busy processes on two cores, so this bound separates only a gross
regression (a log line or a decode-and-refuse with an exception per message), not those two
nodes.
"""


def test_shock_flood_leaves_the_node_responsive(run, tmp_path):
    # A flood of 10 000 shocks per second for 2 s, against an equal window just before in which
    # the probe floods a reference process instead (raw_drain.py: the same publishing in this
    # process, the same receiving work on the host). On a 2-core host the node (~1 core per
    # simulated second here: 100 kHz published to this probe and recorded), the probe and the
    # flood saturate the machine, so the node's progress in wall time says as much about the
    # host as about the node: its progress is judged against the reference window, where the
    # host carries the same load. Its CPU time per message is judged against what receiving
    # the message costs the reference process: two costs of the same middleware on the same
    # host. (Judged against the node's own CPU per simulated second, the bound would move with
    # how fast the host simulates, not with what a message costs: doc/performance.md, "The
    # node under a shock flood".)
    probe = run.probe
    rss_before = run.node.rss_bytes()
    counted_keys = ('accepted_shocks', 'rejected_shock', 'lost_inputs')
    wall = time.monotonic()
    probe.spin_until(lambda: probe.latest_diagnostics(wall) is not None, 10, 'diagnostics')
    counted_before = sum(int(probe.latest_diagnostics(wall)[k]) for k in counted_keys)

    decoy_topic = f'{probe.target}/shock_flood_reference'
    decoy = probe.create_publisher(type(conversions.shock_message(0, 1.0)), decoy_topic, 100)
    with open(tmp_path / 'raw_drain.log', 'wb') as log:
        reference = subprocess.Popen(
            [sys.executable, str(pathlib.Path(__file__).with_name('raw_drain.py')), decoy_topic],
            env=node_env(), stdout=log, stderr=subprocess.STDOUT)
        try:
            probe.spin_until(lambda: decoy.get_subscription_count() > 0, MATCH_TIMEOUT_S,
                             'the reference subscriber')
            probe.spin_for(0.5)
            idle0, idle_wall0 = process_cpu_seconds(reference.pid), time.monotonic()
            probe.spin_for(1.0)
            idle_rate = ((process_cpu_seconds(reference.pid) - idle0)
                         / (time.monotonic() - idle_wall0))

            def window(publisher):
                sent = [0]
                sim_before = probe.last_time_ns()
                blocks_before = len(probe.blocks['modal_displacement'])
                cpu0 = run.node.cpu_seconds()
                ref0 = process_cpu_seconds(reference.pid)
                wall0 = time.monotonic()
                thread = threading.Thread(target=flood, args=(publisher, sent))
                thread.start()
                probe.spin_for(FLOOD_S / 2)
                t_call = time.monotonic()
                assert probe.remote_get('real_time_factor', timeout=2.0) == 1.0  # mid-flood
                call_s = time.monotonic() - t_call
                probe.spin_until(lambda: not thread.is_alive(), 10, 'the flood to end')
                wall = time.monotonic() - wall0
                cpu = run.node.cpu_seconds() - cpu0
                ref_cpu = process_cpu_seconds(reference.pid) - ref0
                sim_advance = (probe.last_time_ns() - sim_before) * 1e-9
                blocks = len(probe.blocks['modal_displacement']) - blocks_before
                return sent[0], wall, cpu, ref_cpu, sim_advance, blocks, call_s

            ref_sent, ref_wall, cpu, ref_cpu, reference_advance, _, _ = window(decoy)
            sent, wall, flood_cpu, _, sim_advance, blocks, call_s = window(probe.shock_pub)
        finally:
            reference.send_signal(signal.SIGINT)
            try:
                reference.wait(10)
            except subprocess.TimeoutExpired:
                reference.kill()
                reference.wait()
    per_sim_s = cpu / reference_advance  # the node's CPU time per simulated second
    ref_us = (ref_cpu - idle_rate * ref_wall) / ref_sent * 1e6
    node_us = (flood_cpu - per_sim_s * sim_advance) / sent * 1e6
    ratio = node_us / ref_us
    rss_after = run.node.rss_bytes()
    print(f'\nreference window: {ref_sent} shocks to raw_drain.py in {ref_wall:.2f} s, which '
          f'took {ref_cpu:.2f} s of CPU ({ref_us:.1f} us per message, idle {idle_rate:.3f} of '
          f'a core subtracted; {(tmp_path / "raw_drain.log").read_text().strip()}); the node '
          f'simulated {reference_advance:.3f} s meanwhile, CPU {cpu:.2f} s ({per_sim_s:.3f} s '
          f'per simulated s)')
    print(f'flood: {sent} shocks in {wall:.2f} s ({sent / wall:.0f}/s); the node simulated '
          f'{sim_advance:.3f} s meanwhile ({blocks} blocks, {sim_advance / reference_advance:.2f} '
          f'of the window without), CPU {flood_cpu:.2f} s: {node_us:.1f} us per message, '
          f"{ratio:.2f} times the reference's; a service call answered in "
          f'{call_s * 1e3:.0f} ms, RSS {rss_before / 1e6:.1f} -> {rss_after / 1e6:.1f} MB')
    assert sent / wall > 8000  # the 10 000/s, less the publisher's own jitter
    assert sim_advance / reference_advance > FLOOD_PROGRESS_BOUND  # kept simulating
    assert ratio < FLOOD_COST_BOUND
    assert rss_after - rss_before < 50e6  # coarse: measured +0.1 MB; bounds are in the node
    probe.wait_sim_time(probe.last_time_ns() + 50_000_000, 5)
    assert_contiguous(probe)
    # Every shock is accounted for: accepted, refused (pending limit) or reported lost. A node
    # that does not drain its whole queue loses most of a flood in the middleware, uncounted.
    wall = time.monotonic()
    probe.spin_until(lambda: probe.latest_diagnostics(wall) is not None, 10, 'diagnostics')
    counted = sum(int(probe.latest_diagnostics(wall)[k]) for k in counted_keys) - counted_before
    print(f'flood: {counted} of {sent} shocks counted (accepted, refused or lost)')
    assert counted >= 0.95 * sent
    assert probe.reset().success


def test_contact_is_reported_and_reset_recovers(run):
    probe = run.probe
    sent = time.monotonic()
    probe.shock(10 * PEAK)  # 100 000 g, now: the ring hits the outer electrodes

    def status(levels, contact):
        levels = levels if isinstance(levels, tuple) else (levels,)
        return lambda: any(wall >= sent and st.level in levels and values['contact'] == contact
                           for wall, st, values in probe.diagnostics)
    try:
        probe.spin_until(status(DiagnosticStatus.ERROR, 'True'), 5, 'an ERROR on /diagnostics')
    except BaseException:
        # Seen once in a full run (not reproduced since): the shock left no trace. Show why.
        print('\nlast diagnostics:', probe.latest_diagnostics(),
              '\nnode log tail:\n', run.node.output()[-3000:])
        raise
    message = next(st.message for wall, st, values in reversed(probe.diagnostics)
                   if st.level == DiagnosticStatus.ERROR)
    print(f'\ncontact: {message}')
    assert 'contact' in message and 't = ' in message and 'theta = ' in message
    probe.wait_sim_time(probe.last_time_ns() + 200_000_000, 5)  # still running
    assert run.node.proc.poll() is None
    response = probe.reset()
    assert response.success
    reset_ns = int(round(float(re.search(r'simulation time ([0-9.]+) s',
                                         response.message).group(1)) * 1e9))
    sent = time.monotonic()
    # OK again, or WARN if the loaded machine makes the node lag (the lag warning).
    probe.spin_until(status((DiagnosticStatus.OK, DiagnosticStatus.WARN), 'False'), 5,
                     'no contact again on /diagnostics')
    # The samples after the reset (by sample time: the last block received when the
    # diagnostics arrive may still be one from before it).
    probe.wait_sim_time(reset_ns + 20_000_000, 5, topic='radial_gap')
    _, gap = probe.stacked('radial_gap')
    after = gap[sample_indices(gap[:, 0]) * PERIOD_NS > reset_ns]
    assert np.all(np.isfinite(gap)) and np.all(after[:, -1] > 9e-6)  # at rest, near d_g
    assert_contiguous(probe)


def test_sigterm_ends_the_node_and_finalises_the_recording(run):
    probe = run.probe
    received = probe.last_time_ns()
    run.node.signal(signal.SIGTERM)
    t0 = time.monotonic()
    code = run.node.wait(10.0)
    elapsed = time.monotonic() - t0
    print(f'\nSIGTERM: exit code {code} after {elapsed:.2f} s')
    assert code == 0
    assert elapsed < 2.0
    assert 'stopped (SIGTERM): ' in run.node.output()

    data = run.record_path.read_bytes()
    assert data.endswith(b'\x89MCAP0\r\n')  # finished: footer and closing magic
    meta = read_metadata(run.record_path, 'ring_gyro_sim')
    assert yaml.safe_load(meta['parameters'])['output.rate'] == 100000.0
    topics = {}
    for m in read_messages(run.record_path):
        topics.setdefault(m.topic, []).append(m)
    blocks = topics['/ring_gyro/modal_displacement']
    assert blocks[-1].log_time_ns >= received
    index = sample_indices(np.concatenate(
        [conversions.block_arrays(decode(m))[1][:, 0] for m in blocks]))
    assert index[0] == 1 and np.all(np.diff(index) == 1)  # every block from the start
    shocks = [(m.log_time_ns, decode(m).vector.x) for m in topics['/ring_gyro/shock']]
    assert all(math.isfinite(x) for _, x in shocks)
    # The two shocks of the tests at their stamps; not the rejected one stamped in the past.
    assert sorted(s for s in shocks if s[1] == PEAK) == sorted(run.shocks)
    changes = [(m.log_time_ns, yaml.safe_load(decode(m).data))
               for m in topics['/ring_gyro/events/parameters']]
    assert changes[0][1] == {'electrodes.outer_voltage': 75.0}
    resets = [m.log_time_ns for m in topics['/ring_gyro/events/reset']]
    assert resets[0] == run.reset_ns
    assert changes[0][0] <= run.reset_ns
    assert '/diagnostics' in topics
    accel = [(m.log_time_ns, decode(m).accel.linear.x)
             for m in topics['/ring_gyro/base_acceleration']]
    assert accel == run.base_acceleration
    assert [decode(m).data for m in topics['/ring_gyro/drive/amplitude']] == [0.05]
    assert [decode(m).data for m in topics['/ring_gyro/drive/frequency']] == [15790.0]
    clock = [m.log_time_ns for m in topics['/clock']]
    assert clock == [m.log_time_ns for m in blocks]


def test_the_recording_resimulates_bit_for_bit(run, tmp_path):
    # Every accepted input was recorded at the simulation time it acted at: re-simulating the
    # recording (offline, same Simulator) gives the same output blocks, bit for bit. (Decoded:
    # the CDR bytes differ in their alignment padding, which the serializer leaves as it is.)
    t0 = time.monotonic()
    summary = resimulate(str(run.record_path), output=str(tmp_path / 'again.mcap'),
                         progress=False)
    print(f'\nre-simulated {summary.sim_time_s:.2f} s in {time.monotonic() - t0:.1f} s')
    for topic in ('/ring_gyro/modal_displacement', '/ring_gyro/radial_gap',
                  '/ring_gyro/sense_electrodes'):
        node, again = ([(m.log_time_ns, conversions.block_arrays(decode(m)))
                        for m in read_messages(path, [topic])]
                       for path in (run.record_path, tmp_path / 'again.mcap'))
        assert [t for t, _ in node] == [t for t, _ in again]
        for (_, (labels, data)), (_, (labels_again, data_again)) in zip(node, again):
            assert labels == labels_again
            assert np.array_equal(data.view(np.int64), data_again.view(np.int64)), topic
