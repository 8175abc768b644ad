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
Running a sweep on ``dask.distributed``: :func:`run_sweep`.

Where it runs
    Without ``scheduler``: a ``LocalCluster`` of ``workers`` processes (default: the
    machine's cores), one thread each (the numba kernels release no GIL worth sharing: one
    point per process keeps it simple), each started by a nanny that restarts it if it
    dies; its background work (profiler, watchdogs, monitors) is turned down so that it
    takes little from the points' cores (:func:`local_cluster_config`). With
    ``scheduler`` (``tcp://host:port``): that cluster, as it is; nothing else
    changes. The Dask dashboard address is printed when the scheduler serves one (it needs
    ``bokeh``: without it the line says so).

What is computed
    Every point of the spec whose record is not in ``DIR/points`` (:mod:`.store`): one
    task per point (:func:`ring_gyro_sim.sweep.point.compute`), keyed by the point's hash,
    submitted at once; the scheduler balances them. Each point depends on the drive setup
    of its configuration (the point without its shock: branches and start state, ~1.7 s of
    shooting), one task per configuration (:func:`ring_gyro_sim.sweep.point.setup_task`),
    computed once on the cluster and sent to whichever worker computes a point of it (a
    few hundred bytes); a setup lost with its worker is computed again. A point's record
    is stored by its worker as soon as it is computed (when the worker sees ``DIR``) and
    again by the client on receipt, atomically. A point that raises, or whose task the
    scheduler gives up on (its workers died ``distributed.scheduler.allowed-failures``
    times), is a failure: it is reported with its parameters on stderr and in
    ``DIR/failures.json``, and the sweep goes on. A worker killed mid-point costs that
    point's time only: Dask runs it again elsewhere.

Resume
    One sweep at a time writes into ``DIR`` (a lock, :meth:`.store.PointStore.lock`): a
    second one started there is refused at once, naming the holder.
    A new sweep refuses a ``DIR`` that already holds computed points; ``resume=True``
    keeps every stored point (never recomputed: its key is its content) and computes the
    rest, failures included. A stored file that holds no whole record (truncated) is
    named on the log, kept as ``<key>.json.damaged`` and its point computed again.
    Ctrl-C stops the client: what was stored stays.

Output
    ``DIR/results.nc`` and ``DIR/results.csv`` (:mod:`.results`), ``DIR/jump_map.png``,
    ``DIR/map_<metric>.png`` and, with kept envelopes, ``DIR/envelope_<channel>.png``
    (:func:`ring_gyro_sim.analysis.plotting.plot_sweep`), ``DIR/sweep.json`` (the resolved
    spec), ``DIR/failures.json``. A gyroscope sweep (a device population) also writes its
    datasheet, ``DIR/datasheet.json`` and ``DIR/datasheet.md``
    (:func:`.results.population_datasheet`), and its histograms, ``DIR/population.png``
    (:func:`ring_gyro_sim.analysis.plotting.plot_population`). ``ring_gyro report`` runs its
    Case 4 through this function (:func:`ring_gyro_sim.report.run_case4`).
"""

from contextlib import contextmanager
from dataclasses import dataclass, field
import importlib.util
import json
import logging
import os
import sys
import time
from typing import Any, Dict, List, Optional, TextIO
import warnings

from ring_gyro_sim import extras
from ring_gyro_sim.core.errors import RingGyroError
from ring_gyro_sim.outdir import prepare_directory
from ring_gyro_sim.progress import Counter
from ring_gyro_sim.sweep import point as point_mod
from ring_gyro_sim.sweep.spec import describe, SweepSpec
from ring_gyro_sim.sweep.store import PointStore

__all__ = ['LOCAL_CLUSTER_CONFIG', 'SETUP_PREFIX', 'SweepError', 'SweepOutcome', 'TASK_PREFIX',
           'local_cluster_config', 'run_sweep']

TASK_PREFIX = 'ring_gyro_point-'
"""Dask key of a point's task: this prefix and the point's hash."""
SETUP_PREFIX = 'ring_gyro_setup-'
"""Dask key of a configuration's drive setup: this prefix and :func:`.point.setup_key`."""
DASHBOARD_PROBE_S = 3.0
LOCAL_CLUSTER_CONFIG: Dict[str, Any] = {
    'distributed.worker.profile.enabled': False,
    'distributed.admin.tick.interval': '1s',
    'distributed.admin.system-monitor.interval': '2s',
    'distributed.worker.memory.monitor-interval': '1s',
}
"""Dask settings of the local cluster (not of one given by ``--scheduler``): the
background work of the client, scheduler, nannies and workers, which shares the cores with
the points, at a fifth (0.11 -> 0.02 cores with 2 workers, doc/sweeps.md): no statistical
profiler in the workers (a stack sample every 10 ms: the dashboard's profile page stays
empty), the event-loop watchdog every 1 s instead of 20 ms, the system monitor every 2 s
(0.5 s), the nannies' memory check every 1 s (0.1 s)."""


class SweepError(RingGyroError, RuntimeError):
    """A sweep cannot start (output directory, scheduler, options)."""


@dataclass
class SweepOutcome:
    """
    What :func:`run_sweep` did.

    Attributes
    ----------
    dataset : xarray.Dataset
        The results (:mod:`ring_gyro_sim.sweep.results`).
    points, computed, reused : int
        Points of the spec, computed now, taken from the store.
    failures : list of dict
        Failure records (``key``, ``parameters``, ``error``) of the points without a result.
    wall_time_s : float
        Wall time of the sweep, s.
    workers : int
        Workers of the cluster when the sweep started (0: nothing to compute).
    dashboard : str
        The dashboard line printed.
    files : dict
        ``netcdf``, ``csv``, ``plots`` (list), ``failures``.

    """

    dataset: Any
    points: int
    computed: int
    reused: int
    failures: List[Dict[str, Any]]
    wall_time_s: float
    workers: int = 0
    dashboard: str = ''
    files: Dict[str, Any] = field(default_factory=dict)

    def summary(self) -> Dict[str, Any]:
        """Return the counts, times and files, JSON-ready (``ring_gyro sweep`` prints it)."""
        return {'points': self.points, 'computed': self.computed, 'reused': self.reused,
                'failed': len(self.failures), 'workers': self.workers,
                'wall_time_s': round(self.wall_time_s, 3), 'files': self.files}


def _dashboard_line(client, local: bool, disabled: bool = False) -> str:
    """Return 'dashboard: URL' when it answers, else why there is none."""
    link = getattr(client, 'dashboard_link', None)
    if local and disabled:
        return 'dashboard: none (disabled)'
    if local and importlib.util.find_spec('bokeh') is None:
        return 'dashboard: none (bokeh is not installed: pip install "bokeh>=3.1")'
    services = client.scheduler_info().get('services', {})
    if not link or 'dashboard' not in services:
        # no HTTP service at all: nothing to probe
        return 'dashboard: none (the scheduler serves no dashboard)'
    import urllib.error
    import urllib.request
    try:
        with urllib.request.urlopen(link, timeout=DASHBOARD_PROBE_S) as reply:  # noqa: S310
            ok = reply.status == 200
    except (urllib.error.URLError, OSError, ValueError):
        ok = False
    return f'dashboard: {link}' if ok else f'dashboard: none ({link} does not answer: ' \
                                           f'bokeh missing on the scheduler?)'


def _check_addresses(scheduler: Optional[str], dashboard_address: Optional[str]) -> None:
    """Refuse a scheduler or dashboard address that cannot be one, before anything runs."""
    if scheduler:
        from distributed.comm.addressing import parse_address, parse_host_port
        try:
            scheme, location = parse_address(scheduler)
            if scheme in ('tcp', 'tls', 'ucx', 'ws', 'wss'):
                parse_host_port(location)
        except ValueError as exc:
            raise SweepError(f'--scheduler {scheduler!r}: not a scheduler address '
                             f'(tcp://HOST:PORT): {exc}') from None
    if dashboard_address:
        _, colon, port = dashboard_address.rpartition(':')
        if not (colon and port.isdigit() and int(port) <= 65535):
            raise SweepError(f'--dashboard-address {dashboard_address!r}: expected [HOST]:PORT '
                             f"(:8787; :0 for any free port; '' for none)")


@contextmanager
def _client(scheduler: Optional[str], workers: Optional[int], dashboard_address):
    """Yield ``(client, local)`` connected to ``scheduler`` or to a new LocalCluster."""
    import dask
    from distributed import Client, LocalCluster
    if scheduler:
        try:
            client = Client(scheduler, timeout='30s')
        except (OSError, TimeoutError, ValueError) as exc:
            raise SweepError(f'--scheduler {scheduler}: cannot connect ({exc})') from None
        try:
            yield client, False
        finally:
            client.close()
        return
    n = workers if workers else (os.cpu_count() or 1)
    with dask.config.set(local_cluster_config()):
        with warnings.catch_warnings():
            if dashboard_address is None:
                # no dashboard: the scheduler's plain HTTP server (health, metrics) then tries
                # :8787 all the same and warns when it is taken; it moves to a free port
                warnings.filterwarnings('ignore', message='Port .* is already in use')
            try:
                cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       dashboard_address=dashboard_address,
                                       silence_logs=logging.ERROR,
                                       preload=['ring_gyro_sim.sweep._worker'])
            except (OSError, RuntimeError, ValueError) as exc:
                where = f' (dashboard {dashboard_address})' if dashboard_address else ''
                raise SweepError(f'the local Dask cluster did not start{where}: '
                                 f'{exc}') from None
        try:
            client = Client(cluster)
            try:
                yield client, True
            finally:
                client.close()
        finally:
            cluster.close()


def local_cluster_config() -> Dict[str, Any]:
    """
    Return the Dask settings of the local cluster (:data:`LOCAL_CLUSTER_CONFIG` and the rest).

    Besides :data:`LOCAL_CLUSTER_CONFIG`: the environment the nannies give their workers
    (``distributed.nanny.pre-spawn-environ``) without ``MALLOC_TRIM_THRESHOLD_``, which
    makes glibc map and unmap the chunk-sized arrays of every block (~175 000 page faults
    and ~0.2 s of system time per 25 s point, doc/sweeps.md); the rest of it (one BLAS
    thread) stays.
    """
    import dask
    import distributed  # noqa: F401 - its defaults are in dask.config once imported
    environ = dict(dask.config.get('distributed.nanny.pre-spawn-environ', default={}) or {})
    environ.pop('MALLOC_TRIM_THRESHOLD_', None)
    return dict(LOCAL_CLUSTER_CONFIG, **{'distributed.nanny.pre-spawn-environ': environ})


def _bar(total: int, initial: int, enabled: bool):
    """Return the points' progress bar on stderr: plain lines when it is not a terminal."""
    return Counter(total, initial, unit='point', enabled=enabled, name='sweep')


def run_sweep(spec: SweepSpec, out_dir, scheduler: Optional[str] = None,
              workers: Optional[int] = None, resume: bool = False, progress: bool = True,
              dashboard_address: Optional[str] = ':8787', plots: bool = True,
              log: TextIO = sys.stderr) -> SweepOutcome:
    """
    Run ``spec`` on Dask and write its results into ``out_dir`` (module docstring).

    Parameters
    ----------
    spec : SweepSpec
        The sweep (:func:`ring_gyro_sim.sweep.spec.load_spec`).
    out_dir : str or path-like
        Output directory (created).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://127.0.0.1:8786``); None: a LocalCluster.
    workers : int, optional
        Processes of the LocalCluster (default: the cores); refused with ``scheduler``.
    resume : bool
        Keep the points already stored in ``out_dir`` and compute the rest.
    progress : bool
        Progress bar on stderr (``progress.Counter``: whole lines when it is not a
        terminal).
    dashboard_address : str or None
        Dashboard of the LocalCluster (``':8787'``; ``':0'`` any free port; None: none).
    plots : bool
        Write the PNG maps.
    log : file
        Where the dashboard line, failures and the end line go.

    Returns
    -------
    SweepOutcome

    Raises
    ------
    SweepError
        ``out_dir`` holds points and ``resume`` is False, another sweep is writing into it
        (its lock, :meth:`PointStore.lock`), ``workers`` with ``scheduler``, a scheduler
        or dashboard address that is not one (checked first), the scheduler cannot be
        reached or the local cluster does not start.
    OutputPathError
        ``out_dir`` is a file, cannot be created or is not writable (checked first).
    KeyboardInterrupt
        Ctrl-C: the points stored so far stay (``--resume`` continues).

    """
    extras.require(extras.SWEEP, 'sweep')
    if scheduler and workers:
        raise SweepError('--workers: applies to the local cluster only, not with --scheduler '
                         '(start as many dask workers as you want)')
    if workers is not None and workers < 1:
        raise SweepError(f'--workers: must be >= 1, got {workers!r}')
    _check_addresses(scheduler, dashboard_address)
    wall0 = time.perf_counter()
    out = os.path.abspath(os.fspath(out_dir))
    prepare_directory(out, '--out')
    store = PointStore(out)
    holder = store.lock()
    if holder is not None:
        raise SweepError(f'--out {out}: another sweep is writing into it ({holder}): wait '
                         f'for it to end (then --resume), or choose another directory')
    try:
        return _sweep(spec, store, out, wall0, scheduler, workers, resume, progress,
                      dashboard_address, plots, log)
    finally:
        store.unlock()


def _sweep(spec: SweepSpec, store: PointStore, out: str, wall0: float,
           scheduler: Optional[str], workers: Optional[int], resume: bool, progress: bool,
           dashboard_address, plots: bool, log: TextIO) -> SweepOutcome:
    """Run the sweep into ``store``, whose lock the caller holds (:func:`run_sweep`)."""
    from ring_gyro_sim.sweep import results
    points = spec.points()
    stored, damaged = set(), {}
    for key in store.keys():
        why = store.check(key)
        if why is None:
            stored.add(key)
        else:
            damaged[key] = why
    if (stored or damaged) and not resume:
        raise SweepError(f'--out {out}: holds {len(stored) + len(damaged)} computed points '
                         f'already: --resume keeps them (none is recomputed), or choose '
                         f'another directory')
    with open(os.path.join(out, 'sweep.json'), 'w', encoding='utf-8') as fh:
        json.dump(spec.describe(), fh, indent=1, sort_keys=True, default=str)
    unique = {}
    for p in points:
        unique.setdefault(p.key, p)
    for key in sorted(k for k in damaged if k in unique):
        moved = store.set_aside(key)
        log.write(f'[sweep] {store.path(key)}: damaged, {damaged[key]}: kept as {moved.name}; '
                  f'the point is computed again\n')
    pending = [p for key, p in unique.items() if key not in stored]
    reused = len(unique) - len(pending)
    computed = 0
    n_workers = 0
    dashboard = ''
    if pending:
        try:
            computed, n_workers, dashboard = _run_pending(
                pending, store, out, reused, len(unique), scheduler, workers,
                dashboard_address, progress, log)
        except KeyboardInterrupt:
            done = sum(1 for key in unique if store.has(key))
            log.write(f'\n[sweep] interrupted: {done} of {len(unique)} points stored in '
                      f'{out}/points; `ring_gyro sweep ... --out {out} --resume` computes '
                      f'the rest\n')
            log.flush()
            raise
    records = {p.key: store.read(p.key) for p in points}
    failures_by_key = {k: store.read_failure(k) for k, r in records.items() if r is None}
    failures = []
    for p in unique.values():
        if records[p.key] is None:
            f = failures_by_key.get(p.key) or point_mod.failure_record(p, 'not computed')
            failures.append({'key': p.key, 'parameters': p.parameters(),
                             'error': f.get('error')})
    ds = results.build_dataset(spec, points, records, failures_by_key)
    files: Dict[str, Any] = results.write_results(ds, out)
    fpath = os.path.join(out, 'failures.json')
    with open(fpath, 'w', encoding='utf-8') as fh:
        json.dump(failures, fh, indent=1, sort_keys=True, default=str)
    files['failures'] = fpath
    sheet = None
    if spec.kind == 'gyroscope':  # a device population: its datasheet
        sheet = results.population_datasheet(ds)
        files.update(results.write_datasheet(sheet, out))
    if plots:
        from ring_gyro_sim.analysis import plotting
        files['plots'] = plotting.plot_sweep(ds, spec.plot_axes, spec.metrics, out)
        if sheet is not None:
            files['plots'] += plotting.plot_population(ds, sheet,
                                                       os.path.join(out, 'population.png'))
    outcome = SweepOutcome(dataset=ds, points=len(points), computed=computed, reused=reused,
                           failures=failures, wall_time_s=time.perf_counter() - wall0,
                           workers=n_workers, dashboard=dashboard, files=files)
    log.write(f'[sweep] done in {outcome.wall_time_s:.1f} s: {computed} computed, {reused} '
              f'stored before, {len(failures)} failed -> {out}\n')
    return outcome


def _run_pending(pending, store: PointStore, out: str, reused: int, total: int,
                 scheduler: Optional[str], workers: Optional[int], dashboard_address,
                 progress: bool, log: TextIO):
    """Open the cluster, compute ``pending``; return (computed, workers, dashboard line)."""
    with _client(scheduler, workers, dashboard_address) as (client, local):
        n_workers = len(client.nthreads())
        dashboard = _dashboard_line(client, local, dashboard_address is None)
        if not n_workers:
            log.write(f'[sweep] {scheduler} has no worker yet: the points wait for one\n')
        log.write(f'[sweep] {len(pending)} of {total} points to compute ({reused} stored) '
                  f'on {n_workers} workers ({"local cluster" if local else scheduler}); '
                  f'{dashboard}\n')
        log.flush()
        computed = _compute(client, pending, store, out, reused, total, progress, log)
    return computed, n_workers, dashboard


def _compute(client, pending, store: PointStore, out: str, reused: int, total: int,
             progress: bool, log: TextIO) -> int:
    """Submit ``pending`` and store each record as it comes; return the number computed."""
    from distributed import as_completed
    futures = {}
    setups = {}
    for p in pending:
        try:
            skey = point_mod.setup_key(p)
        except Exception:  # noqa: B902 - no configuration: the point reports why when computed
            setup = None
        else:
            setup = setups.get(skey)
            if setup is None:
                setup = setups[skey] = client.submit(point_mod.setup_task, p,
                                                     key=SETUP_PREFIX + skey, retries=0)
        fut = client.submit(point_mod.compute, p, out, setup, key=TASK_PREFIX + p.key,
                            retries=0)
        futures[fut] = p
    bar = _bar(total, reused, progress)
    computed = 0
    try:
        for fut in as_completed(list(futures)):
            p = futures[fut]
            try:
                record = fut.result()
            except Exception as exc:  # noqa: B902 - a lost task is one failed point
                record = point_mod.failure_record(p, f'{type(exc).__name__}: {exc}')
            if record.get('error') is None:
                computed += 1
                if not store.has(p.key):
                    store.write(record)
            else:
                store.write(record)
                bar.write(f'[sweep] point failed: {describe(p.coords) or p.key} '
                          f'({p.key}): {record["error"]}', file=log)
            bar.update(1)
            fut.release()
    finally:
        bar.close()
    return computed
