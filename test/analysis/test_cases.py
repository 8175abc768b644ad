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
Tests of analysis/cases.py: the drive + shock cases of section 3.4 and section 3.5.

Fast tests check the case definitions against the paper, the branch amplitudes, the first
tenths of a second of a shocked run against an unshocked control, and the exact q2 = 0 of
symmetric electrodes (eq. 36). The slow ones run Cases 1-3 long enough to decide the branch.
"""

from dataclasses import replace
import json
import math
import subprocess
import sys

import numpy as np
import pytest
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.core.params import paper_config, STANDARD_GRAVITY

UPPER_M = 0.394e-6
LOWER_M = 0.037e-6
"""q2 branch amplitudes at 15 798.6 Hz for the defaults (core/params.py)."""


def shortened(spec, seconds, **changes):
    return replace(spec, duration_s=seconds, **changes)


def test_paper_cases_match_section_3_4():
    c = cases.paper_cases()
    assert (c['case1'].shock_g, c['case1'].q1_quality) == (2000.0, 120000.0)
    assert (c['case2'].shock_g, c['case2'].q1_quality) == (10000.0, 120000.0)
    assert (c['case3'].shock_g, c['case3'].q1_quality) == (10000.0, 40000.0)
    assert [c[k].expected_branch for k in ('case1', 'case2', 'case3')] == \
        ['upper', 'upper', 'lower']
    assert all(s.start_on == 'upper_branch' for s in c.values())
    q = [s.q1_quality for s in cases.case4_specs()]
    assert min(q) == 5000.0 and max(q) == 180000.0
    assert all(s.shock_g == 10000.0 for s in cases.case4_specs())


def test_case_config_sets_q1_start_and_rate_only():
    cfg = cases.paper_cases()['case3'].config(output_rate_hz=100000.0)
    default = paper_config({})
    assert cfg.modes.quality_factors[0] == 40000.0
    assert list(cfg.modes.quality_factors[1:]) == list(default.modes.quality_factors[1:])
    assert cfg.drive.start_on == 'upper_branch'
    assert cfg.run.output_rate == 100000.0
    assert cfg.drive.frequency == default.drive.frequency


def test_symmetric_inner_voltage_cancels_the_even_terms():
    cfg = paper_config({})
    vi = cases.symmetric_inner_voltage(cfg)
    assert cfg.inner_radius * vi ** 2 == pytest.approx(cfg.outer_radius
                                                       * cfg.electrodes.outer_voltage ** 2)
    spec = cases.inner_electrode_cases()['symmetric_rest']
    assert dict(spec.overrides)['electrodes.inner_voltage'] == vi
    assert spec.start_on == 'rest'


def test_branches_at_the_paper_drive():
    b = cases.drive_branches(paper_config({}))
    assert b.upper_m == pytest.approx(UPPER_M, rel=0.02)
    assert b.lower_m == pytest.approx(LOWER_M, rel=0.05)
    assert b.threshold_m == pytest.approx(math.sqrt(b.upper_m * b.lower_m))
    assert b.classify(0.3e-6) == 'upper' and b.classify(0.05e-6) == 'lower'
    assert cases.drive_branches(paper_config({'drive.amplitude': 0.0})) is None


def test_shock_pulls_q2_off_the_upper_branch_and_control_stays():
    """Case 3, first 0.2 s: the q1^2 coupling throws q2 far off; without shock it stays."""
    spec = shortened(cases.paper_cases()['case3'], 0.2)
    shocked = cases.run_case(spec, progress=False)
    control = cases.run_case(replace(spec, shock_g=0.0), progress=False)
    q2 = control.envelope.channel('q2')
    assert np.max(np.abs(q2 / control.branches.upper_m - 1.0)) < 0.01
    assert shocked.numbers['q2_after_shock_m'] > 2.0 * shocked.branches.upper_m
    # and the shock is the paper's: about 55-60 % of the gap at theta = 0
    assert 0.5 < shocked.numbers['peak_w0_fraction'] < 0.7
    assert not shocked.contact
    assert shocked.numbers['peak_q1_m'] == pytest.approx(5.77e-6, rel=0.02)


def test_envelope_does_not_depend_on_the_output_rate_much():
    """Same integration step at 100 and 200 kHz output; envelopes agree where q2 is smooth."""
    spec = shortened(cases.paper_cases()['case1'], 0.1)
    a = cases.run_case(spec, output_rate_hz=100000.0, progress=False)
    b = cases.run_case(spec, output_rate_hz=200000.0, progress=False)
    for name in ('q1', 'q2'):
        x, y = a.envelope.channel(name), b.envelope.channel(name)
        assert np.median(np.abs(x - y) / y) < 0.01
    assert a.min_gap_m == pytest.approx(b.min_gap_m, rel=1e-3)


def test_symmetric_electrodes_give_exactly_zero_q2_from_rest():
    spec = shortened(cases.inner_electrode_cases()['symmetric_rest'], 0.05, keep_raw_s=0.05)
    r = cases.run_case(spec, progress=False)
    assert r.raw_q.shape[0] >= 4999                  # 0.05 s at 100 kHz (t < keep_raw_s)
    assert np.max(np.abs(r.raw_q[:, 0])) > 5e-6      # q1 is thrown to ~60 % of the gap
    assert np.all(r.raw_q[:, 1] == 0.0)               # eq. (36): q2 = 0 identically
    # control: the outer electrode alone does couple q1 into q2
    outer = replace(spec, overrides=(('drive.amplitude', 0.0),))
    assert np.max(np.abs(cases.run_case(outer, progress=False).raw_q[:, 1])) > 1e-7


def test_case_result_csv_json_and_plot(tmp_path):
    r = cases.run_case(shortened(cases.paper_cases()['case1'], 0.02), progress=False)
    r.to_csv(tmp_path / 'c.csv')
    data = np.loadtxt(tmp_path / 'c.csv', delimiter=',', skiprows=1)
    header = (tmp_path / 'c.csv').read_text().splitlines()[0]
    assert header == 't_s,q1_m,q2_m,q3_m,w0_m,wmax_m'
    np.testing.assert_allclose(data[:, 2], r.envelope.channel('q2'), rtol=1e-8)
    summary = json.loads(r.to_json())
    assert summary['shock_g'] == 2000.0 and summary['final_branch'] in ('upper', 'lower')
    pytest.importorskip('matplotlib')  # an extra (setup.py 'plots')
    r.plot(tmp_path / 'c.png')
    assert (tmp_path / 'c.png').stat().st_size > 1000


def test_importing_cases_does_not_load_matplotlib():
    code = ('import sys, ring_gyro_sim.analysis.cases, ring_gyro_sim.report, '
            'ring_gyro_sim.analysis.plotting; print("matplotlib" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True)
    assert out.stdout.strip() == 'False'


def test_contact_is_reported_not_nan():
    """A shock far beyond the paper's pulls the ring in: flagged, finite, stopped."""
    spec = shortened(cases.paper_cases()['case2'], 0.02, shock_g=40000.0)
    r = cases.run_case(spec, progress=False)
    assert r.contact and r.final_branch == 'contact'
    assert r.min_gap_m == 0.0 and math.isfinite(r.contact_time_s)
    assert np.all(np.isfinite(r.envelope.values))


def test_run_cases_in_two_processes_matches_serial():
    specs = [shortened(s, 0.02) for s in cases.case4_specs((5000.0, 180000.0))]
    serial = cases.run_cases(specs, workers=1, progress=False)
    parallel = cases.run_cases(specs, workers=2, progress=False)
    for a, b in zip(serial, parallel):
        assert a.spec == b.spec
        np.testing.assert_array_equal(a.envelope.values, b.envelope.values)


def test_shock_is_converted_from_g_at_the_boundary():
    assert STANDARD_GRAVITY == 9.80665
    spec = shortened(cases.paper_cases()['case1'], 0.002, start_on='rest',
                     overrides=(('drive.amplitude', 0.0),))
    weak = cases.run_case(spec, progress=False).numbers['peak_q1_m']
    strong = cases.run_case(replace(spec, shock_g=4000.0), progress=False).numbers['peak_q1_m']
    assert strong / weak == pytest.approx(2.0, rel=0.05)   # nearly linear at 2 000 g


# ---------------------------------------------------------------------------- slow (paper)
@pytest.mark.slow
def test_case1_returns_to_the_upper_branch():
    """Case 1 with the default drive (15 798.6 Hz, q2 = 0.39 um): back on the upper branch."""
    r = cases.run_case(cases.paper_cases()['case1'])
    assert not r.contact
    assert r.numbers['settled'] and r.final_branch == 'upper'


@pytest.mark.slow
def test_case1_at_the_papers_frequency_falls_off_our_fold():
    """
    Case 1 at the paper's 15 798.3 Hz ends on the lower branch in our model (measured).

    The drive sits 0.009 Hz above the fold of our upper branch (stable orbit 0.4265 um,
    saddle 0.4243 um), so its basin is very thin: q2 nearly returns (0.37 um at 7 s) and
    falls off at ~8 s. This is why the default drive is 0.3 Hz higher (doc/calibration.md).
    """
    spec = cases.paper_cases()['case1']
    r = cases.run_case(replace(spec, overrides=(('drive.frequency', 15798.3),)))
    assert r.numbers['settled'] and r.final_branch == 'lower'


@pytest.mark.slow
def test_case2_drops_to_the_lower_branch_then_returns():
    r = cases.run_case(cases.paper_cases()['case2'])
    n = r.numbers
    assert not r.contact
    assert n['left_upper'] and n['min_q2_m'] < 0.05e-6
    assert n['settled'] and r.final_branch == 'upper'
    assert r.final_q2_m == pytest.approx(r.branches.upper_m, rel=0.01)
    assert 5.0 < n['return_time_s'] < 20.0


@pytest.mark.slow
def test_case3_stays_on_the_lower_branch():
    r = cases.run_case(cases.paper_cases()['case3'])
    assert not r.contact
    assert r.numbers['settled'] and r.final_branch == 'lower'
    assert r.final_q2_m == pytest.approx(r.branches.lower_m, rel=0.02)


@pytest.mark.slow
def test_symmetric_electrodes_q2_zero_over_two_seconds():
    spec = cases.inner_electrode_cases()['symmetric_rest']
    r = cases.run_case(replace(spec, keep_raw_s=spec.duration_s))
    assert not r.contact
    assert np.all(r.raw_q[:, 1] == 0.0)
    assert r.numbers['peak_q2_m'] == 0.0


def test_report_plan_covers_the_paper_figures():
    from ring_gyro_sim import report
    plan = report.make_plan(quick=True)
    names = {s.name for s in plan.drive_cases + plan.sweep + plan.inner + plan.ritz}
    assert {'case1', 'case2', 'case3', 'symmetric_rest', 'symmetric_drive',
            'nr1', 'nr5'} <= names
    assert [s.overrides[-1] for s in plan.sensitivity] == \
        [('drive.frequency', report.SENSITIVITY_DRIVE_HZ)] * 3
    full = report.make_plan()
    assert [s.duration_s for s in full.drive_cases] == [24.0, 30.0, 20.0]
    assert full.backbone_orders == (4, 5, 6, 7, 8, 9, 10)


def test_bursts_finds_the_rises_of_an_envelope():
    from ring_gyro_sim.report import bursts
    t = np.arange(0.0, 2.0, 1e-3)
    x = np.exp(-t) * (1.0 + 3.0 * np.exp(-((t - 0.4) / 0.03) ** 2)
                      + 5.0 * np.exp(-((t - 0.9) / 0.03) ** 2))
    found = bursts(t, x)
    assert [round(b[0], 2) for b in found] == [0.4, 0.9]
    assert bursts(t, np.exp(-t)) == []
