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
Parameter refusals of the real node, across processes.

And the environment changed live: ``ros2 param set`` of the vibration.

rclpy refuses undeclared, read-only and out-of-range changes before the node's callback
runs; they must be counted on ``/diagnostics`` by kind and answered with a reason naming the
parameter. A params file the node and ``ring_gyro run`` would read differently stops the node
with one FATAL line, the same reason ``check_params_file`` gives.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import math
import time

from node_harness import connected, NodeProcess, params_yaml, Probe, start_node
import numpy as np
import pytest
from rcl_interfaces.srv import SetParametersAtomically
from rclpy.parameter import Parameter
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import paper_config
from ring_gyro_sim.paramfile import check_params_file
# isort: on

EXIT_TIMEOUT_S = 60.0
CONFIG = {'output.rate': 100000.0, 'real_time_factor': 1.0, 'drive.start_on': 'rest',
          'drive.amplitude': 0.0}
# The default device's voltage limit, from SimConfig.voltage_limits (test_params checks it
# against eq. 26 independently): 215.59 V.
V_LIMIT = paper_config({}).voltage_limits()[0]
REFUSED = [
    # (name, value, kind, text the reason must hold)
    ('electrodes.voltage', 80.0, 'undeclared',
     'electrodes.voltage: unknown parameter of ring_gyro_sim (did you mean '
     'electrodes.outer_voltage?)'),
    ('output.rate', 50000.0, 'read_only', 'output.rate: read-only'),
    ('record.path', 'x.mcap', 'read_only', 'record.path: read-only'),
    ('electrodes.outer_voltage', 1e6, 'range', 'electrodes.outer_voltage: must be between'),
    ('electrodes.outer_voltage', math.nan, 'range', 'electrodes.outer_voltage'),
    ('real_time_factor', -1.0, 'range', 'real_time_factor: must be between 0 and inf'),
    ('modes.quality_factors', [1e5, 6e4], 'invalid', 'modes.quality_factors: has 2 values'),
    ('electrodes.inner_voltage', 'high', 'invalid', 'electrodes.inner_voltage: expected'),
]


@pytest.fixture(scope='module')
def node(ros, tmp_path_factory):
    workdir = tmp_path_factory.mktemp('node_parameters')
    proc = start_node(workdir, CONFIG)
    with connected(proc, Probe) as probe:
        yield proc, probe


def test_the_voltage_descriptor_carries_the_configuration_limit(node):
    _, probe = node
    voltage, = probe.remote_describe('electrodes.outer_voltage')
    r = voltage.floating_point_range[0]
    assert r.to_value == pytest.approx(V_LIMIT, rel=1e-12)
    assert r.from_value == pytest.approx(-V_LIMIT, rel=1e-12)
    assert 'pull-in' in voltage.additional_constraints


def test_every_refusal_is_named_counted_by_kind_and_logged(node):
    proc, probe = node
    probe.spin_until(lambda: probe.latest_diagnostics() is not None, 10, 'diagnostics')
    before = probe.latest_diagnostics()
    for name, value, kind, text in REFUSED:
        result = probe.remote_set((name, value))[0]
        print(f'\n{name} = {value!r}: {result.reason}')
        assert not result.successful
        assert text in result.reason
    accepted = probe.remote_set(('electrodes.outer_voltage', 70.0))[0]  # not counted
    assert accepted.successful, accepted.reason
    sent = time.monotonic()
    expected = {kind: sum(1 for r in REFUSED if r[2] == kind)
                for kind in ('undeclared', 'read_only', 'range', 'invalid')}

    def counted():
        values = probe.latest_diagnostics(sent)
        return values is not None and int(values['rejected_parameter_changes']) >= \
            int(before['rejected_parameter_changes']) + len(REFUSED)
    probe.spin_until(counted, 10, 'the refusals on /diagnostics')
    values = probe.latest_diagnostics(sent)
    print('\ndiagnostics:', values)
    assert int(values['rejected_parameter_changes']) - \
        int(before['rejected_parameter_changes']) == len(REFUSED)
    for kind, n in expected.items():
        key = f'rejected_parameter_{kind}'
        assert int(values[key]) - int(before[key]) == n, key
    log = proc.output()
    assert 'parameter change refused (undeclared): electrodes.voltage: unknown' in log
    assert 'parameter change refused (read_only): output.rate' in log
    assert 'parameter change refused (range): real_time_factor' in log
    assert 'parameter change refused (invalid): modes.quality_factors' in log


BAD_FILES = {
    'wrong node name': params_yaml({'duration': 1.0}, 'camera'),
    'unknown name': params_yaml({'electrodes.outer_voltag': 70.0}),
    'duplicate key': params_yaml({'duration': 1.0}) + '    duration: 2.0\n',
    'empty': '',
    'binary': b'\x89PNG\r\n\x1a\n\x00\xff',
}


@pytest.fixture(scope='module')
def bad_files(tmp_path_factory):
    procs = {}
    try:
        for case, content in BAD_FILES.items():
            workdir = tmp_path_factory.mktemp(case.replace(' ', '_'))
            path = workdir / 'p.yaml'
            if isinstance(content, bytes):
                path.write_bytes(content)
            else:
                path.write_text(content, encoding='utf-8')
            procs[case] = (NodeProcess(path, workdir), path)
        yield procs
    finally:
        for proc, _ in procs.values():
            proc.stop()


@pytest.mark.parametrize('case', sorted(BAD_FILES))
def test_a_params_file_run_refuses_stops_the_node_with_the_same_reason(bad_files, case):
    proc, path = bad_files[case]
    code = proc.wait(EXIT_TIMEOUT_S)
    log = proc.output()
    print(f'\n{case}: exit code {code}: {log.strip()}')
    with pytest.raises(ParameterError) as info:
        check_params_file(str(path))
    assert code == 1
    fatal = [line for line in log.splitlines() if '[FATAL]' in line]
    assert fatal == [f'[FATAL] [ring_gyro_node]: cannot start: {info.value}']
    assert 'Traceback' not in log


def q1_moves_after(probe, t_ns):
    """Tell whether a received block holds a sample after ``t_ns`` with q1 off rest."""
    for block in probe.blocks['modal_displacement']:
        late = block.t > t_ns * 1e-9
        if late.any() and np.any(block.data[late, block.labels.index('q1')] != 0.0):
            return True
    return False


def test_the_environment_is_changed_live_and_a_bad_value_is_refused_by_name(node):
    """
    ``scenario.vibration_*`` are live parameters: set, they act on the running ring.

    The resonator at rest (no drive) keeps q1 at exactly 0 until the vibration is switched
    on; a bad value is refused with a reason naming the parameter and changes nothing; the
    profile's two lists change together through ``set_parameters_atomically``.
    """
    proc, probe = node
    probe.spin_until(lambda: probe.blocks['modal_displacement'], 30, 'a block')
    assert not q1_moves_after(probe, 0)
    for name, value, text in [
            ('scenario.vibration_amplitude', -1.0,
             'scenario.vibration_amplitude: must be between 0'),
            ('scenario.vibration_frequency', 3000.0,
             'scenario.vibration_frequency: 3000 Hz is above output.rate / 40'),
            ('scenario.vibration_psd_frequencies', [20.0, 2000.0],
             'scenario.vibration_psd_values: has 0 values')]:
        result = probe.remote_set((name, value), timeout=30.0)[0]
        print(f'\n{name} = {value!r}: {result.reason}')
        assert not result.successful and text in result.reason
    accepted = probe.remote_set(('scenario.vibration_frequency', 1000.0),
                                ('scenario.vibration_amplitude', 20.0), timeout=30.0)
    assert all(r.successful for r in accepted), [r.reason for r in accepted]
    assert probe.remote_get('scenario.vibration_amplitude', timeout=30.0) == 20.0
    now = probe.last_time_ns()
    probe.spin_until(lambda: q1_moves_after(probe, now), 60, 'q1 to answer the vibration')
    client = probe.create_client(SetParametersAtomically,
                                 f'{probe.target}/set_parameters_atomically')
    probe.spin_until(client.service_is_ready, 30, 'set_parameters_atomically')
    request = SetParametersAtomically.Request(parameters=[
        Parameter('scenario.vibration_psd_frequencies',
                  value=[20.0, 2000.0]).to_parameter_msg(),
        Parameter('scenario.vibration_psd_values', value=[0.01, 0.01]).to_parameter_msg()])
    result = probe.call(client, request, timeout=30.0).result
    assert result.successful, result.reason
    probe.spin_until(lambda: 'scenario.vibration_psd_values = ' in proc.output(),
                     30, 'the node to log the change')
    assert 'parameters applied at simulation time' in proc.output()
