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

"""Tests of ``ring_gyro_sim.core.params``: the parameter table, validation and the YAML loader."""

import math
from pathlib import Path

import pytest
from ring_gyro_sim.core.errors import ParameterError, RingGyroError
from ring_gyro_sim.core.params import (build_config, defaults, paper_config, PAPER_RESONATOR,
                                       PARAMETERS, SimConfig, SPECS, to_flat, upgraded)
from ring_gyro_sim.paramfile import load_yaml, parameters_from_yaml_text

PACKAGE_ROOT = Path(__file__).resolve().parents[2]
NUMERIC_KINDS = ('float', 'int', 'float_list')


def rejects(values, name):
    """Assert that ``build_config(values)`` fails with a message starting with ``name``."""
    with pytest.raises(ParameterError) as info:
        build_config(values)
    assert str(info.value).startswith(name + ':'), str(info.value)
    return str(info.value)


def test_parameter_error_is_a_value_error():
    assert issubclass(ParameterError, ValueError)
    assert issubclass(ParameterError, RingGyroError)


def test_defaults_build():
    config = build_config({})
    assert isinstance(config, SimConfig)
    assert config == SimConfig()  # the table and the dataclass defaults agree
    assert config.modes.count == 3
    assert config.electrodes.taylor_terms == 10
    assert config.electrodes.fold_linear_stiffness
    assert config.run.shock_times == () and config.run.shock_peaks == ()


def test_table_names_are_unique_and_complete():
    names = [p.name for p in PARAMETERS]
    assert len(names) == len(set(names))
    assert set(to_flat(build_config({}))) == set(names)
    for spec in PARAMETERS:
        assert spec.description and spec.unit, spec.name


# -- NaN anywhere -----------------------------------------------------------------------------

def nan_value(spec):
    if spec.kind == 'float_list':
        if spec.name.startswith('modes.'):
            return [math.nan, 1.0, 1.0]
        return [math.nan]
    return math.nan


@pytest.mark.parametrize('name', [p.name for p in PARAMETERS if p.kind in NUMERIC_KINDS])
def test_nan_is_rejected_everywhere(name):
    values = {name: nan_value(SPECS[name])}
    if name.startswith('modes.companion'):
        values['modes.companions'] = True
    if name.startswith('scenario.'):  # keep the two lists the same length
        values.setdefault('scenario.shock_times', [0.1])
        values.setdefault('scenario.shock_peaks', [1.0])
    rejects(values, name)


@pytest.mark.parametrize('text', [
    'ring_gyro: {ros__parameters: {electrodes.gap: .nan}}\n',
    'ring_gyro:\n  ros__parameters:\n    electrodes:\n      gap: .nan\n',
    '/**:\n  ros__parameters:\n    electrodes: {gap: .NaN}\n',
])
def test_nan_from_yaml_text(text):
    rejects(parameters_from_yaml_text(text), 'electrodes.gap')


@pytest.mark.parametrize('name, value', [
    ('electrodes.outer_voltage', math.inf),
    ('electrodes.inner_voltage', -math.inf),
    ('modes.frequencies', [11200.0, math.inf, 22000.0]),
])
def test_infinity_is_rejected(name, value):
    rejects({name: value}, name)


# -- one invalid value at a time --------------------------------------------------------------

@pytest.mark.parametrize('name, value', [
    ('modes.frequencies', [0.0, 15800.0, 22000.0]),
    ('modes.frequencies', [11200.0, -15800.0, 22000.0]),
    ('modes.quality_factors', [120000.0, 0.5, 170000.0]),
    ('modes.quality_factors', [120000.0, 64700.0, 0.0]),
    ('modes.quality_factors', [120000.0, 64700.0, -3.0]),
    ('modes.quality_factors', [120000.0, 64700.0]),
    ('modes.quality_factors', [120000.0, 64700.0, 170000.0, 1000.0]),
    ('electrodes.gap', 0.0),
    ('electrodes.gap', -10e-6),
    ('electrodes.taylor_terms', 1),
    ('electrodes.taylor_terms', 2),
    ('electrodes.taylor_terms', 41),
    ('electrodes.taylor_terms', -1),
    ('electrodes.count', 0),
    ('electrodes.relative_permittivity', 0.0),
    ('electrodes.outer_radius', 1.0e-3),   # inside the ring
    ('electrodes.inner_radius', 2.0e-3),   # outside the ring
    ('ring.radius', 0.0),
    ('ring.thickness', -1.0),
    ('legs.mass', -1e-9),
    ('legs.count', -1),
    ('drive.frequency', -1.0),
    ('drive.start_on', 'middle_branch'),
    ('integrator.method', 'rk4'),
    ('integrator.max_step', -1e-6),
    ('integrator.fidelity', 'fast'),
    ('duration', -1.0),
    ('output.rate', 0.0),
    ('output.rate', 300000.0),     # period 3333.33 ns
    ('output.rate', 3e9),          # period below 1 ns
    ('output.block_duration', 1e-6),  # shorter than one sample at 200 kHz
])
def test_invalid_value_names_the_parameter(name, value):
    rejects({name: value}, name)


@pytest.mark.parametrize('name, value, reason', [
    ('gyro.range', -1.0, 'must be >= 0'),
    ('gyro.range', math.nan, 'must be finite'),
    ('gyro.range', math.inf, 'must be finite'),
    ('gyro.resolution', -1e-4, 'must be >= 0'),
    ('gyro.resolution', math.nan, 'must be finite'),
    ('gyro.resolution', -math.inf, 'must be finite'),
    ('gyro.resolution', 1e-13, 'must be 0 (none) or >= 1e-12 rad/s'),
])
def test_a_bad_range_or_resolution_is_refused_by_name(name, value, reason):
    assert reason in rejects({name: value}, name)


def test_the_resolution_must_be_below_the_range():
    message = rejects({'gyro.range': 5.0, 'gyro.resolution': 5.0}, 'gyro.resolution')
    assert 'must be below gyro.range (5 rad/s)' in message
    config = build_config({'gyro.range': 5.0, 'gyro.resolution': 1e-3})
    assert (config.gyro.range, config.gyro.resolution) == (5.0, 1e-3)
    assert build_config({'gyro.resolution': 10.0}).gyro.range == 0.0  # no range: any LSB


def test_empty_frequencies_need_a_mode_count_and_legs():
    """Empty ``modes.frequencies`` means: from ring and legs (eqs. 7-17)."""
    rejects({'modes.frequencies': []}, 'modes.count')
    rejects({'modes.frequencies': [], 'modes.count': 3}, 'legs.radial_stiffness')


def test_static_pull_in_is_rejected_with_mechanical_frequencies():
    """Unfolded (mechanical) frequencies: K_c (eq. 26) must stay below every stiffness."""
    message = rejects({'electrodes.outer_voltage': 1e4,
                       'electrodes.fold_linear_stiffness': False}, 'electrodes.outer_voltage')
    assert 'pull-in' in message
    message = rejects({'electrodes.inner_voltage': 1e4,
                       'electrodes.fold_linear_stiffness': False}, 'electrodes.inner_voltage')
    assert 'pull-in' in message


def test_pull_in_threshold_with_mechanical_frequencies():
    """The limit is where K_c equals the 1theta stiffness m_1 omega_1^2 (the softest mode)."""
    config = build_config({'electrodes.fold_linear_stiffness': False})
    m1 = config.modal_masses()[0]
    k1 = m1 * (2.0 * math.pi * config.modes.frequencies[0]) ** 2
    v_pull_in = math.sqrt(k1 * config.electrodes.gap ** 2
                          / (2.0 * math.pi * config.a_eps * config.outer_radius))
    build_config({'electrodes.fold_linear_stiffness': False,
                  'electrodes.outer_voltage': 0.999 * v_pull_in})
    rejects({'electrodes.fold_linear_stiffness': False,
             'electrodes.outer_voltage': 1.001 * v_pull_in}, 'electrodes.outer_voltage')


def test_unknown_parameter():
    message = rejects({'electrodes.voltage': 80.0}, 'electrodes.voltage')
    assert 'unknown' in message
    with pytest.raises(ParameterError, match=r'^typo: unknown parameter'):
        parameters_from_yaml_text('ring_gyro:\n  ros__parameters:\n    typo: 1\n')


@pytest.mark.parametrize('name, value', [
    ('electrodes.gap', '10e-6'),
    ('electrodes.gap', True),
    ('electrodes.gap', [10e-6]),
    ('electrodes.taylor_terms', 10.5),
    ('electrodes.taylor_terms', '10'),
    ('modes.companions', 'yes'),
    ('modes.companions', 1),
    ('modes.frequencies', '11200'),
    ('modes.frequencies', 11200.0),
    ('modes.frequencies', [11200.0, 'x', 22000.0]),
    ('modes.frequencies', [11200.0, True, 22000.0]),
    ('record.path', 3),
])
def test_wrong_type(name, value):
    rejects({name: value}, name)


def test_wrong_type_from_yaml():
    text = 'ring_gyro:\n  ros__parameters:\n    electrodes:\n      gap: ten microns\n'
    rejects(parameters_from_yaml_text(text), 'electrodes.gap')


@pytest.mark.parametrize('times, peaks', [([0.1, 0.2], [1.0]), ([], [1.0]), ([0.1], [])])
def test_mismatched_shock_schedule(times, peaks):
    message = rejects({'scenario.shock_times': times, 'scenario.shock_peaks': peaks},
                      'scenario.shock_peaks')
    assert 'scenario.shock_times' in message


def test_negative_shock_time():
    rejects({'scenario.shock_times': [-1.0], 'scenario.shock_peaks': [1.0]},
            'scenario.shock_times')


# -- accepted forms ---------------------------------------------------------------------------

def test_integer_literals_are_accepted_for_floats():
    text = ('ring_gyro:\n  ros__parameters:\n    modes:\n'
            '      frequencies: [11200, 15800, 22000]\n'
            '      quality_factors: [120000, 64700, 170000]\n'
            '    electrodes: {outer_voltage: 78, gap: 0.00001}\n'
            '    output: {rate: 200000}\n')
    config = build_config(parameters_from_yaml_text(text))
    assert config.modes.frequencies == (11200.0, 15800.0, 22000.0)
    assert all(type(f) is float for f in config.modes.frequencies)
    assert type(config.electrodes.outer_voltage) is float
    assert config == build_config({})


@pytest.mark.parametrize('literal, value', [('150.0e9', 150e9), ('1e-5', 1e-5), ('2e5', 2e5),
                                            ('1.5E+3', 1.5e3), ('-3e-2', -3e-2)])
def test_exponent_forms_that_rcl_reads_as_double(literal, value):
    """
    The node's parser (rcl_yaml_param_parser, strtod) reads all of these as doubles.

    PyYAML's YAML 1.1 resolver reads ``150.0e9``, ``1e-5`` and ``2e5`` as strings; the same
    file must drive the node and the offline command line (doc/architecture.md).
    """
    flat = parameters_from_yaml_text(f'ring_gyro:\n  ros__parameters:\n    duration: {literal}\n')
    assert flat == {'duration': value}


def test_whole_float_accepted_for_int():
    assert build_config({'electrodes.taylor_terms': 12.0}).electrodes.taylor_terms == 12


def test_empty_yaml_list_gives_empty_list():
    text = ('ring_gyro:\n  ros__parameters:\n    scenario:\n'
            '      shock_times: []\n      shock_peaks: []\n')
    flat = parameters_from_yaml_text(text)
    config = build_config(flat)
    assert config.run.shock_times == ()
    assert config.run.shock_peaks == ()


@pytest.mark.parametrize('literal', ['~', 'null'])
def test_yaml_null_is_a_string_as_rcl_reads_it(literal):
    """Rcl types ``~`` and ``null`` as strings (parse.c get_value), so the node refuses them."""
    text = f'ring_gyro:\n  ros__parameters:\n    scenario:\n      shock_times: {literal}\n'
    assert parameters_from_yaml_text(text) == {'scenario.shock_times': literal}
    rejects(parameters_from_yaml_text(text), 'scenario.shock_times')
    text = f'ring_gyro:\n  ros__parameters:\n    electrodes:\n      gap: {literal}\n'
    rejects(parameters_from_yaml_text(text), 'electrodes.gap')


def test_an_empty_value_is_refused_as_rcl_refuses_it():
    text = 'ring_gyro:\n  ros__parameters:\n    scenario:\n      shock_times:\n    duration: 1.0\n'
    with pytest.raises(ParameterError, match=r'^scenario.shock_times: no value .*line 4'):
        parameters_from_yaml_text(text)


def test_wildcard_and_node_sections_are_both_read():
    text = ('/**:\n'
            '  ros__parameters:\n'
            '    electrodes: {gap: 12.0e-6}\n'
            'ring_gyro:\n'
            '  ros__parameters:\n'
            '    duration: 2.5\n'
            '    modes: {companions: true}\n'
            'other_node:\n'
            '  ros__parameters:\n'
            '    duration: 99.0\n')
    flat = parameters_from_yaml_text(text)
    assert flat == {'electrodes.gap': 12.0e-6, 'duration': 2.5, 'modes.companions': True}
    config = build_config(flat)
    assert config.electrodes.gap == 12.0e-6
    assert config.run.duration == 2.5
    assert config.modes.companions


@pytest.mark.parametrize('key', ['/ring_gyro', '"**"', '"/*"', '/**/ring_gyro'])
def test_qualified_node_names_are_read(key):
    flat = parameters_from_yaml_text(f'{key}:\n  ros__parameters:\n    duration: 4.0\n')
    assert flat == {'duration': 4.0}


def test_a_namespaced_section_applies_only_in_its_namespace():
    """Rcl applies '/sensors/ring_gyro' to /sensors/ring_gyro only (checked with rclpy)."""
    text = '/sensors/ring_gyro:\n  ros__parameters:\n    duration: 4.0\n'
    assert parameters_from_yaml_text(text, node_name='/sensors/ring_gyro') == {'duration': 4.0}
    with pytest.raises(ParameterError, match='no ros__parameters section'):
        parameters_from_yaml_text(text)


def test_other_node_name_argument():
    text = 'gyro_left:\n  ros__parameters:\n    duration: 4.0\n'
    assert parameters_from_yaml_text(text, node_name='gyro_left') == {'duration': 4.0}


def test_file_for_another_node_fails_clearly():
    text = 'camera:\n  ros__parameters:\n    duration: 4.0\n'
    with pytest.raises(ParameterError) as info:
        parameters_from_yaml_text(text)
    message = str(info.value)
    assert 'ros__parameters' in message and "'/ring_gyro'" in message and '/**' in message


@pytest.mark.parametrize('text', ['a: [1, 2\n', '- 1\n- 2\n'])
def test_bad_yaml_fails_with_parameter_error(text):
    with pytest.raises(ParameterError, match='params file'):
        parameters_from_yaml_text(text)


@pytest.mark.parametrize('text', ['', '# nothing here\n', '/**:\n  ros__parameters: {}\n'])
def test_a_file_that_sets_nothing_is_refused(text):
    """Rcl reads these as "no parameters": the node would run silently on its defaults."""
    with pytest.raises(ParameterError, match='params file'):
        parameters_from_yaml_text(text)


# -- round trip and shipped files -------------------------------------------------------------

ROUND_TRIP_CASES = [
    {},
    {'modes.companions': True, 'modes.companion_frequencies': [11200.0, 15810.0, 22005.0],
     'electrodes.inner_voltage': 50.0, 'electrodes.outer_radius': 1.52e-3,
     'electrodes.taylor_terms': 0, 'electrodes.fold_linear_stiffness': False,
     'legs.mass': 1e-9, 'scenario.shock_times': [0.1, 0.5],
     'scenario.shock_peaks': [98066.5, -1000.0], 'drive.start_on': 'rest',
     'integrator.method': 'bm4', 'output.rate': 100000.0, 'record.path': 'out/x.mcap'},
    {'modes.frequencies': [11200.0, 15800.0, 22000.0, 36300.0, 59200.0],
     'modes.quality_factors': [120000.0, 64700.0, 170000.0, 80000.0, 50000.0]},
]


@pytest.mark.parametrize('values', ROUND_TRIP_CASES)
def test_to_flat_round_trips(values):
    config = build_config(values)
    flat = to_flat(config)
    assert build_config(flat) == config
    assert to_flat(build_config(flat)) == flat
    for name, value in values.items():
        assert flat[name] == value, name


def test_defaults_mapping_is_a_copy():
    d = defaults()
    d['modes.frequencies'].append(1.0)
    assert len(defaults()['modes.frequencies']) == 3


def test_default_yaml_loads_and_matches_the_table():
    config = load_yaml(str(PACKAGE_ROOT / 'config' / 'default.yaml'))
    assert config == build_config({})


def test_demo_yaml_loads():
    # make run: the default gyroscope at 10 deg/s, 10 000 g at 0.5 s.
    config = load_yaml(str(PACKAGE_ROOT / 'config' / 'demo.yaml'))
    assert config.run.shock_times == (0.5,)
    assert config.run.shock_peaks == (98066.5,)
    assert config.run.rate_values == (math.radians(10.0),)
    assert config.run.duration == 8.0
    assert config.run.record_path == 'out/demo.mcap'
    default = build_config({})
    assert (config.gyro, config.control, config.modes) == (default.gyro, default.control,
                                                           default.modes)


def test_the_defaults_are_the_gyroscope_and_paper_yaml_the_resonator():
    default = build_config({})
    assert default.gyro.enabled and default.modes.companions
    assert default.control.mode == 'rebalance'
    paper = load_yaml(str(PACKAGE_ROOT / 'config' / 'paper.yaml'))
    assert paper == paper_config() == build_config(PAPER_RESONATOR)
    assert not paper.gyro.enabled and not paper.modes.companions
    assert paper.control.mode == 'open_loop'
    # The resonator is the same device as the gyroscope: only PAPER_RESONATOR differs.
    differ = {k for k, v in to_flat(paper).items() if to_flat(default)[k] != v}
    assert differ == set(PAPER_RESONATOR)


def test_missing_file_fails_with_parameter_error(tmp_path):
    with pytest.raises(ParameterError, match='params file'):
        load_yaml(str(tmp_path / 'nope.yaml'))


# -- physical ranges --------------------------------------------------------------------------

def test_voltage_limit_with_folded_frequencies():
    """
    Folded (Table 1) frequencies: K_c (eq. 26) must stay below m_1 omega_1^2.

    215.6 V is that limit for the default device, computed here independently of
    ``voltage_limits`` from the modal mass, the 1theta frequency and eq. (26).
    """
    config = build_config({})
    m1 = config.modal_masses()[0]
    k1 = m1 * (2.0 * math.pi * config.modes.frequencies[0]) ** 2
    v_limit = math.sqrt(k1 * config.electrodes.gap ** 2
                        / (2.0 * math.pi * config.a_eps * config.outer_radius))
    assert v_limit == pytest.approx(215.59, abs=0.01)
    assert config.voltage_limits()[0] == pytest.approx(v_limit, rel=1e-12)
    build_config({'electrodes.outer_voltage': -0.999 * v_limit})
    message = rejects({'electrodes.outer_voltage': 1.001 * v_limit}, 'electrodes.outer_voltage')
    assert 'pull-in' in message and '215.6 V' in message
    rejects({'electrodes.outer_voltage': 1e6}, 'electrodes.outer_voltage')
    # Both together: each alone is below its limit, the sum of eq. (26) is not.
    v_o, v_i = config.voltage_limits()
    build_config({'electrodes.outer_voltage': 0.7 * v_o, 'electrodes.inner_voltage': 0.7 * v_i})
    rejects({'electrodes.outer_voltage': 0.8 * v_o, 'electrodes.inner_voltage': 0.7 * v_i},
            'electrodes.outer_voltage')
    rejects({'electrodes.outer_voltage': 0.7 * v_o, 'electrodes.inner_voltage': 0.8 * v_i},
            'electrodes.inner_voltage')


@pytest.mark.parametrize('values, name', [
    ({'electrodes.relative_permittivity': 0.5}, 'electrodes.relative_permittivity'),
    ({'output.rate': 1e9}, 'output.rate'),
    ({'output.rate': 2e7}, 'output.rate'),
    ({'output.block_duration': 10.0}, 'output.block_duration'),
    ({'duration': 2.0 ** 31}, 'duration'),
    ({'scenario.shock_times': [2.0 ** 31], 'scenario.shock_peaks': [1.0]},
     'scenario.shock_times'),
    ({'inputs.horizon': 1e300}, 'inputs.horizon'),
])
def test_out_of_physical_range(values, name):
    rejects(values, name)


def test_block_memory_is_bounded():
    """
    At most MAX_BLOCK_BYTES (4 MiB) of block messages per block.

    The paper's resonator: t + 3 q, t + 8 gaps + min gap, t + 8 C = 23 values = 184 bytes per
    sample, so 4 MiB / 184 B = 22795 samples: 0.11 s at 200 kHz fits, 0.12 s does not. The
    gyroscope (the defaults) adds 3 companions and ~/demodulator's t + 4 channels: 31 values,
    16912 samples, 0.08 s.
    """
    assert paper_config().block_values_per_sample() == 23
    assert build_config({}).block_values_per_sample() == 31
    assert paper_config({'output.block_duration': 0.11}).run.block_samples == 22000
    message = rejects({**PAPER_RESONATOR, 'output.block_duration': 0.12},
                      'output.block_duration')
    assert '22795 samples per block' in message and 'MiB' in message
    build_config({'output.block_duration': 0.08})
    assert '16912 samples per block' in rejects({'output.block_duration': 0.09},
                                                'output.block_duration')
    # 10 MHz with the default 10 ms block: 100 000 samples, refused before any allocation.
    rejects({'output.rate': 1e7}, 'output.block_duration')
    paper_config({'output.rate': 1e7, 'output.block_duration': 0.002})
    # More channels, fewer samples: 360 electrodes -> 4 + 3 + 720 values per sample.
    rejects({**PAPER_RESONATOR, 'electrodes.count': 360}, 'output.block_duration')


def test_every_numeric_row_is_checked_by_its_dataclass():
    """A value the row refuses is refused by the dataclass too (one check, from the row)."""
    from dataclasses import replace
    config = build_config({})
    with pytest.raises(ParameterError, match='^electrodes.relative_permittivity:'):
        replace(config.electrodes, relative_permittivity=0.9)
    with pytest.raises(ParameterError, match='^output.rate:'):
        replace(config.run, output_rate=1e9)
    with pytest.raises(ParameterError, match='^modes.quality_factors:'):
        replace(config.modes, quality_factors=(1e5, 0.4, 1e5))


def test_a_class_field_without_a_row_is_refused_at_import():
    from ring_gyro_sim.core import params
    cls = type('Extra', (), {'__annotations__': {'radius': float, 'colour': str}})
    with pytest.raises(TypeError, match='Extra.colour: no row'):
        params._parameter_group('ring')(cls)


def test_field_paths_name_real_attributes():
    config = build_config({})
    for spec in PARAMETERS:
        assert hasattr(getattr(config, spec.group), spec.attribute), spec.field


@pytest.mark.parametrize('name, value', [('control.drive_loop', 'closed'),
                                         ('control.rebalance', True)])
def test_the_parameters_control_mode_replaced_are_refused_with_its_name(name, value):
    with pytest.raises(ParameterError, match=f'^{name}: replaced by control.mode'):
        build_config({name: value})


@pytest.mark.parametrize('old, mode', [
    ({'control.drive_loop': 'open', 'control.rebalance': False}, 'open_loop'),
    ({'control.drive_loop': 'closed', 'control.rebalance': False}, 'closed_loop'),
    ({'control.drive_loop': 'closed', 'control.rebalance': True}, 'rebalance'),
    ({'control.drive_loop': 'closed'}, 'rebalance'),     # the old default: rebalance on
    ({'control.rebalance': False}, 'closed_loop'),       # the old default: closed loop
    ({'control.drive_loop': 'open'}, 'open_loop'),       # rebalance needed the closed loop
])
def test_a_recordings_old_mode_parameters_become_its_control_mode(old, mode):
    # What a recording's metadata holds from before control.mode (offline.load_recording):
    # the same gyroscope, the other values untouched.
    new = upgraded({**old, 'duration': 2.0})
    assert new == {'control.mode': mode, 'duration': 2.0}
    assert build_config(new).control.mode == mode
    assert upgraded({'duration': 2.0}) == {'duration': 2.0}
