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
The integrator's levers, measured for accuracy: longer steps with dense output, others.

The simulator takes one bm6 step per output sample. Each lever below is a prototype in plain
Python (the kernel's force, its exact linear flows; slow, a few seconds a run), run on
``benchmarks/paper.yaml`` over 30 ms (a 10 000 g shock at 10 ms) and compared, as
``make bench`` does, with a DOP853 reference at rtol 1e-10: the largest error in any q over
every output sample, relative to the peak q1 (the budget is 1e-4).

* ``bm6`` with the step H decoupled from the output period (5 us), the samples between the
  step ends by **dense output**: the exact linear flow from the step's start plus the
  remainder ``r = q - q_lin`` (``r'' + 2 zeta omega r' + omega^2 r = g``, g the force and the
  forcing) by the quintic Hermite interpolant of ``r, r', r''`` at both ends (``r(0) = r'(0)
  = 0``, ``r''`` from the force at the ends, which the FSAL kicks evaluate anyway). Steps
  that overlap the shock pulse are cut at its ends and at the sample times in them, as the
  kernel cuts them at the pulse's ends, so that no sample is interpolated across a kink.
* a **force-gradient** splitting: Chin's 4th-order scheme C (kicks 1/6, 2/3 with the
  gradient term, 1/6; two drifts of 1/2), ``[B, [A, B]] = 2 J(x) (a_nl + a_ext)`` for the
  damped linear flow A (the damping cancels in that commutator), J the force's Jacobian:
  two force evaluations and one Jacobian product per step against bm6's eleven.
* a **composition** of Strang steps of order 8 (Kahan & Li, 17 stages) with dense output.

    python benchmarks/bench_step_levers.py           # all of them, ~1 min
"""

import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_simulator as bench  # noqa: E402,I100 - the same problem and reference as make bench
import numpy as np  # noqa: E402
from ring_gyro_sim.core import forces, kernels  # noqa: E402
from ring_gyro_sim.core.gyro.operating_point import start_state  # noqa: E402
from ring_gyro_sim.paramfile import load_yaml  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
WINDOW_S = 0.03
PULSE_SUBSTEPS = 16
KAHAN_LI_8 = [0.13020248308889008087881763, 0.56116298177510838456196441,
              -0.38947496264484728640807860, 0.15884190655515560089621075,
              -0.39590389413323757733623154, 0.18453964097831570709183254,
              0.25837438768632204729397911, 0.29501172360931029887096624,
              -0.60550853383003451169892108]


def composition(gammas):
    """Drifts and kicks of the symmetric composition of Strang steps ``gammas`` (+ mirror)."""
    g = list(gammas) + list(gammas[-2::-1])
    kicks = [g[0] / 2] + [(g[i] + g[i + 1]) / 2 for i in range(len(g) - 1)] + [g[-1] / 2]
    return np.array(g), np.array(kicks)


def hermite5(s, h, r0, d0, a0, r1, d1, a1):
    """Quintic Hermite interpolant at ``s`` in [0, 1] of values, slopes, curvatures at 0, 1."""
    s2, s3, s4, s5 = s * s, s ** 3, s ** 4, s ** 5
    return ((1 - 10 * s3 + 15 * s4 - 6 * s5) * r0 + (s - 6 * s3 + 8 * s4 - 3 * s5) * h * d0
            + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * h * h * a0 + (10 * s3 - 15 * s4 + 6 * s5) * r1
            + (-4 * s3 + 7 * s4 - 3 * s5) * h * d1 + 0.5 * (s3 - 2 * s4 + s5) * h * h * a1)


class Prototype:
    """The paper configuration's equations, stepped in Python with the kernel's force."""

    def __init__(self) -> None:
        config = load_yaml(os.path.join(HERE, 'paper.yaml'))
        self.problem = bench.ScipyProblem(config)
        self.state = start_state(config)
        self.period = config.run.output_period_ns * 1e-9
        self.n_samples = int(round(WINDOW_S / self.period))
        self.t_eval = self.period * np.arange(1, self.n_samples + 1)
        p = self.problem
        self.omega, self.zeta = p.omega, p.zeta
        self.pulse = (p.shock_start, p.shock_duration, p.shock_peak)
        self.reference = None

    def forcing(self, t: float) -> np.ndarray:
        p = self.problem
        f = np.zeros(p.n)
        f[1] = p.drive_amp * math.cos(p.drive_omega * t)
        start, duration, peak = self.pulse
        if start <= t <= start + duration:
            f[0] -= peak * math.sin(math.pi * (t - start) / duration)
        return f

    def accel(self, x: np.ndarray, t: float) -> np.ndarray:
        return forces.nonlinear_acceleration(x, self.problem.model) + self.forcing(t)

    def flow(self, tau: float) -> np.ndarray:
        return kernels.linear_propagators(self.omega, self.zeta, np.array([tau]))[0]

    def step(self, x, v, t, h, a, b, grad=None):
        """One BAB step; ``grad[i]``: the coefficient of ``h^3 J g`` in kick i (or None)."""
        for i in range(a.size + 1):
            g = self.accel(x, t)
            kick = b[i] * h * g
            if grad is not None and grad[i] != 0.0:
                kick = kick + grad[i] * h ** 3 * (forces.jacobian(x, self.problem.model) @ g)
            v = v + kick
            if i == a.size:
                break
            flow = self.flow(a[i] * h)
            x, v = flow[:, 0] * x + flow[:, 1] * v, flow[:, 2] * x + flow[:, 3] * v
            t += a[i] * h
        return x, v

    def run(self, h, a, b, grad=None):
        """Coordinates at every output sample, steps of ``h`` on an absolute grid."""
        x, v = self.state[0].copy(), self.state[1].copy()
        out = np.empty((self.n_samples, self.problem.n))
        c = 2.0 * self.zeta * self.omega
        start, duration, _ = self.pulse
        j = done = 0
        while done < self.n_samples:
            t0, t1 = j * h, (j + 1) * h
            j += 1
            if t0 < start + duration and t1 > start:
                due = [(k + 1) * self.period for k in range(done, self.n_samples)
                       if (k + 1) * self.period <= t1 + 1e-15]
                cuts = sorted({t0, t1, max(t0, start), min(t1, start + duration), *due})
                for c0, c1 in zip(cuts[:-1], cuts[1:]):
                    if c1 - c0 <= 1e-15:
                        continue
                    m = max(1, math.ceil((c1 - c0) / (duration / PULSE_SUBSTEPS) - 1e-9))
                    for r in range(m):
                        x, v = self.step(x, v, c0 + r * (c1 - c0) / m, (c1 - c0) / m, a, b,
                                         grad)
                    while done < self.n_samples and abs((done + 1) * self.period - c1) < 1e-12:
                        out[done] = x
                        done += 1
                continue
            g0 = self.accel(x, t0)
            x1, v1 = self.step(x, v, t0, h, a, b, grad)
            flow = self.flow(h)
            r1 = x1 - (flow[:, 0] * x + flow[:, 1] * v)
            d1 = v1 - (flow[:, 2] * x + flow[:, 3] * v)
            a1 = self.accel(x1, t1) - self.omega ** 2 * r1 - c * d1
            while done < self.n_samples and (done + 1) * self.period <= t1 + 1e-15:
                tau = (done + 1) * self.period - t0
                f = self.flow(tau)
                out[done] = (f[:, 0] * x + f[:, 1] * v
                             + hermite5(tau / h, h, 0.0, 0.0, g0, r1, d1, a1))
                done += 1
            x, v = x1, v1
        return out

    def error(self, q: np.ndarray) -> float:
        if self.reference is None:
            self.reference, _, _ = self.problem.solve(self.state, self.t_eval,
                                                      bench.REFERENCE_RTOL,
                                                      bench.REFERENCE_ATOL)
        return float(np.max(np.abs(q - self.reference)) / np.max(np.abs(self.reference[:, 0])))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps-us', type=float, nargs='*',
                        default=[5.0, 6.25, 20.0 / 3.0, 7.5, 8.0, 10.0])
    args = parser.parse_args(argv)
    proto = Prototype()
    bm6 = kernels.splitting_coefficients('bm6')
    chin = (np.array([0.5, 0.5]), np.array([1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0]),
            np.array([0.0, (2.0 / 3.0) * (2.0 / 48.0), 0.0]))
    kl8 = composition(KAHAN_LI_8)
    rows = [('bm6, dense output', bm6, None, args.steps_us),
            ('Chin C (force gradient)', chin[:2], chin[2], [5.0, 2.5, 1.25]),
            ('Kahan-Li 8 (17 Strang stages)', kl8, None, [5.0, 7.5, 10.0])]
    print(f'paper.yaml, {WINDOW_S * 1e3:.0f} ms, error against DOP853 rtol '
          f'{bench.REFERENCE_RTOL:g} (largest |q - q_ref| over every sample / peak |q1|), '
          'budget 1e-4')
    for name, (a, b), grad, steps in rows:
        evals = a.size + (1 if grad is not None else 0)
        for h_us in steps:
            w0 = time.perf_counter()
            err = proto.error(proto.run(h_us * 1e-6, a, b, grad))
            print(f'  {name:30s} H = {h_us:5.2f} us: error {err:.2e}; force evaluations per '
                  f'5 us sample {evals * 5.0 / h_us:5.2f} ({time.perf_counter() - w0:.1f} s)',
                  flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
