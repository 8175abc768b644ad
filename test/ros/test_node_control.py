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
Node test of the closed loop's ROS side: ``~/control`` out, its keys on ``/diagnostics``.

The node runs ``config/gyro.yaml`` with a second params file that closes the loop
(``control.mode: closed_loop``), recording, until the probe has received 0.2 s of simulated
time on ``~/control`` (then SIGINT: a fixed duration would race the probe's discovery); real
rclpy across processes (``node_harness``). The open-loop nodes of ``test_node_gyro.py`` check
that the publisher exists only with the closed loop.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import signal

from diagnostic_msgs.msg import DiagnosticStatus
from node_harness import connected, NodeProcess, params_yaml, Probe, REPO_ROOT
import numpy as np
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.offline import resimulate
from ring_gyro_sim.recording.reader import (block_sample_counts, decode, read_block_topic,
                                            read_messages)
from ring_gyro_sim.ros import conversions
from std_msgs.msg import Float64MultiArray
# isort: on

NS = '/ring_gyro'
LABELS = ['t', *CONTROL_CHANNELS]
LIVE_BLOCKS = 20
"""Blocks of 10 ms received live before the node is stopped."""
DRIVE_HZ = 15800.0
"""``drive.frequency`` of config/gyro.yaml: the centre of the NCO."""


class ControlProbe(Probe):
    """The harness probe, also on ``~/control``."""

    def __init__(self):
        super().__init__()
        self.control = []
        self.create_subscription(Float64MultiArray, f'{NS}/control', self.control.append, 200)


def test_closed_loop_node_publishes_and_records_control(ros, tmp_path):
    path = tmp_path / 'closed.mcap'
    override = tmp_path / 'closed.yaml'
    override.write_text(params_yaml({'control.mode': 'closed_loop', 'duration': 0.0,
                                     'record.path': str(path)}, device={}), encoding='utf-8')
    node = NodeProcess(REPO_ROOT / 'config' / 'gyro.yaml', tmp_path, '--params-file',
                       str(override))
    with connected(node, ControlProbe) as probe:
        types = dict(probe.get_topic_names_and_types())
        assert types[f'{NS}/control'] == ['std_msgs/msg/Float64MultiArray']
        (info,) = probe.get_publishers_info_by_topic(f'{NS}/control')
        assert info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
        assert info.qos_profile.durability == DurabilityPolicy.VOLATILE
        probe.spin_until(lambda: len(probe.control) >= LIVE_BLOCKS, 60.0,
                         f'{LIVE_BLOCKS} blocks on ~/control')
        node.signal(signal.SIGINT)
        probe.spin_until(lambda: node.proc.poll() is not None, 30.0, 'the node to stop')
        assert node.wait(10.0) == 0, node.output()[-3000:]
        probe.spin_for(0.5)
    log = node.output()
    assert probe.control, log[-3000:]
    live = []
    for msg in probe.control:
        labels, data = conversions.block_arrays(msg)
        assert labels == LABELS
        live.append(data)
    live = np.concatenate(live)
    # One row per loop update, 1 ms apart on the simulation clock (none lost or repeated).
    stamps = np.rint(live[:, 0] * 1e9).astype(np.int64)
    assert np.all(np.diff(stamps) == 1_000_000)
    values = dict(zip(LABELS, live.T))
    assert np.all(values['locked'] == 1.0)
    assert np.all(np.abs(values['frequency_hz'] - DRIVE_HZ) < 1.0)
    # The recording holds every update from 1 ms on, one per block's 10 ms but the update at
    # a block's end, reported by the next block (so 9 rows in the first), and what
    # subscribers got live is that.
    recorded = read_block_topic(path, 'control')
    assert recorded.labels == LABELS
    ms = len(recorded.end_ns) * 10  # blocks of 10 ms
    assert len(recorded.end_ns) >= LIVE_BLOCKS
    assert np.rint(recorded.data[:, 0] * 1e9).astype(np.int64).tolist() == [
        1_000_000 * (m + 1) for m in range(ms - 1)]
    first = int(np.searchsorted(recorded.data[:, 0], live[0, 0]))
    assert np.array_equal(live, recorded.data[first:first + len(live)])
    print(f'~/control: {len(live)} of {len(recorded.data)} rows live, NCO '
          f'{values["frequency_hz"].min():.4f} ... {values["frequency_hz"].max():.4f} Hz')
    # /diagnostics carries the loop's state: live and in the recording.
    diag = probe.latest_diagnostics()
    assert diag is not None
    assert diag['pll_locked'] == 'True', diag
    assert abs(float(diag['pll_frequency_hz']) - DRIVE_HZ) < 1.0, diag
    last = decode(list(read_messages(path, '/diagnostics'))[-1])
    values = {kv.key: kv.value for kv in last.status[0].values}
    assert values['pll_locked'] == 'True' and values['pll_lost_lock'] == 'False'
    assert abs(float(values['pll_frequency_hz']) - DRIVE_HZ) < 1.0


def test_a_failure_is_published_at_once_and_leaves_no_hole(ros, tmp_path):
    # A non-finite value fails the run, and no block after it is withheld (holes in the
    # stream and the recording, which --from cannot repeat). Here a bias of 1e-320 V set at run
    # time (0 V is refused; a params file cannot hold a subnormal number, ros2 param set can)
    # makes the closed loops' measured amplitude overflow at their next update: the run fails,
    # says so on /diagnostics with the block it failed in, and every block still goes out.
    path = tmp_path / 'failed.mcap'
    params = tmp_path / 'params.yaml'
    params.write_text(params_yaml({'drive.start_on': 'rest', 'output.rate': 20000.0,
                                   'duration': 0.0, 'record.path': str(path)}, device={}),
                      encoding='utf-8')
    node = NodeProcess(params, tmp_path)
    with connected(node, Probe) as probe:
        (result,) = probe.remote_set(('electrodes.outer_voltage', 1e-320))
        assert result.successful, result.reason
        probe.spin_until(lambda: any(st.level == DiagnosticStatus.ERROR
                                     for _, st, _ in probe.diagnostics), 20.0,
                         'an ERROR on /diagnostics')
        errors = len(probe.blocks['modal_displacement'])
        probe.spin_until(lambda: len(probe.blocks['modal_displacement']) >= errors + 20, 20.0,
                         '20 blocks after the failure')
        node.signal(signal.SIGINT)
        assert node.wait(30.0) == 0, node.output()[-3000:]
    message = next(st.message for _, st, _ in probe.diagnostics
                   if st.level == DiagnosticStatus.ERROR)
    print(f'\n{message}')
    assert message.startswith('failed: non-finite loop state (numerical failure), t = ')
    for block in probe.blocks['modal_displacement']:
        assert np.all(np.isfinite(block.data))
    sizes = block_sample_counts(str(path))
    assert set(sizes) == {200}  # every block from the start: no hole
    (change,) = [m.log_time_ns for m in read_messages(path, f'{NS}/events/parameters')]
    # Published with the block it failed in (the loops update every 1 ms), not a second later.
    errors = [m.log_time_ns for m in read_messages(path, '/diagnostics')
              if decode(m).status[0].level == DiagnosticStatus.ERROR]
    assert change < errors[0] <= change + 20_000_000
    again = tmp_path / 'again.mcap'
    resimulate(str(path), str(again), progress=False)
    for topic in ('modal_displacement', 'control', 'demodulator'):
        node_blocks, resimulated = (read_block_topic(p, topic) for p in (path, again))
        assert np.array_equal(node_blocks.data, resimulated.data), topic
