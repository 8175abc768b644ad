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
Parameter refusals of the real node, across processes (issue 10 items 3 and 4).

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
import pytest
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
