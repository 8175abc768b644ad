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

"""Tests of sweep/point.py and sweep/store.py: the point function, its failures, the store."""

from dataclasses import replace
import json
import math

import numpy as np
import pytest
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.core.params import paper_config
from ring_gyro_sim.sweep import load_spec, point
from ring_gyro_sim.sweep.store import PointStore
from sweep_harness import TINY, write_spec


def same(a, b):
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a)
                      and math.isnan(b))


def test_a_point_is_the_case_run_with_its_parameters(tmp_path):
    """evaluate() == cases.run_case of the same case written by hand (fresh drive setup)."""
    spec = load_spec(str(write_spec(tmp_path)))
    p = spec.points()[3]                        # 8000 g at half a drive period, Q_1 40 000
    by_hand = cases.CaseSpec('by_hand', '', 8000.0, 40000.0, 0.5, shock_phase=0.5)
    expected = cases.run_case(by_hand, progress=False).numbers
    got = point.evaluate(p)
    assert set(got) == set(point.METRICS)
    for name, value in got.items():
        assert same(value, expected[name] if name in expected else None) or \
            (value == 'none' and expected.get(name) is None), name
    again = point.evaluate(p)                   # drive setup from the cache now: same numbers
    assert all(same(again[k], got[k]) for k in got)
    at_phase_0 = point.evaluate(spec.points()[2])
    assert at_phase_0['q2_after_shock_m'] != got['q2_after_shock_m']   # the phase acts


def test_shock_phase_is_a_time_in_drive_periods():
    cfg = paper_config({})
    spec = cases.CaseSpec('p', '', 1000.0, None, 0.01, shock_phase=0.25, shock_angle_deg=90.0)
    shock = cases.shock_input(spec, cfg)
    assert shock.at_ns == round(0.25 / cfg.drive.frequency * 1e9)   # 15.8 us at 15 798.6 Hz
    assert abs(shock.x) < 1e-9 * shock.y and shock.y == 1000.0 * 9.80665
    paper = cases.shock_input(replace(spec, shock_phase=0.0, shock_angle_deg=0.0), cfg)
    assert (paper.at_ns, paper.x, paper.y) == (None, 1000.0 * 9.80665, 0.0)   # t = 0, on x


def test_a_failing_point_is_a_record_with_its_parameters(tmp_path):
    spec = load_spec(str(write_spec(tmp_path)))
    bad = replace(spec.points()[0], shock_angle_deg=30.0)   # off x, and no companions
    store = PointStore(tmp_path / 'out')
    record = point.compute(bad, str(tmp_path / 'out'))
    assert record['metrics'] is None
    assert 'needs modes.companions' in record['error'] and 'InputError' in record['error']
    assert record['parameters']['coords'] == {'shock.peak_g': 2000.0, 'shock.phase': 0.0}
    stored = json.loads(store.path(bad.key, failed=True).read_text())
    assert stored['error'] == record['error'] and not store.has(bad.key)


def test_points_differing_in_their_shock_share_one_drive_setup(tmp_path):
    two_q = TINY.replace('  modes.quality_factors[0]: 40000.0\n', '') + \
        '  modes.quality_factors[0]: [20000.0, 40000.0]\n'
    points = load_spec(str(write_spec(tmp_path, two_q))).points()   # 2 x 2 x 2, Q_1 last
    keys = [point.setup_key(p) for p in points]
    assert len(set(keys)) == 2 and keys == [keys[0], keys[1]] * 4   # one per Q_1
    point._SETUP_CACHE.clear()
    setup = point.setup_task(points[1])
    assert isinstance(setup, cases.DriveSetup) and len(point._SETUP_CACHE) == 1
    assert setup.branches.upper_m > 1.5 * setup.branches.lower_m > 0.0


def test_a_failed_drive_setup_is_the_failure_of_its_points(tmp_path):
    p = load_spec(str(write_spec(tmp_path))).points()[0]
    bad = replace(p, overrides=p.overrides + (('modes.frequencies', 'not a list'),))
    failed = point.setup_task(bad)                            # does not raise
    assert isinstance(failed, point.SetupFailure) and 'Traceback' in failed.traceback
    store = PointStore(tmp_path / 'out')
    record = point.compute(p, str(tmp_path / 'out'), setup=failed)
    assert record['metrics'] is None and record['error'] == failed.error
    assert record['traceback'] == failed.traceback and record['cpu_time_s'] >= 0.0
    assert store.read_failure(p.key)['error'] == failed.error and not store.has(p.key)


def test_store_writes_whole_records_and_nan_as_null(tmp_path):
    store = PointStore(tmp_path)
    rec = {'key': 'abc', 'metrics': {'x': math.nan, 'y': 1.5}, 'error': None}
    path = store.write(rec)
    assert json.loads(path.read_text())['metrics'] == {'x': None, 'y': 1.5}
    assert [p.name for p in path.parent.iterdir()] == ['abc.json']   # no temporary left
    assert store.read('abc')['metrics']['y'] == 1.5 and store.read('nope') is None
    store.write({'key': 'def', 'metrics': None, 'error': 'E: boom'})
    assert store.read_failure('def')['error'] == 'E: boom' and list(store.keys()) == ['abc']
    store.write({'key': 'def', 'metrics': {}, 'error': None})   # a retry that succeeded
    assert store.read_failure('def') is None


def test_kept_envelopes_fill_the_results_over_time_and_stay_out_of_the_csv(tmp_path):
    """A run stopped by contact keeps fewer windows: nan after it; a failed point: all nan."""
    from ring_gyro_sim.sweep import parse_spec, results
    spec = parse_spec({'duration': 0.004, 'axes': {'shock.peak_g': [1.0, 2.0, 3.0]},
                       'envelopes': ['q2']})
    p = spec.points()
    t = [0.0005, 0.0015, 0.0025, 0.0035]

    def record(at, n, q2):
        return {'key': at.key, 'metrics': {m: None for m in point.METRICS}, 'error': None,
                'wall_time_s': 1.0, 'envelope': {'names': ['q2'], 'complete': False,
                                                 'window_s': 0.001, 't_s': t[:n],
                                                 'values': {'q2': q2}}}

    records = {p[0].key: record(p[0], 4, [1e-7, 2e-7, None, 4e-7]),
               p[1].key: record(p[1], 2, [5e-7, 6e-7]), p[2].key: None}
    ds = results.build_dataset(spec, p, records, {p[2].key: {'error': 'E: boom'}})
    np.testing.assert_array_equal(ds['time'].values, t)
    q2 = ds['envelope_q2_m'].values
    assert q2.shape == (3, 4) and ds['envelope_q2_m'].attrs['units'] == 'm'
    np.testing.assert_array_equal(q2[0], [1e-7, 2e-7, np.nan, 4e-7])
    np.testing.assert_array_equal(q2[1], [5e-7, 6e-7, np.nan, np.nan])
    assert np.all(np.isnan(q2[2]))
    files = results.write_results(ds, tmp_path)
    assert len(open(files['csv']).read().splitlines()) == 1 + 3     # one row per point
    np.testing.assert_array_equal(results.open_results(files['netcdf'])['envelope_q2_m'], q2)
    from ring_gyro_sim.analysis import plotting
    if plotting.available():   # Fig. 13 of a sweep: one line per point
        assert plotting.plot_sweep_envelopes(ds, tmp_path) == [str(tmp_path / 'envelope_q2.png')]
    with pytest.raises(ValueError, match='does not keep every envelope'):
        point.case_result(records[p[0].key], cases.case4_specs((5000.0,), 0.004)[0])
