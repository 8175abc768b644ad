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
The flake8 test of `ros2 pkg create --build-type ament_python`, runnable without ROS.

It calls ``ament_flake8.main.main_with_errors`` as the generated test does (PyPI
``ros-jazzy-ament-flake8``, in requirements-dev.txt). Only when ament_flake8 is not installed does
it fall back to flake8 itself with ament's configuration and the plugins an ament installation
brings. The control test checks that whichever of the two runs reports each kind of violation.
"""

from pathlib import Path
import subprocess
import sys
import textwrap

import pytest

try:
    from ament_flake8.main import main_with_errors
except ImportError:  # not installed: the flake8 fallback below
    main_with_errors = None

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
LINTED = ('ring_gyro_sim', 'test', 'setup.py', 'benchmarks')

# ament_flake8/configuration/ament_flake8.ini of ROS 2 Jazzy, plus flake8-quotes' default
# (single inline quotes) made explicit. ament sets no application-import-names: every
# non-stdlib import is in one group.
AMENT_FLAKE8_INI = textwrap.dedent("""\
    [flake8]
    extend-ignore = B902,C816,D100,D101,D102,D103,D104,D105,D106,D107,D203,D212,D404,I202
    import-order-style = google
    max-line-length = 99
    show-source = true
    statistics = true
    inline-quotes = single
    """)

# The plugins an ament (ROS dev tools) installation brings and whose codes the ini above uses;
# without them flake8 would pass code that ament fails.
REQUIRED_PLUGINS = {'flake8_quotes': 'flake8-quotes', 'flake8_import_order': 'flake8-import-order',
                    'flake8_docstrings': 'flake8-docstrings'}


def linted_paths():
    return [str(PACKAGE_ROOT / p) for p in LINTED if (PACKAGE_ROOT / p).exists()]


def _missing_plugins():
    import importlib.util
    return [dist for module, dist in REQUIRED_PLUGINS.items()
            if importlib.util.find_spec(module) is None]


def _fallback_flake8(tmp_path, paths):
    """Run flake8 with ament's settings: (return code, report)."""
    missing = _missing_plugins()
    assert not missing, f'flake8 plugins missing (pip install {" ".join(missing)})'
    config = tmp_path / 'ament_flake8.ini'
    config.write_text(AMENT_FLAKE8_INI, encoding='utf-8')
    result = subprocess.run(
        [sys.executable, '-m', 'flake8', f'--config={config}', *paths],
        cwd=PACKAGE_ROOT, capture_output=True, text=True, check=False)
    return result.returncode, result.stdout + result.stderr


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(tmp_path):
    if main_with_errors is not None:
        rc, errors = main_with_errors(argv=linted_paths())
        assert rc == 0, \
            'Found %d code style errors / warnings:\n' % len(errors) + \
            '\n'.join(errors)
        return
    rc, report = _fallback_flake8(tmp_path, linted_paths())
    assert rc == 0, f'flake8 found code style errors / warnings:\n{report}'


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.parametrize('source, code', [
    ('x = "double"\n', 'Q000'),
    ('import sys\nimport os\n\nprint(os, sys)\n', 'I100'),
    ('x = 1  # ' + 'long ' * 20 + '\n', 'E501'),
    ('def f():\n    """return nothing."""\n', 'D403'),
    ('import os\n', 'F401'),
])
def test_flake8_settings_catch(tmp_path, source, code):
    """Control: the linter test_flake8 runs does report each kind of violation."""
    sample = tmp_path / 'sample.py'
    sample.write_text(source, encoding='utf-8')
    if main_with_errors is not None:
        rc, errors = main_with_errors(argv=[str(sample)])
        report = '\n'.join(errors)
    else:
        rc, report = _fallback_flake8(tmp_path, [str(sample)])
    assert rc == 1 and f' {code} ' in report, report
