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
The verbs say at their start which libraries they miss.

In a ROS workspace rosdep installs no allantools, dask or xarray (no rosdep key): each verb
runs here in a Python process whose first act puts a blocker on ``sys.meta_path`` that
refuses the modules named on its command line, as an installation without them does.
"""

import pathlib
import subprocess
import sys
import time

import pytest
from ring_gyro_sim import extras

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
WRAPPER = """\
import sys

BLOCKED = set(sys.argv[1].split(','))


class Blocker:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in BLOCKED:
            raise ModuleNotFoundError(f'No module named {name!r}', name=name)
        return None


sys.meta_path.insert(0, Blocker())
from ring_gyro_sim import cli
sys.exit(cli.main(sys.argv[2:]))
"""


def without(blocked, *args):
    """Run ``ring_gyro *args`` with ``blocked`` modules refused: (code, stdout, stderr, s)."""
    started = time.monotonic()
    proc = subprocess.run([sys.executable, '-c', WRAPPER, ','.join(blocked), *map(str, args)],
                          cwd=REPO_ROOT, env={'PYTHONPATH': str(REPO_ROOT),
                                              'PATH': '/usr/bin:/bin'},
                          capture_output=True, text=True, timeout=600)
    return proc.returncode, proc.stdout, proc.stderr, time.monotonic() - started


@pytest.mark.parametrize('blocked, args, names, install', [
    (['allantools'], ['characterize', 'config/gyro.yaml', '--out', 'OUT', '--quick'],
     'characterize (the Allan deviation) needs allantools', 'pip install allantools'),
    (['distributed', 'xarray'], ['sweep', 'config/sweep_case4.yaml', '--out', 'OUT'],
     'sweep needs distributed, xarray', 'pip install "dask[distributed]" xarray'),
    (['netCDF4'], ['report', '--out', 'OUT', '--quick'],
     'report (its Case 4 runs through the sweep engine) needs netCDF4',
     'pip install netCDF4 (in a ROS workspace: rosdep keys python3-netcdf4'),
])
def test_a_verb_names_what_it_misses_at_once(tmp_path, blocked, args, names, install):
    # before: characterize computed ~13 s (--quick; ~20 min in full) and then failed with an
    # ImportError traceback; sweep failed with one at once
    args = [str(tmp_path / 'out') if a == 'OUT' else a for a in args]
    code, stdout, stderr, wall = without(blocked, *args)
    line = stderr.strip()
    assert code == 1 and stdout == '', stderr
    assert '\n' not in line and 'Traceback' not in stderr, stderr
    verb = args[0]
    assert line.startswith(f'ring_gyro {verb}: error: {names}, not installed: {install}'), line
    assert 'doc/ros_workspace.md' in line
    assert not (tmp_path / 'out').exists()  # nothing was made before the check
    assert wall < 30.0  # imports only (the process, numpy), no run


def test_the_blocker_blocks():
    code, _, stderr, _ = without(['allantools'], '--version')
    assert code == 0
    proc = subprocess.run([sys.executable, '-c', WRAPPER.split('from ring_gyro_sim')[0]
                           + 'import allantools', 'allantools'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0 and 'ModuleNotFoundError' in proc.stderr


def test_the_message_names_each_rosdep_key_or_its_absence():
    assert extras.missing(['json', 'no_such_module_here']) == ['no_such_module_here']
    extras.MODULES['no_such_module_here'] = ('no-such-module', None)
    try:
        with pytest.raises(extras.MissingDependencyError) as info:
            extras.require(['json', 'no_such_module_here'], 'a verb')
    finally:
        del extras.MODULES['no_such_module_here']
    assert str(info.value) == ('a verb needs no_such_module_here, not installed: pip install '
                               'no-such-module (in a ROS workspace: no rosdep key for '
                               'no_such_module_here: doc/ros_workspace.md)')
    assert issubclass(extras.MissingDependencyError, ImportError)


def test_package_xml_and_the_workspace_page_agree_with_the_table():
    xml = (REPO_ROOT / 'package.xml').read_text(encoding='utf-8')
    page = (REPO_ROOT / 'doc' / 'ros_workspace.md').read_text(encoding='utf-8')
    for module, (pip, key) in extras.MODULES.items():
        if key:  # declared the way rosdep installs it
            assert f'<exec_depend>{key}</exec_depend>' in xml, key
        else:  # said where a ROS user looks, with the pip command
            assert f'`{module}`' in page and pip in page, module
