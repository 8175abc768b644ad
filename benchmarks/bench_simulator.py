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
Benchmark of the simulator: ``make bench`` (doc/performance.md).

Every configuration is a parameter file, so that ``ring_gyro run benchmarks/<name>.yaml``
reproduces it: ``paper.yaml`` (the paper configuration, drive on its upper branch, 10 000 g
along x), ``nr3_companions.yaml`` (N_R = 3 with the sine companions, the shock at 45 deg),
``nr5_companions.yaml`` (N_R = 5 with companions, the shock at 45 deg). Sections:

1. numba compile / cache-load time (first Simulator construction, ``set_state`` and 10 ms
   ``advance``), in this process and, in child processes, from an empty numba cache (a full
   compile) and from the cache that compile left;
2. the whole run of each file (integration + output channels at 200 kHz, through
   :class:`ring_gyro_sim.run.Run` in the files' 10 ms blocks, nothing recorded): real-time
   factor from wall time (``rtf``) and from process CPU time (``rtf_cpu``), best of N runs
   in a child process per tree. With ``--baseline DIR`` (a checkout of an older tree, e.g.
   ``git worktree add DIR <commit>``) the same runs are made with that tree's code in
   alternation with the current tree's, in the same session, and printed side by side;
3. the limit: floating-point operations per simulated second (the flops of one force
   evaluation, of a splitting stage and of the output channels, counted from the code of
   ``core/kernels/`` for each configuration) against the measured peak of one core for
   scalar double adds and multiplies without FMA (a small compiled loop of independent
   chains);
4. speed-up over scipy ``solve_ivp`` (DOP853, Python right-hand side) on the paper
   configuration at matched accuracy: the loosest rtol whose error against a tight DOP853
   reference is no larger than the simulator's;
5. recording overhead: the default gyroscope (every parameter at its
   default, config/default.yaml, with the demo's scenario: 10 deg/s and a 10 000 g shock at
   0.5 s) and the paper configuration, each run offline as ``ring_gyro run`` runs it, with and
   without an MCAP recording, the two alternating in one child process per tree; the ratio
   recorded / unrecorded of each pair (wall and CPU time, from the first block to the
   recording finalised), its median, the file's size per simulated second, with the
   defaults and with ``record.decimation: 1`` (every 200 kHz sample). ``--only recording``
   runs this section alone; with ``--baseline`` the older tree's runs alternate with these.

The targets (doc/performance.md) are printed next to the results; a missed target is reported with
what limits it, never hidden. The machine's load average is printed with the numbers: on a
shared machine compare ``rtf_cpu`` and the old/new ratio of one session, not wall times.
Progress goes to stderr, results to stdout; ``--json FILE`` also writes the numbers,
``--quick`` shortens every run (a smoke test).
"""

import argparse
from dataclasses import replace
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
from ring_gyro_sim.core import forces, kernels
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.gyro.operating_point import start_state
from ring_gyro_sim.core.params import SimConfig
from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.run import Run
import scipy
from scipy.integrate import solve_ivp

SHOCK_G = 10_000.0
SHOCK_TIME_S = 0.01
CHUNK_S = 0.01
"""The simulator is advanced in 10 ms chunks, as the node publishes its blocks."""

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CASES = (
    # (parameter file, label, goal for the whole run's real-time factor)
    ('paper.yaml', 'paper N_R=3, drive + 10 000 g', 10.0),
    ('nr3_companions.yaml', 'N_R=3 + companions, 45 deg', 6.0),
    ('nr5_companions.yaml', 'N_R=5 + companions, 45 deg', 3.0),
    ('gyro.yaml', 'gyroscope: N_R=3 + companions, electronics, noise', 2.0),
    ('gyro_closed.yaml', 'gyroscope with PLL, AGC and rebalance (issue 14)', 1.0),
)
TARGET_SPEEDUP = 200.0
TARGET_RTF_RECORDING = 1.0
"""Recording must not pull the paper configuration below real time."""
TARGET_RECORDING_RATIO = 1.3
"""A recorded run with the defaults costs at most 1.3 times an unrecorded one."""
DEFAULT_SCENARIO = """\
/**:
  ros__parameters:
    scenario:
      shock_times: [0.5]
      shock_peaks: [98066.5]
      rate_times: [0.0]
      rate_values: [0.17453292519943295]
"""
"""The default gyroscope of section 5: every parameter at its default, the demo's scenario."""
RECORDING_VARIANTS = (('defaults', {}), ('decimation 1', {'record.decimation': 1}))
"""Section 5 records each configuration with the defaults and with every 200 kHz sample."""

REFERENCE_RTOL = 1e-10
REFERENCE_ATOL = 1e-16
SCIPY_ATOL = 1e-16
"""Absolute tolerance of the scipy runs, m: tiny, so that rtol alone sets their accuracy."""

# Run in child processes: the first construction + set_state + 10 ms advance, timed.
COLD_START_CODE = """
import json, time
t0 = time.perf_counter()
import numpy as np
from ring_gyro_sim.core import kernels
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.paramfile import load_yaml
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


def paper_config() -> SimConfig:
    """Return the paper configuration of ``benchmarks/paper.yaml`` (shock at 10 ms, drive on)."""
    return load_yaml(os.path.join(HERE, 'paper.yaml'))


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
    config = paper_config()
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


# Run in a child process per tree (argv: tree, parameter file, duration, repeats): the whole
# run of a parameter file through Run in its blocks, best of N, after a warm-up run that also
# computes the start state (memoised, not timed). A baseline tree from before Run started
# itself is handed the start state its own shooting gives.
WHOLE_RUN_CODE = """
import json, sys, time
tree, path, duration, repeats = sys.argv[1:5]
sys.path.insert(0, tree)
import ring_gyro_sim
from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.run import Run
config = load_yaml(path)
try:
    from ring_gyro_sim.core.gyro import operating_point  # Run(config) starts itself
    start = {}
except ImportError:
    from ring_gyro_sim.analysis.nnm import drive_initial_state
    start = {'start_state': drive_initial_state(config)}
period = config.run.output_period_ns * 1e-9
block = max(1, int(round(config.run.block_duration / period)))
n_blocks = max(1, int(round(float(duration) / (block * period))))
warm = Run(config, **start)
warm.advance(block)
best = None
for _ in range(int(repeats)):
    run = Run(config, **start)
    w0 = time.perf_counter()
    c0 = time.process_time()
    for _ in range(n_blocks):
        run.advance(block)
    cpu = time.process_time() - c0
    wall = time.perf_counter() - w0
    sim = run.full_model() if hasattr(run, 'full_model') else run.sim   # an older tree
    row = {'wall_s': wall, 'cpu_s': cpu, 'sim_s': sim.time_s, 'status': str(sim.status),
           'message': sim.message, 'steps': sim.steps_taken,
           'samples': sim.sample_index, 'module': ring_gyro_sim.__file__}
    if best is None or cpu < best['cpu_s']:
        best = dict(row, wall_s=min(wall, best['wall_s']) if best else wall)
    else:
        best['wall_s'] = min(best['wall_s'], wall)
print(json.dumps(best))
"""


def whole_run(tree: str, path: str, duration_s: float,
              repeats: int) -> Optional[Dict[str, Any]]:
    """Best of ``repeats`` whole runs of a parameter file with the code of ``tree`` (child)."""
    env = dict(os.environ, PYTHONPATH=tree)
    result = subprocess.run([sys.executable, '-c', WHOLE_RUN_CODE, tree, path,
                             repr(duration_s), str(repeats)], env=env, capture_output=True,
                            text=True, check=False, timeout=3600)
    if result.returncode != 0:
        log(f'child process failed ({tree}): {result.stderr.strip()[-500:]}')
        return None
    row = json.loads(result.stdout.strip().splitlines()[-1])
    row['rtf'] = row['sim_s'] / row['wall_s']
    row['rtf_cpu'] = row['sim_s'] / row['cpu_s']
    return row


def bench_cases(duration_s: float, repeats: int, rounds: int,
                baseline: Optional[str]) -> List[Dict[str, Any]]:
    """Section 2: each parameter file as a whole run, the current tree and the baseline."""
    rows = []
    for name, label, goal in CASES:
        path = os.path.join(HERE, name)
        config = load_yaml(path)
        trees = [('new', REPO)] + ([('old', baseline)] if baseline else [])
        found: Dict[str, Any] = {}
        for k in range(rounds):  # alternate the trees, so both see the same load
            for tag, tree in trees:
                log(f'{name}: {tag} tree, {repeats} x {duration_s:g} s simulated '
                    f'(round {k + 1} of {rounds})')
                got = whole_run(tree, path, duration_s, repeats)
                if got is None:
                    continue
                prev = found.get(tag)
                if prev is None or got['cpu_s'] < prev['cpu_s']:
                    wall = min(got['wall_s'], prev['wall_s']) if prev else got['wall_s']
                    found[tag] = dict(got, wall_s=wall, rtf=got['sim_s'] / wall)
                else:
                    prev['wall_s'] = min(prev['wall_s'], got['wall_s'])
                    prev['rtf'] = prev['sim_s'] / prev['wall_s']
        sim = Simulator(config)
        rows.append({'file': name, 'label': label, 'goal': goal, 'runs': found,
                     'flops': flop_model(sim), 'load': os.getloadavg()})
    return rows


def series_flops(slots: int, degree: int) -> int:
    """
    Operations of one value of the series (``kernels.force._series_values``), from the code.

    Estrin's scheme with S = 4, 8, 12 or 16 slots: the powers ``u^2, u^4, u^8`` it needs, a
    multiply and an add per coefficient pair and per block, the blocks' combination and the
    ``u^2`` (or 1) scale; S = 0: Horner's rule of degree D, ``2 D``.
    """
    if slots == 0:
        return 2 * degree
    powers = {4: 1, 8: 2, 12: 3, 16: 3}[slots]
    combine = {4: 0, 8: 2, 12: 4, 16: 6}[slots]
    return powers + slots + slots // 2 + combine + 1


def flop_model(sim: Simulator) -> Dict[str, Any]:
    """
    Floating-point operations of the kernels per simulated second, counted from the code.

    ``core/kernels/``: one force evaluation at m angles (``_force``: m = 2 R without sine
    content, ``_force_general``: m = 4 R) is ``m (2 n - 1)`` for the angle values (all
    coordinates non-zero), ``2 n`` for the reach that spares the range check, the series at
    each angle (:func:`series_flops`), and the projection (5 per representative and
    coordinate even under theta -> -theta on the common path, 8 per representative and
    coordinate on the general one); a stage adds the fused kick and drift (12 n) and the drive
    (3). The output channels of one sample: the centre gaps (2 n K), the ring grid
    (G (2 n - 1)), the electrode angles (E (2 n - 1)), their gaps and the capacitance sums
    four nodes per division (18 per 4 angles, of which one division), the curvature (2 n) and
    the scale (K). Shock sub-steps (a few per shock) are left out.
    """
    model = sim.model
    n = model.n_coordinates
    r = int(model.kernel.projection.shape[1])
    degree = int(model.kernel.poly.size) - 1
    slots = int(model.kernel.series.size)
    general = bool(sim.config.modes.companions)  # the companions are excited in the files
    m = (4 if general else 2) * r
    even = int(np.sum(model.kernel.signs[1] > 0.0))
    projection = 8 * n * r if general else 5 * even * r
    force = m * (2 * n - 1) + 2 * n + series_flops(slots, degree) * m + projection
    stage = force + 12 * n + 3
    stages = int(sim._a.size)
    step = stages * stage + 3 * n + 3
    steps_per_s = sim.n_sub / sim.period_s
    geometry = sim._output_geometry
    k = geometry.centre_shapes.shape[1]
    g = geometry.ring_shapes.shape[1]
    e = geometry.electrode_shapes.shape[1]
    output = 2 * n * k + g * (2 * n - 1) + e * (2 * n - 1) + 18 * e // 4 + 2 * n + k
    samples_per_s = 1.0 / sim.period_s
    return {'n': n, 'angles': m, 'degree': degree, 'slots': slots, 'force_flops': force,
            'stage_flops': stage, 'stages': stages, 'step_flops': step,
            'steps_per_sim_s': steps_per_s, 'output_flops': output,
            'output_divisions': e // 4, 'samples_per_sim_s': samples_per_s,
            'integration_flops_per_sim_s': step * steps_per_s,
            'output_flops_per_sim_s': output * samples_per_s,
            'flops_per_sim_s': step * steps_per_s + output * samples_per_s}


@njit(cache=False)
def _scalar_peak_loop(count, seed):
    """16 independent chains of one multiply and one add each (no FMA: no fast-math)."""
    x = np.empty(16)
    for c in range(16):
        x[c] = seed + c
    a0, a1, a2, a3, a4, a5, a6, a7 = x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]
    b0, b1, b2, b3, b4, b5, b6, b7 = x[8], x[9], x[10], x[11], x[12], x[13], x[14], x[15]
    m = 0.999999999
    d = 1e-9
    for _ in range(count):
        a0 = a0 * m + d
        a1 = a1 * m + d
        a2 = a2 * m + d
        a3 = a3 * m + d
        a4 = a4 * m + d
        a5 = a5 * m + d
        a6 = a6 * m + d
        a7 = a7 * m + d
        b0 = b0 * m + d
        b1 = b1 * m + d
        b2 = b2 * m + d
        b3 = b3 * m + d
        b4 = b4 * m + d
        b5 = b5 * m + d
        b6 = b6 * m + d
        b7 = b7 * m + d
    return a0 + a1 + a2 + a3 + a4 + a5 + a6 + a7 + b0 + b1 + b2 + b3 + b4 + b5 + b6 + b7


@njit(cache=False)
def _vector_peak_loop(count, x):
    """Run the same multiply and add over a short array (the loop vectorises, as the kernels')."""
    m = 0.999999999
    d = 1e-9
    for _ in range(count):
        for k in range(x.size):
            x[k] = x[k] * m + d
    return x[0]


def bench_peak(count: int) -> Dict[str, Any]:
    """Section 3: peak double adds + multiplies per second of one core (best of 5, CPU time)."""
    _scalar_peak_loop(10, 1.0)
    x = np.ones(512)  # 4 kB: in L1, and long enough to be throughput-bound
    _vector_peak_loop(10, x)
    asm = next(iter(_scalar_peak_loop.inspect_asm().values()))
    packed = 'mulpd' in asm
    best_s = best_v = math.inf
    for _ in range(5):
        c0 = time.process_time()
        _scalar_peak_loop(count, 1.0)
        best_s = min(best_s, time.process_time() - c0)
        c0 = time.process_time()
        _vector_peak_loop(count // 32, x)
        best_v = min(best_v, time.process_time() - c0)
    return {'scalar_flops_per_s': 32.0 * count / best_s,
            'vector_flops_per_s': 2.0 * x.size * (count // 32) / best_v,
            'scalar_loop_packed': packed, 'load': os.getloadavg()}


def stage_costs(config: SimConfig, state, repeats: int = 5) -> Dict[str, float]:
    """
    CPU ns per sample of the integration alone, bm6 and strang, and what they imply.

    ``Simulator._integrate`` (private: the benchmark splits the cost of ``advance``) over
    10 ms blocks after the shock, best of ``repeats``; bm6 has 11 stages, strang 1, so their
    difference / 10 is the marginal cost of one stage (force + kick + drift + external) and
    the rest of strang the per-step cost; the output channels are timed alone on the same
    block (``Simulator._samples``).
    """
    out: Dict[str, float] = {}
    for method in ('bm6', 'strang'):
        sim = Simulator(replace(config, integrator=replace(config.integrator, method=method)))
        sim.set_state(*state)
        per_block = int(round(CHUNK_S / sim.period_s))
        sim.advance_samples(int(round(2.0 * SHOCK_TIME_S / sim.period_s)))  # past the shock
        q = np.empty((per_block, sim.model.n_coordinates))
        v = np.empty_like(q)
        best = math.inf
        for _ in range(repeats):
            c0 = time.process_time()
            sim._integrate(per_block, q, v)
            best = min(best, time.process_time() - c0)
        out[f'{method}_ns_per_sample'] = 1e9 * best / per_block
        if method == 'bm6':
            t = sim.period_s * np.arange(per_block)
            best = math.inf
            for _ in range(repeats):
                c0 = time.process_time()
                sim._samples(t, q, v)
                best = min(best, time.process_time() - c0)
            out['outputs_ns_per_sample'] = 1e9 * best / per_block
            out['n_sub'] = sim.n_sub
    stages = evaluations_per_step('bm6') - evaluations_per_step('strang')
    out['stage_ns'] = (out['bm6_ns_per_sample'] - out['strang_ns_per_sample']) / stages / \
        out['n_sub']
    out['step_ns'] = out['strang_ns_per_sample'] / out['n_sub'] - out['stage_ns']
    return out


def evaluations_per_step(method: str) -> int:
    """Force evaluations per step of a splitting method (one per drift, the last kick FSAL)."""
    a, _ = kernels.splitting_coefficients(method)
    return int(a.size)


class ScipyProblem:
    """Problem (a) for ``solve_ivp``: the same equations with a Python right-hand side."""

    def __init__(self, config: SimConfig) -> None:
        self.model = forces.build_force_model(config)
        self.n = self.model.n_coordinates
        self.omega = 2.0 * np.pi * np.asarray(config.modes.coordinate_frequencies())
        self.zeta = 1.0 / (2.0 * np.asarray(config.modes.coordinate_quality_factors()))
        # The Simulator's drive A cos(omega (t - t_ref) + phase) with t_ref = phase = 0 until
        # a change (kernels.forcing._external), on q2; the start state is at drive phase 0.
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


def simulator_window(config: SimConfig, n_samples: int) -> Tuple[np.ndarray, float]:
    """Return the coordinates (K, n) of ``n_samples`` periods in 10 ms blocks, and the wall s."""
    run = Run(config)
    per_chunk = int(round(CHUNK_S / run.full_model().period_s))
    parts = []
    w0 = time.perf_counter()
    done = 0
    while done < n_samples:
        size = min(per_chunk, n_samples - done)
        parts.append(run.advance(size).samples.q)
        done += size
    wall = time.perf_counter() - w0
    if not run.running:
        raise RuntimeError(f'simulator: {run.full_model().message}')
    return np.concatenate(parts), wall


def bench_scipy(config: SimConfig, state, after_shock_s: float,
                repeats: int) -> Dict[str, Any]:
    """Section 4: speed-up over DOP853 with a Python RHS at matched accuracy (paper.yaml)."""
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
    runs = [simulator_window(config, n_samples) for _ in range(repeats)]
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


# Run in a child process per tree (argv: tree, parameter file, JSON of parameter overrides,
# duration, pairs): the run as ``ring_gyro run`` makes it (Run in its blocks, a diagnostics
# snapshot every simulated second, the sink of offline.run_offline), without and with a
# recording in turn; each run timed from its first block to the recording finalised.
RECORDING_CODE = """
import json, os, shutil, sys, tempfile, time
tree, path, overrides, duration, pairs = sys.argv[1:6]
sys.path.insert(0, tree)
from ring_gyro_sim.core.params import build_config, to_flat
from ring_gyro_sim.core.engine.full import channel_names
from ring_gyro_sim.paramfile import load_yaml
from ring_gyro_sim.ros.recorder import RunRecorder
from ring_gyro_sim.ros.sinks import RosSink
from ring_gyro_sim.run import NullSink, Pacing, Run
config = load_yaml(path)
if json.loads(overrides):
    config = build_config({**to_flat(config), **json.loads(overrides)})
period = config.run.output_period_ns * 1e-9
block = max(1, int(round(config.run.block_duration / period)))
n_blocks = max(1, int(round(float(duration) / (block * period))))
per_second = max(1, int(round(1.0 / (block * period))))
names = channel_names(config)
directory = tempfile.mkdtemp(prefix='ring_gyro_bench_')


def once(record):
    sink, out = NullSink(), None
    if record:
        out = os.path.join(directory, 'run.mcap')
        sink = RosSink(names, '/ring_gyro', recorder=RunRecorder(
            out, config, names, '/ring_gyro', publish_clock=config.run.publish_clock),
            frame_id=config.gyro.frame_id)
    run = Run(config, sink=sink)
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(n_blocks):
        run.advance(block)
        last = k == n_blocks - 1
        if (k + 1) % per_second == 0 or last:
            run.diagnostics(Pacing(target=0.0, achieved=0.0, average=0.0), finished=last)
    status = str(run.full_model().status)
    run.close()
    row = {'wall_s': time.perf_counter() - w0, 'cpu_s': time.process_time() - c0,
           'sim_s': run.full_model().time_s, 'status': status}
    if out:
        row['bytes'] = os.path.getsize(out)
        os.remove(out)
    return row


once(False)  # the start state (memoised) and the kernels, not timed
rows = []
try:
    for _ in range(int(pairs)):
        rows.append({'plain': once(False), 'recorded': once(True)})
finally:
    shutil.rmtree(directory, ignore_errors=True)
print(json.dumps({'pairs': rows, 'decimation': config.run.record_decimation}))
"""


def recording_pairs(tree: str, path: str, overrides: Dict[str, Any], duration_s: float,
                    pairs: int) -> Optional[Dict[str, Any]]:
    """Unrecorded and recorded runs in turn with the code of ``tree`` (child), medians."""
    env = dict(os.environ, PYTHONPATH=tree)
    result = subprocess.run([sys.executable, '-c', RECORDING_CODE, tree, path,
                             json.dumps(overrides), repr(duration_s), str(pairs)], env=env,
                            capture_output=True, text=True, check=False, timeout=3600)
    if result.returncode != 0:
        log(f'child process failed ({tree}): {result.stderr.strip()[-500:]}')
        return None
    out = json.loads(result.stdout.strip().splitlines()[-1])
    rows = out['pairs']
    plain = [r['plain'] for r in rows]
    recorded = [r['recorded'] for r in rows]
    sim_s = recorded[0]['sim_s']
    return {
        'pairs': rows, 'decimation': out['decimation'], 'sim_s': sim_s,
        'ratio_wall': float(np.median([r['wall_s'] / p['wall_s']
                                       for p, r in zip(plain, recorded)])),
        'ratio_cpu': float(np.median([r['cpu_s'] / p['cpu_s']
                                      for p, r in zip(plain, recorded)])),
        'rtf_plain': sim_s / float(np.median([p['wall_s'] for p in plain])),
        'rtf_recorded': sim_s / float(np.median([r['wall_s'] for r in recorded])),
        'rtf_cpu_plain': sim_s / float(np.median([p['cpu_s'] for p in plain])),
        'rtf_cpu_recorded': sim_s / float(np.median([r['cpu_s'] for r in recorded])),
        'mb_per_sim_s': recorded[0]['bytes'] / 1e6 / sim_s,
        'status': sorted({r['status'] for r in plain + recorded})}


def bench_recording(duration_s: float, pairs: int,
                    baseline: Optional[str]) -> List[Dict[str, Any]]:
    """Section 5: runs with and without a recording, ratios per pair."""
    rows = []
    with tempfile.TemporaryDirectory(prefix='ring_gyro_bench_') as tmp:
        default = os.path.join(tmp, 'default_gyroscope.yaml')
        with open(default, 'w', encoding='utf-8') as f:
            f.write(DEFAULT_SCENARIO)
        configs = (('the default gyroscope', default, TARGET_RECORDING_RATIO),
                   ('paper configuration (paper.yaml)', os.path.join(HERE, 'paper.yaml'), None))
        trees = [('new', REPO)] + ([('old', baseline)] if baseline else [])
        for label, path, goal in configs:
            for variant, overrides in RECORDING_VARIANTS:
                found = {}
                for tag, tree in trees:  # one tree after the other, both in this session
                    log(f'recording: {label}, {variant}, {tag} tree, {pairs} pairs of '
                        f'{duration_s:g} s simulated')
                    got = recording_pairs(tree, path, overrides, duration_s, pairs)
                    if got is not None:
                        found[tag] = got
                rows.append({'label': label, 'variant': variant, 'runs': found,
                             'goal': goal if variant == 'defaults' else None,
                             'load': os.getloadavg()})
    return rows


def print_recording(rows: List[Dict[str, Any]]) -> None:
    """Print section 5."""
    print('\n5. Recording (issues 5 and 22): a run as `ring_gyro run` makes it, without and '
          'with an MCAP recording in turn in one process, timed to the file finalised; '
          'recorded / unrecorded per pair, median')
    print(f'  {"configuration":<34}{"record":<14}{"tree":<5}{"decim.":>7}{"MB/sim s":>9}'
          f'{"rtf":>6}{"rec.":>6}{"x wall":>8}{"x cpu":>7}{"load":>6}  goal')
    for row in rows:
        for tag in ('new', 'old'):
            run = row['runs'].get(tag)
            if run is None:
                continue
            goal = ''
            if row['goal'] is not None and tag == 'new':
                worst = max(run['ratio_wall'], run['ratio_cpu'])
                goal = (f'{"PASS" if worst <= row["goal"] else "MISS"} (target <= '
                        f'{row["goal"]:g})')
            print(f'  {row["label"]:<34}{row["variant"]:<14}{tag:<5}{run["decimation"]:>7}'
                  f'{run["mb_per_sim_s"]:>9.2f}{run["rtf_plain"]:>6.2f}'
                  f'{run["rtf_recorded"]:>6.2f}{run["ratio_wall"]:>8.2f}'
                  f'{run["ratio_cpu"]:>7.2f}{row["load"][0]:>6.2f}  {goal}')
            if run['status'] != ['running']:
                print(f'    !! status {run["status"]} (not meaningful)')
    paper = [row['runs']['new'] for row in rows
             if row['label'].startswith('paper') and 'new' in row['runs']]
    if paper:
        rtf = min(run['rtf_recorded'] for run in paper)
        print(f'  recording keeps the paper configuration at or above real time: '
              f'{verdict(rtf, TARGET_RTF_RECORDING)}')


def verdict(value: float, target: float) -> str:
    """PASS / MISS against a target (higher is better)."""
    return f'{"PASS" if value >= target else "MISS"} (target >= {target:g})'


def print_compile(c: Dict[str, Any]) -> None:
    """Print section 1."""
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


def print_scipy(s: Dict[str, Any]) -> None:
    """Print section 4."""
    print(f'\n4. Speed-up over scipy solve_ivp DOP853 (Python RHS), paper configuration, drive '
          f'{"on" if s["drive_on"] else "off"}, 0..{s["window_s"] * 1e3:.1f} ms '
          f'({s["window_s"] * 1e3 - SHOCK_TIME_S * 1e3:.0f} ms after the shock), '
          f'{s["samples"]} samples compared')
    print(f'  reference rtol {REFERENCE_RTOL:g} atol {REFERENCE_ATOL:g}: '
          f'{s["reference_wall_s"]:.2f} s, {s["reference_nfev"]} RHS calls; its own error '
          f'(vs rtol 1e-11) {s["reference_error_vs_rtol_1e-11"]:.2e} of peak |q1| = '
          f'{s["peak_q1_m"] * 1e6:.3f} um')
    print(f'  simulator ({s["simulator_method"]}): {s["simulator_wall_s"] * 1e3:.1f} ms, '
          f'max error / peak |q1| = {s["simulator_error"]:.2e} (budget 1e-4)')
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
              'noisy; the rtf_cpu columns (process CPU time) and old/new ratios are less '
              'affected')

    c = r.get('compile')
    if c:
        print_compile(c)

    if 'cases' in r:
        print_cases(r)
    if 'scipy' in r:
        print_scipy(r['scipy'])
    if 'recording' in r:
        print_recording(r['recording'])
    if r.get('baseline'):
        print(f'  old = {r["baseline"]}')
    print('=' * 99)


def print_cases(r: Dict[str, Any]) -> None:
    """Print sections 2 and 3."""
    print('\n2. Whole runs (integration + output channels at 200 kHz, Run in 10 ms blocks, '
          'nothing recorded), best of N; `ring_gyro run benchmarks/<file>` reproduces each')
    print(f'  {"case":<30}{"tree":<5}{"sim s":>6}{"wall s":>8}{"rtf":>7}{"cpu s":>8}'
          f'{"rtf_cpu":>8}{"ns/sample":>10}  {"load":>5}  goal')
    for row in r['cases']:
        for tag in ('new', 'old'):
            run = row['runs'].get(tag)
            if run is None:
                continue
            ns = 1e9 * run['cpu_s'] / run['samples']
            goal = verdict(run['rtf_cpu'], row['goal']) if tag == 'new' else ''
            print(f'  {row["label"]:<30}{tag:<5}{run["sim_s"]:>6.2f}{run["wall_s"]:>8.3f}'
                  f'{run["rtf"]:>7.2f}{run["cpu_s"]:>8.3f}{run["rtf_cpu"]:>8.2f}{ns:>10.0f}  '
                  f'{row["load"][0]:>5.2f}  {goal}')
            if run['status'] != 'running':
                print(f'    !! status {run["status"]}: {run["message"]} (not meaningful)')
        if 'new' in row['runs'] and 'old' in row['runs']:
            new, old = row['runs']['new'], row['runs']['old']
            print(f'    new / old: rtf_cpu x{new["rtf_cpu"] / old["rtf_cpu"]:.2f}, '
                  f'rtf x{new["rtf"] / old["rtf"]:.2f}')

    p = r['peak']
    print('\n3. Limit: floating-point operations per simulated second against one core')
    print(f'  measured peak of one core, double multiply + add without FMA: scalar '
          f'{p["scalar_flops_per_s"] / 1e9:.2f} Gflop/s'
          f'{" (the compiler packed the loop!)" if p["scalar_loop_packed"] else ""}, '
          f'vectorised loop {p["vector_flops_per_s"] / 1e9:.2f} Gflop/s (load '
          f'{p["load"][0]:.2f})')
    for row in r['cases']:
        f = row['flops']
        run = row['runs'].get('new')
        form = (f'Estrin, {f["slots"]} slots' if f.get('slots') else 'Horner')
        print(f'  {row["label"]}: n = {f["n"]}, {f["angles"]} angles, series of degree '
              f'{f["degree"]} ({form}): force {f["force_flops"]} flops, stage '
              f'{f["stage_flops"]}, step {f["step_flops"]} ({f["stages"]} stages) x '
              f'{f["steps_per_sim_s"]:.0f} steps/s;'
              f' outputs {f["output_flops"]} flops ({f["output_divisions"]} divisions) x '
              f'{f["samples_per_sim_s"]:.0f} samples/s')
        total = f['flops_per_sim_s']
        outputs = f['output_flops_per_sim_s'] / 1e9
        line = (f'    {total / 1e9:.2f} Gflop per simulated s ({outputs:.2f} of them outputs): '
                f'rtf <= {p["scalar_flops_per_s"] / total:.1f} at the scalar '
                f'peak, <= {p["vector_flops_per_s"] / total:.1f} at the vectorised peak')
        if run is not None:
            line += (f'; achieved {total * run["rtf_cpu"] / 1e9:.2f} Gflop/s of CPU time '
                     f'(rtf_cpu {run["rtf_cpu"]:.2f})')
        print(line)
    print('  where the time goes (CPU time, in this process, best of 5; ns per sample):')
    for name, st in r['stages'].items():
        print(f'    {name}: integration {st["bm6_ns_per_sample"]:.0f} (n_sub {st["n_sub"]}: '
              f'11 stages at {st["stage_ns"]:.0f} + {st["step_ns"]:.0f} per step), outputs '
              f'{st["outputs_ns_per_sample"]:.0f}; strang {st["strang_ns_per_sample"]:.0f}')


def main(argv: Optional[List[str]] = None) -> int:
    """Parse the arguments and run every section."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='short runs (smoke test)')
    parser.add_argument('--json', metavar='FILE', help='also write the numbers as JSON')
    parser.add_argument('--baseline', metavar='DIR',
                        help='an older checkout whose code runs the same files, side by side')
    parser.add_argument('--only', choices=('cases', 'recording', 'all'), default='all',
                        help='cases: sections 2 and 3 only (no compile, scipy, recording); '
                             'recording: section 5 only')
    parser.add_argument('--repeats', type=int, default=3, help='runs per child process')
    parser.add_argument('--pairs', type=int, default=5,
                        help='unrecorded / recorded pairs per child process (section 5)')
    args = parser.parse_args(argv)
    quick = args.quick
    case_s = 0.05 if quick else 0.5
    record_s = 0.1 if quick else 1.0
    after_shock_s = 0.005 if quick else 0.02

    r: Dict[str, Any] = {'quick': quick, 'baseline': args.baseline, 'machine': {
        'python': platform.python_version(), 'numpy': np.__version__,
        'scipy': scipy.__version__, 'numba': numba.__version__,
        'processor': platform.processor() or platform.machine(), 'cpus': os.cpu_count(),
        'load_start': os.getloadavg()}}
    t_start = time.perf_counter()
    everything = args.only == 'all'
    if everything:
        r['compile'] = bench_compile(children=True)
    if args.only in ('cases', 'all'):
        r['cases'] = bench_cases(case_s, 1 if quick else args.repeats, 1 if quick else 2,
                                 args.baseline)
        log('peak flops of one core (a small compiled loop)')
        r['peak'] = bench_peak(2_000_000 if quick else 20_000_000)
        log('stage costs: bm6 and strang, integration alone, and the output channels alone')
        r['stages'] = {}
        for name, _, _ in CASES:
            config = load_yaml(os.path.join(HERE, name))
            r['stages'][name] = stage_costs(config, start_state(config))
    if everything:
        paper = paper_config()
        paper_state = start_state(paper)
        r['scipy'] = bench_scipy(paper, paper_state, after_shock_s, repeats=3 if quick else 5)
    if args.only in ('recording', 'all'):
        r['recording'] = bench_recording(record_s, 2 if quick else args.pairs, args.baseline)
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
