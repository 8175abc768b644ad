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
``rosdep install --from-paths src --ignore-src`` resolves every key of package.xml.

The project's shared tool ``../shared/tools/rosdep-check`` (beside the repository, in CI too)
runs the real ``rosdep`` (PyPI ``rosdep``, requirements-dev.txt) offline against a copy of the
rosdistro database (Jazzy, Ubuntu noble): ``rosdep install --simulate`` exits non-zero when a key
does not resolve. A control checks that it does on a key that does not exist
(``python3-zstandard``, the key package.xml had before).
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
ROSDEP_CHECK = PACKAGE_ROOT.parent / 'shared' / 'tools' / 'rosdep-check'
TIMEOUT_S = 120.0
"""rosdep update + install --simulate from local files: about 3 s idle."""

pytestmark = [
    pytest.mark.rosdep,
    pytest.mark.skipif(not ROSDEP_CHECK.is_file(),
                       reason=f'{ROSDEP_CHECK} absent (the shared tools are not beside the '
                              'repository)'),
]


def rosdep_check(package_dir):
    """Run the shared rosdep-check on ``package_dir``: the completed process."""
    env = dict(os.environ)
    # the rosdep of this interpreter's environment (the venv's bin is not always on PATH)
    env['PATH'] = os.pathsep.join([str(Path(sys.executable).parent), env.get('PATH', '')])
    if shutil.which('rosdep', path=env['PATH']) is None:
        pytest.fail('rosdep missing: pip install rosdep (requirements-dev.txt)')
    return subprocess.run(['bash', str(ROSDEP_CHECK), str(package_dir)], env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S, check=False)


def test_every_rosdep_key_resolves():
    result = rosdep_check(PACKAGE_ROOT)
    assert result.returncode == 0, f'{result.stdout}\n{result.stderr}'
    assert 'Cannot locate rosdep definition' not in result.stdout + result.stderr


def test_an_unknown_key_fails_the_check(tmp_path):
    """Control: the check does fail on a key the rosdistro database does not have."""
    package = tmp_path / 'ring_gyro_sim'
    package.mkdir()
    xml = (PACKAGE_ROOT / 'package.xml').read_text(encoding='utf-8')
    assert '<exec_depend>python3-zstandard</exec_depend>' not in xml
    xml = xml.replace('  <exec_depend>python3-numpy</exec_depend>',
                      '  <exec_depend>python3-zstandard</exec_depend>\n'
                      '  <exec_depend>python3-numpy</exec_depend>')
    (package / 'package.xml').write_text(xml, encoding='utf-8')
    result = rosdep_check(package)
    assert result.returncode != 0
    assert 'Cannot locate rosdep definition for [python3-zstandard]' in \
        result.stdout + result.stderr, f'{result.stdout}\n{result.stderr}'
