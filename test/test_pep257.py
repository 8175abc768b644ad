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
The pep257 test of `ros2 pkg create`, runnable without ROS.

ament_pep257 when it is installed, else pydocstyle with its "ament" convention.
"""

from pathlib import Path
import subprocess
import sys

import pytest

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
LINTED = ('ring_gyro_sim', 'test', 'setup.py', 'benchmarks')

# ament_pep257's "ament" convention: every pydocstyle check except these.
AMENT_IGNORE = ('D100', 'D101', 'D102', 'D103', 'D104', 'D105', 'D106', 'D107', 'D203',
                'D212', 'D404')


def linted_paths():
    return [str(PACKAGE_ROOT / p) for p in LINTED if (PACKAGE_ROOT / p).exists()]


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    try:
        from ament_pep257.main import main
    except ImportError:
        main = None
    if main is not None:
        rc = main(argv=linted_paths())
        assert rc == 0, 'Found code style errors / warnings'
        return
    # The same call as ament_pep257.main: --ignore, and its file and directory patterns.
    result = subprocess.run(
        [sys.executable, '-m', 'pydocstyle', '--ignore=' + ','.join(AMENT_IGNORE),
         r'--match=.*\.py', r'--match-dir=[^\._].*', *linted_paths()],
        cwd=PACKAGE_ROOT, capture_output=True, text=True, check=False)
    assert 'No module named pydocstyle' not in result.stderr, \
        'pydocstyle missing (pip install flake8-docstrings, which brings it)'
    assert result.returncode == 0, \
        f'pydocstyle found docstring errors:\n{result.stdout}{result.stderr}'


@pytest.mark.linter
@pytest.mark.pep257
@pytest.mark.parametrize('source, code', [
    ('def f():\n    """Summary on the first line.\n\n    More.\n    """\n', 'D213'),
    ('def f():\n    """summary"""\n', 'D400'),
])
def test_pep257_settings_catch(tmp_path, source, code):
    """Control: the pydocstyle fallback reports what the "ament" convention forbids."""
    sample = tmp_path / 'test_sample.py'
    sample.write_text(source, encoding='utf-8')
    result = subprocess.run(
        [sys.executable, '-m', 'pydocstyle', '--ignore=' + ','.join(AMENT_IGNORE),
         r'--match=.*\.py', str(sample)], capture_output=True, text=True, check=False)
    assert result.returncode == 1 and f'{code}:' in result.stdout, result.stdout
