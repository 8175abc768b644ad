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
The slow flow of the driven 2theta pair open loop, for analysis (not an engine).

:class:`AveragedModel` integrates (S2) of ``core.engine.averaged`` (its docstring derives
it) for one configuration with the drive open loop and no electronics: the reference the
closed-loop averaged model and the full model are checked against (doc/averaged.md,
``benchmarks/bench_averaged.py``). A run never uses it: ``run.Run`` runs the engines.
"""

import cmath
from dataclasses import dataclass
import math
from typing import Optional, Sequence

import numpy as np
from ring_gyro_sim.core import harmonic_balance, kernels, structure, thermal
from ring_gyro_sim.core.engine.averaged import pair_force_arrays, state_of
from ring_gyro_sim.core.errors import ParameterError, SimulationError
from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.params import SimConfig
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

__all__ = ['AveragedModel', 'AveragedSamples']


J = np.array([[0.0, -1.0], [1.0, 0.0]])
"""The Coriolis coupling's matrix in (q_c, q_s) (G5, G6)."""


RTOL = 1e-10
"""Relative tolerance of ``solve_ivp`` (DOP853) on the scaled envelopes."""


@dataclass(frozen=True)
class AveragedSamples:
    """
    Output of :meth:`AveragedModel.run`.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s.
    envelope : ndarray of complex, shape (K, 2)
        ``(A_c, A_s)`` at each sample, m (S1).
    q, v : ndarray, shape (K, 2)
        The reconstructed ``(q2, q2s)`` (m) and their velocities (m/s) (R).
    rate : ndarray, shape (K,)
        The sensor frame's rate at each sample, rad/s.
    steps : int
        Right-hand-side evaluations the integration took.

    """

    t: np.ndarray
    envelope: np.ndarray
    q: np.ndarray
    v: np.ndarray
    rate: np.ndarray
    steps: int


class AveragedModel:
    """
    The slow flow (S2) of the driven 2theta pair of one configuration (module docstring).

    Parameters
    ----------
    config : SimConfig
        Needs ``modes.companions`` (the pair), ``modes.frequencies`` with at least the 2theta
        mode, ``drive.frequency > 0``. Open loop: another ``control.mode`` than
        ``open_loop`` is refused (not modelled here). The rate profile is used when
        ``gyro.enabled``.

    """

    def __init__(self, config: SimConfig) -> None:
        if not config.modes.companions:
            raise ParameterError('modes.companions: the averaged model is that of the 2theta '
                                 'pair and needs the companions')
        if config.modes.count < 2:
            raise ParameterError('modes.frequencies: the averaged model needs the 2theta mode '
                                 f'(N_R >= 2), got N_R = {config.modes.count}')
        if config.drive.frequency <= 0.0:
            raise ParameterError('drive.frequency: the averaged model turns at the drive '
                                 f'frequency and needs it > 0, got {config.drive.frequency}')
        if modes.of(config).closed:
            raise ParameterError('control.mode: this averaged model is open loop (the PLL, '
                                 'AGC and force-to-rebalance are in AveragedGyro), got '
                                 f'{config.control.mode}')
        # The device at the die temperature of t = 0 (core.thermal, T3-T6), as the full
        # model starts; later temperature changes are not followed.
        self.config = thermal.device_at(config, thermal.DieTemperature(config).kelvin)
        m = self.config.modes.count
        self.index = (1, m + 1)   # q2, q2s in the coordinate vector
        self.stiffness, self.damping = self.config.modes.pair_matrices(2)
        self.omega = 2.0 * math.pi * self.config.drive.frequency
        self.drive = float(self.config.drive.amplitude)
        self.kappa = float(structure.gyroscopic_coefficient(2))
        g = self.config
        self.rate_times = tuple(g.run.rate_times) if g.gyro.enabled else ()
        self.rate_values = tuple(g.run.rate_values) if g.gyro.enabled else ()
        # One harmonic of harmonic_balance's AFT: N(A) of (S2), the reference; the
        # closed form (S3) of the compiled kernel when the force is a truncated series.
        self._balance = harmonic_balance.Balance(self.config, 1, cosine_only=False,
                                                 damped=False, drive_m_s2=0.0)
        self._coeff = np.zeros((self._balance.n, self._balance.h))
        self._fast = (pair_force_arrays(self._balance.model, *self.index)
                      if self.config.electrodes.taylor_terms > 0 else None)
        self.evaluations = 0

    # ------------------------------------------------------------------ the slow flow
    def nonlinear(self, envelope: np.ndarray) -> np.ndarray:
        """
        Return N(A), the first harmonic of the electrostatic force on the pair (m/s^2).

        ``a_nl(Re(A e^{i phi}))`` over one period of phi, as ``harmonic_balance``'s AFT
        computes it: ``a_nl = Re(N e^{i phi}) + other harmonics``.

        Raises
        ------
        SimulationError
            The orbit leaves the force's range (contact, ``|w| >= d_g``).

        """
        ic, is_ = self.index
        c = self._coeff
        c[ic, 1], c[ic, 2] = envelope[0].real, -envelope[0].imag
        c[is_, 1], c[is_, 2] = envelope[1].real, -envelope[1].imag
        f, _ = self._balance.nonlinear(c, jac=False)
        return np.array([complex(f[ic, 1], -f[ic, 2]), complex(f[is_, 1], -f[is_, 2])])

    def nonlinear_fast(self, envelope: np.ndarray) -> np.ndarray:
        """
        Return N(A) (m/s^2) by the closed form (S3) of the compiled kernel.

        The same as :meth:`nonlinear` to round-off (``test_averaged``); with an untruncated
        force (``electrodes.taylor_terms: 0``) it is :meth:`nonlinear`.

        Raises
        ------
        SimulationError
            The orbit leaves the series' range.

        """
        if self._fast is None:
            return self.nonlinear(envelope)
        n_c, n_s = kernels.force_harmonic(complex(envelope[0]), complex(envelope[1]),
                                          *self._fast)
        if not (cmath.isfinite(n_c) and cmath.isfinite(n_s)):
            raise SimulationError("averaged model: the orbit left the force's range")
        return np.array([n_c, n_s])

    def derivative(self, envelope: np.ndarray, rate: float = 0.0,
                   rate_dot: float = 0.0) -> np.ndarray:
        """Return ``A'`` of (S2), m/s, at envelopes A (m), a rate (rad/s) and its slope."""
        a = np.asarray(envelope, dtype=complex)
        w = self.omega
        lin = ((w * w + rate * rate) * a - self.stiffness @ a
               - 1j * w * ((self.damping + 2.0 * self.kappa * rate * J) @ a)
               - self.kappa * rate_dot * (J @ a))
        total = lin + self.nonlinear_fast(a)
        total[0] += self.drive
        self.evaluations += 1
        return (-0.5j / w) * total

    def steady_state(self, guess: Sequence[complex], rate: float = 0.0) -> np.ndarray:
        """
        Return the fixed point A (m) of (S2) at a constant rate (rad/s), Newton from ``guess``.

        It is the one-harmonic balance of the pair; which branch (of a bistable drive) is the
        guess's.

        Raises
        ------
        SimulationError
            No convergence.

        """
        g = np.asarray(guess, dtype=complex)
        scale = max(float(np.max(np.abs(g))), 1e-15)

        def residual(y):
            a = np.array([complex(y[0], y[1]), complex(y[2], y[3])]) * scale
            d = self.derivative(a, rate) * (2.0 * self.omega / (scale * self.omega ** 2))
            return [d[0].real, d[0].imag, d[1].real, d[1].imag]

        y0 = np.array([g[0].real, g[0].imag, g[1].real, g[1].imag]) / scale
        y, _, ier, msg = fsolve(residual, y0, full_output=True, xtol=1e-14)
        if ier != 1 and np.max(np.abs(residual(y))) > 1e-11:
            raise SimulationError(f'averaged steady state did not converge: {msg}')
        return np.array([complex(y[0], y[1]), complex(y[2], y[3])]) * scale

    # ------------------------------------------------------------------ integration
    def _segments(self, t0: float, t1: float):
        """Yield ``(start, end, rate at start, slope)`` of the rate profile over [t0, t1]."""
        times, values = self.rate_times, self.rate_values
        if not times:
            yield t0, t1, 0.0, 0.0
            return
        knots = sorted(set(t for t in times if t0 < t < t1))
        edges = [t0] + knots + [t1]

        def value(t, after):
            # the profile of core.rate_profile: linear between knots, 0 before the first,
            # held after the last, the value after a repeated time (a step) on its right
            k = -1
            for j, tk in enumerate(times):
                if tk < t or (after and tk == t):
                    k = j
            if k < 0:
                return 0.0
            if k >= len(times) - 1:
                return values[-1]
            dt = times[k + 1] - times[k]
            return values[k] + (values[k + 1] - values[k]) * ((t - times[k]) / dt if dt else 0)

        for a, b in zip(edges[:-1], edges[1:]):
            left = value(a, after=True)
            yield a, b, left, (value(b, after=False) - left) / (b - a)

    def run(self, duration_s: float, sample_rate_hz: float,
            start: Optional[Sequence[complex]] = None) -> AveragedSamples:
        """
        Integrate (S2) from t = 0 and return the samples at ``k / sample_rate_hz``.

        Parameters
        ----------
        duration_s : float
            Simulated time, s (> 0).
        sample_rate_hz : float
            Output samples per second (> 0); the samples are at ``0, 1/rate, ...`` up to
            ``duration_s`` inclusive.
        start : (complex, complex) or None
            ``(A_c, A_s)`` at t = 0, m (e.g. :func:`envelope_of` of a full model's state);
            None: at rest.

        Returns
        -------
        AveragedSamples

        Raises
        ------
        ParameterError
            A non-positive duration or sample rate.
        SimulationError
            The integration failed or the orbit reached the force's range.

        """
        if not duration_s > 0.0:
            raise ParameterError(f'duration_s: must be > 0, got {duration_s}')
        if not sample_rate_hz > 0.0:
            raise ParameterError(f'sample_rate_hz: must be > 0, got {sample_rate_hz}')
        if duration_s * sample_rate_hz < 1.0:
            raise ParameterError(f'duration_s: {duration_s} s is shorter than one sample '
                                 f'period at sample_rate_hz = {sample_rate_hz}')
        n_out = int(math.floor(duration_s * sample_rate_hz + 1e-9)) + 1
        t_out = np.arange(n_out) / sample_rate_hz
        a = np.zeros(2, dtype=complex) if start is None else np.asarray(start, dtype=complex)
        # The envelopes scaled to about 1 (the drive's linear peak response, or the start).
        w2 = math.sqrt(self.stiffness[0, 0])
        scale = max(abs(self.drive) / (w2 * self.damping[0, 0]), float(np.max(np.abs(a))),
                    1e-15)
        out = np.empty((n_out, 2), dtype=complex)
        rates = np.empty(n_out)
        first = 0
        evaluations = self.evaluations
        for t_a, t_b, rate0, slope in self._segments(0.0, t_out[-1]):
            last = int(np.searchsorted(t_out, t_b, side='left')) if t_b < t_out[-1] else n_out
            t_eval = t_out[first:last]

            def rhs(t, y, t_a=t_a, rate0=rate0, slope=slope):
                env = np.array([complex(y[0], y[1]), complex(y[2], y[3])]) * scale
                d = self.derivative(env, rate0 + slope * (t - t_a), slope) / scale
                return [d[0].real, d[0].imag, d[1].real, d[1].imag]

            y0 = np.array([a[0].real, a[0].imag, a[1].real, a[1].imag]) / scale
            extra = t_eval.size == 0 or t_eval[-1] != t_b   # the segment's end, for the next
            sol = solve_ivp(rhs, (t_a, t_b), y0, method='DOP853',
                            t_eval=np.append(t_eval, t_b) if extra else t_eval,
                            rtol=RTOL, atol=RTOL * 1e-2)
            if sol.status != 0:
                raise SimulationError(f'averaged model: integration failed at {t_a} s: '
                                      f'{sol.message}')
            y = sol.y.T * scale
            a = np.array([complex(y[-1, 0], y[-1, 1]), complex(y[-1, 2], y[-1, 3])])
            y = y[:t_eval.size]
            out[first:last, 0] = y[:, 0] + 1j * y[:, 1]
            out[first:last, 1] = y[:, 2] + 1j * y[:, 3]
            rates[first:last] = rate0 + slope * (t_eval - t_a)
            first = last
        phase = self.omega * t_out
        q, v = state_of(out, self.omega, phase)
        return AveragedSamples(t=t_out, envelope=out, q=q, v=v, rate=rates,
                               steps=self.evaluations - evaluations)
