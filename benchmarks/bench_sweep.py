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
Cost of sweep points: alone against paired (CPU time), and the 2-worker speed-up.

Four measurements (doc/sweeps.md, "Measured: cost and speed-up")::

    python benchmarks/bench_sweep.py pair [--pairs 3] [--duration 25] [--dask-env] [--pin same]
    python benchmarks/bench_sweep.py spin [--pairs 3]
    python benchmarks/bench_sweep.py dask [--pairs 3] [--duration 25] [--config KEY=JSON ...]
    python benchmarks/bench_sweep.py sweep [--workers 1 2 1 2] [--duration 25]
    python benchmarks/bench_sweep.py spec [--duration 25] > sweep16.yaml   # for ring_gyro sweep

``pair``
    One sweep point (8 000 g, Q_1 = 38 751, the default device, 25 s) computed by
    :func:`ring_gyro_sim.sweep.point.compute` in a fresh process, alone, then by two
    identical processes started at once, ``--pairs`` times alternating. Each process first
    warms up (numba kernels loaded, drive setup cached: what a sweep worker has after its
    first point of a configuration), then waits for the go and measures the **process CPU
    time** (``time.process_time``) of the point, split into its parts (exclusive CPU time of:
    ``kernel`` the integration, ``channels`` gaps and capacitances of the output samples,
    ``sim_other`` the rest of ``Simulator.advance_samples``, ``run_stats`` and ``run_other``
    the rest of ``Run.advance``, ``envelope`` the streaming envelope, ``case_loop`` the rest of
    ``run_case``, ``numbers`` the metrics, ``store`` the record written). Also the peak RSS
    (``ru_maxrss``), the minor page faults and, with ``--trace-memory``, the largest
    Python/numpy allocation total during the point (``tracemalloc``; one channel of the full
    record would be 2.5 M x 8 B = 20 MB). ``--dask-env`` gives the processes the environment
    a Dask nanny gives its workers by default (``distributed.nanny.pre-spawn-environ``:
    ``MALLOC_TRIM_THRESHOLD_=65536``, one BLAS thread); ``--pin same`` runs both on CPU 1
    (one core time-shared), ``--pin split`` on CPUs 1 and 0.
``spin``
    The platform alone: a compute-only numba loop (no memory traffic) and a memory-streaming
    numba loop (a 64 MB array summed), each alone then paired, CPU time.
``dask``
    The point on a 2-worker local cluster made as ``run_sweep`` makes it (the tree's
    :func:`~ring_gyro_sim.sweep.engine.local_cluster_config` when it has one, plus
    ``--config``): one worker busy, then both, alternating; the task thread's CPU time, the
    worker process's CPU time beside it (its other threads: profiler, event loop), the page
    faults, and the CPU time of the client process (client, scheduler, nannies) in cores.
``sweep``
    ``run_sweep`` of a 16-point spec (1 000 and 8 000 g x 8 Q_1 from 5 000 to 180 000, log;
    ``--duration`` s each; local cluster, no dashboard, no plots) for each ``--workers``
    count in turn, in this process: wall time, the speed-up (median wall of the smallest
    count over the median of each other), the points' wall and CPU times (the record's
    ``cpu_time_s``, the task thread's), the drive setups computed, the CPU time of the
    client process and of the workers (reaped children), the 1-min load, and whether every
    run gave the results of the first (bit for bit, wall and CPU times aside). Before and
    after each run, a reference: the median CPU time of three 1 s runs of the point in this
    process. On this shared machine the CPU time of the same point drifts by up to 2x within
    minutes (the host runs other tenants; a register-only loop does not drift): when the
    references differ by more than 5 % the comparison is flagged. Only an idle machine gives
    a meaningful speed-up.

CPU time, not wall time, is what ``pair``, ``spin`` and ``dask`` compare: it is what the
point costs and it does not count the time the process waited for a core. It is not immune
to the host, though (above): compare only runs made in one session, alternated, and look at
the spread of the repetitions.

Run it from the repository (``PYTHONPATH=.``) or on another tree with ``--tree DIR`` (the
children, the cluster and the sweep import that tree's ``ring_gyro_sim``): e.g. the main
branch checked out with ``git worktree add --detach /tmp/old main``.
"""

import argparse
from collections import defaultdict
import dataclasses
import json
import os
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Any, Dict, List

REPO_ROOT = pathlib.Path(__file__).resolve().parents[1]
POINT_INDEX = 12
"""Point of :func:`spec_text` measured by ``pair``: 8 000 g, Q_1 = 38 751 (lower branch)."""
DASK_ENV = {'MALLOC_TRIM_THRESHOLD_': '65536', 'OMP_NUM_THREADS': '1',
            'MKL_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1'}
"""What ``distributed.nanny.pre-spawn-environ`` sets in a Dask worker (distributed 2024)."""
PINNING = {'split': 'alone on CPU 1, paired on CPUs 1 and 0',
           'same': 'alone on CPU 1, paired both on CPU 1: one core time-shared'}
"""``pair --pin``: where the processes run (``none``: where the kernel puts them)."""
PARTS = [('ring_gyro_sim.core.engine.full', 'Simulator', '_integrate', 'kernel'),
         ('ring_gyro_sim.core.engine.full', 'Simulator', '_channels', 'channels'),
         ('ring_gyro_sim.core.engine.full', 'Simulator', 'advance_samples', 'sim_other'),
         ('ring_gyro_sim.run', 'RunStats', 'add', 'run_stats'),
         ('ring_gyro_sim.run', 'Run', 'advance', 'run_other'),
         ('ring_gyro_sim.run', 'Run', '__init__', 'run_init'),
         ('ring_gyro_sim.analysis.envelope', 'StreamingEnvelope', 'add', 'envelope'),
         ('ring_gyro_sim.analysis.cases', None, '_key_numbers', 'numbers'),
         ('ring_gyro_sim.analysis.cases', None, 'run_case', 'case_loop'),
         ('ring_gyro_sim.sweep.store', 'PointStore', 'write', 'store'),
         ('ring_gyro_sim.sweep.point', None, 'compute', 'record')]
"""Parts of a point: (module, class or None, function, name); exclusive CPU time each."""


def spec_text(duration: float) -> str:
    """Return the 16-point spec: 1 000 and 8 000 g x 8 Q_1 (log 5 000-180 000)."""
    return (f"base: {REPO_ROOT / 'config' / 'default.yaml'}\n"
            f'duration: {duration!r}\n'
            'set:\n  shock.phase: 0.0\n'
            'axes:\n  shock.peak_g: [1000.0, 8000.0]\n'
            '  modes.quality_factors[0]: {log: [5000.0, 180000.0, 8]}\n'
            'metrics: [final_branch, final_q2_m, min_q2_m, q2_after_shock_m, min_gap_m, '
            'contact,\n          contact_time_s, return_time_s, settled, peak_q1_m]\n')


def _write_spec(directory: str, duration: float) -> str:
    path = os.path.join(directory, 'spec.yaml')
    with open(path, 'w', encoding='utf-8') as fh:
        fh.write(spec_text(duration))
    return path


def _median(values) -> float:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else float('nan')


# ---------------------------------------------------------------------------- pair: child
def _instrument() -> Dict[str, float]:
    """Wrap the functions of :data:`PARTS`; return the dict of exclusive CPU times."""
    import importlib
    spent: Dict[str, float] = defaultdict(float)
    stack: List[float] = []

    def wrap(owner, attr, name):
        inner = getattr(owner, attr)

        def timed(*args, **kwargs):
            t0 = time.process_time()
            stack.append(0.0)
            try:
                return inner(*args, **kwargs)
            finally:
                dt = time.process_time() - t0
                spent[name] += dt - stack.pop()
                if stack:
                    stack[-1] += dt
        setattr(owner, attr, timed)

    for module, cls, attr, name in PARTS:
        mod = importlib.import_module(module)
        wrap(getattr(mod, cls) if cls else mod, attr, name)
    return spent


def child_point(args) -> int:
    """Warm up, print READY, wait for a line on stdin, compute the point, print RESULT."""
    if args.cpu is not None:
        os.sched_setaffinity(0, {args.cpu})
    from ring_gyro_sim.sweep import point as pt
    from ring_gyro_sim.sweep.spec import load_spec
    from ring_gyro_sim.sweep.store import PointStore
    work = tempfile.mkdtemp(prefix='bench_sweep_')
    p = load_spec(_write_spec(work, args.duration)).points()[POINT_INDEX]
    store = os.path.join(work, 'out')
    PointStore(store)
    pt.compute(dataclasses.replace(p, duration_s=0.2), store)  # kernels, drive setup cached
    spent = _instrument() if not args.trace_memory else {}
    rss_ready = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print('READY', flush=True)
    sys.stdin.readline()
    if args.trace_memory:
        import tracemalloc
        tracemalloc.start()
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    c0, w0 = time.process_time(), time.perf_counter()
    record = pt.compute(p, store)
    c1, w1 = time.process_time(), time.perf_counter()
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    out = {'cpu_s': c1 - c0, 'wall_s': w1 - w0, 'parts_s': dict(spent),
           'user_s': r1.ru_utime - r0.ru_utime, 'system_s': r1.ru_stime - r0.ru_stime,
           'minor_faults': r1.ru_minflt - r0.ru_minflt,
           'maxrss_ready_mb': rss_ready / 1024, 'maxrss_mb': r1.ru_maxrss / 1024,
           'error': record['error'], 'final_branch': (record['metrics'] or {}).get(
               'final_branch')}
    if args.trace_memory:
        out['traced_peak_mb'] = tracemalloc.get_traced_memory()[1] / 2**20
    print('RESULT ' + json.dumps(out), flush=True)
    return 0


# ---------------------------------------------------------------------------- pair / spin
def _children(argv: List[str], n: int, env: Dict[str, str],
              cpus=(None, None)) -> List[Dict[str, Any]]:
    """Start ``n`` identical children (on ``cpus``), let them go at once when all are READY."""
    procs = [subprocess.Popen(argv + ([] if cpu is None else ['--cpu', str(cpu)]),
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
             for cpu in cpus[:n]]
    try:
        for proc in procs:
            line = proc.stdout.readline()
            if not line.startswith('READY'):
                raise RuntimeError(f'child did not start: {line!r}')
        for proc in procs:
            proc.stdin.write('go\n')
            proc.stdin.flush()
        results = []
        for proc in procs:
            for line in proc.stdout:
                if line.startswith('RESULT '):
                    results.append(json.loads(line[len('RESULT '):]))
            proc.wait()
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    if len(results) != n:
        raise RuntimeError('a child gave no result')
    return results


def _child_env(args) -> Dict[str, str]:
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [str(pathlib.Path(args.tree).resolve()), env.get('PYTHONPATH', '')]).rstrip(os.pathsep)
    if getattr(args, 'dask_env', False):
        env.update(DASK_ENV)
    return env


def _alternate(argv, args, key: str) -> Dict[str, Any]:
    """Alone then paired, ``args.pairs`` times; the rows and their medians."""
    env = _child_env(args)
    pin = getattr(args, 'pin', 'none')
    cpus = {'none': (None, None), 'split': (1, 0), 'same': (1, 1)}[pin]
    rows = []
    for i in range(args.pairs):
        load0 = os.getloadavg()[0]
        alone = _children(argv, 1, env, cpus)[0]
        pair = _children(argv, 2, env, cpus)
        rows.append({'alone': alone, 'paired': pair, 'load': [load0, os.getloadavg()[0]]})
        print(f'[{i + 1}/{args.pairs}] load {load0:.2f}: alone {alone[key]:.3f} s, paired '
              f'{pair[0][key]:.3f} / {pair[1][key]:.3f} s CPU (wall {alone["wall_s"]:.2f}, '
              f'{pair[0]["wall_s"]:.2f} / {pair[1]["wall_s"]:.2f} s)', file=sys.stderr)
    alone = _median(r['alone'][key] for r in rows)
    paired = _median(x[key] for r in rows for x in r['paired'])
    return {'rows': rows, 'alone_s': alone, 'paired_s': paired, 'ratio': paired / alone}


def cmd_pair(args) -> int:
    """``pair``: the point's CPU time alone and paired, by part."""
    argv = [sys.executable, os.path.abspath(__file__), '_point', '--duration',
            repr(args.duration)] + (['--trace-memory'] if args.trace_memory else [])
    out = _alternate(argv, args, 'cpu_s')
    rows = out['rows']
    print(f'point CPU time (median of {args.pairs} alone, {2 * args.pairs} paired): alone '
          f"{out['alone_s']:.3f} s, paired {out['paired_s']:.3f} s: ratio {out['ratio']:.3f}"
          f"{' (Dask worker environment)' if args.dask_env else ''}"
          f"{'' if args.pin == 'none' else ' (pinned: ' + PINNING[args.pin] + ')'}")
    for name in ['user_s', 'system_s', 'minor_faults', 'maxrss_ready_mb', 'maxrss_mb'] + (
            ['traced_peak_mb'] if args.trace_memory else []):
        a = _median(r['alone'][name] for r in rows)
        b = _median(x[name] for r in rows for x in r['paired'])
        print(f'  {name:16s} alone {a:12.3f}  paired {b:12.3f}')
    if not args.trace_memory:
        print('  part (exclusive CPU s)   alone    paired   ratio')
        for name in [p[3] for p in PARTS]:
            a = _median(r['alone']['parts_s'].get(name, 0.0) for r in rows)
            b = _median(x['parts_s'].get(name, 0.0) for r in rows for x in r['paired'])
            print(f'  {name:22s} {a:8.3f}  {b:8.3f}  {b / a if a else float("nan"):6.3f}')
    if args.json:
        print(json.dumps(out))
    return 0


def child_spin(args) -> int:
    """Numba loops: compute-only (``--kind compute``) or memory streaming (``stream``)."""
    import numba
    import numpy as np

    @numba.njit(cache=False)
    def compute(n):
        x, y = 0.1, 0.2
        for _ in range(n):
            x = x * 0.9999999 + y * 1e-7
            y = y * 0.9999998 + x * 2e-7
        return x + y

    @numba.njit(cache=False)
    def stream(a, reps):
        s = 0.0
        for _ in range(reps):
            for i in range(a.size):
                s += a[i]
        return s

    a = np.ones(8 * 2**20)  # 64 MB: far beyond L2 (4 MB)
    compute(10)
    stream(a[:10], 1)
    print('READY', flush=True)
    sys.stdin.readline()
    c0, w0 = time.process_time(), time.perf_counter()
    if args.kind == 'compute':
        compute(500_000_000)
    else:
        stream(a, 300)
    print('RESULT ' + json.dumps({'cpu_s': time.process_time() - c0,
                                  'wall_s': time.perf_counter() - w0}), flush=True)
    return 0


def cmd_spin(args) -> int:
    """``spin``: the platform's own paired/alone CPU time ratio, compute and memory."""
    for kind in ('compute', 'stream'):
        argv = [sys.executable, os.path.abspath(__file__), '_spin', '--kind', kind]
        out = _alternate(argv, args, 'cpu_s')
        print(f"numba {kind} loop CPU time: alone {out['alone_s']:.3f} s, paired "
              f"{out['paired_s']:.3f} s: ratio {out['ratio']:.3f}")
    return 0


# ---------------------------------------------------------------------------- dask
def _dask_task(p, store):
    """Compute ``p`` on a worker: the record's times, the worker process's CPU time."""
    from ring_gyro_sim.sweep import point as pt
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    c0, t0 = time.process_time(), time.thread_time()
    record = pt.compute(p, store)
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    return {'cpu_s': time.thread_time() - t0, 'wall_s': record['wall_time_s'],
            'process_cpu_s': time.process_time() - c0,
            'minor_faults': r1.ru_minflt - r0.ru_minflt, 'pid': os.getpid(),
            'error': record['error']}


def cmd_dask(args) -> int:
    """``dask``: the point alone and paired on the sweep's own 2-worker local cluster."""
    import logging
    sys.path.insert(0, str(pathlib.Path(args.tree).resolve()))
    os.environ.update({'PYTHONPATH': _child_env(args)['PYTHONPATH']})
    import dask
    from distributed import Client, LocalCluster
    from ring_gyro_sim.sweep.spec import load_spec
    from ring_gyro_sim.sweep import engine
    from ring_gyro_sim.sweep.store import PointStore
    settings = dict(getattr(engine, 'local_cluster_config', dict)())  # what run_sweep uses
    for item in args.config:
        name, _, value = item.partition('=')
        settings[name] = json.loads(value)
    work = tempfile.mkdtemp(prefix='bench_sweep_')
    p = load_spec(_write_spec(work, args.duration)).points()[POINT_INDEX]
    store = os.path.join(work, 'out')
    PointStore(store)
    with dask.config.set(settings), LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
            silence_logs=logging.ERROR, preload=['ring_gyro_sim.sweep._worker']) as cluster, \
            Client(cluster) as client:
        workers = list(client.scheduler_info()['workers'])
        warm = dataclasses.replace(p, duration_s=0.2)
        client.gather([client.submit(_dask_task, warm, store, workers=[w], pure=False)
                       for w in workers])
        rows = []
        for i in range(args.pairs):
            row = {'load': os.getloadavg()[0]}
            for phase, on in (('alone', workers[:1]), ('paired', workers)):
                c0 = time.process_time()
                w0 = time.perf_counter()
                row[phase] = client.gather([client.submit(_dask_task, p, store, workers=[w],
                                                          pure=False) for w in on])
                row[phase + '_client_cores'] = (time.process_time() - c0) / (
                    time.perf_counter() - w0)
            rows.append(row)
            a, b = row['alone'][0], row['paired']
            print(f"[{i + 1}/{args.pairs}] load {row['load']:.2f}: alone {a['cpu_s']:.3f} s "
                  f"(worker {a['process_cpu_s']:.3f}), paired {b[0]['cpu_s']:.3f} / "
                  f"{b[1]['cpu_s']:.3f} s (workers {b[0]['process_cpu_s']:.3f} / "
                  f"{b[1]['process_cpu_s']:.3f}) CPU; wall {a['wall_s']:.2f}, "
                  f"{b[0]['wall_s']:.2f} / {b[1]['wall_s']:.2f} s", file=sys.stderr)
    print(f"point on a 2-worker local cluster{' ' + json.dumps(settings) if settings else ''}"
          f' (median of {args.pairs} alone, {2 * args.pairs} paired):')
    for name in ('cpu_s', 'process_cpu_s', 'minor_faults'):
        a = _median(r['alone'][0][name] for r in rows)
        b = _median(x[name] for r in rows for x in r['paired'])
        print(f'  {name:14s} alone {a:12.3f}  paired {b:12.3f}  ratio {b / a:.3f}')
    background = [(x['process_cpu_s'] - x['cpu_s']) / x['wall_s']
                  for r in rows for x in r['alone'] + r['paired']]
    print(f'  worker threads beside the task: {_median(background):.3f} cores per worker')
    for phase in ('alone', 'paired'):
        print(f'  client process (client, scheduler, nannies) during {phase}: '
              f"{_median(r[phase + '_client_cores'] for r in rows):.3f} cores")
    if args.json:
        print(json.dumps(rows))
    return 0


# ---------------------------------------------------------------------------- sweep
def _config_key(point) -> str:
    from ring_gyro_sim.core.params import to_flat
    config = point.case_spec().config(None, point.output_rate_hz)
    return json.dumps(to_flat(config), sort_keys=True)


def _same(a, b, names) -> bool:
    """Whether the variables ``names`` of two result Datasets are identical (nan == nan)."""
    import numpy as np
    try:
        for name in names:
            np.testing.assert_array_equal(a[name].values, b[name].values)
    except AssertionError:
        return False
    return True


def _reference_cpu(point_mod, p) -> float:
    """Median CPU time of three 1 s runs of ``p`` here: how fast the host runs now, s."""
    short = dataclasses.replace(p, duration_s=1.0)
    times = []
    for _ in range(3):
        c0 = time.process_time()
        point_mod.compute(short)
        times.append(time.process_time() - c0)
    return statistics.median(times)


def _one_sweep(spec, points, configs, n, out, point_mod) -> Dict[str, Any]:
    """Run the sweep on ``n`` local workers into ``out``; its numbers."""
    from ring_gyro_sim.sweep import run_sweep
    from ring_gyro_sim.sweep.store import PointStore
    load0 = os.getloadavg()[0]
    self0 = resource.getrusage(resource.RUSAGE_SELF)
    kids0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    outcome = run_sweep(spec, out, workers=n, progress=False, dashboard_address=None,
                        plots=False)
    self1 = resource.getrusage(resource.RUSAGE_SELF)
    kids1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    store = PointStore(out, create=False)
    records = [store.read(p.key) for p in points]
    walls = [r['wall_time_s'] for r in records]
    cpus = [r.get('cpu_time_s') for r in records]
    if hasattr(point_mod, 'setup_task'):  # one setup task per configuration
        setups = len(set(configs.values()))
    else:  # each worker computes the setup of each configuration it meets
        setups = len({(r['worker'], configs[r['key']]) for r in records})
    return {'workers': n, 'wall_s': outcome.wall_time_s, 'load': [load0, os.getloadavg()[0]],
            'point_wall_sum_s': sum(walls), 'point_wall_median_s': _median(walls),
            'point_cpu_median_s': _median(cpus), 'setups': setups,
            'client_cpu_s': self1.ru_utime + self1.ru_stime - self0.ru_utime - self0.ru_stime,
            'workers_cpu_s': kids1.ru_utime + kids1.ru_stime - kids0.ru_utime - kids0.ru_stime,
            'failed': len(outcome.failures), 'dataset': outcome.dataset}


def cmd_sweep(args) -> int:
    """``sweep``: run_sweep with each worker count; wall, speed-up, CPU accounting."""
    sys.path.insert(0, str(pathlib.Path(args.tree).resolve()))
    os.environ.update({'PYTHONPATH': _child_env(args)['PYTHONPATH']})
    from ring_gyro_sim.sweep import load_spec
    from ring_gyro_sim.sweep import point as point_mod
    from ring_gyro_sim.sweep import results
    work = tempfile.mkdtemp(prefix='bench_sweep_')
    spec = load_spec(_write_spec(work, args.duration))
    points = spec.points()
    configs = {p.key: _config_key(p) for p in points}
    point_mod.compute(dataclasses.replace(points[POINT_INDEX], duration_s=0.1))  # kernels
    runs = []
    for i, n in enumerate(args.workers):
        ref0 = _reference_cpu(point_mod, points[POINT_INDEX])
        run = _one_sweep(spec, points, configs, n, os.path.join(work, f'run{i}_{n}'),
                         point_mod)
        run['reference_cpu_s'] = [ref0, _reference_cpu(point_mod, points[POINT_INDEX])]
        runs.append(run)
        print(f"[sweep] run {i + 1}/{len(args.workers)}: {n} worker(s), {run['wall_s']:.1f} s "
              f"wall, load {run['load'][0]:.2f} -> {run['load'][1]:.2f}, reference "
              f"{run['reference_cpu_s'][0]:.3f} -> {run['reference_cpu_s'][1]:.3f} s",
              file=sys.stderr)
    base = runs[0]
    names = results.comparable(base['dataset'])
    refs = [x for r in runs for x in r['reference_cpu_s']]
    print(f'{len(points)} points x {args.duration:g} s, {args.tree}')
    for i, run in enumerate(runs):
        busy = run['point_wall_sum_s'] / (run['workers'] * run['wall_s'])
        same = _same(run['dataset'], base['dataset'], names)
        print(f"run {i + 1}: {run['workers']} worker(s): wall {run['wall_s']:7.1f} s; points: "
              f"{100 * busy:.0f} % of the workers' time, wall median "
              f"{run['point_wall_median_s']:.2f} s, CPU median {run['point_cpu_median_s']:.2f} "
              f"s; drive setups {run['setups']}; CPU workers {run['workers_cpu_s']:.1f} s, "
              f"client {run['client_cpu_s']:.1f} s; load {run['load'][0]:.2f} -> "
              f"{run['load'][1]:.2f}; reference {run['reference_cpu_s'][0]:.3f} / "
              f"{run['reference_cpu_s'][1]:.3f} s; failed {run['failed']}; results "
              f"{'identical' if same else 'DIFFER'} to run 1")
    walls = {n: _median(r['wall_s'] for r in runs if r['workers'] == n) for n in args.workers}
    one = min(walls)
    for n in sorted(walls):
        if n != one:
            print(f'speed-up {n} workers over {one}: {walls[one] / walls[n]:.2f}x (median '
                  f'walls {walls[one]:.1f} s / {walls[n]:.1f} s)')
    spread = (max(refs) - min(refs)) / min(refs)
    if spread > 0.05:
        print(f'WARNING: the reference CPU time varied by {100 * spread:.0f} % over the '
              f'runs (the host ran at another speed): the comparison is not valid; run '
              f'again on an idle machine')
    if args.json:
        print(json.dumps([{k: v for k, v in r.items() if k != 'dataset'} for r in runs]))
    return 0


def cmd_spec(args) -> int:
    """``spec``: print the 16-point spec of ``sweep`` (for ``ring_gyro sweep``)."""
    sys.stdout.write(spec_text(args.duration))
    return 0


def main(argv=None) -> int:
    """Command line (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    sub = parser.add_subparsers(dest='mode', required=True)
    for name in ('pair', 'spin', 'dask', 'sweep', 'spec', '_point', '_spin'):
        p = sub.add_parser(name)
        p.add_argument('--tree', default=str(REPO_ROOT),
                       help='repository whose ring_gyro_sim is measured (default: this one)')
        p.add_argument('--json', action='store_true', help='also print the numbers as JSON')
        if name in ('pair', '_point', 'dask', 'sweep', 'spec'):
            p.add_argument('--duration', type=float, default=25.0, help='simulated s per point')
        if name in ('pair', 'spin', 'dask'):
            p.add_argument('--pairs', type=int, default=3, help='alone/paired repetitions')
        if name in ('pair', '_point'):
            p.add_argument('--trace-memory', action='store_true',
                           help='tracemalloc peak of the point (no part split)')
        if name == 'pair':
            p.add_argument('--pin', choices=('none', 'split', 'same'), default='none',
                           help='CPU affinity of the processes (PINNING)')
        if name == '_point':
            p.add_argument('--cpu', type=int, default=None, help='run on this CPU only')
        if name == 'pair':
            p.add_argument('--dask-env', action='store_true',
                           help="a Dask worker's environment (MALLOC_TRIM_THRESHOLD_ ...)")
        if name == 'dask':
            p.add_argument('--config', nargs='*', default=[], metavar='KEY=JSON',
                           help='dask settings for the cluster, e.g. '
                                'distributed.worker.profile.enabled=false')
        if name == '_spin':
            p.add_argument('--kind', choices=('compute', 'stream'), default='compute')
        if name == 'sweep':
            p.add_argument('--workers', type=int, nargs='+', default=[1, 2, 1, 2],
                           help='worker counts, run in this order (alternate them: the '
                                'speed-up compares the medians of each count)')
    args = parser.parse_args(argv)
    return {'pair': cmd_pair, 'spin': cmd_spin, 'dask': cmd_dask, 'sweep': cmd_sweep,
            'spec': cmd_spec, '_point': child_point, '_spin': child_spin}[args.mode](args)


if __name__ == '__main__':
    sys.exit(main())
