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
The numba disk cache of ``core/kernels/`` when the package is installed read-only.

A colcon install space or a system site-packages is not writable by the user: numba then
caches under the user's cache directory, and the second start must still load the kernels
from disk instead of compiling them. The package is copied, bind-mounted read-only in a
private mount namespace (``unshare -m``), and started twice in fresh interpreters.
"""

import json
from pathlib import Path
import shutil
import subprocess
import sys
import textwrap

import pytest
import ring_gyro_sim

CHILD = textwrap.dedent("""
    import json
    import sys
    # Import the read-only copy, not the editable install of the development environment.
    sys.meta_path = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]
    from ring_gyro_sim.core import kernels
    from ring_gyro_sim.core.params import paper_config
    from ring_gyro_sim.core.engine.full import Simulator
    sim = Simulator(paper_config({'drive.start_on': 'rest'}))
    sim.shock(1000.0)
    sim.advance(0.001)
    stats = {name: getattr(kernels, name).stats
             for name in ('run_samples', 'output_channels')}
    print(json.dumps({name: [sum(s.cache_hits.values()), sum(s.cache_misses.values())]
                      for name, s in stats.items()}))
    print(kernels.__file__)
""")


def run_read_only(package_parent: Path, cache_home: Path):
    """Start CHILD with the package mounted read-only; return its JSON stats and path."""
    package = package_parent / 'ring_gyro_sim'
    script = (f'mount --bind {package} {package} && mount -o remount,bind,ro {package} && '
              f'exec {sys.executable} -c "$CHILD"')
    env = {'PATH': '/usr/bin:/bin', 'PYTHONPATH': str(package_parent), 'CHILD': CHILD,
           'XDG_CACHE_HOME': str(cache_home), 'HOME': str(cache_home)}
    result = subprocess.run(['unshare', '-m', 'sh', '-c', script], env=env, cwd=cache_home,
                            capture_output=True, text=True, timeout=300, check=False)
    return result


@pytest.mark.ci
def test_second_start_loads_the_kernels_from_disk_when_installed_read_only(tmp_path):
    parent = tmp_path / 'install'
    shutil.copytree(Path(ring_gyro_sim.__file__).parent, parent / 'ring_gyro_sim',
                    ignore=shutil.ignore_patterns('__pycache__'))
    probe = subprocess.run(['unshare', '-m', 'sh', '-c', f'mount --bind {parent} {parent}'],
                           capture_output=True, text=True, check=False)
    if probe.returncode != 0:
        pytest.skip(f'no private mount namespace here: {probe.stderr.strip()}')
    cache_home = tmp_path / 'home'
    cache_home.mkdir()
    first = run_read_only(parent, cache_home)
    assert first.returncode == 0, first.stderr
    second = run_read_only(parent, cache_home)
    assert second.returncode == 0, second.stderr
    stats_1, path_1 = first.stdout.strip().splitlines()[-2:]
    stats_2, path_2 = second.stdout.strip().splitlines()[-2:]
    assert path_1 == path_2 == str(parent / 'ring_gyro_sim' / 'core' / 'kernels' / '__init__.py')
    stats_1, stats_2 = json.loads(stats_1), json.loads(stats_2)
    print(f'\nfirst start (hits, misses): {stats_1}\nsecond start: {stats_2}')
    assert all(misses >= 1 for _, misses in stats_1.values())  # compiled the first time
    assert all(hits >= 1 and misses == 0 for hits, misses in stats_2.values())
    # Nothing was written into the read-only package; the cache is the user's.
    assert not list((parent / 'ring_gyro_sim').rglob('*.nbi'))
    assert list(cache_home.rglob('*.nbi'))


COLD = ('import json\n'
        'from ring_gyro_sim.core.kernels.cache import cold_kernels\n'
        'print(json.dumps(cold_kernels()))')


def cold_in_a_fresh_process(**env):
    package_parent = Path(ring_gyro_sim.__file__).parents[1]
    result = subprocess.run([sys.executable, '-c', COLD], capture_output=True, text=True,
                            timeout=120, check=False,
                            env={'PATH': '/usr/bin:/bin', 'PYTHONPATH': str(package_parent),
                                 **env})
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_cold_kernels_tells_an_empty_cache_from_a_filled_one(tmp_path):
    # The first compile takes tens of seconds: the command line asks this before it runs
    # anything, to say so (it compiles nothing itself).
    from ring_gyro_sim.core.params import paper_config
    from ring_gyro_sim.core.engine.full import Simulator
    Simulator(paper_config({'drive.start_on': 'rest'})).advance(0.001)  # fills the cache
    assert cold_in_a_fresh_process() == []
    empty = tmp_path / 'numba'
    empty.mkdir()
    assert cold_in_a_fresh_process(NUMBA_CACHE_DIR=str(empty)) == ['run_samples',
                                                                   'output_channels']
    assert list(empty.rglob('*.nb[ic]')) == []  # asking compiled nothing
