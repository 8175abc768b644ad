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
Node test of ``integrator.fidelity: auto``: the node hands between the models on its own.

The default gyroscope (its noises on), recording; real rclpy across processes
(``node_harness``). The node starts on the full model and is averaged from its first check;
a 10 g shock on ``~/shock`` hands it to the full model at once and, the fast modes below the
threshold, back one check later. ``/diagnostics`` says which model runs; the recording's
metadata holds the hand-offs, and ``--from`` makes the same ones, ``~/rate`` bit for bit.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import signal

from node_harness import connected, NodeProcess, params_yaml, Probe
from ring_gyro_sim.core.params import STANDARD_GRAVITY
from ring_gyro_sim.offline import resimulate
from ring_gyro_sim.recording.reader import read_handoffs, read_rate
# isort: on


def test_the_node_hands_between_the_models_and_records_it(ros, tmp_path):
    path = tmp_path / 'auto.mcap'
    params = tmp_path / 'params.yaml'
    params.write_text(params_yaml({'duration': 0.0, 'record.path': str(path)}, device={}),
                      encoding='utf-8')
    node = NodeProcess(params, tmp_path)
    with connected(node, Probe) as probe:
        probe.spin_until(lambda: (probe.latest_diagnostics() or {}).get('model') == 'averaged',
                         20.0, 'model averaged on /diagnostics')
        probe.shock(10.0 * STANDARD_GRAVITY)   # a zero stamp: now
        probe.spin_until(lambda: int((probe.latest_diagnostics() or {}).get(
            'model_changes', 0)) >= 3, 20.0, 'two more changes of model')
        node.signal(signal.SIGINT)
        probe.spin_until(lambda: node.proc.poll() is not None, 30.0, 'the node to stop')
        assert node.wait(10.0) == 0, node.output()[-3000:]
    log = node.output()
    assert 'models: full from 0 s, averaged from 0.01 s, full from' in log, log[-3000:]
    handoffs = read_handoffs(path)
    assert [model for _, model in handoffs][:4] == ['full', 'averaged', 'full', 'averaged']
    (t0, _), (t1, _), (t2, _), (t3, _) = handoffs[:4]
    assert (t0, t1) == (0, 10_000_000)
    # the shock acts at a block's start (a loop update): full from there, back at the next
    # check, 10 ms on
    assert t2 % 10_000_000 == 0 and t3 - t2 == 10_000_000
    again = tmp_path / 'again.mcap'
    resimulate(str(path), str(again), progress=False)
    assert read_handoffs(again) == handoffs
    a, b = read_rate(path), read_rate(again)
    assert len(a.t_ns) > 100 and a.t_ns.tolist() == b.t_ns.tolist()
    assert a.rate.tolist() == b.rate.tolist()
