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
Benchmark of the simulator (issue 3 item 5, issue 5 item 6): ``make bench``.

Everything is measured in one process on one machine, and every speed is also given as a
ratio against a reference run made in the same process, so the numbers can be compared
between machines:

1. numba compile / cache-load time of the kernels (first Simulator construction, first
   ``set_state`` and first 10 ms ``advance``), in this process and, in child processes, from
   an empty numba cache (a full compile) and from the cache that compile left;
2. real-time factor (simulated s per wall s, one core) of (a) the paper configuration (N_R = 3,
   N_T = 10, 200 kHz output, the 2theta drive on its upper branch, a 10 000 g shock at 10 ms)
   for every integrator method, and of (b) N_R = 5 with the sine companions; steps per
   second, ns per step and ns per force evaluation;
3. speed-up over scipy ``solve_ivp`` (DOP853, Python right-hand side) on problem (a) at
   matched accuracy: the loosest rtol whose error against a tight DOP853 reference is no
   larger than the simulator's;
4. recording overhead (issue 5): (a) through :func:`ring_gyro_sim.offline.run_offline` with
   and without an MCAP file, and the file's bytes per simulated second.

Targets from the issues are printed next to the results; a missed target is reported with
what limits it, never hidden. Progress goes to stderr, results to stdout; ``--json FILE``
also writes the numbers, ``--quick`` shortens every run (a smoke test of under a minute).
"""

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from typing import Any, Dict, List, Optional, Tuple

import numba
from numba import njit
import numpy as np
from ring_gyro_sim import offline
from ring_gyro_sim.analysis.nnm import drive_initial_state
from ring_gyro_sim.core import forces, kernels
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.params import build_config, SimConfig, STANDARD_GRAVITY
from ring_gyro_sim.core.simulator import Simulator
from ring_gyro_sim.run import Run
import scipy
from scipy.integrate import solve_ivp

SHOCK_G = 10_000.0
SHOCK_TIME_S = 0.01
CHUNK_S = 0.01
"""The simulator is advanced in 10 ms chunks, as the node publishes its blocks."""

TARGET_RTF_PAPER = 10.0
TARGET_RTF_FIVE_MODES = 1.0
TARGET_SPEEDUP = 200.0
TARGET_RTF_RECORDING = 1.0
"""Issue 5: recording must not pull the paper configuration below real time."""

REFERENCE_RTOL = 1e-10
REFERENCE_ATOL = 1e-16
SCIPY_ATOL = 1e-16
"""Absolute tolerance of the scipy runs, m: tiny, so that rtol alone sets their accuracy."""

# (b): Table 1 of the paper. With 8 legs only the 4theta pair splits (2n / N_l integer):
# 36.3 kHz (Q 80 000) is the cos(4 theta) mode aligned with alpha = 0, 25.7 kHz (Q 180 000)
# its sine companion; every other companion has the frequency and Q of its cos mode.
FIVE_MODES = {
    'modes.frequencies': [11200.0, 15800.0, 22000.0, 36300.0, 59200.0],
    'modes.quality_factors': [120000.0, 64700.0, 170000.0, 80000.0, 50000.0],
    'modes.companions': True,
    'modes.companion_frequencies': [11200.0, 15800.0, 22000.0, 25700.0, 59200.0],
    'modes.companion_quality_factors': [120000.0, 64700.0, 170000.0, 180000.0, 50000.0],
}

# Run in child processes: the first construction + set_state + 10 ms advance, timed.
COLD_START_CODE = """
import json, time
t0 = time.perf_counter()
import numpy as np
from ring_gyro_sim.core import kernels
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.core.simulator import Simulator
t1 = time.perf_counter()
sim = Simulator(build_config({}))
sim.set_state(np.zeros(3), np.zeros(3))
sim.advance(0.01)
t2 = time.perf_counter()
hits = sum(sum(f.stats.cache_hits.values()) for f in (kernels.run_samples, kernels.nl_accel,
                                                       kernels.output_channels))
misses = sum(sum(f.stats.cache_misses.values()) for f in (kernels.run_samples, kernels.nl_accel,
                                                           kernels.output_channels))
print(json.dumps({'import_s': t1 - t0, 'first_run_s': t2 - t1, 'cache_hits': hits,
                  'cache_misses': misses}))
"""


def log(text: str) -> None:
    """Write a progress line to stderr."""
    sys.stderr.write(f'.. {text}\n')
    sys.stderr.flush()


def paper_values(**extra: Any) -> Dict[str, Any]:
    """Flat parameters of problem (a): defaults, drive on, a 10 000 g shock at 10 ms."""
    values: Dict[str, Any] = {'scenario.shock_times': [SHOCK_TIME_S],
                              'scenario.shock_peaks': [SHOCK_G * STANDARD_GRAVITY]}
    values.update(extra)
    return values


def evaluations_per_step(method: str) -> int:
    """Force evaluations per step of a splitting method (one per drift, the last kick FSAL)."""
    a, _ = kernels.splitting_coefficients(method)
    return int(a.size)


def cache_state() -> str:
    """Whether the kernels came from numba's disk cache in this process."""
    hits = misses = 0
    for f in (kernels.run_samples, kernels.nl_accel, kernels.output_channels):
        hits += sum(f.stats.cache_hits.values())
        misses += sum(f.stats.cache_misses.values())
    if misses == 0 and hits > 0:
        return f'loaded from the disk cache ({hits} kernels, no compile)'
    if hits == 0:
        return f'compiled in this process ({misses} cache misses: cache absent or stale)'
    return f'mixed: {hits} loaded from the disk cache, {misses} compiled'


def first_run(config: SimConfig) -> Tuple[float, float, float]:
    """Wall time (s) of construction, set_state and the first 10 ms chunk."""
    t0 = time.perf_counter()
    sim = Simulator(config)
    t1 = time.perf_counter()
    sim.set_state(np.zeros(sim.model.n_coordinates), np.zeros(sim.model.n_coordinates))
    t2 = time.perf_counter()
    sim.advance(CHUNK_S)
    t3 = time.perf_counter()
    return t1 - t0, t2 - t1, t3 - t2


def child_cold_start(cache_dir: Optional[str]) -> Optional[Dict[str, float]]:
    """Run :data:`COLD_START_CODE` in a fresh interpreter (optionally with its own cache)."""
    env = dict(os.environ)
    if cache_dir is not None:
        env['NUMBA_CACHE_DIR'] = cache_dir
    result = subprocess.run([sys.executable, '-c', COLD_START_CODE], env=env,
                            capture_output=True, text=True, check=False, timeout=300)
    if result.returncode != 0:
        log(f'child process failed: {result.stderr.strip()[-500:]}')
        return None
    return json.loads(result.stdout.strip().splitlines()[-1])


def bench_compile(children: bool) -> Dict[str, Any]:
    """Section 1: JIT compile / cache-load time, measured before any timed run."""
    log('compile: first Simulator construction + set_state + 10 ms advance in this process')
    config = build_config(paper_values())
    first = first_run(config)
    state = cache_state()
    steady = min((first_run(config) for _ in range(3)), key=sum)
    out: Dict[str, Any] = {
        'this_process_first_s': sum(first), 'steady_same_work_s': sum(steady),
        'this_process_overhead_s': sum(first) - sum(steady),
        'first_construct_s': first[0], 'first_set_state_s': first[1],
        'first_advance_s': first[2], 'cache': state}
    if children:
        with tempfile.TemporaryDirectory(prefix='ring_gyro_numba_') as cache_dir:
            log('compile: fresh interpreter with an empty numba cache (full compile)')
            out['empty_cache_child'] = child_cold_start(cache_dir)
            log('compile: fresh interpreter loading the cache the compile just wrote')
            out['warm_cache_child'] = child_cold_start(cache_dir)
    return out


def run_chunks(run: Run, duration_s: float) -> Tuple[float, float]:
    """Advance ``run`` in 10 ms blocks, as the node does; return (wall s, process CPU s)."""
    per_chunk = int(round(CHUNK_S / run.sim.period_s))
    chunks = int(round(duration_s / CHUNK_S))
    w0 = time.perf_counter()
    c0 = time.process_time()
    for _ in range(chunks):
        run.advance(per_chunk)
    return time.perf_counter() - w0, time.process_time() - c0


def measure_rtf(config: SimConfig, state, duration_s: float) -> Dict[str, Any]:
    """Real-time factor and per-step costs of one configuration from ``state``."""
    run = Run(config, start_state=state)
    sim = run.sim
    wall, cpu = run_chunks(run, duration_s)
    out_ns = output_ns_per_sample(sim)
    method = config.integrator.method
    evals = evaluations_per_step(method)
    steps = sim.steps_taken
    return {
        'method': method, 'sim_s': sim.time_s, 'wall_s': wall, 'cpu_s': cpu,
        'rtf': sim.time_s / wall, 'rtf_cpu': sim.time_s / cpu,
        'status': sim.status, 'message': sim.message,
        'n_sub': sim.n_sub, 'step_us': sim.h * 1e6, 'steps': steps,
        'steps_per_wall_s': steps / wall, 'ns_per_step': 1e9 * wall / steps,
        'ns_per_step_cpu': 1e9 * cpu / steps,
        'evals_per_step': evals,
        'force_evals_per_sim_s': evals * steps / sim.time_s,
        'ns_per_eval_in_step': 1e9 * wall / (steps * evals),
        'samples_per_sim_s': 1.0 / sim.period_s,
        'output_ns_per_sample': out_ns,
        'integration_ns_per_step': (1e9 * wall - out_ns * sim.sample_index) / steps,
        'coordinates': sim.model.n_coordinates,
        'quadrature_representatives': int(sim.model.basis.shape[0]),
    }


def output_ns_per_sample(sim: Simulator) -> float:
    """Ns per output sample of the gap / capacitance channels (best of 5, one 10 ms block)."""
    k = int(round(CHUNK_S / sim.period_s))
    q = np.repeat(sim.q[None, :], k, axis=0)
    v = np.zeros_like(q)
    t = sim.period_s * np.arange(1, k + 1)
    best = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        sim._samples(t, q, v)  # private: the benchmark splits the cost of advance()
        best = min(best, time.perf_counter() - t0)
    return 1e9 * best / k


@njit
def _force_loop(x, force, work, out, info, count):
    """
    Evaluate the force ``count`` times at slowly changing states (no Python in between).

    The calls are made as ``kernels.run_samples`` makes them (the common case inline, the general
    path called from the loop): ``kernels.nl_accel`` called as a function costs ~3x more.
    """
    total = 0.0
    for k in range(count):
        x[0] += 1e-15 * (1 - 2 * (k & 1))
        kernels._force(x, force, work, out, info)
        if info[0] != 0:
            info[0] = 0
            kernels._force_general(x, force, work, out, info)
        total += out[0]
    return total


def standalone_force_ns(config: SimConfig, state, count: int) -> float:
    """Ns per compiled force evaluation, called from a compiled loop (no Python overhead)."""
    model = forces.build_force_model(config)
    x = np.array(state[0] if state is not None else np.zeros(model.n_coordinates))
    x[0] = 4e-6  # a shocked state: q1 at 40 % of the gap
    work = np.empty(forces.scratch_size(model))
    out = np.empty(model.n_coordinates)
    info = np.zeros(2, dtype=np.int64)
    args = (model.kernel, work, out, info)
    _force_loop(x, *args, 10)
    best = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        _force_loop(x, *args, count)
        best = min(best, time.perf_counter() - t0)
    return 1e9 * best / count


class ScipyProblem:
    """Problem (a) for ``solve_ivp``: the same equations with a Python right-hand side."""

    def __init__(self, config: SimConfig) -> None:
        self.model = forces.build_force_model(config)
        self.n = self.model.n_coordinates
        self.omega = 2.0 * np.pi * np.asarray(config.modes.coordinate_frequencies())
        self.zeta = 1.0 / (2.0 * np.asarray(config.modes.coordinate_quality_factors()))
        # The Simulator's drive A cos(omega (t - t_ref) + phase) with t_ref = phase = 0 until
        # a change (kernels._external), on q2; the start state is at drive phase 0.
        self.drive_amp = config.drive.amplitude
        self.drive_omega = 2.0 * math.pi * config.drive.frequency
        self.shock_start = config.run.shock_times[0]
        self.shock_duration = config.shock_duration_s
        self.shock_peak = config.run.shock_peaks[0]

    def rhs(self, t: float, y: np.ndarray, pulse: bool) -> np.ndarray:
        """Return dy/dt; the pulse acts on the segment it spans (as in the kernel)."""
        n = self.n
        x, v = y[:n], y[n:]
        # A trial stage of a too-long step can leave the gap: NaN makes DOP853 reject the
        # step and shrink it (a real contact would end in 'step size too small').
        if not np.all(np.isfinite(y)):
            return np.full(2 * n, np.nan)
        try:
            f_nl = forces.nonlinear_acceleration(x, self.model)
        except SimulationError:
            return np.full(2 * n, np.nan)
        a = -2.0 * self.zeta * self.omega * v - self.omega ** 2 * x + f_nl
        a[1] += self.drive_amp * math.cos(self.drive_omega * t)
        if pulse:
            a[0] -= self.shock_peak * math.sin(math.pi * (t - self.shock_start)
                                               / self.shock_duration)
        return np.concatenate([v, a])

    def solve(self, y0: np.ndarray, t_eval: np.ndarray, rtol: float,
              atol: float) -> Tuple[np.ndarray, float, int]:
        """Coordinates at ``t_eval`` (K, n), wall s and RHS calls; split at the pulse's ends."""
        t_end = float(t_eval[-1])
        edges = [0.0, self.shock_start, self.shock_start + self.shock_duration, t_end]
        y = np.concatenate(y0)
        parts: List[np.ndarray] = []
        nfev = 0
        w0 = time.perf_counter()
        for k in range(3):
            lo, hi = edges[k], edges[k + 1]
            inside = t_eval[(t_eval > lo) & (t_eval <= hi)] if k else t_eval[t_eval <= hi]
            # The segment's end state starts the next segment, sampled or not.
            ends = inside if inside.size and inside[-1] == hi else np.append(inside, hi)
            sol = solve_ivp(self.rhs, (lo, hi), y, method='DOP853', rtol=rtol, atol=atol,
                            t_eval=ends, args=(k == 1,))
            if sol.status != 0:
                raise RuntimeError(f'solve_ivp failed on [{lo}, {hi}]: {sol.message}')
            nfev += sol.nfev
            parts.append(sol.y[:self.n, :inside.size].T)
            y = sol.y[:, -1]
        return np.concatenate(parts), time.perf_counter() - w0, nfev


def simulator_window(config: SimConfig, state, n_samples: int) -> Tuple[np.ndarray, float]:
    """Return the coordinates (K, n) of ``n_samples`` periods in 10 ms blocks, and the wall s."""
    run = Run(config, start_state=state)
    per_chunk = int(round(CHUNK_S / run.sim.period_s))
    parts = []
    w0 = time.perf_counter()
    done = 0
    while done < n_samples:
        size = min(per_chunk, n_samples - done)
        parts.append(run.advance(size).samples.q)
        done += size
    wall = time.perf_counter() - w0
    if not run.running:
        raise RuntimeError(f'simulator: {run.sim.message}')
    return np.concatenate(parts), wall


def bench_scipy(state, after_shock_s: float, repeats: int) -> Dict[str, Any]:
    """Section 3: speed-up over DOP853 with a Python RHS at matched accuracy, problem (a)."""
    config = build_config(paper_values())
    problem = ScipyProblem(config)
    period = config.run.output_period_ns * 1e-9
    n_samples = int(round((SHOCK_TIME_S + after_shock_s) / period))
    t_eval = period * np.arange(1, n_samples + 1)
    log(f'scipy: tight reference (DOP853 rtol {REFERENCE_RTOL:g}, atol {REFERENCE_ATOL:g}) '
        f'over {t_eval[-1] * 1e3:.1f} ms')
    ref, ref_wall, ref_nfev = problem.solve(state, t_eval, REFERENCE_RTOL, REFERENCE_ATOL)
    peak = float(np.max(np.abs(ref[:, 0])))

    def error(q: np.ndarray) -> float:
        return float(np.max(np.abs(q - ref)) / peak)

    log('scipy: the simulator on the same window')
    runs = [simulator_window(config, state, n_samples) for _ in range(repeats)]
    sim_q = runs[0][0]
    sim_wall = min(r[1] for r in runs)
    sim_err = error(sim_q)
    # How good the reference is: one decade tighter.
    log('scipy: checking the reference against rtol 1e-11')
    check, _, _ = problem.solve(state, t_eval, REFERENCE_RTOL * 0.1, REFERENCE_ATOL)
    ref_err = error(check)
    scan = []
    chosen = None
    for exponent in np.arange(4.0, 10.01, 0.5):
        rtol = 10.0 ** -exponent
        log(f'scipy: DOP853 rtol {rtol:.2g}')
        q, wall, nfev = problem.solve(state, t_eval, rtol, SCIPY_ATOL)
        err = error(q)
        scan.append({'rtol': rtol, 'error': err, 'wall_s': wall, 'nfev': nfev})
        if err <= sim_err:
            chosen = scan[-1]
            break
    out: Dict[str, Any] = {
        'window_s': float(t_eval[-1]), 'samples': n_samples, 'peak_q1_m': peak,
        'reference_wall_s': ref_wall, 'reference_nfev': ref_nfev,
        'reference_error_vs_rtol_1e-11': ref_err,
        'simulator_wall_s': sim_wall, 'simulator_error': sim_err,
        'simulator_method': config.integrator.method, 'scan': scan, 'matched': chosen,
        'drive_on': config.drive.amplitude != 0.0}
    if chosen is not None:
        out['speedup'] = chosen['wall_s'] / sim_wall
        out['scipy_us_per_rhs'] = 1e6 * chosen['wall_s'] / chosen['nfev']
    else:
        # Even rtol 1e-10 is not as accurate: compare with the reference's own cost.
        out['speedup_lower_bound'] = ref_wall / sim_wall
    return out


def bench_recording(config: SimConfig, state, duration_s: float) -> Dict[str, Any]:
    """Section 4: run_offline with and without an MCAP recording (issue 5)."""
    log(f'recording: run_offline without output, {duration_s:g} s simulated')
    plain = offline.run_offline(config, duration_s=duration_s, progress=False,
                                start_state=state)
    with tempfile.TemporaryDirectory(prefix='ring_gyro_bench_') as tmp:
        path = os.path.join(tmp, 'bench.mcap')
        log(f'recording: run_offline to {path}')
        recorded = offline.run_offline(config, duration_s=duration_s, output=path,
                                       progress=False, start_state=state)
        size = os.path.getsize(path)
    return {
        'sim_s': plain.sim_time_s, 'rtf_plain': plain.real_time_factor,
        'rtf_recorded': recorded.real_time_factor, 'wall_plain_s': plain.wall_time_s,
        'wall_recorded_s': recorded.wall_time_s,
        'overhead_ratio': recorded.wall_time_s / plain.wall_time_s,
        'file_bytes': size, 'bytes_per_sim_s': size / recorded.sim_time_s,
        'status': (plain.status, recorded.status)}


def verdict(value: float, target: float) -> str:
    """PASS / MISS against a target (higher is better)."""
    return f'{"PASS" if value >= target else "MISS"} (target >= {target:g})'


def print_report(r: Dict[str, Any]) -> None:
    """Print every number of a run (stdout)."""
    m = r['machine']
    print('=' * 99)
    print(f'ring_gyro_sim benchmark ({"quick" if r["quick"] else "full"}): python '
          f'{m["python"]}, numpy {m["numpy"]}, scipy {m["scipy"]}, numba {m["numba"]}')
    print(f'machine: {m["processor"]}, {m["cpus"]} CPUs, load average '
          f'{m["load_start"][0]:.2f} at start, {m["load_end"][0]:.2f} at end')
    if max(m['load_start'][0], m['load_end'][0]) > 0.5 * m['cpus']:
        print('  WARNING: the machine was busy with other work: wall-clock speeds are low and '
              'noisy; the rtf_cpu columns (process CPU time) are less affected')

    c = r['compile']
    print('\n1. JIT compile / cache load (first construction + set_state + 10 ms advance)')
    print(f'  this process: {c["this_process_first_s"]:.3f} s (construct '
          f'{c["first_construct_s"]:.3f}, set_state {c["first_set_state_s"]:.3f}, advance '
          f'{c["first_advance_s"]:.3f}); the same work warm: {c["steady_same_work_s"]:.4f} s; '
          f'overhead {c["this_process_overhead_s"]:.3f} s')
    print(f'  kernels: {c["cache"]}')
    for key, label in (('empty_cache_child', 'fresh process, empty numba cache (full compile)'),
                       ('warm_cache_child', 'fresh process, warm numba cache (load only)')):
        child = c.get(key)
        if child:
            print(f'  {label}: {child["first_run_s"]:.3f} s (+ imports {child["import_s"]:.3f} '
                  f's; cache hits {child["cache_hits"]}, misses {child["cache_misses"]})')

    print('\n2. Real-time factor (one core, 10 ms chunks, from the upper branch, shock at '
          f'{SHOCK_TIME_S * 1e3:g} ms)')
    header = (f'  {"case":<24}{"method":<8}{"sim s":>7}{"wall s":>8}{"RTF":>7}{"rtf_cpu":>8}'
              f'{"n_sub":>6}{"h us":>7}{"steps/s":>10}{"ns/step":>9}{"ev/st":>6}'
              f'{"ns/ev":>7}{"out ns":>7}')
    print(header)
    for row in r['rtf']:
        print(f'  {row["case"]:<24}{row["method"]:<8}{row["sim_s"]:>7.2f}{row["wall_s"]:>8.2f}'
              f'{row["rtf"]:>7.2f}{row["rtf_cpu"]:>8.2f}{row["n_sub"]:>6d}'
              f'{row["step_us"]:>7.3f}{row["steps_per_wall_s"]:>10.0f}'
              f'{row["ns_per_step"]:>9.0f}{row["evals_per_step"]:>6d}'
              f'{row["ns_per_eval_in_step"]:>7.0f}{row["output_ns_per_sample"]:>7.0f}')
        if row['status'] != 'running':
            print(f'    !! status {row["status"]}: {row["message"]} (the RTF is not meaningful)')
    base = r['rtf'][0]
    ratios = ', '.join(f'{row["method"]} {row["rtf"] / base["rtf"]:.2f}'
                       for row in r['rtf'] if row['case'] == base['case'])
    print(f'  RTF relative to {base["method"]} on (a): {ratios}')
    print(f'  (b) modes: frequencies {FIVE_MODES["modes.frequencies"]} Hz, Q '
          f'{FIVE_MODES["modes.quality_factors"]};')
    print(f'      companions {FIVE_MODES["modes.companion_frequencies"]} Hz, Q '
          f'{FIVE_MODES["modes.companion_quality_factors"]}')
    f = r['force']
    print(f'  standalone force evaluation (compiled loop): (a) {f["paper_ns"]:.0f} ns, '
          f'(b) {f["five_ns"]:.0f} ns')
    stage = r.get('stage_ns')
    if stage is not None:
        print(f'  marginal cost of one splitting stage (force + drift + kick + drive), '
              f'from bm6 - strang on (a), process CPU time: {stage:.0f} ns')
    for row in r['rtf']:
        if row['case'].startswith('(a)') and row['method'] != base['method']:
            continue
        target = TARGET_RTF_PAPER if row['case'].startswith('(a)') else TARGET_RTF_FIVE_MODES
        print(f'  {row["case"]} {row["method"]}: RTF {row["rtf"]:.2f} '
              f'{verdict(row["rtf"], target)}')
        ns_eval = f['paper_ns'] if row['case'].startswith('(a)') else f['five_ns']
        force_share = ns_eval * row['force_evals_per_sim_s'] * 1e-9
        output_share = row['output_ns_per_sample'] * row['samples_per_sim_s'] * 1e-9
        print(f'    limit: {row["samples_per_sim_s"]:.0f} samples/s x n_sub {row["n_sub"]} x '
              f'{row["evals_per_step"]} force evaluations/step = '
              f'{row["force_evals_per_sim_s"]:.3g} evaluations per simulated s; at '
              f'{ns_eval:.0f} ns each that alone is {force_share:.2f} s of CPU per simulated s '
              f'(RTF <= {1.0 / force_share:.2f}); measured {row["wall_s"] / row["sim_s"]:.2f} '
              f'wall s ({row["cpu_s"] / row["sim_s"]:.2f} CPU s) per simulated s, of which '
              f'output channels {output_share:.2f} s')
        if row['rtf'] < target:
            need = 1e9 / (target * row['force_evals_per_sim_s'])
            print(f'    to reach {target:g}x at this step and method one force evaluation may '
                  f'take at most {need:.0f} ns, everything else included')

    s = r['scipy']
    print(f'\n3. Speed-up over scipy solve_ivp DOP853 (Python RHS), problem (a) with the drive '
          f'{"on" if s["drive_on"] else "off"}, 0..{s["window_s"] * 1e3:.1f} ms '
          f'({s["window_s"] * 1e3 - SHOCK_TIME_S * 1e3:.0f} ms after the shock), '
          f'{s["samples"]} samples compared')
    print(f'  reference rtol {REFERENCE_RTOL:g} atol {REFERENCE_ATOL:g}: '
          f'{s["reference_wall_s"]:.2f} s, {s["reference_nfev"]} RHS calls; its own error '
          f'(vs rtol 1e-11) {s["reference_error_vs_rtol_1e-11"]:.2e} of peak |q1| = '
          f'{s["peak_q1_m"] * 1e6:.3f} um')
    print(f'  simulator ({s["simulator_method"]}): {s["simulator_wall_s"] * 1e3:.1f} ms, '
          f'max error / peak |q1| = {s["simulator_error"]:.2e}')
    for row in s['scan']:
        print(f'    scipy rtol {row["rtol"]:8.2g}: error {row["error"]:.2e}, '
              f'{row["wall_s"]:7.3f} s, {row["nfev"]} RHS calls')
    if s['matched'] is not None:
        mt = s['matched']
        print(f'  matched: scipy rtol {mt["rtol"]:.2g}, {mt["wall_s"]:.3f} s, error '
              f'{mt["error"]:.2e} <= {s["simulator_error"]:.2e}; '
              f'{s["scipy_us_per_rhs"]:.1f} us per RHS call')
        print(f'  speed-up {s["speedup"]:.0f}x {verdict(s["speedup"], TARGET_SPEEDUP)}')
    else:
        print('  no scanned rtol reached the error of the simulator; speed-up over the '
              f'reference itself >= {s["speedup_lower_bound"]:.0f}x '
              f'{verdict(s["speedup_lower_bound"], TARGET_SPEEDUP)}')
    if s['simulator_error'] < 3.0 * s['reference_error_vs_rtol_1e-11']:
        print('  note: the error of the simulator is near that of the reference: the matched '
              'rtol is uncertain')

    rec = r['recording']
    print(f'\n4. Recording (issue 5): run_offline on (a), {rec["sim_s"]:g} s simulated')
    print(f'  RTF without recording {rec["rtf_plain"]:.2f}, with MCAP {rec["rtf_recorded"]:.2f}; '
          f'overhead ratio (wall with / without) {rec["overhead_ratio"]:.2f}')
    print(f'  file {rec["file_bytes"]} bytes = {rec["bytes_per_sim_s"] / 1e6:.2f} MB per '
          f'simulated second')
    print(f'  recording keeps (a) at or above real time: '
          f'{verdict(rec["rtf_recorded"], TARGET_RTF_RECORDING)}')
    print('=' * 99)


def main(argv: Optional[List[str]] = None) -> int:
    """Parse the arguments and run every section."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='short runs (smoke test)')
    parser.add_argument('--json', metavar='FILE', help='also write the numbers as JSON')
    args = parser.parse_args(argv)
    quick = args.quick
    paper_s = 0.1 if quick else 1.5
    five_s = 0.05 if quick else 0.5
    record_s = 0.1 if quick else 1.0
    after_shock_s = 0.005 if quick else 0.02

    r: Dict[str, Any] = {'quick': quick, 'machine': {
        'python': platform.python_version(), 'numpy': np.__version__,
        'scipy': scipy.__version__, 'numba': numba.__version__,
        'processor': platform.processor() or platform.machine(), 'cpus': os.cpu_count(),
        'load_start': os.getloadavg()}}
    t_start = time.perf_counter()
    r['compile'] = bench_compile(children=True)

    log('start states: upper branch of the drive (shooting, not timed)')
    paper = build_config(paper_values())
    five = build_config(paper_values(**FIVE_MODES))
    paper_state = drive_initial_state(paper)
    five_state = drive_initial_state(five)

    rows = []
    for method in ('bm6', 'bm4', 'strang'):
        log(f'RTF (a) paper configuration, {method}, {paper_s:g} s simulated')
        row = measure_rtf(build_config(paper_values(**{'integrator.method': method})),
                          paper_state, paper_s)
        rows.append({'case': '(a) paper N_R=3', **row})
    log(f'RTF (b) N_R = 5 with companions, bm6, {five_s:g} s simulated')
    rows.append({'case': '(b) N_R=5 + companions', **measure_rtf(five, five_state, five_s)})
    r['rtf'] = rows
    by_method = {row['method']: row for row in rows if row['case'].startswith('(a)')}
    if 'bm6' in by_method and 'strang' in by_method:
        bm6, strang = by_method['bm6'], by_method['strang']
        # From CPU time: less disturbed than wall time on a shared machine.
        r['stage_ns'] = ((bm6['ns_per_step_cpu'] - strang['ns_per_step_cpu'])
                         / (bm6['evals_per_step'] - strang['evals_per_step']))

    log('standalone force evaluation (compiles a small loop)')
    count = 20_000 if quick else 200_000
    r['force'] = {'paper_ns': standalone_force_ns(paper, paper_state, count),
                  'five_ns': standalone_force_ns(five, five_state, count)}

    r['scipy'] = bench_scipy(paper_state, after_shock_s, repeats=3 if quick else 5)
    r['recording'] = bench_recording(paper, paper_state, record_s)
    r['machine']['load_end'] = os.getloadavg()
    r['total_wall_s'] = time.perf_counter() - t_start
    log(f'done in {r["total_wall_s"]:.0f} s')
    print_report(r)
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as f:
            json.dump(r, f, indent=2, sort_keys=True, default=str)
    return 0


if __name__ == '__main__':
    sys.exit(main())
