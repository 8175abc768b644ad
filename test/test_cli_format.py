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

"""The printed summary of ``ring_gyro run`` stays readable for a state blown up to 1.7e308."""

import argparse
import json
import math


import pytest
from ring_gyro_sim import cli, offline
from ring_gyro_sim.run import format_number


@pytest.mark.parametrize('value, text', [
    (0.39412345, '0.3941'), (1.7e308, '1.7000e+308'), (-3e12, '-3.0000e+12'),
    (math.inf, 'inf'), (math.nan, 'nan'), (999999.99994, '999999.9999')])
def test_fixed_keeps_decimals_for_ordinary_values_and_exponents_for_huge(value, text):
    assert format_number(value) == text


def test_the_json_summary_is_valid_json_with_non_finite_numbers():
    summary = offline.RunSummary(
        sim_time_s=0.0, wall_time_s=0.0, real_time_factor=math.inf, peak_abs_m={'q1': 0.0},
        final_abs_m={'q1': math.nan}, min_gap_m=math.inf, contact=False, status='running',
        message='', samples=0, steps=0)
    data = json.loads(summary.to_json())  # strict: Infinity / NaN would not be JSON
    assert data['real_time_factor'] is None and data['min_gap_m'] is None
    assert data['final_abs_m'] == {'q1': None}


def test_run_prints_a_huge_held_state_in_a_few_characters(monkeypatch, capsys, tmp_path):
    # A 1.7e308 input leaves a held state whose summary must not print a 293-digit number
    # (f'{x:.4f}'); here the summary the run returns holds such numbers.
    huge = 1.7e300  # m; times 1e6 for um stays finite
    summary = offline.RunSummary(
        sim_time_s=0.1, wall_time_s=0.2, real_time_factor=0.5,
        peak_abs_m={'q1': huge, 'q2': 1e-7}, final_abs_m={'q1': huge, 'q2': 1e-7},
        min_gap_m=-huge, contact=True, status='contact', message='', samples=1, steps=1)
    monkeypatch.setattr(offline, 'run_offline', lambda *a, **k: summary)
    monkeypatch.setattr(cli, '_load', lambda *a: type('C', (), {'run': type('R', (), {
        'record_path': ''})()})())
    args = argparse.Namespace(source=None, scenario=str(tmp_path / 'x.yaml'), output=None,
                              node_name='ring_gyro', duration=None, no_progress=True,
                              json=False, overwrite=False, decimation=None)
    assert cli.cmd_run(args) == 0
    out = capsys.readouterr().err  # the readable summary (stdout has the JSON)
    print(out)
    assert max(len(line) for line in out.splitlines()) < 100
    assert 'q1: peak 1.7000e+306 um' in out and 'q2: peak 0.1000 um' in out
