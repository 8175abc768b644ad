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
Tests of sweep/engine.py on real Dask clusters: workers, resume, failures, kills, Ctrl-C.

The reference is the tiny sweep on a LocalCluster of one worker. Every other way of running
it (two workers, a separately started scheduler and workers, a worker killed with SIGKILL,
an interrupted client resumed) must give the same Dataset, bit for bit, wall times aside.
"""

import io
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess

from distributed import LocalCluster, SchedulerPlugin
import psutil
import pytest
from ring_gyro_sim.sweep import load_spec, point, run_sweep
from ring_gyro_sim.sweep.engine import SETUP_PREFIX, SweepError, TASK_PREFIX
from ring_gyro_sim.sweep.results import open_results
from ring_gyro_sim.sweep.store import LOCK_NAME, PointStore
from sweep_harness import (assert_same_results, cli, DaskCluster, env, run_cli,
                           START_TIMEOUT_S, stored, TINY, wait_for, worker_of, write_spec)

FAILING = """\
duration: 0.05
set:
  shock.peak_g: 1000.0
axes:
  shock.angle_deg: [0.0, 30.0]
  modes.companions: [true, false]
"""
"""One point of four fails: a shock 30 deg off x on a ring without the sine companions
(InputError from the Simulator); each value alone is valid, so the spec is accepted."""


def sweep(spec_path, out, **kwargs):
    kwargs.setdefault('progress', False)
    kwargs.setdefault('dashboard_address', None)
    kwargs.setdefault('plots', False)
    return run_sweep(load_spec(str(spec_path)), out, **kwargs)


@pytest.fixture(scope='module')
def reference(tmp_path_factory):
    """Run the tiny sweep on one local worker: (spec path, output dir, outcome)."""
    d = tmp_path_factory.mktemp('reference')
    spec = write_spec(d)
    outcome = sweep(spec, d / 'out', workers=1)
    assert (outcome.computed, outcome.reused, outcome.failures) == (4, 0, [])
    return spec, d / 'out', outcome


def test_two_workers_give_the_results_of_one(reference, tmp_path):
    spec, ref_out, ref = reference
    outcome = sweep(spec, tmp_path / 'out', workers=2)
    assert outcome.workers == 2 and outcome.computed == 4
    assert_same_results(outcome.dataset, ref.dataset)
    on_disk = open_results(tmp_path / 'out' / 'results.nc')
    assert_same_results(on_disk, ref.dataset)
    assert set(on_disk['final_branch'].values.ravel()) <= {'upper', 'lower'}
    assert json.loads(on_disk.attrs['spec'])['axes'] == {'shock.peak_g': [2000.0, 8000.0],
                                                         'shock.phase': [0.0, 0.5]}
    rows = (tmp_path / 'out' / 'results.csv').read_text().splitlines()
    assert rows[0].startswith('shock.peak_g,shock.phase,final_branch,') and len(rows) == 5


class ComputedKeys(SchedulerPlugin):
    """Every key the scheduler saw computed (processing -> memory), in order."""

    def __init__(self):
        self.keys = []

    def transition(self, key, start, finish, *args, **kwargs):
        if start == 'processing' and finish == 'memory':
            self.keys.append(key)


def test_one_drive_setup_per_configuration_on_two_workers(tmp_path):
    two_q = TINY.replace('duration: 0.5', 'duration: 0.05').replace(
        '  modes.quality_factors[0]: 40000.0\n', '') + \
        '  modes.quality_factors[0]: [20000.0, 40000.0]\n'
    spec = write_spec(tmp_path, two_q)                      # 8 points on 2 configurations
    log = ComputedKeys()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        cluster.scheduler.add_plugin(log)
        outcome = sweep(spec, tmp_path / 'out', scheduler=cluster.scheduler_address)
    assert outcome.computed == 8 and not outcome.failures
    setups = [k for k in log.keys if k.startswith(SETUP_PREFIX)]
    assert sorted(setups) == sorted(SETUP_PREFIX + point.setup_key(p)
                                    for p in load_spec(str(spec)).points()[:2])
    assert sum(k.startswith(TASK_PREFIX) for k in log.keys) == 8


def test_resume_recomputes_no_stored_point(reference, tmp_path):
    spec, ref_out, ref = reference
    out = tmp_path / 'out'
    shutil.copytree(ref_out / 'points', out / 'points')
    lost = sorted((out / 'points').glob('*.json'))[:2]   # as if interrupted before these two
    for p in lost:
        p.unlink()
    kept = stored(out)
    with pytest.raises(SweepError, match='--resume keeps them'):
        sweep(spec, out, workers=1)
    outcome = sweep(spec, out, workers=1, resume=True)
    assert (outcome.computed, outcome.reused) == (2, 2)
    after = stored(out)
    assert {k: after[k] for k in kept} == kept            # not rewritten: not recomputed
    assert_same_results(outcome.dataset, ref.dataset)
    again = sweep(spec, out, resume=True)                 # nothing left: no cluster at all
    assert (again.computed, again.reused, again.workers) == (0, 4, 0)
    assert stored(out) == after


def test_a_failing_point_is_reported_and_the_rest_complete(tmp_path):
    spec = write_spec(tmp_path, FAILING)
    out = tmp_path / 'out'
    result = run_cli('sweep', spec, '--out', out, '--workers', '2', '--no-progress',
                     '--dashboard-address', '')
    assert result.returncode == 3, result.stderr            # 3: results written, some failed
    assert 'point failed: shock.angle_deg = 30, modes.companions = False' in result.stderr
    assert 'needs modes.companions' in result.stderr
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert (summary['computed'], summary['failed']) == (3, 1)
    ds = open_results(out / 'results.nc')
    errors = ds['error'].values
    assert 'InputError' in errors[1, 1] and (errors != '').sum() == 1
    assert ds['branch_code'].values[1, 1] == -1 and (ds['branch_code'].values >= 0).sum() == 3
    failures = json.loads((out / 'failures.json').read_text())
    assert failures[0]['parameters']['coords'] == {'shock.angle_deg': 30.0,
                                                   'modes.companions': False}
    assert (out / 'jump_map.png').stat().st_size > 1000 and (out / 'results.csv').is_file()
    assert 'bokeh is not installed' in result.stderr or 'dashboard' in result.stderr


@pytest.mark.ci
def test_a_separate_scheduler_and_workers_give_identical_results(reference, tmp_path):
    spec, _, ref = reference
    cluster = DaskCluster(tmp_path, workers=2)
    try:
        result = run_cli('sweep', spec, '--out', tmp_path / 'out', '--scheduler',
                         cluster.address, '--no-progress', '--no-plots')
    finally:
        cluster.close()
    assert result.returncode == 0, result.stderr
    assert 'on 2 workers' in result.stderr and cluster.address in result.stderr
    assert_same_results(open_results(tmp_path / 'out' / 'results.nc'), ref.dataset)


@pytest.mark.ci
def test_kill_9_of_a_worker_mid_sweep_still_gives_identical_results(reference, tmp_path):
    spec, _, ref = reference
    out = tmp_path / 'out'
    cluster = DaskCluster(tmp_path, workers=2, nanny=False)   # the worker is the process
    try:
        proc = subprocess.Popen(cli('sweep', spec, '--out', out, '--scheduler',
                                    cluster.address, '--no-progress', '--no-plots'),
                                env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        first = wait_for(lambda: sorted((out / 'points').glob('*.json')), START_TIMEOUT_S,
                         'a first point')[0]
        survivor = worker_of(first)
        victim = next(w for w in cluster.workers if w.pid != survivor)
        os.kill(victim.pid, signal.SIGKILL)
        at_kill = len(stored(out))
        stdout, stderr = proc.communicate(timeout=START_TIMEOUT_S)
    finally:
        cluster.close()
    assert at_kill < 4, 'the sweep had ended before the kill'
    assert victim.wait(timeout=10) == -signal.SIGKILL
    assert proc.returncode == 0, stderr
    assert json.loads(stdout.strip().splitlines()[-1])['failed'] == 0
    assert_same_results(open_results(out / 'results.nc'), ref.dataset)
    workers = {worker_of(p) for p in (out / 'points').glob('*.json')}
    assert survivor in workers


def test_ctrl_c_then_resume_recomputes_nothing_finished(reference, tmp_path):
    spec, _, ref = reference
    out = tmp_path / 'out'
    proc = subprocess.Popen(cli('sweep', spec, '--out', out, '--workers', '1',
                                '--no-progress', '--no-plots', '--dashboard-address', ''),
                            env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    wait_for(lambda: stored(out), START_TIMEOUT_S, 'a first point')
    children = psutil.Process(proc.pid).children(recursive=True)
    proc.send_signal(signal.SIGINT)                       # the client only, as kill -INT
    _, stderr = proc.communicate(timeout=START_TIMEOUT_S)
    assert proc.returncode == 130, stderr
    assert 'interrupted' in stderr and '--resume' in stderr
    _, alive = psutil.wait_procs(children, timeout=60)
    assert not alive, f'workers left running: {alive}'
    finished = stored(out)
    assert 1 <= len(finished) < 4, 'the sweep had ended before the interrupt'
    outcome = sweep(spec, out, workers=1, resume=True)
    assert (outcome.computed, outcome.reused) == (4 - len(finished), len(finished))
    after = stored(out)
    assert {k: after[k] for k in finished} == finished
    assert_same_results(outcome.dataset, ref.dataset)
    assert Path(out / 'results.nc').is_file()


def test_two_sweeps_into_one_directory_the_second_is_refused(reference, tmp_path):
    # Two sweeps started together into one --out would both exit 0, one's results replacing
    # the other's. The first holds the directory's lock; the second says so.
    spec, _, ref = reference
    out = tmp_path / 'out'
    first = subprocess.Popen(cli('sweep', spec, '--out', out, '--workers', '1',
                                 '--no-progress', '--no-plots', '--dashboard-address', ''),
                             env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    try:
        wait_for(lambda: PointStore(out, create=False).root.joinpath(LOCK_NAME).is_file(),
                 START_TIMEOUT_S, 'the first sweep to take its lock')
        second = run_cli('sweep', spec, '--out', out, '--workers', '1', '--no-progress',
                         '--no-plots', '--dashboard-address', '')
        still_running = first.poll() is None
    finally:
        stdout, stderr = first.communicate(timeout=START_TIMEOUT_S)
    assert second.returncode == 1, second.stderr
    assert still_running, 'the first sweep had ended before the second started'
    line = second.stderr.strip()
    assert line.startswith('ring_gyro sweep: error: --out ') and '\n' not in line, line
    assert f'another sweep is writing into it (pid {first.pid} on ' in line
    assert first.returncode == 0, stderr
    assert_same_results(open_results(out / 'results.nc'), ref.dataset)
    again = sweep(spec, out, resume=True)                  # the lock went with the process
    assert (again.computed, again.reused) == (0, 4)


def test_a_held_lock_refuses_the_sweep_before_anything_is_written(tmp_path):
    spec = write_spec(tmp_path)
    holder = PointStore(tmp_path / 'out')
    assert holder.lock() is None
    try:
        with pytest.raises(SweepError, match='another sweep is writing into it'):
            sweep(spec, tmp_path / 'out', workers=1)
        assert not (tmp_path / 'out' / 'sweep.json').exists()
    finally:
        holder.unlock()
    after = PointStore(tmp_path / 'out')
    assert after.lock() is None
    after.unlock()


def test_resume_names_a_truncated_point_file_and_computes_the_point_again(
        reference, tmp_path):
    # A truncated point file must not block --resume for good ("not computed", exit 3, the
    # file never named).
    spec, ref_out, ref = reference
    out = tmp_path / 'out'
    shutil.copytree(ref_out / 'points', out / 'points')
    cut = sorted((out / 'points').glob('*.json'))[1]
    text = cut.read_bytes()
    cut.write_bytes(text[:len(text) // 2])
    log = io.StringIO()
    outcome = sweep(spec, out, workers=1, resume=True, log=log)
    assert (outcome.computed, outcome.reused, outcome.failures) == (1, 3, [])
    assert f'{cut}: damaged, not a whole JSON record ({len(text) // 2} bytes' in log.getvalue()
    assert (out / 'points' / f'{cut.name}.damaged').read_bytes() == text[:len(text) // 2]
    assert json.loads(cut.read_text())['metrics'] is not None
    assert_same_results(outcome.dataset, ref.dataset)


def test_the_progress_bar_writes_whole_lines_into_a_log(reference, tmp_path):
    # tqdm's carriage-return frames do not belong in a non-terminal stderr
    spec, _, _ = reference
    log = tmp_path / 'sweep.log'
    with open(log, 'w') as stderr:
        result = subprocess.run(cli('sweep', spec, '--out', tmp_path / 'out', '--workers', '1',
                                    '--no-plots', '--dashboard-address', ''), env=env(),
                                stdout=subprocess.PIPE, stderr=stderr, text=True,
                                timeout=START_TIMEOUT_S * 3, check=False)
    text = log.read_text()
    assert result.returncode == 0, text
    assert '\r' not in text and '\x1b[' not in text, repr(text)
