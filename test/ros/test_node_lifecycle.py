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
Start-up and end of ring_gyro_sim.ros.node: bad parameter files, ``duration``, remapping.

All the node processes of this module are started at once by one fixture (none of them needs
a second node) and each test checks one of them.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import math
import re

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from node_harness import NodeProcess, params_yaml, start_node
import pytest
from ring_gyro_sim.offline import run_offline
from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.recording.reader import read_messages
# isort: on

EXIT_TIMEOUT_S = 60.0
FAST = {'output.rate': 100000.0, 'real_time_factor': 0.0, 'drive.start_on': 'rest'}
BAD = {
    'mismatched_lists': ({'modes.quality_factors': [120000.0, 64700.0]},
                         'modes.quality_factors'),
    'nan': ({'electrodes.outer_voltage': math.nan}, 'electrodes.outer_voltage'),
    'out_of_range': ({'real_time_factor': -1.0}, 'real_time_factor'),
    'integer_out_of_range': ({'electrodes.taylor_terms': 2}, 'electrodes.taylor_terms'),
    'wrong_kind': ({'electrodes.count': 'eight'}, 'electrodes.count'),
    'bad_choice': ({'drive.start_on': 'sideways'}, 'drive.start_on'),
    'unwritable_record': ({'record.path': '{workdir}/params.yaml/run.mcap'}, 'record.path'),
    # The closed loop reads the drive through a pick-off biased by V_o: 0 V divided by zero.
    'unbiased_closed_loop': ({'control.mode': 'closed_loop', 'electrodes.outer_voltage': 0.0},
                             'electrodes.outer_voltage'),
    # A typo is refused as `ring_gyro run` refuses it (test/ros/test_node_parameters.py).
    'unknown': ({'electrodes.outer_voltag': 70.0}, 'electrodes.outer_voltag'),
}
# rcl cannot read lists mixing integers and floats: it fails before the node exists.
UNPARSABLE = 'ring_gyro:\n  ros__parameters:\n    modes:\n      frequencies: [11200, 15800.5]\n'
# config/demo.yaml, shortened: the shock at 0.5 s on the upper branch, as fast as possible.
DURATION = {'drive.start_on': 'upper_branch', 'output.rate': 100000, 'real_time_factor': 0,
            'duration': 0.6, 'scenario.shock_times': [0.5], 'scenario.shock_peaks': [98066.5]}


@pytest.fixture(scope='module')
def processes(tmp_path_factory):
    """Start every node process of the module; return {case: (process, workdir)}."""
    procs = {}
    try:
        for case, (values, _) in BAD.items():
            workdir = tmp_path_factory.mktemp(case)
            values = {k: (v.format(workdir=workdir) if isinstance(v, str) else v)
                      for k, v in values.items()}
            procs[case] = (start_node(workdir, {**FAST, 'duration': 1.0, **values}), workdir)
        workdir = tmp_path_factory.mktemp('unparsable')
        (workdir / 'bad.yaml').write_text(UNPARSABLE)
        procs['unparsable'] = (NodeProcess(workdir / 'bad.yaml', workdir), workdir)
        # The nodes refused exist for a moment, under the name of the one below: it would
        # refuse to start beside them (a namesake in the graph; ros/node.py, "Start-up").
        for proc, _ in procs.values():
            proc.wait(EXIT_TIMEOUT_S)
        workdir = tmp_path_factory.mktemp('duration')
        procs['duration'] = (start_node(workdir, {**DURATION, 'record.path':
                                                  str(workdir / 'run.mcap')}), workdir)
        workdir = tmp_path_factory.mktemp('remapped')
        (workdir / 'params.yaml').write_text(params_yaml(
            {**FAST, 'duration': 0.05, 'record.path': str(workdir / 'run.mcap')}, node='/**'))
        procs['remapped'] = (NodeProcess(workdir / 'params.yaml', workdir, '-r', '__node:=gyro_b',
                                         '-r', '__ns:=/bench'), workdir)
        yield procs
    finally:
        for proc, _ in procs.values():
            proc.stop()


@pytest.mark.parametrize('case', sorted(BAD))
def test_a_bad_parameter_stops_the_node_naming_it(processes, case):
    proc, _ = processes[case]
    code = proc.wait(EXIT_TIMEOUT_S)
    log = proc.output()
    print(f'\n{case}: exit code {code}: {log.strip()}')
    assert code not in (0, None)
    fatal = [line for line in log.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and BAD[case][1] in fatal[0]
    assert 'Traceback' not in log


def test_an_unparsable_params_file_stops_the_node(processes):
    proc, _ = processes['unparsable']
    code = proc.wait(EXIT_TIMEOUT_S)
    log = proc.output()
    print(f'\nunparsable: exit code {code}: {log.strip()}')
    assert code not in (0, None)
    assert 'params file' in log and 'Traceback' not in log


def test_duration_reached_ends_the_run_with_a_summary(processes):
    proc, workdir = processes['duration']
    code = proc.wait(EXIT_TIMEOUT_S)
    log = proc.output()
    print(f'\nduration: exit code {code}: {log.strip()}')
    assert code == 0
    line = next(line for line in log.splitlines() if 'duration reached: ' in line)
    numbers = {key: float(value) for key, value in re.findall(
        r'(peak \|q1\||smallest gap|q2 amplitude) = ?([0-9.]+) um', line.replace(
            'q2 amplitude ', 'q2 amplitude = ', 1))}
    assert 'over the 10 ms before the first shock (t = 0.500000 s)' in line
    assert 'over the last 10 ms' in line
    # The same numbers as the offline run of the same file (the same Simulator).
    summary = run_offline(load_yaml(str(workdir / 'params.yaml')), progress=False)
    assert numbers['peak |q1|'] == pytest.approx(1e6 * summary.peak_abs_m['q1'], abs=1e-4)
    assert numbers['smallest gap'] == pytest.approx(1e6 * summary.min_gap_m, abs=1e-4)
    # Driven on the upper branch before the shock (paper: ~0.39 um; here 0.418 um).
    assert 0.38 < numbers['q2 amplitude'] < 0.46
    data = (workdir / 'run.mcap').read_bytes()
    assert data.endswith(b'\x89MCAP0\r\n')  # finalised
    blocks = [m for m in read_messages(workdir / 'run.mcap')
              if m.topic == '/ring_gyro/modal_displacement']
    assert blocks[-1].log_time_ns == 600_000_000


def test_the_node_name_and_namespace_are_remappable(processes):
    proc, workdir = processes['remapped']
    code = proc.wait(EXIT_TIMEOUT_S)
    log = proc.output()
    assert code == 0, log
    assert '[bench.gyro_b]: duration reached' in log
    topics = {m.topic for m in read_messages(workdir / 'run.mcap')}
    assert '/bench/gyro_b/modal_displacement' in topics


def _topics_and_diagnostics_keys(path):
    """Return (channel topics, key lists of every /diagnostics status) read by mcap_ros2."""
    with open(path, 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        topics = sorted(c.topic for c in reader.get_summary().channels.values())
        keys = [[kv.key for kv in status.values]
                for _, _, _, msg in reader.iter_decoded_messages(topics=['/diagnostics'])
                for status in msg.status]
    return topics, keys


def test_node_and_offline_recordings_look_the_same(processes, tmp_path):
    """The same scenario recorded by the node and by ring_gyro run."""
    proc, workdir = processes['duration']
    assert proc.wait(EXIT_TIMEOUT_S) == 0, proc.output()
    offline_path = tmp_path / 'offline.mcap'
    run_offline(load_yaml(str(workdir / 'params.yaml')), output=str(offline_path),
                progress=False)
    node_topics, node_keys = _topics_and_diagnostics_keys(workdir / 'run.mcap')
    off_topics, off_keys = _topics_and_diagnostics_keys(offline_path)
    assert node_topics == off_topics
    assert '/ring_gyro/shock' in node_topics and '/diagnostics' in node_topics
    assert node_keys and off_keys
    assert all(k == node_keys[0] for k in node_keys + off_keys)
    # The recorded samples are the same too (the same Run): compare the block log times.
    node_blocks = [m.log_time_ns for m in read_messages(workdir / 'run.mcap')
                   if m.topic == '/ring_gyro/modal_displacement']
    off_blocks = [m.log_time_ns for m in read_messages(offline_path)
                  if m.topic == '/ring_gyro/modal_displacement']
    assert node_blocks == off_blocks
