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
``ring_gyro backbone``, ``frf`` and ``report`` where matplotlib (an extra) cannot be imported.

Each verb runs in its own Python process whose first act is to put a blocker on
``sys.meta_path`` that refuses ``matplotlib`` (as an installation without it does), then calls
``cli.main``. The verb must say once, before computing, that matplotlib is missing and how to
install it, write its CSVs, say the plots were skipped and exit with code 0.
"""

import json
import pathlib
import subprocess
import sys

import pytest

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
WRAPPER = """\
import sys


class NoMatplotlib:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] == 'matplotlib':
            raise ModuleNotFoundError(f'No module named {name!r}', name=name)
        return None


sys.meta_path.insert(0, NoMatplotlib())
from ring_gyro_sim import cli
if sys.argv[1] == 'report':  # a plan of one short case and one backbone (seconds, not minutes)
    from dataclasses import replace
    from ring_gyro_sim import report
    from ring_gyro_sim.analysis import cases
    case1 = replace(cases.paper_cases()['case1'], duration_s=0.05)
    report.make_plan = lambda quick, base: report.ReportPlan(
        drive_cases=(case1,), sweep=(), ritz=(), inner=(), backbone_orders=(4,), frf=False,
        quick=True, base=dict(base or {}))
sys.exit(cli.main(sys.argv[1:]))
"""
HINT = 'matplotlib is not installed: the plots will be skipped'


def run_without_matplotlib(*args):
    """Run ``ring_gyro *args`` with matplotlib blocked; return (exit code, stdout, stderr)."""
    proc = subprocess.run([sys.executable, '-c', WRAPPER, *map(str, args)], cwd=REPO_ROOT,
                          env={'PYTHONPATH': str(REPO_ROOT), 'PATH': '/usr/bin:/bin'},
                          capture_output=True, text=True, timeout=600)
    return proc.returncode, proc.stdout, proc.stderr


def check_hint(stderr, verb):
    assert 'Traceback' not in stderr, stderr
    assert stderr.count('matplotlib is not installed') == 1, stderr
    assert stderr.startswith(f'ring_gyro {verb}: {HINT}'), stderr  # said first, once
    assert '`pip install matplotlib`' in stderr and 'python3-matplotlib' in stderr


def test_the_blocker_blocks():
    blocker_only = WRAPPER.split('from ring_gyro_sim')[0]
    proc = subprocess.run([sys.executable, '-c', blocker_only + 'import matplotlib.pyplot'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0 and 'ModuleNotFoundError' in proc.stderr


def test_backbone_writes_the_csv_and_skips_the_plot(tmp_path):
    out = tmp_path / 'bb.csv'
    code, stdout, stderr = run_without_matplotlib(
        'backbone', '--taylor-terms', '4', '--max-amplitude', '2e-6', '-o', out)
    assert code == 0, stderr
    check_hint(stderr, 'backbone')
    assert 'plot skipped' in stderr
    assert out.read_text().startswith('amplitude_m,frequency_hz')
    assert not (tmp_path / 'bb.png').exists()
    assert json.loads(stdout)['png'] is None


def test_frf_writes_the_csv_and_skips_the_plot(tmp_path):
    out = tmp_path / 'frf.csv'
    code, stdout, stderr = run_without_matplotlib(
        'frf', '--f-range', '15797', '15801', '-o', out)
    assert code == 0, stderr
    check_hint(stderr, 'frf')
    assert out.read_text().startswith('frequency_hz,amplitude_m,stable')
    assert not (tmp_path / 'frf.png').exists()
    assert json.loads(stdout)['png'] is None


def test_report_writes_csvs_and_summary_and_skips_the_figures(tmp_path):
    code, stdout, stderr = run_without_matplotlib('report', '--out', tmp_path, '--workers', '1')
    assert code == 0, stderr
    check_hint(stderr, 'report')
    assert 'figures skipped (no matplotlib)' in stderr
    written = sorted(p.name for p in tmp_path.iterdir())
    assert 'summary.json' in written and 'summary.md' in written
    assert 'envelope_case1.csv' in written and 'fig04_backbone_nt4.csv' in written
    assert not [n for n in written if n.endswith('.png')]


@pytest.mark.parametrize('module', ['matplotlib'])
def test_with_matplotlib_the_hint_is_not_printed(module, tmp_path, capsys):
    pytest.importorskip(module)
    from ring_gyro_sim import cli
    assert cli.main(['backbone', '--taylor-terms', '4', '--max-amplitude', '1e-6',
                     '-o', str(tmp_path / 'b.csv')]) == 0
    assert 'matplotlib' not in capsys.readouterr().err
    assert (tmp_path / 'b.png').exists()
