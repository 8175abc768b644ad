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

"""Tests of sweep/spec.py: the spec format, names with [i], ranges, keys, refusals."""

from pathlib import Path
import time

import numpy as np
import pytest
from ring_gyro_sim.core.params import paper_config
from ring_gyro_sim.sweep import load_spec, parse_spec, SweepSpecError
from ring_gyro_sim.sweep.spec import MAX_POINTS
from sweep_harness import REPO, TINY, write_spec
import yaml


def spec_of(text, tmp_path=None):
    return parse_spec(yaml.safe_load(text), directory=str(tmp_path or '.'))


def test_tiny_spec_points_in_c_order_with_q1_by_index(tmp_path):
    spec = load_spec(str(write_spec(tmp_path)))
    assert spec.shape == (2, 2) and spec.size == 4
    points = spec.points()
    assert [p.coords for p in points] == [
        (('shock.peak_g', 2000.0), ('shock.phase', 0.0)),
        (('shock.peak_g', 2000.0), ('shock.phase', 0.5)),
        (('shock.peak_g', 8000.0), ('shock.phase', 0.0)),
        (('shock.peak_g', 8000.0), ('shock.phase', 0.5))]
    cfg = points[0].case_spec().config(None, spec.output_rate_hz)
    default = paper_config({})
    # modes.quality_factors[0] replaces Q_1 only, the other Q from the base
    assert cfg.modes.quality_factors == (40000.0,) + default.modes.quality_factors[1:]
    assert len({p.key for p in points}) == 4


def test_linear_and_log_ranges_include_their_ends():
    spec = spec_of("""
duration: 1.0
axes:
  shock.peak_g: {linear: [1000, 12000, 8]}
  modes.quality_factors[0]: {log: [5000, 180000, 8]}
""")
    g, q = spec.axes
    np.testing.assert_allclose(g.values, np.linspace(1000.0, 12000.0, 8))
    np.testing.assert_allclose(q.values, np.geomspace(5000.0, 180000.0, 8))
    assert (g.spacing, q.spacing) == ('linear', 'log')
    assert (g.unit, q.unit) == ('g', '-')
    assert spec.plot_axes == ('shock.peak_g', 'modes.quality_factors[0]')


def test_an_integer_range_includes_its_stop():
    spec = spec_of("""
duration: 1.0
axes:
  device.seed: {range: [1, 5]}
  modes.quality_factors[0]: {range: [5000, 9000, 2000]}
""")
    seed, q = spec.axes
    assert seed.values == (1, 2, 3, 4, 5) and all(type(v) is int for v in seed.values)
    assert q.values == (5000.0, 7000.0, 9000.0) and all(type(v) is float for v in q.values)
    assert (seed.spacing, seed.unit) == ('range', '-')
    assert spec.shape == (5, 3)


@pytest.mark.parametrize('axis, message', [
    ('{range: [1]}', 'expected integers [start, stop]'),
    ('{range: [1.5, 3]}', 'expected integers'),
    ('{range: [5, 1]}', 'start <= stop and step >= 1'),
    ('{range: [1, 5, 0]}', 'start <= stop and step >= 1'),
    ('{range: [-1, 1]}', 'device.seed: must be >= 0'),
])
def test_bad_ranges_are_refused(axis, message):
    with pytest.raises(SweepSpecError) as info:
        spec_of(f'duration: 1\naxes:\n  device.seed: {axis}\n')
    assert message in str(info.value), str(info.value)


def test_set_takes_a_whole_list_and_an_axis_does_not():
    spec = spec_of("""
duration: 1.0
set:
  modes.quality_factors: [40000.0, 64700.0, 170000.0]
axes:
  modes.quality_factors[1]: [60000.0, 70000.0]
""")
    configs = [p.case_spec().config(None, spec.output_rate_hz) for p in spec.points()]
    assert [c.modes.quality_factors for c in configs] == [
        (40000.0, 60000.0, 170000.0), (40000.0, 70000.0, 170000.0)]
    with pytest.raises(SweepSpecError) as info:
        spec_of('duration: 1\naxes:\n  modes.quality_factors: [[1.0, 2.0, 3.0]]\n')
    assert 'a list parameter: sweep one element' in str(info.value)


def test_a_point_key_is_its_content_not_its_spelling():
    a = spec_of('duration: 1.0\naxes:\n  modes.quality_factors[0]: [5000, 20000]\n')
    b = spec_of('duration: 1.0\nset: {shock.peak_g: 0}\n'
                'axes:\n  modes.quality_factors[0]: [20000.0, 5000.0]\n')
    assert a.points()[0].key == b.points()[1].key
    c = spec_of('duration: 2.0\naxes:\n  modes.quality_factors[0]: [5000, 20000]\n')
    assert c.points()[0].key != a.points()[0].key     # the run length is part of the point


def test_the_case4_example_is_the_papers_case4():
    spec = load_spec(str(REPO / 'config' / 'sweep_case4.yaml'))
    assert spec.base_path == str(REPO / 'config' / 'paper.yaml')
    assert spec.axes[0].name == 'modes.quality_factors[0]'
    assert spec.axes[0].values == (5000.0, 20000.0, 40000.0, 80000.0, 120000.0, 180000.0)
    assert spec.fixed['shock.peak_g'] == 10000.0 and spec.duration_s == 30.0
    assert spec.envelopes == ('q2',)                     # Fig. 13: q2 over time per point


@pytest.mark.parametrize('text, message', [
    ('duration: 1\naxes:\n  modes.quality_factor[0]: [1.0]', 'unknown parameter'),
    ('duration: 1\naxes: {modes.quality_factors: [1.0]}', 'sweep one element'),
    ('duration: 1\naxes:\n  modes.quality_factors[3]: [1.0]', 'index 3 is beyond'),
    ('duration: 1\naxes:\n  drive.frequency[0]: [1.0]', 'list parameters only'),
    ('duration: 1\naxes: {shock.peak: [1.0]}', 'scenario inputs: shock.peak_g'),
    ('duration: 1\naxes: {shock.phase: [1.0]}', 'must be in [0, 1)'),
    ('duration: 1\naxes: {shock.angle_deg: [30.0]}', 'needs modes.companions'),
    ('duration: 1\naxes: {electrodes.gap: [-1.0]}', 'electrodes.gap'),
    ('duration: 1\naxes: {shock.peak_g: {log: [0, 10, 3]}}', 'must be > 0'),
    ('duration: 1\naxes: {shock.peak_g: {linear: [1, 10]}}', '[start, stop, count]'),
    ('duration: 1\naxes: {shock.peak_g: [1.0, 1.0]}', 'given twice'),
    ('duration: 1\naxes: {duration: [1.0]}', 'spec keys duration'),
    ('duration: 1\naxes: {shock.peak_g: [1.0]}\nmetrics: [final_brunch]', 'unknown'),
    ('duration: 1\naxes: {shock.peak_g: [1.0]}\nplot: {x: drive.frequency}', 'not an axis'),
    ('duration: 1\naxis: {shock.peak_g: [1.0]}', "unknown key(s) ['axis']"),
    ('axes: {shock.peak_g: [1.0]}', 'give the simulated time'),
    ('duration: 1\nset: {shock.peak_g: 1.0}\naxes: {shock.peak_g: [2.0]}', 'also under set'),
    ('duration: 1\naxes: {shock.peak_g: [1.0]}\nenvelopes: [q4]', 'not an envelope channel'),
    ('duration: 1\naxes: {shock.peak_g: [1.0]}\nenvelopes: [q2, q2]', 'given twice'),
    ('duration: 1\naxes: {shock.peak_g: [1.0]}\nenvelopes: q2', "expected 'all'"),
    ('duration: 1\naxes: {shock.peak_g: [1.0]}\nenvelopes: [all, q2]', 'give it alone'),
])
def test_bad_specs_are_refused_naming_the_key(text, message):
    with pytest.raises(SweepSpecError, match=None) as info:
        spec_of(text)
    assert message in str(info.value), str(info.value)


def test_kept_envelopes_make_another_point_and_none_keeps_the_key():
    text = 'duration: 1.0\naxes:\n  modes.quality_factors[0]: [5000, 20000]\n'
    plain = spec_of(text).points()[0]
    assert spec_of(text + 'envelopes: []\n').points()[0].key == plain.key
    kept = spec_of(text + 'envelopes: [q2, wmax]\n').points()[0]
    assert kept.envelopes == ('q2', 'wmax') and kept.key != plain.key
    every = spec_of(text + 'envelopes: all\n').points()[0]
    assert every.envelopes == ('all',) and every.key not in (plain.key, kept.key)
    companions = spec_of('duration: 1.0\nset: {modes.companions: true}\n'
                         'axes: {shock.peak_g: [1.0]}\nenvelopes: [q2s]\n')
    assert companions.envelopes == ('q2s',)


def test_base_parameters_without_a_file_and_not_with_one(tmp_path):
    data = {'duration': 1.0, 'axes': {'modes.quality_factors[0]': [5000.0]}}
    spec = parse_spec(data, base_params={'drive.frequency': 15798.3})
    assert spec.base == {'drive.frequency': 15798.3} and spec.base_path is None
    assert dict(spec.points()[0].overrides)['drive.frequency'] == 15798.3
    with pytest.raises(SweepSpecError, match='base: .*electrodes.gap'):
        parse_spec(data, base_params={'electrodes.gap': -1.0})
    base = write_spec(tmp_path, 'ring_gyro:\n  ros__parameters: {}\n', 'base.yaml')
    with pytest.raises(SweepSpecError, match='given together'):
        parse_spec(dict(data, base=base.name), directory=str(tmp_path), base_params={})


def test_duplicate_keys_and_base_shocks_are_refused(tmp_path):
    path = write_spec(tmp_path, TINY + '  shock.phase: [0.25]\n', 'dup.yaml')
    with pytest.raises(SweepSpecError, match="'shock.phase': given twice"):
        load_spec(str(path))
    base = tmp_path / 'base.yaml'
    base.write_text('ring_gyro:\n  ros__parameters:\n    scenario:\n      shock_times: [0.1]\n'
                    '      shock_peaks: [1000.0]\n', encoding='utf-8')
    path = write_spec(tmp_path, f'base: {base.name}\n' + TINY, 'based.yaml')
    with pytest.raises(SweepSpecError, match='schedules shocks'):
        load_spec(str(path))


def test_base_file_goes_through_the_params_file_check(tmp_path):
    base = tmp_path / 'base.yaml'
    base.write_text('ring_gyro:\n  ros__parameters:\n    drive:\n      frequncy: 1.0\n',
                    encoding='utf-8')
    path = write_spec(tmp_path, f'base: {base.name}\n' + TINY, 'based.yaml')
    with pytest.raises(ValueError, match='drive.frequncy'):
        load_spec(str(path))
    assert Path(path).is_file()


def test_the_sweep_verb_refuses_a_bad_spec_naming_the_key(tmp_path, capsys):
    from ring_gyro_sim import cli
    bad = write_spec(tmp_path, 'duration: 1\naxes:\n  modes.quality_factors[7]: [1.0]\n')
    assert cli.main(['sweep', str(bad), '--out', str(tmp_path / 'o')]) == 1
    err = capsys.readouterr().err
    assert err.startswith('ring_gyro sweep: error: sweep spec') and 'index 7' in err
    good = write_spec(tmp_path)
    assert cli.main(['sweep', str(good), '--out', str(tmp_path / 'o'), '--workers', '2',
                     '--scheduler', 'tcp://127.0.0.1:1']) == 1
    assert '--workers: applies to the local cluster only' in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(['--help'])
    assert 'sweep' in capsys.readouterr().out


@pytest.mark.parametrize('axes, count', [
    ({'shock.peak_g': {'linear': [1000.0, 12000.0, 1_000_000_000]}}, 1_000_000_000),
    ({'shock.peak_g': {'linear': [1000.0, 12000.0, 1000]},
      'modes.quality_factors[0]': {'log': [5000.0, 180000.0, 1000]}}, 1_000_000),
])
def test_a_spec_beyond_the_size_a_sweep_takes_is_refused_at_once(axes, count):
    # 1e9 points would reach 3 GB in 8 s without a word if numpy made every value before
    # anything was counted: the count is read from the spec as written.
    started = time.process_time()
    with pytest.raises(SweepSpecError) as info:
        parse_spec({'duration': 25.0, 'axes': axes})
    assert time.process_time() - started < 1.0
    text = str(info.value)
    assert f'{count} points' in text and f'the {MAX_POINTS} a sweep takes' in text, text
    assert 'CPU-' in text and 'about' in text
    at_limit = {'shock.peak_g': {'linear': [1000.0, 12000.0, 1000]},
                'shock.phase': {'linear': [0.0, 0.99, MAX_POINTS // 1000]}}
    assert len(parse_spec({'duration': 1.0, 'axes': at_limit}).axes[1]) == MAX_POINTS // 1000


@pytest.mark.parametrize('key, value, message', [
    ('duration', 1.0e308, 'duration: must be at most 2.14748e+09'),
    ('envelope_window', 2.0, 'envelope_window: must be at most 1'),
])
def test_run_settings_beyond_the_parameter_ranges_are_refused(key, value, message):
    # Refused at once: duration 1.0e+308 would otherwise fail later (OverflowError)
    data = {'duration': 1.0, 'axes': {'shock.peak_g': [1000.0]}, key: value}
    with pytest.raises(SweepSpecError, match=None) as info:
        parse_spec(data)
    assert message in str(info.value), str(info.value)
