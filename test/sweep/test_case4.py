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
"""

import math

import pytest
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.sweep import parse_spec, run_sweep
from ring_gyro_sim.sweep.point import METRICS
from sweep_harness import REPO
import yaml

SPEC = REPO / 'config' / 'sweep_case4.yaml'


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


def test_case4_sweep_gives_the_numbers_of_the_single_runs(tmp_path):
    q1 = (5000.0, 180000.0)
    ds = case4_as_sweep(tmp_path, duration=0.2, axes={'modes.quality_factors[0]': list(q1)})
    singles = [cases.run_case(s, progress=False) for s in cases.case4_specs(q1, 0.2)]
    assert_as_single_runs(ds, singles)
    assert ds['final_q2_m'].values[0] != ds['final_q2_m'].values[1]   # Q_1 did change


@pytest.mark.slow
def test_full_case4_sweep_gives_the_branches_and_numbers_of_the_single_runs(tmp_path):
    ds = case4_as_sweep(tmp_path)
    singles = cases.run_cases(cases.case4_specs(duration_s=30.0), workers=2, progress=False)
    assert_as_single_runs(ds, singles)
    # README "Reproducing the paper": lower for Q_1 <= 80 000, upper for >= 120 000
    assert list(ds['final_branch'].values) == ['lower'] * 4 + ['upper'] * 2
    assert all(ds['settled'].values == 1)
