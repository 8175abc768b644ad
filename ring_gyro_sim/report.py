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
The reproduction report: every figure of the paper we can regenerate, and the key numbers.

:func:`build_report` runs Case 4 (Fig. 13, one run per Q_1) through the sweep engine, the
same path as ``ring_gyro sweep config/sweep_case4.yaml`` (:func:`run_case4`: a sweep spec,
its points, a Dask ``LocalCluster`` of ``workers`` processes, the point store and results),
then the other jobs of a :class:`ReportPlan` on a pool of processes (both cores by default),
and writes into one directory:

* PNG figures (``fig04_backbones.png``, ``fig05_ritz_orders.png``, ``fig06_nr5_modes.png``,
  ``fig07_spectrogram.png``, ``fig09_frf.png``, ``fig10_case1.png`` ... ``fig13_case4.png``,
  ``fig14_symmetric_rest.png``, ``fig15_symmetric_drive.png``, and
  ``sensitivity_case*_f15798.3.png``: Cases 1-3 at the paper's drive frequency, 9 mHz
  from the fold of our upper branch) and the CSV of every envelope and curve;
* ``summary.json`` (all numbers) and ``summary.md`` (our numbers beside the paper's);
* ``case4_sweep/``: the Case 4 sweep's own output (``results.nc``, ``results.csv``,
  ``points/``, as ``ring_gyro sweep --out``; replaced by each report).

Case 4's points keep their envelopes (``envelopes: all``, :mod:`ring_gyro_sim.sweep.spec`)
and come back as the :class:`~ring_gyro_sim.analysis.cases.CaseResult` of each run
(:func:`ring_gyro_sim.sweep.point.case_result`): the same envelopes and numbers as
:func:`~ring_gyro_sim.analysis.cases.run_case` of the same case gives (tested, bit for bit),
so Fig. 13, the envelope CSVs and the summary rows are made as for the other cases. This is
the one place ``analysis`` uses the sweep layer above it: imported in :func:`run_case4`
only, so importing this module loads no Dask, and a plan without Case 4 needs none.
Case 4 needs the ``sweep`` extra (``dask[distributed]``, ``xarray``, ``netCDF4``).

The harmonic-balance figures (Figs. 4 and 9) come from :mod:`ring_gyro_sim.analysis.hbm`
when it is importable; otherwise the summary says so and the time-domain part still runs.
``quick`` shortens every run (minutes in all): the numbers are then a smoke test and the
final branches are not decided.
"""

from concurrent.futures import as_completed, ProcessPoolExecutor
from dataclasses import dataclass, field, replace
import io
import json
import math
import multiprocessing
from pathlib import Path
import shutil
import sys
import time
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim import extras
from ring_gyro_sim.analysis import cases
from ring_gyro_sim.analysis import envelope as env
from ring_gyro_sim.analysis import hbm, plotting
from ring_gyro_sim.core.errors import RingGyroError
from ring_gyro_sim.core.params import build_config, PAPER_RESONATOR
from ring_gyro_sim.outdir import prepare_directory
from ring_gyro_sim.run import format_number

PAPER = {
    'backbone_f0_hz': 11.2e3,
    'backbone_f_at_6um_hz': 10.6e3,
    'shock_from_rest_gap_fraction': '0.55-0.60',
    'converged_ritz_order': 3,
    'q1_frequency_after_shock_hz': 10.6e3,
    'q1_frequency_late_hz': 11.2e3,
    'q5_burst_time_s': '0.28-0.30',
    'upper_branch_q2_m': 0.39e-6,
    'lower_branch_q2_m': 0.03e-6,
    'case1': 'returns to the upper branch after about 7 s',
    'case2': 'falls to about 0.03 um for about 5 s, then returns to the upper branch',
    'case3': 'jumps to the lower branch and stays',
    'case4': 'low Q_1 ends lower, high Q_1 returns upper',
    'symmetric_rest': 'q2 = 0 for all t',
    'symmetric_drive': 'q2 jumps; q1 -> q3 transfer near t = 0.1 s',
}
"""The paper's numbers (doc/physics.md, "Results reproduced")."""

DIFFERENCES = (
    'Outer voltage: the paper does not give V_o. The exact Fig. 4 fit (10.6 kHz at 6 um) needs '
    '83.5 V, at which the N_R = 3 ring pulls in under the 10 000 g shock (q2 and q3, fed '
    'through the q1^2 terms, add to q1 at theta = 0); with the drive on, 80 V already pulls '
    'in for some shock instants. The default 78 V stays free of contact and puts the '
    'backbone at 10.685 kHz at 6 um. Everything that follows from the softening is shifted '
    'accordingly: the 1theta frequency just after the shock (10.75 instead of 10.6 kHz), the '
    'q5 burst times (internal resonance 2 omega_1 + omega_2 + omega_3 is reached later) and '
    'the time of the q1 -> q3 transfer with symmetric electrodes.',
    'Drive frequency: our upper branch of the 2theta resonance ends at 15 798.29 Hz, 9 mHz '
    "below the paper's 15 798.3 Hz, where a 2 000 g shock knocks q2 down for good (Case 1 "
    'ends on the lower branch: sensitivity runs). The default drive, 15 798.6 Hz, is where '
    "our upper branch has the paper's q2 = 0.39 um; there Cases 1-3 end as in the paper.",
    'Return times (Case 1: 4.2 s instead of about 7 s; Case 2: lower minimum of q2, 0.007 '
    'instead of 0.03 um): they depend on how deep inside the bistable interval the drive '
    "sits and on the decay of q1, both of which differ slightly from the paper's model.",
)
"""Differences from the paper and their causes (doc/calibration.md), for summary.md."""

QUICK_DIFFERENCES_NOTE = (
    'These notes quote the full report (`ring_gyro report` without `--quick`; '
    'doc/paper_reproduction.md), not this run: `--quick` runs a tenth of each case, too short '
    'for the branches, return times and late frequencies they speak of, so its own numbers '
    '(the tables above) differ from them.')
"""Said before :data:`DIFFERENCES` in a ``--quick`` summary.md, whose tables they would
contradict: their numbers are the full run's."""

RIDGE_BAND_HZ = (9.5e3, 12.0e3)
"""Band searched for the 1theta line of the spectrogram, Hz."""
SENSITIVITY_DRIVE_HZ = 15798.3
"""Drive frequency of the sensitivity runs, Hz: the paper's. Our bistable interval is
15 798.29-15 799.47 Hz (``ring_gyro frf``), so there the upper orbit sits 0.01 Hz from its
fold (stable orbit and saddle 0.5 % apart); the default drive, 15 798.6 Hz, is where our
upper branch has the paper's q2 = 0.39 um."""
CASE4_SWEEP_DIR = 'case4_sweep'
"""Subdirectory of the report's Case 4 sweep (a ``ring_gyro sweep --out`` directory)."""
SWEEP_MODULES = extras.SWEEP
"""What the Case 4 sweep imports (setup.py extra ``sweep``)."""


class ReportError(RingGyroError, RuntimeError):
    """The report cannot run (the sweep extra is missing) or a Case 4 point failed."""


@dataclass(frozen=True)
class ReportPlan:
    """
    What :func:`build_report` runs.

    Attributes
    ----------
    drive_cases : tuple of CaseSpec
        Cases 1-3.
    sweep : tuple of CaseSpec
        Case 4 (one per Q_1; cases that differ in Q_1 only): run through the sweep engine
        (:func:`run_case4`), not the job pool.
    ritz : tuple of CaseSpec
        Fig. 5 (N_R = 1..5 from rest); the last one also gives Fig. 7.
    inner : tuple of CaseSpec
        Figs. 14-15.
    backbone_orders : tuple of int
        N_T of the Fig. 4 backbones.
    frf : bool
        Compute the Fig. 9 forced response.
    sensitivity : tuple of CaseSpec
        Cases 1-3 again with the drive inside the bistable interval (see
        :data:`SENSITIVITY_DRIVE_HZ`).
    ritz_rate_hz : float
        Output rate of the N_R runs, Hz (resolves q5 at 59.2 kHz and 3 omega_1).
    quick : bool
        Shortened runs.

    """

    drive_cases: Tuple[cases.CaseSpec, ...]
    sweep: Tuple[cases.CaseSpec, ...]
    ritz: Tuple[cases.CaseSpec, ...]
    inner: Tuple[cases.CaseSpec, ...]
    sensitivity: Tuple[cases.CaseSpec, ...] = ()
    backbone_orders: Tuple[int, ...] = (4, 5, 6, 7, 8, 9, 10)
    frf: bool = True
    ritz_rate_hz: float = 200000.0
    quick: bool = False
    base: Dict[str, Any] = field(default_factory=dict)


def make_plan(quick: bool = False, base: Optional[Mapping[str, Any]] = None) -> ReportPlan:
    """
    Return the full plan (durations that decide the branches) or the quick one.

    Full: Cases 1-3 for 24, 30 and 20 s (and again at :data:`SENSITIVITY_DRIVE_HZ`), Case 4
    with six Q_1 for 30 s (a sweep, :func:`run_case4`), N_R = 1..5 for 8 s, symmetric
    electrodes 2 s (rest) and 20 s (drive). Quick: a tenth of the case durations, three Q_1
    for 2 s, N_R runs of 0.3 s, backbones for N_T = 4 and 10 only.
    """
    base = {**PAPER_RESONATOR, **dict(base or {})}  # the paper's device, whatever the defaults
    scale = 0.1 if quick else 1.0
    drive = tuple(cases.paper_cases(scale).values())
    if quick:
        sweep = cases.case4_specs((5000.0, 40000.0, 180000.0), duration_s=2.0)
        ritz = cases.ritz_order_specs(duration_s=0.3, keep_raw_s=0.3)
    else:
        sweep = cases.case4_specs(duration_s=30.0)
        ritz = cases.ritz_order_specs(duration_s=8.0, keep_raw_s=8.0)
    ritz = [r if r.name == 'nr5' else replace(r, keep_raw_s=0.0) for r in ritz]
    inner = tuple(cases.inner_electrode_cases(base, scale).values())
    sens = tuple(replace(c, name=f'{c.name}_f{SENSITIVITY_DRIVE_HZ:g}',
                         description=f'{c.description}, drive {SENSITIVITY_DRIVE_HZ:g} Hz',
                         overrides=c.overrides + (('drive.frequency', SENSITIVITY_DRIVE_HZ),))
                 for c in drive)
    return ReportPlan(drive_cases=drive, sweep=tuple(sweep), ritz=tuple(ritz), inner=inner,
                      sensitivity=sens,
                      backbone_orders=(4, 10) if quick else (4, 5, 6, 7, 8, 9, 10),
                      quick=quick, base=base)


def _spectral_numbers(result: cases.CaseResult) -> Dict[str, Any]:
    """Spectrogram of q1 (Fig. 7) and its 1theta ridge, computed where the raw data are."""
    t, q1 = result.raw_t, result.raw_q[:, 0]
    rate = result.sample_rate_hz
    spec = env.spectrogram(q1, rate, segment_s=10e-3, overlap=0.5, t0_s=float(t[0]))
    keep = spec.f <= min(70e3, 0.5 * rate)
    spec = env.Spectrogram(t=spec.t, f=spec.f[keep], power=spec.power[keep].astype(np.float32))
    ridge = spec.ridge(RIDGE_BAND_HZ)
    inst = env.instantaneous_frequency(q1[:int(0.02 * rate)], rate, band_hz=RIDGE_BAND_HZ)
    n = int(0.002 * rate)
    out = {'q1_frequency_first_segment_hz': float(ridge[0]),
           'q1_frequency_last_segment_hz': float(ridge[-1]),
           'q1_frequency_last_segment_time_s': float(spec.t[-1]),
           'q1_instantaneous_frequency_2_to_18ms_hz': float(np.mean(inst[n:-n]))}
    return {'spectrogram': spec, 'ridge_hz': ridge, 'numbers': out}


def _job(job):
    """Run one report job in a worker process; returns ``(key, payload, wall s)``."""
    kind, key, args = job
    wall0 = time.perf_counter()
    if kind == 'case':
        spec, base, rate = args
        result = cases.run_case(spec, base, output_rate_hz=rate)
        extra = None
        if result.raw_q is not None and result.raw_q.shape[0] > 100:
            extra = _spectral_numbers(result)
        result.raw_t = result.raw_q = None
        payload = (result, extra)
    elif kind == 'backbone':
        base, order = args
        payload = hbm.backbone(build_config(base), mode=1, taylor_terms=order)
    elif kind == 'frf':
        payload = hbm.frf(build_config(args), mode=2)
    else:
        raise ValueError(f'job kind: unknown {kind!r}')
    return key, payload, time.perf_counter() - wall0


def _cost(job) -> float:
    kind, _, args = job
    if kind != 'case':
        return 10.0
    spec = args[0]
    factor = {'nr4': 4.0, 'nr5': 6.0}.get(spec.name, 1.0)
    return spec.duration_s * factor * 3.0


def plan_jobs(plan: ReportPlan) -> List[tuple]:
    """Every job of ``plan`` for the pool, the longest first; Case 4 is not one (a sweep)."""
    jobs = []
    rate = cases.DEFAULT_OUTPUT_RATE_HZ
    for spec in plan.drive_cases + plan.inner + plan.sensitivity:
        jobs.append(('case', spec.name, (spec, plan.base, rate)))
    for spec in plan.ritz:
        jobs.append(('case', spec.name, (spec, plan.base, plan.ritz_rate_hz)))
    for order in plan.backbone_orders:
        jobs.append(('backbone', f'backbone_nt{order}', (plan.base, order)))
    if plan.frf:
        jobs.append(('frf', 'frf', plan.base))
    return sorted(jobs, key=_cost, reverse=True)


def run_jobs(jobs: Sequence[tuple], workers: int = 2, progress: bool = True
             ) -> Dict[str, Any]:
    """Run ``jobs`` (``plan_jobs``) on ``workers`` spawned processes; ``{key: payload}``."""
    out: Dict[str, Any] = {}
    walls: Dict[str, float] = {}
    t0 = time.perf_counter()

    def note(key, wall):
        walls[key] = wall
        if progress:
            sys.stderr.write(f'[report] {len(out)}/{len(jobs)} done: {key} ({wall:.1f} s, '
                             f'{time.perf_counter() - t0:.0f} s elapsed)\n')
            sys.stderr.flush()

    if workers <= 1:
        for job in jobs:
            key, payload, wall = _job(job)
            out[key] = payload
            note(key, wall)
    else:
        ctx = multiprocessing.get_context('spawn')
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            futures = [pool.submit(_job, job) for job in jobs]
            for fut in as_completed(futures):
                key, payload, wall = fut.result()
                out[key] = payload
                note(key, wall)
    out['_walls'] = walls
    return out


def case4_sweep_mapping(specs: Sequence[cases.CaseSpec],
                        output_rate_hz: float = cases.DEFAULT_OUTPUT_RATE_HZ,
                        window_s: float = env.DEFAULT_WINDOW_S) -> Dict[str, Any]:
    """
    Return Case 4 as a sweep spec mapping (:func:`ring_gyro_sim.sweep.parse_spec`).

    One axis, ``modes.quality_factors[0]``, over the Q_1 of ``specs`` (in their order); the
    shock, start branch, duration and overrides, which the cases share, under ``set``;
    ``envelopes: all`` (each point comes back as its ``CaseResult``). The same points as
    ``config/sweep_case4.yaml`` on the defaults, but for the envelopes they keep.

    Raises
    ------
    ValueError
        No case, a case without its own Q_1, cases that differ in more than Q_1, or one that
        keeps raw samples (a sweep point keeps none).

    """
    if not specs:
        raise ValueError('Case 4: no case')
    first = specs[0]

    def rest(s: cases.CaseSpec) -> cases.CaseSpec:
        return replace(s, name='', description='', q1_quality=None)

    if any(s.q1_quality is None for s in specs):
        raise ValueError('Case 4: every case needs its Q_1 (q1_quality)')
    if any(rest(s) != rest(first) for s in specs[1:]):
        raise ValueError('Case 4: the cases must differ in Q_1 only')
    if first.keep_raw_s:
        raise ValueError('Case 4: keep_raw_s: a sweep point keeps no raw samples')
    fixed: Dict[str, Any] = dict(first.overrides)
    fixed.update({'drive.start_on': first.start_on, 'shock.peak_g': float(first.shock_g),
                  'shock.phase': float(first.shock_phase),
                  'shock.angle_deg': float(first.shock_angle_deg)})
    return {'duration': float(first.duration_s), 'output_rate': float(output_rate_hz),
            'envelope_window': float(window_s), 'set': fixed,
            'axes': {'modes.quality_factors[0]': [float(s.q1_quality) for s in specs]},
            'envelopes': 'all'}


def _check_sweep_extra() -> None:
    """Raise ``MissingDependencyError`` before anything runs when the sweep extra is missing."""
    extras.require(SWEEP_MODULES, 'the report (its Case 4 runs through the sweep engine)')


def run_case4(plan: ReportPlan, out_dir, workers: int = 2, progress: bool = True
              ) -> Tuple[Dict[str, cases.CaseResult], Dict[str, Any]]:
    """
    Run Case 4 (``plan.sweep``) through the sweep engine; its results and what ran.

    :func:`case4_sweep_mapping` on ``plan.base`` is parsed as any sweep spec, run by
    :func:`ring_gyro_sim.sweep.run_sweep` on a local Dask cluster of ``workers`` processes
    (no dashboard) into ``out_dir/case4_sweep`` (removed first: the report recomputes), and
    each point's stored record is given back as the ``CaseResult`` of its case.

    Parameters
    ----------
    plan : ReportPlan
        The plan (``sweep`` and ``base`` are used).
    out_dir : str or path-like
        The report's directory.
    workers : int
        Processes of the local cluster.
    progress : bool
        Progress bar and the sweep's lines on stderr.

    Returns
    -------
    (dict, dict)
        ``{case name: CaseResult}`` in the order of ``plan.sweep``, and ``case4_sweep`` of
        ``summary.json``: the sweep directory, each case's point key and wall time (s), the
        points computed, the workers and the sweep's wall time (s).

    Raises
    ------
    ReportError
        A point failed (its parameters and error are named).

    """
    from ring_gyro_sim.sweep import parse_spec, run_sweep
    from ring_gyro_sim.sweep.point import case_result
    from ring_gyro_sim.sweep.store import PointStore
    specs = list(plan.sweep)
    spec = parse_spec(case4_sweep_mapping(specs), source="'ring_gyro report: Case 4'",
                      base_params=plan.base)
    directory = Path(out_dir) / CASE4_SWEEP_DIR
    if directory.exists():
        shutil.rmtree(directory)
    outcome = run_sweep(spec, directory, workers=max(1, int(workers)), progress=progress,
                        dashboard_address=None, plots=False,
                        log=sys.stderr if progress else io.StringIO())
    if outcome.failures:
        raise ReportError('Case 4: ' + '; '.join(
            f"{f['parameters']['coords']}: {f['error']}" for f in outcome.failures))
    store = PointStore(directory, create=False)
    results: Dict[str, cases.CaseResult] = {}
    keys: Dict[str, str] = {}
    walls: Dict[str, float] = {}
    for case, point in zip(specs, spec.points()):
        assert dict(point.coords)['modes.quality_factors[0]'] == case.q1_quality
        record = store.read(point.key)
        results[case.name] = case_result(record, case)
        keys[case.name] = point.key
        walls[case.name] = record['wall_time_s']
    info = {'directory': str(directory), 'point_keys': keys, 'point_wall_s': walls,
            'computed': outcome.computed, 'workers': outcome.workers,
            'wall_time_s': outcome.wall_time_s}
    return results, info


def _ritz_numbers(results: Sequence[cases.CaseResult]) -> Dict[str, Any]:
    """N_R convergence (Fig. 5) and the q5 burst (Fig. 6) from the N_R runs."""
    by = {r.spec.name: r for r in results}
    out: Dict[str, Any] = {}
    ref = by.get('nr5')
    for name, r in sorted(by.items()):
        out[f'{name}_peak_w0_fraction'] = r.numbers.get('peak_w0_fraction')
        out[f'{name}_peak_wmax_fraction'] = r.numbers.get('peak_wmax_fraction')
        out[f'{name}_peak_q1_fraction'] = r.numbers.get('peak_q1_m', math.nan) / r.gap_m
        out[f'{name}_contact'] = r.contact
        if ref is not None and r is not ref:
            a, b = r.envelope.channel('w0'), ref.envelope.channel('w0')
            m = min(a.size, b.size)
            diff = np.mean(np.abs(a[:m] - b[:m])) / max(np.mean(b[:m]), 1e-30)
            out[f'{name}_vs_nr5_mean_rel_diff'] = float(diff)
    if ref is not None and 'q5' in ref.envelope.names:
        found = bursts(ref.envelope.t, ref.envelope.channel('q5'))
        out['q5_bursts'] = [[round(t, 4), m] for t, m in found]
        if found:
            out['q5_first_burst_time_s'], out['q5_first_burst_m'] = found[0]
            out['q5_largest_burst_time_s'], out['q5_largest_burst_m'] = max(
                found, key=lambda b: b[1])
    return out


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    """Return the moving average over ``n`` windows (same length, shorter at the ends)."""
    n = max(1, int(n))
    kernel = np.ones(n)
    return np.convolve(x, kernel, 'same') / np.convolve(np.ones_like(x), kernel, 'same')


def bursts(t, x, smooth_s: float = 0.02, rise: float = 1.5) -> List[Tuple[float, float]]:
    """
    Find local maxima of a smoothed envelope that rise ``rise`` times over the last minimum.

    Parameters
    ----------
    t : array_like, shape (W,)
        Envelope times, s (uniform).
    x : array_like, shape (W,)
        Envelope, m.
    smooth_s : float
        Moving-average length, s.
    rise : float
        Ratio of the maximum to the lowest value since the previous burst (or the start).

    Returns
    -------
    list of (float, float)
        ``(time s, smoothed envelope m)`` of each burst, in time order.

    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.size < 3:
        return []
    y = _smooth(x, round(smooth_s / (t[1] - t[0])))
    out = []
    low = y[0]
    for k in range(1, y.size - 1):
        low = min(low, y[k])
        if y[k] >= y[k - 1] and y[k] > y[k + 1] and y[k] >= rise * low:
            out.append((float(t[k]), float(y[k])))
            low = y[k]
    return out


def _exchange_numbers(prefix: str, r: cases.CaseResult) -> Dict[str, Any]:
    """Steepest fall of q1 (20 ms smoothed) in the first 2 s and the q3 envelope then."""
    e = r.envelope
    sel = e.t < 2.0
    if np.count_nonzero(sel) < 10 or 'q3' not in e.names:
        return {}
    n = max(1, round(0.02 / e.window_s))
    q1 = _smooth(e.channel('q1')[sel], n)
    q3 = _smooth(e.channel('q3')[sel], n)
    k = int(np.argmin(np.gradient(q1)))
    return {f'{prefix}_q1_steepest_fall_time_s': float(e.t[sel][k]),
            f'{prefix}_q1_at_fall_m': float(q1[k]), f'{prefix}_q3_at_fall_m': float(q3[k]),
            f'{prefix}_q3_max_first_2s_m': float(np.max(q3)),
            f'{prefix}_q3_max_time_s': float(e.t[sel][int(np.argmax(q3))])}


def _inner_numbers(results: Dict[str, cases.CaseResult]) -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    rest = results.get('symmetric_rest')
    if rest is not None:
        out['symmetric_rest_max_abs_q2_m'] = rest.numbers.get('peak_q2_m')
        out['symmetric_rest_peak_q1_m'] = rest.numbers.get('peak_q1_m')
        out.update(_exchange_numbers('symmetric_rest', rest))
    drive = results.get('symmetric_drive')
    if drive is not None:
        out.update(_exchange_numbers('symmetric_drive', drive))
    return out


def _fmt(v, scale=1.0, unit='', digits=4) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return '-'
    if isinstance(v, (bool, str)):
        return str(v)
    return f'{v * scale:.{digits}g}{unit}'


def _markdown(summary: Dict[str, Any]) -> str:
    """Write the side-by-side tables of ``summary.md``."""
    lines = ['# ring_gyro_sim: reproduction report', '',
             f"mode: {'quick (runs too short to decide branches)' if summary['quick'] else 'full'}"
             f", wall time {summary['wall_time_s']:.0f} s, workers {summary['workers']}", '']
    if summary.get('hbm_note'):
        lines += [f"> {summary['hbm_note']}", '']
    hb = summary.get('hbm', {})
    lines += ['## Nonlinear mode and forced response (Figs. 4, 9)', '',
              '| quantity | paper | ours |', '|---|---|---|']
    for key, val in sorted(hb.get('backbone_f_at_6um_hz', {}).items()):
        lines.append(f'| backbone f at 6 um, {key} | 10.6 kHz (N_T = 10) | '
                     f'{_fmt(val, 1e-3, " kHz")} |')
    if 'frf_branches_at_drive' in hb:
        br = hb['frf_branches_at_drive']
        lines.append(f"| FRF branches at the drive, {summary['drive_frequency_hz']:.1f} Hz (um, "
                     's: stable) | 0.39 (top), 0.03 (bottom) at 15 798.3 Hz '
                     '| ' + ', '.join(f'{format_number(a, 1e6)} ({"s" if s else "u"})'
                                      for a, s in br)
                     + ' |')
        lines.append(f'| FRF folds | bistable near 15.8 kHz | '
                     f"{', '.join(f'{f:.2f} Hz' for f in hb['frf_folds_hz'])} |")
        if hb['frf_folds_hz']:
            gap = summary['drive_frequency_hz'] - min(hb['frf_folds_hz'])
            lines.append(f'| drive - lower fold | (marker near the peak) | {gap:.3f} Hz |')
    r = summary.get('ritz', {})
    lines += ['', '## Shock from rest (Figs. 5-7)', '', '| quantity | paper | ours |',
              '|---|---|---|',
              f'| peak q1/d_g, 10 000 g, N_R = 3 | 0.55-0.60 | '
              f"{_fmt(r.get('nr3_peak_q1_fraction'), digits=3)} |",
              f'| peak w(0)/d_g (sum of q_n), N_R = 3 | 0.55-0.60 | '
              f"{_fmt(r.get('nr3_peak_w0_fraction'), digits=3)} |",
              f'| peak max_theta w / d_g, N_R = 3 | 0.55-0.60 | '
              f"{_fmt(r.get('nr3_peak_wmax_fraction'), digits=3)} |"]
    for k in (1, 2, 3, 4):
        lines.append(f'| w(0) envelope, N_R = {k} vs 5 (mean rel. diff) | converged at 3 | '
                     f"{_fmt(r.get(f'nr{k}_vs_nr5_mean_rel_diff'), digits=3)} |")
    lines += [f'| q1 frequency just after the shock | 10.6 kHz | '
              f"{_fmt(r.get('q1_frequency_first_segment_hz'), 1e-3, ' kHz')} |",
              f"| q1 frequency at t = {_fmt(r.get('q1_frequency_last_segment_time_s'), digits=3)}"
              f' s | rises to 11.2 kHz | '
              f"{_fmt(r.get('q1_frequency_last_segment_hz'), 1e-3, ' kHz')} |",
              f'| first q5 burst (N_R = 5) | t = 0.28-0.30 s | t = '
              f"{_fmt(r.get('q5_first_burst_time_s'), digits=3)} s, "
              f"{_fmt(r.get('q5_first_burst_m'), 1e6, ' um', 3)} |",
              f'| largest q5 burst (N_R = 5) | (one burst) | t = '
              f"{_fmt(r.get('q5_largest_burst_time_s'), digits=3)} s, "
              f"{_fmt(r.get('q5_largest_burst_m'), 1e6, ' um', 3)} |"]
    lines += ['', '## Drive + shock (Figs. 10-13, 15)', '',
              '| case | paper | q2 after shock (um) | min q2 (um) at (s) | final q2 (um) | '
              'final branch | return (s) | settled | min gap / d_g | contact |',
              '|---|---|---|---|---|---|---|---|---|---|']
    for row in summary['cases']:
        if row.get('upper_branch_m') is None and row['name'] != 'symmetric_rest':
            continue
        lines.append(
            f"| {row['description']} | {row['paper']} | {_fmt(row.get('q2_after_shock_m'), 1e6)}"
            f" | {_fmt(row.get('min_q2_m'), 1e6)} at {_fmt(row.get('min_q2_time_s'), digits=3)}"
            f" | {_fmt(row.get('final_q2_m'), 1e6)} | {row.get('final_branch')} | "
            f"{_fmt(row.get('return_time_s'), digits=3)} | {row.get('settled')} | "
            f"{_fmt(row.get('min_gap_fraction'), digits=3)} | {row.get('contact')} |")
    inner = summary.get('inner', {})
    if summary.get('case4_sweep'):
        sw = summary['case4_sweep']
        lines += ['', f'Case 4 ran through the sweep engine (`ring_gyro sweep`, '
                      f"{len(sw['point_keys'])} points on {sw['workers']} workers): "
                      f'`{CASE4_SWEEP_DIR}/results.nc`.']
    lines += ['', '## Inner + outer electrodes (Figs. 14-15)', '',
              '| quantity | paper | ours |', '|---|---|---|',
              f'| max q2, symmetric, from rest | 0 | '
              f"{_fmt(inner.get('symmetric_rest_max_abs_q2_m'), 1e6, ' um')} |",
              f'| q1 -> q3 transfer, symmetric + drive: steepest fall of q1 | near t = 0.1 s | '
              f"t = {_fmt(inner.get('symmetric_drive_q1_steepest_fall_time_s'), digits=3)} s "
              f"(q1 {_fmt(inner.get('symmetric_drive_q1_at_fall_m'), 1e6, ' um', 3)}, "
              f"q3 {_fmt(inner.get('symmetric_drive_q3_at_fall_m'), 1e6, ' um', 3)}) |",
              f'| largest q3 in the first 2 s, symmetric + drive | sudden increase | '
              f"{_fmt(inner.get('symmetric_drive_q3_max_first_2s_m'), 1e6, ' um', 3)} at "
              f"t = {_fmt(inner.get('symmetric_drive_q3_max_time_s'), digits=3)} s |", '']
    lines += ['Definitions: envelopes are the largest |q| in 1 ms windows (sine-fit refined); '
              'final values are the mean envelope over the last 0.2 s; the branch threshold is '
              'the geometric mean of the upper and lower branch amplitudes; "return" is the '
              'end of the last window below it. See ring_gyro_sim/analysis/cases.py.', '']
    lines += ['## Where we differ from the paper, and why', '']
    if summary['quick']:
        lines += [QUICK_DIFFERENCES_NOTE, '']
    lines += [f'- {d}' for d in DIFFERENCES]
    lines.append('')
    return '\n'.join(lines)


def build_report(out_dir, quick: bool = False, workers: int = 2, progress: bool = True,
                 base: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
    """
    Run the plan and write the figures, CSVs, ``summary.json`` and ``summary.md``.

    Case 4 runs first, through the sweep engine (:func:`run_case4`, a local Dask cluster
    into ``out_dir/case4_sweep``), then the other jobs on the pool (:func:`run_jobs`).

    Parameters
    ----------
    out_dir : str or path-like
        Output directory (created).
    quick : bool
        Short runs (a few minutes in all) instead of the full plan.
    workers : int
        Worker processes of the pool and of the Case 4 cluster (default 2, the machine's
        cores; one at a time).
    progress : bool
        Progress lines on stderr.
    base : mapping, optional
        Flat parameters under every run, laid over the paper's resonator
        (``core.params.PAPER_RESONATOR``; default: the resonator itself).

    Returns
    -------
    dict
        The content of ``summary.json``.

    Raises
    ------
    MissingDependencyError
        The sweep extra is missing (said before anything runs).
    ReportError
        A Case 4 point failed.
    OutputPathError
        ``out_dir`` is a file, cannot be created or is not writable (checked first).

    """
    out = Path(out_dir)
    wall0 = time.perf_counter()
    plan = make_plan(quick, base)
    if plan.sweep:
        _check_sweep_extra()
    prepare_directory(out)
    jobs = plan_jobs(plan)
    if progress:
        first = f'Case 4 ({len(plan.sweep)} points) through the sweep engine, then ' \
            if plan.sweep else ''
        sys.stderr.write(f'[report] {first}{len(jobs)} jobs on {workers} workers '
                         f"({'quick' if quick else 'full'}) -> {out}\n")
    case4: Dict[str, cases.CaseResult] = {}
    case4_info = None
    if plan.sweep:
        case4, case4_info = run_case4(plan, out, workers, progress)
    done = run_jobs(jobs, workers, progress)
    walls = done.pop('_walls')
    for name, result in case4.items():
        done[name] = (result, None)
        walls[name] = case4_info['point_wall_s'][name]
    summary: Dict[str, Any] = {'quick': quick, 'workers': workers, 'paper': PAPER,
                               'job_wall_s': walls,
                               'drive_frequency_hz': build_config(plan.base).drive.frequency,
                               'base_parameters': plan.base, 'case4_sweep': case4_info}
    # --- harmonic balance (Figs. 4, 9)
    hb: Dict[str, Any] = {}
    f6 = {}
    backbones = [done[f'backbone_nt{o}'] for o in plan.backbone_orders]
    for b in backbones:
        b.to_csv(out / f'fig04_backbone_nt{b.taylor_terms}.csv')
        try:
            f6[f'N_T={b.taylor_terms}'] = b.frequency_at(6e-6)
        except ValueError:
            f6[f'N_T={b.taylor_terms}'] = math.nan
    hb['backbone_f_at_6um_hz'] = f6
    if backbones:
        hb['backbone_f0_hz'] = float(backbones[-1].frequency_hz[0])
        _plot_backbones(backbones, out / 'fig04_backbones.png')
    if plan.frf:
        resp = done['frf']
        resp.to_csv(out / 'fig09_frf.csv')
        resp.plot(out / 'fig09_frf.png', marker_hz=build_config(plan.base).drive.frequency)
        hb['frf_folds_hz'] = list(resp.fold_frequencies_hz)
        hb['frf_branches_at_drive'] = resp.branches_at(
            build_config(plan.base).drive.frequency)
    summary['hbm'] = hb
    # --- time-domain cases
    results: Dict[str, cases.CaseResult] = {}
    spectral = None
    for spec in plan.drive_cases + plan.sweep + plan.inner + plan.sensitivity + plan.ritz:
        result, extra = done[spec.name]
        results[spec.name] = result
        result.to_csv(out / f'envelope_{spec.name}.csv')
        if extra is not None:
            spectral = extra
    for spec in plan.sensitivity:
        results[spec.name].plot(out / f'sensitivity_{spec.name}.png')
    figs = {'case1': 'fig10_case1.png', 'case2': 'fig11_case2.png',
            'case3': 'fig12_case3.png', 'symmetric_rest': 'fig14_symmetric_rest.png',
            'symmetric_drive': 'fig15_symmetric_drive.png'}
    for name, fname in figs.items():
        if name in results:
            results[name].plot(out / fname)
    plotting.plot_q2_sweep([results[s.name] for s in plan.sweep], out / 'fig13_case4.png')
    ritz_results = [results[s.name] for s in plan.ritz]
    if ritz_results:
        plotting.plot_ritz_orders(ritz_results, out / 'fig05_ritz_orders.png')
    if 'nr5' in results:
        results['nr5'].plot(out / 'fig06_nr5_modes.png',
                            title='N_R = 5, 10 000 g from rest: modal envelopes (Fig. 6)')
    ritz = _ritz_numbers(ritz_results)
    if spectral is not None:
        ritz.update(spectral['numbers'])
        plotting.plot_spectrogram(spectral['spectrogram'], out / 'fig07_spectrogram.png',
                                  ridge_t=spectral['spectrogram'].t,
                                  ridge_hz=spectral['ridge_hz'])
    summary['ritz'] = ritz
    summary['inner'] = _inner_numbers(results)
    summary['cases'] = [r.summary() for r in results.values()]
    summary['wall_time_s'] = time.perf_counter() - wall0
    summary = _clean(summary)
    (out / 'summary.json').write_text(json.dumps(summary, indent=1, sort_keys=True))
    (out / 'summary.md').write_text(_markdown(summary))
    if progress:
        sys.stderr.write(f"[report] done in {summary['wall_time_s']:.0f} s: {out}\n")
    return summary


def _plot_backbones(backbones, path) -> None:
    """Fig. 4: the 1theta backbones for several N_T on one axis (skipped without matplotlib)."""
    plotting.plot_backbones(backbones, path)


def _clean(v):
    """JSON-ready copy: nan/inf -> None, numpy scalars -> Python, tuples -> lists."""
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
