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
Helpers of the sweep tests: tiny specs, the CLI in a subprocess, a separate Dask cluster.

The tiny sweep (:data:`TINY`) is 2 x 2 points on one configuration (shock amplitude x shock
phase), 0.5 s simulated each: the drive setup (shooting, ~1.7 s) is done once on the cluster
(a task the points depend on) and each point then runs in ~0.12 s (idle; RTF ~4.5), long
enough for a worker to be killed or the client interrupted mid-sweep, short enough that a
test's time is mostly the cluster's start.
"""

import json
import os
from pathlib import Path
import subprocess
import sys
import time

import numpy as np
import psutil
from ring_gyro_sim.sweep import results

REPO = Path(__file__).resolve().parents[2]
DASK = Path(sys.executable).parent / 'dask'
START_TIMEOUT_S = 120.0
"""A scheduler or worker start, or a whole tiny sweep: ~3-10 s on the loaded 2 cores."""

TINY = """\
duration: 0.5
set:
  modes.quality_factors[0]: 40000.0
axes:
  shock.peak_g: [2000.0, 8000.0]
  shock.phase: [0.0, 0.5]
"""


def write_spec(directory, text=TINY, name='spec.yaml') -> Path:
    """Write a spec file into ``directory``; its path."""
    path = Path(directory) / name
    path.write_text(text, encoding='utf-8')
    return path


def env() -> dict:
    """Environment of a subprocess that imports this worktree's ring_gyro_sim."""
    out = dict(os.environ)
    out['PYTHONPATH'] = os.pathsep.join([str(REPO), out.get('PYTHONPATH', '')]).rstrip(
        os.pathsep)
    return out


def cli(*args) -> list:
    """Return the command line of ``ring_gyro`` (this interpreter, this worktree)."""
    return [sys.executable, '-m', 'ring_gyro_sim.cli', *map(str, args)]


def run_cli(*args, timeout=START_TIMEOUT_S * 3) -> subprocess.CompletedProcess:
    """Run ``ring_gyro ARGS`` to the end."""
    return subprocess.run(cli(*args), env=env(), capture_output=True, text=True,
                          timeout=timeout, check=False)


def stored(out_dir) -> dict:
    """Return ``{point file name: mtime_ns}`` of the computed points under ``out_dir``."""
    return {p.name: p.stat().st_mtime_ns for p in (Path(out_dir) / 'points').glob('*.json')}


def wait_for(predicate, timeout_s, what, poll_s=0.02):
    """Poll ``predicate`` until true; fail after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(poll_s)
    raise AssertionError(f'timed out after {timeout_s} s waiting for {what}')


def assert_same_results(a, b) -> None:
    """Every reproducible variable and coordinate of two result Datasets is identical."""
    assert list(a.dims) == list(b.dims)
    for name in a.coords:
        np.testing.assert_array_equal(a[name].values, b[name].values)
    names = results.comparable(a)
    assert names == results.comparable(b)
    for name in names:
        np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def worker_of(record_path) -> int:
    """Return the pid of the worker that computed a stored point."""
    record = json.loads(Path(record_path).read_text(encoding='utf-8'))
    return int(record['worker'].rsplit(':', 1)[1])


class DaskCluster:
    """A ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1, a free port each."""

    def _address_written(self) -> bool:
        """Tell whether the scheduler file holds its address (it is written after creation)."""
        try:
            return 'address' in json.loads(self.file.read_text())
        except (OSError, ValueError):
            return False

    def __init__(self, directory, workers=2, nanny=True) -> None:
        self.directory = Path(directory)
        self.file = self.directory / 'scheduler.json'
        self.procs = []
        self.workers = []
        try:
            self.scheduler = self._start([str(DASK), 'scheduler', '--host', '127.0.0.1',
                                          '--port', '0', '--no-dashboard',
                                          '--scheduler-file', str(self.file)], 'scheduler')
            # the scheduler creates the file before it writes it: wait for the whole JSON
            wait_for(self._address_written, START_TIMEOUT_S, 'the scheduler file')
            self.address = json.loads(self.file.read_text())['address']
            for i in range(workers):
                self.workers.append(self._start(
                    [str(DASK), 'worker', self.address, '--nthreads', '1', '--host',
                     '127.0.0.1', '--nanny' if nanny else '--no-nanny', '--name', f'w{i}'],
                    f'worker{i}'))
            self.wait_workers(workers)
        except BaseException:
            self.close()
            raise

    def _start(self, argv, name):
        log = open(self.directory / f'{name}.log', 'w')
        proc = subprocess.Popen(argv, env=env(), stdout=log, stderr=subprocess.STDOUT)
        log.close()
        self.procs.append(proc)
        return proc

    def wait_workers(self, n) -> None:
        """Wait until ``n`` workers are connected to the scheduler."""
        from distributed import Client
        with Client(self.address, timeout='60s') as client:
            client.wait_for_workers(n, timeout=START_TIMEOUT_S)

    def close(self) -> None:
        """Stop every process started here (workers first) and reap them."""
        for proc in reversed(self.procs):
            if proc.poll() is None:
                proc.terminate()
        for proc in reversed(self.procs):
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=30)


def children_gone(pid, timeout_s=60.0) -> None:
    """Wait until no process descends from ``pid`` any more (the LocalCluster's workers)."""
    def gone():
        return not [p for p in psutil.process_iter(['ppid']) if p.info['ppid'] == pid]
    wait_for(gone, timeout_s, f'the children of {pid} to exit', poll_s=0.2)
