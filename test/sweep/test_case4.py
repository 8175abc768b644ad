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
Case 4 of the paper as a sweep (config/sweep_case4.yaml) = the single runs of cases.py.

Short in the default suite (0.2 s, two Q_1: numbers only, no branch decided); the full
30 s, six Q_1 in ``slow``, with the branches of README "Reproducing the paper".
``ring_gyro report`` runs its Case 4 through the same sweep path (report.run_case4): its
numbers, envelopes and branches are those of the single runs too, bit for bit.
"""

import json
import math

import numpy as np
import pytest
from ring_gyro_sim import report
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.sweep import parse_spec, run_sweep
from ring_gyro_sim.sweep import results as sweep_results
from ring_gyro_sim.sweep.point import METRICS
from sweep_harness import REPO
import yaml

SPEC = REPO / 'config' / 'sweep_case4.yaml'
SHORT_Q1 = (5000.0, 180000.0)
SHORT_S = 0.2


@pytest.fixture(scope='module')
def short_singles():
    """Return the two short Case 4 runs, each by cases.run_case on its own (the reference)."""
    return [cases.run_case(s, progress=False) for s in cases.case4_specs(SHORT_Q1, SHORT_S)]


def case4_as_sweep(tmp_path, **changes):
    data = yaml.safe_load(SPEC.read_text(encoding='utf-8'))
    data.update(changes)
    spec = parse_spec(data, source=str(SPEC), directory=str(SPEC.parent))
    return run_sweep(spec, tmp_path / 'out', workers=2, progress=False, dashboard_address=None,
                     plots=False).dataset


def assert_as_single_runs(ds, singles):
    q1 = ds['modes.quality_factors[0]'].values
    assert list(q1) == [r.spec.q1_quality for r in singles]
    for i, r in enumerate(singles):
        for name in ds.data_vars:
            if name not in METRICS:
                continue
            got = ds[name].values[i]
            want = r.numbers.get(name)
            if METRICS[name][0] == 'float':
                assert (math.isnan(got) and (want is None or math.isnan(want))) or \
                    got == want, (name, r.spec.name, got, want)
            elif METRICS[name][0] == 'bool':
                assert got == int(bool(want)), (name, r.spec.name)
            else:
                assert got == want, (name, r.spec.name)
        assert ds['error'].values[i] == ''
        # the kept q2 envelope (Fig. 13) is the run's, window for window
        np.testing.assert_array_equal(ds['time'].values, r.envelope.t)
        np.testing.assert_array_equal(ds['envelope_q2_m'].values[i], r.envelope.channel('q2'))


def test_case4_sweep_gives_the_numbers_of_the_single_runs(tmp_path, short_singles):
    ds = case4_as_sweep(tmp_path, duration=SHORT_S,
                        axes={'modes.quality_factors[0]': list(SHORT_Q1)})
    assert_as_single_runs(ds, short_singles)
    assert ds['final_q2_m'].values[0] != ds['final_q2_m'].values[1]   # Q_1 did change
    assert [n for n in ds.data_vars if n.startswith('envelope_')] == ['envelope_q2_m']


def test_the_report_runs_case4_through_the_sweep_engine(tmp_path, monkeypatch, capsys,
                                                        short_singles):
    """
    build_report's Case 4: a sweep (points, a 1-worker LocalCluster, the store), not the pool.

    The pool runs in this process with one worker: a spy on cases.run_case here would see
    any case the pool runs, and sees none (the plan is Case 4 only); the sweep's stored
    points and results are in case4_sweep/. The report's Case 4 numbers (every one but the
    wall time), envelope CSVs and branches equal the single runs' bit for bit. One Q_1
    (each point costs its drive setup, ~2 s, on a fresh worker); the order of several is
    the sweep test's above.
    """
    specs = tuple(cases.case4_specs(SHORT_Q1[1:], SHORT_S))
    plan = report.ReportPlan(drive_cases=(), sweep=specs, ritz=(), inner=(),
                             backbone_orders=(), frf=False, quick=True)
    monkeypatch.setattr(report, 'make_plan', lambda quick, base: plan)
    ran_here = []
    run_case = cases.run_case

    def spy(spec, *args, **kwargs):
        ran_here.append(spec.name)
        return run_case(spec, *args, **kwargs)

    monkeypatch.setattr(cases, 'run_case', spy)
    out = tmp_path / 'report'
    summary = report.build_report(out, quick=True, workers=1, progress=True)
    assert ran_here == []                                         # not in this process
    err = capsys.readouterr().err
    assert 'dashboard: none (disabled)' in err and 'http' not in err  # no dashboard URL
    assert '\r' not in err  # no carriage-return frames in a log
    sweep = summary['case4_sweep']
    assert sweep['workers'] == 1 and sweep['computed'] == len(specs)
    keys = sweep['point_keys']
    assert sorted(p.stem for p in (out / 'case4_sweep' / 'points').glob('*.json')) == \
        sorted(keys.values())
    ds = sweep_results.open_results(out / 'case4_sweep' / 'results.nc')
    rows = {row['name']: row for row in summary['cases']}
    for single in short_singles[1:]:
        name = single.spec.name
        want = json.loads(json.dumps(single.summary()))
        got = rows[name]
        assert got.pop('wall_time_s') > 0.0 and want.pop('wall_time_s') > 0.0
        assert got == want, name                                  # every number, bit for bit
        assert got['final_branch'] == single.final_branch
        single.to_csv(tmp_path / f'{name}.csv')
        assert (out / f'envelope_{name}.csv').read_text() == (tmp_path / f'{name}.csv').read_text()
        i = list(ds['modes.quality_factors[0]'].values).index(single.spec.q1_quality)
        np.testing.assert_array_equal(ds['envelope_q2_m'].values[i], single.envelope.channel('q2'))
        assert ds['final_q2_m'].values[i] == single.final_q2_m
    assert summary['job_wall_s'].keys() == keys.keys()
    if report.plotting.available():
        assert (out / 'fig13_case4.png').stat().st_size > 1000


@pytest.mark.slow
def test_full_case4_sweep_gives_the_branches_and_numbers_of_the_single_runs(tmp_path):
    ds = case4_as_sweep(tmp_path)
    singles = cases.run_cases(cases.case4_specs(duration_s=30.0), workers=2, progress=False)
    assert_as_single_runs(ds, singles)
    # README "Reproducing the paper": lower for Q_1 <= 80 000, upper for >= 120 000
    assert list(ds['final_branch'].values) == ['lower'] * 4 + ['upper'] * 2
    assert all(ds['settled'].values == 1)
