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
The ROS-workspace way, for real: ``colcon build`` in a scratch workspace, then the install space.

doc/ros_workspace.md gives these commands to users; this module runs them:

- the package (this source tree, less virtual environments, build products and caches) is
  copied to ``<ws>/src/ring_gyro_sim`` and ``colcon build`` runs in ``<ws>``. colcon runs
  ``setup.py`` with the interpreter that runs colcon itself (``sys.executable``) and writes it
  into the console scripts and the ``setup.*`` files, so colcon is run here by this test's
  interpreter (the project's venv, or the system Python of a ROS installation);
- the install layout ``ros2 run`` and ``ament_index`` rely on is checked;
- ``ring_gyro_node`` and ``ring_gyro run`` are started from the install space as ``ros2 run``
  starts them: in a bash that sourced ``install/setup.bash``, the executable
  ``<prefix>/lib/ring_gyro_sim/<name>`` with ``<prefix>`` found through the ament index
  (``ros2run.api.get_executable_path`` does exactly this; ros2cli is not on PyPI);
- and that environment imports the installed package, not this source tree.

Marked ``colcon``; part of the default suite (about 15 s on an idle 2-core machine).
"""

import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import textwrap

from mcap.reader import make_reader
import pytest
import ros_domains

PACKAGE_ROOT = Path(__file__).resolve().parents[1]
PACKAGE = 'ring_gyro_sim'
BUILD_TIMEOUT_S = 300.0
"""colcon build takes about 3 s idle; generous for a loaded machine."""
RUN_TIMEOUT_S = 300.0
"""A fresh install space compiles the numba kernels on first use (about 5-20 s, README)."""

# Not part of the package: virtual environments (any directory with a pyvenv.cfg), VCS data,
# a workspace's or setuptools' products, run outputs and caches.
_SKIP_TOP = {'.git', 'build', 'install', 'log', 'out', 'report'}
_SKIP_ANY = shutil.ignore_patterns('__pycache__', '*.pyc', '*.egg-info', '.pytest_cache',
                                   '.ruff_cache', '*.mcap')

# What `ros2 run PACKAGE EXECUTABLE ARGS...` does (ros2run.api): the executable is
# <prefix>/lib/<package>/<executable>, <prefix> from the ament index (AMENT_PREFIX_PATH).
ROS2_RUN = textwrap.dedent("""\
    import os, sys
    from ament_index_python.packages import get_package_prefix
    package, executable, *args = sys.argv[1:]
    path = os.path.join(get_package_prefix(package), 'lib', package, executable)
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        sys.exit('ros2 run: no executable ' + path)
    print('ros2 run:', path, flush=True)
    os.execv(path, [path, *args])
    """)

DOMAIN_ID = str(ros_domains.claim('colcon build'))

pytestmark = [pytest.mark.colcon, pytest.mark.ci]


def _ignore(directory, names):
    skipped = set(_SKIP_ANY(directory, names))
    for name in names:
        path = Path(directory, name)
        if (Path(directory) == PACKAGE_ROOT and name in _SKIP_TOP) or \
                (path.is_dir() and (path / 'pyvenv.cfg').exists()):
            skipped.add(name)
    return skipped


def _environment(ws):
    """Return this process's environment without this source tree on PYTHONPATH."""
    env = dict(os.environ)
    kept = [p for p in env.get('PYTHONPATH', '').split(os.pathsep)
            if p and not Path(p).resolve().is_relative_to(PACKAGE_ROOT)]
    if kept:
        env['PYTHONPATH'] = os.pathsep.join(kept)
    else:
        env.pop('PYTHONPATH', None)
    env['COLCON_HOME'] = str(ws / 'colcon_home')  # no user defaults (e.g. --symlink-install)
    env['ROS_LOG_DIR'] = str(ws / 'ros_log')
    env['ROS_DOMAIN_ID'] = DOMAIN_ID
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['RCUTILS_COLORIZED_OUTPUT'] = '0'
    env['PY'] = sys.executable
    env['ROS2_RUN'] = ROS2_RUN
    return env


def in_install_space(ws, command, timeout=RUN_TIMEOUT_S):
    """Run the bash ``command`` after ``source install/setup.bash`` in the workspace ``ws``."""
    return subprocess.run(
        ['bash', '-c', 'source install/setup.bash && ' + command], cwd=ws, env=_environment(ws),
        capture_output=True, text=True, timeout=timeout, check=False)


def ros2_run(ws, executable, *args):
    """Start ``ros2 run ring_gyro_sim <executable> <args>`` in the workspace's install space."""
    quoted = ' '.join(["'" + a.replace("'", "'\\''") + "'" for a in (PACKAGE, executable, *args)])
    return in_install_space(ws, f'"$PY" -c "$ROS2_RUN" {quoted}')


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """Return a colcon workspace with this package built into ``install/``."""
    ws = tmp_path_factory.mktemp('colcon_ws')
    shutil.copytree(PACKAGE_ROOT, ws / 'src' / PACKAGE, ignore=_ignore, symlinks=True)
    try:
        import colcon_core  # noqa: F401
    except ImportError:
        pytest.fail('colcon missing: pip install colcon-common-extensions (requirements-dev.txt)')
    result = subprocess.run(
        [sys.executable, '-c', 'import sys; from colcon_core.command import main; '
         'sys.exit(main(argv=sys.argv[1:]))', 'build', '--base-paths', 'src'],
        cwd=ws, env=_environment(ws), capture_output=True, text=True, timeout=BUILD_TIMEOUT_S,
        check=False)
    assert result.returncode == 0, f'colcon build failed:\n{result.stdout}\n{result.stderr}'
    assert 'Summary: 1 package finished' in result.stdout, result.stdout
    return ws


def test_install_layout(workspace):
    prefix = workspace / 'install' / PACKAGE
    for name in ('ring_gyro_node', 'ring_gyro'):
        exe = prefix / 'lib' / PACKAGE / name
        assert exe.is_file() and os.access(exe, os.X_OK), f'{exe} is not an executable'
        # colcon's interpreter is the console script's (see the module docstring)
        assert exe.read_text(encoding='utf-8').splitlines()[0] == '#!' + sys.executable
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PACKAGE).is_file()
    assert (prefix / 'share' / PACKAGE / 'package.xml').read_bytes() == \
        (PACKAGE_ROOT / 'package.xml').read_bytes()
    configs = sorted(p.name for p in (PACKAGE_ROOT / 'config').glob('*.yaml'))
    assert configs and sorted(
        p.name for p in (prefix / 'share' / PACKAGE / 'config').glob('*.yaml')) == configs
    for script in ('setup.bash', 'setup.sh', 'local_setup.sh', 'local_setup.bash'):
        assert (workspace / 'install' / script).is_file(), script


def test_install_space_imports_the_installed_package(workspace):
    """The sourced environment imports the package from install/, not from this source tree."""
    # cwd is the workspace root (no ring_gyro_sim/ there), as for the executables below
    result = in_install_space(
        workspace, '"$PY" -c "import ring_gyro_sim; print(ring_gyro_sim.__file__); '
        'from ament_index_python.packages import get_package_share_directory as share; '
        'print(share(\'ring_gyro_sim\'))"')
    assert result.returncode == 0, result.stderr
    module_file, share = (Path(line) for line in result.stdout.split())
    site = workspace / 'install' / PACKAGE / 'lib'
    assert module_file.is_relative_to(site) and 'site-packages' in module_file.parts, \
        f'imported {module_file}, not the install space'
    assert share == workspace / 'install' / PACKAGE / 'share' / PACKAGE


OUTPUT_TOPICS = ('/ring_gyro/modal_displacement', '/ring_gyro/radial_gap',
                 '/ring_gyro/sense_electrodes')
"""The output topics (doc/interface.md); demo.yaml records every topic."""


def recorded_counts(path):
    """Return the number of messages of each topic in the MCAP file ``path``."""
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    counts = summary.statistics.channel_message_counts
    return {channel.topic: counts.get(channel_id, 0)
            for channel_id, channel in summary.channels.items()}


def test_installed_node_runs_like_ros2_run(workspace):
    config = workspace / 'install' / PACKAGE / 'share' / PACKAGE / 'config' / 'demo.yaml'
    recording = workspace / 'node.mcap'
    result = ros2_run(workspace, 'ring_gyro_node', '--ros-args', '--params-file', str(config),
                      '-p', 'duration:=0.05', '-p', 'real_time_factor:=0.0',
                      '-p', 'drive.start_on:=rest', '-p', f'record.path:={recording}')
    assert result.returncode == 0, f'{result.stdout}\n{result.stderr}'
    expected = workspace / 'install' / PACKAGE / 'lib' / PACKAGE / 'ring_gyro_node'
    assert f'ros2 run: {expected}\n' in result.stdout
    counts = recorded_counts(recording)
    assert all(counts.get(topic, 0) > 0 for topic in OUTPUT_TOPICS), counts


def test_installed_run_verb_runs_like_ros2_run(workspace):
    config = workspace / 'install' / PACKAGE / 'share' / PACKAGE / 'config' / 'demo.yaml'
    recording = workspace / 'cli.mcap'
    result = ros2_run(workspace, 'ring_gyro', 'run', str(config), '--duration', '0.05',
                      '-o', str(recording), '--json', '--no-progress')
    assert result.returncode == 0, f'{result.stdout}\n{result.stderr}'
    expected = workspace / 'install' / PACKAGE / 'lib' / PACKAGE / 'ring_gyro'
    assert f'ros2 run: {expected}\n' in result.stdout
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert summary['sim_time_s'] == pytest.approx(0.05)  # --duration 0.05
    counts = recorded_counts(recording)
    assert all(counts.get(topic, 0) > 0 for topic in OUTPUT_TOPICS), counts
