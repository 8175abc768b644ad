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

"""Tests of ``ring_gyro_sim.paramfile``: one check of a params file for the node and ``run``."""

import json
import math
import subprocess
import sys
import textwrap

import pytest
from ring_gyro_sim import cli
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.paramfile import (check_node_arguments, check_params_file, load_yaml,
                                     rcl_scalar, ros_arguments)


def write(tmp_path, text, name='p.yaml'):
    path = tmp_path / name
    path.write_text(text, encoding='utf-8')
    return str(path)


def section(body, node='ring_gyro'):
    return f'{node}:\n  ros__parameters:\n' + textwrap.indent(body, '    ')


REFUSED = {
    'empty': ('', 'empty'),
    'comments only': ('# nothing\n', 'empty'),
    'another node': (section('duration: 1.0\n', 'camera'), "node '/ring_gyro'"),
    'a namespace the node is not in': (section('duration: 1.0\n', '/sensors/ring_gyro'),
                                       'sections: /sensors/ring_gyro'),
    '/** with nothing': ('/**:\n  ros__parameters: {}\n', 'no ros__parameters section'),
    '/** without ros__parameters': ('/**:\n  duration: 1.0\n', 'value before ros__parameters'),
    'a bare mapping': ('duration: 1.0\n', 'value before ros__parameters'),
    'unknown': (section('electrodes:\n  outer_voltag: 70.0\n'),
                'electrodes.outer_voltag: unknown parameter of ring_gyro_sim (did you mean '
                'electrodes.outer_voltage?)'),
    'mixed list': (section('modes:\n  frequencies: [11200, 15800.5, 22000.0]\n'),
                   'modes.frequencies: a list must hold values of one type'),
    'duplicate key': (section('duration: 1.0\nreal_time_factor: 0.0\nduration: 2.0\n'),
                      'duration: given twice'),
    'duplicate group key': (section('drive: {amplitude: 0.0}\ndrive: {start_on: rest}\n'),
                            'drive: given twice'),
    'duplicate section': (section('duration: 1.0\n') + section('real_time_factor: 0.0\n'),
                          "node section 'ring_gyro': given twice"),
    'nested list': (section('scenario:\n  shock_times: [[0.1]]\n'),
                    'scenario.shock_times: a list'),
    'no value': (section('duration:\n'), 'duration: no value'),
    'alias': (section('duration: &d 1.0\nshock:\n  duration: *d\n'), 'aliases'),
    'bad yaml': ('ring_gyro: [\n', 'not valid YAML'),
    'a parameter control.mode replaced': (section('control: {drive_loop: closed}\n'),
                                          'control.drive_loop: unknown parameter of '
                                          'ring_gyro_sim (replaced by control.mode'),
}


@pytest.mark.parametrize('case', sorted(REFUSED))
def test_refused_with_the_reason(tmp_path, case):
    text, expected = REFUSED[case]
    path = write(tmp_path, text)
    with pytest.raises(ParameterError) as info:
        check_params_file(path)
    message = str(info.value)
    print(f'\n{case}: {message}')
    assert expected in message


def test_a_refusal_names_the_line(tmp_path):
    path = write(tmp_path, section('duration: 1.0\nmodes:\n  frequencies: [1, 2.5]\n'))
    with pytest.raises(ParameterError, match=r'^modes.frequencies: .*line 5'):
        check_params_file(path)
    path = write(tmp_path, section('duration: 1.0\nduration: 2.0\n'))
    with pytest.raises(ParameterError, match=r'^duration: .*lines 3 and 4'):
        check_params_file(path)


def test_a_binary_file_is_refused_clearly(tmp_path):
    path = tmp_path / 'b.yaml'
    path.write_bytes(b'\x89PNG\r\n\x1a\n\x00\x00')
    with pytest.raises(ParameterError, match=r"params file .*b.yaml': not UTF-8 text \(byte 0x89"):
        check_params_file(str(path))


def test_what_is_accepted(tmp_path):
    text = ('/**:\n  ros__parameters:\n    use_sim_time: false\n    duration: 1.0\n'
            + section('duration: 2.0\nelectrodes: {gap: 1e-5, count: 0x8}\n'
                      'qos_overrides./diagnostics.publisher.depth: 10\n'))
    assert check_params_file(write(tmp_path, text)) == {
        'duration': 2.0, 'electrodes.gap': 1e-5, 'electrodes.count': 8}  # later section wins


# Scalars as rcl types them; the expected types are checked against rcl itself below.
SCALARS = ['yes', 'Off', 'y', 'true', '~', 'null', '0x10', '010', '08', '1_000', '1e-5', '2e5',
           '150.0e9', '.inf', '-.Inf', '.nan', 'NaN', 'inf', '+5', '1.', '.5', '12abc',
           '1e400', '"3.0"', "'yes'", '2001-12-14', '-0x1F']


def test_scalars_are_typed_as_rcl_types_them(tmp_path):
    """Compare with rcl's parser, reached through rclpy in a separate process."""
    names = [f'p{i}' for i in range(len(SCALARS))]
    body = ''.join(f'{n}: {s}\n' for n, s in zip(names, SCALARS))
    path = write(tmp_path, section(body))
    probe = textwrap.dedent(f"""
        import json, math, rclpy
        from rclpy.node import Node
        rclpy.init(args=['--ros-args', '--params-file', {path!r}])
        node = Node('ring_gyro', allow_undeclared_parameters=True,
                    automatically_declare_parameters_from_overrides=True)
        out = {{}}
        for name, p in node._parameter_overrides.items():
            v = p.value
            out[name] = [type(v).__name__, repr(v)]
        print(json.dumps(out))
    """)
    run = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True,
                         timeout=60, check=True)
    rcl = json.loads(run.stdout.strip().splitlines()[-1])
    for name, text in zip(names, SCALARS):
        quoted = text[0] in '"\''
        ours = rcl_scalar(text.strip('"\'') if quoted else text, quoted)
        kind, value = rcl[name]
        assert type(ours).__name__ == kind, (text, ours, rcl[name])
        if isinstance(ours, float) and math.isnan(ours):
            assert value == 'nan'
        else:
            assert repr(ours) == value, (text, ours, rcl[name])


def test_ros_arguments():
    argv = ['ring_gyro_node', '--ros-args', '--params-file', 'a.yaml', '-r', '__node:=gyro_b',
            '-r', '__ns:=/bench', '--log-level', 'debug', '-p', 'duration:=1.0', '--',
            '--params-file', 'not_ros.yaml', '--ros-args', '--params-file', 'b.yaml',
            '-r', 'other:__node:=x']
    assert ros_arguments(argv) == (['a.yaml', 'b.yaml'], 'gyro_b', '/bench')


def test_node_arguments_use_the_remapped_name(tmp_path):
    path = write(tmp_path, section('duration: 1.0\n', '/bench/gyro_b'))
    argv = ['x', '--ros-args', '--params-file', path, '-r', '__node:=gyro_b',
            '-r', '__ns:=/bench']
    assert check_node_arguments(argv) == {'duration': 1.0}
    with pytest.raises(ParameterError, match="no ros__parameters section .*'/ring_gyro'"):
        check_node_arguments(['x', '--ros-args', '--params-file', path])


def test_node_arguments_with_a_shared_file(tmp_path):
    """Several files: one without a section for the node is fine if another has one."""
    shared = write(tmp_path, section('rate: 5\n', 'camera'), 'shared.yaml')
    own = write(tmp_path, section('duration: 1.0\n'), 'own.yaml')
    argv = ['x', '--ros-args', '--params-file', shared, '--params-file', own]
    assert check_node_arguments(argv) == {'duration': 1.0}
    with pytest.raises(ParameterError, match='camera'):
        check_node_arguments(['x', '--ros-args', '--params-file', shared])
    dup = write(tmp_path, section('duration: 1.0\nduration: 1.0\n', 'camera'), 'dup.yaml')
    with pytest.raises(ParameterError, match='given twice'):  # checked even if not ours
        check_node_arguments(['x', '--ros-args', '--params-file', dup, '--params-file', own])


@pytest.mark.parametrize('case', ['mixed list', 'duplicate key', 'empty', 'another node'])
def test_ring_gyro_run_refuses_as_the_check_does(tmp_path, capsys, case):
    path = write(tmp_path, REFUSED[case][0])
    assert cli.main(['run', path, '--no-progress']) != 0
    err = capsys.readouterr().err
    assert REFUSED[case][1] in err and 'Traceback' not in err


def test_ring_gyro_run_refuses_a_binary_file(tmp_path, capsys):
    path = tmp_path / 'b.yaml'
    path.write_bytes(bytes(range(256)))
    assert cli.main(['run', str(path), '--no-progress']) != 0
    err = capsys.readouterr().err
    assert 'not UTF-8 text' in err and 'Traceback' not in err


def test_load_yaml_builds_the_config(tmp_path):
    config = load_yaml(write(tmp_path, section('electrodes: {outer_voltage: 70}\n')))
    assert config.electrodes.outer_voltage == 70.0
