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
Harmonic balance with pseudo-arclength continuation: backbones (Fig. 4) and the FRF (Fig. 9).

The numerical machinery lives in the core because the gyroscope's operating point needs it
(the PLL's lock frequency is the 2theta backbone at the AGC's set-point:
``core.gyro.operating_point.lock_frequency``); ``analysis/hbm.py`` adds the plots to its
results.

Equations
---------
Every coordinate ``x_i`` of the configuration (eq. 28, divided by the modal mass) obeys

    x_i'' + 2 zeta_i Omega_i x_i' + Omega_i^2 x_i - a_nl,i(x) = f_i cos(omega t),

with ``Omega_i = 2 pi coordinate_frequencies()[i]``, ``zeta_i = 1 / (2 Q_i)``,
``a_nl = forces.nonlinear_acceleration`` (the electrostatic force per modal mass, m/s^2,
without the linear part when it is folded) and the drive ``f = A_e`` on q2 (index 1,
section 3.4). The backbone is the conservative system, eq. (33): ``zeta = 0``, ``f = 0``.

Ansatz and AFT
--------------
``x_i(t) = a_i0 + sum_{k=1}^{N_h} a_ik cos(k omega t) + b_ik sin(k omega t)``: the constant
and the even harmonics are kept because the outer electrodes alone give even powers of w
(a q1 orbit drives q2 through q1^2). The nonlinear force is evaluated by alternating
frequency-time: the orbit is sampled at N equally spaced times, ``a_nl`` and its exact
Jacobian (``forces.jacobian``) are evaluated at each sample, and the samples are projected
back on the harmonics 0..N_h. With the Taylor force (a polynomial of degree N_T - 1) the
projection is exact (no aliasing) for ``N > N_T N_h``; N is the next power of two. With the
untruncated force (N_T = 0), N = 16 N_h.

Backbone (nonlinear normal mode)
--------------------------------
Eq. (33) is reversible: an orbit at rest at t = 0 is even in time. The backbone uses the
cosine-only ansatz (all ``b_ik = 0``), which is the phase condition (the velocity of every
coordinate, q_mode included, is zero at t = 0) and also removes the equation that energy
conservation makes redundant in the full ansatz (``int R . x' dt = 0`` identically), so the
``n (N_h + 1)`` equations in ``n (N_h + 1) + 1`` unknowns (``omega`` included) define a
regular curve. It starts from the linear mode at a small amplitude.

Continuation
------------
Pseudo-arclength (Keller): tangent ``t`` from ``[J; t_prev] t = [0; 1]`` (orientation kept),
predictor ``y + h t``, Newton corrector on ``[R(y); t . (y - y_pred)] = 0`` with the analytic
Jacobian. Step control: the step grows by 1.5 after a corrector that converged in at most
3 iterations and the tangent turned by less than ~15 degrees, and is halved (and the step
retried) otherwise, or if the force leaves its range (contact). Unknowns are scaled (a
length and a frequency scale) so that the arclength weights amplitude and frequency evenly.

Stability (forced response)
---------------------------
Floquet exponents by Hill's method: a perturbation ``e^{lambda t} p(omega t)`` with ``p`` in
the same harmonic basis gives the quadratic eigenproblem
``lambda^2 p + lambda (2 omega D + C) p + J_HB p = 0`` (``D`` the derivative in the basis,
``C`` the damping, ``J_HB`` the harmonic-balance Jacobian). Of its ``2 n (2 N_h + 1)``
eigenvalues (every exponent repeated with shifts ``i k omega``), the ``2 n`` with the smallest
``|Im lambda|`` are the exponents; the multipliers are ``exp(lambda T)``, stable iff all
``|mu| < 1``. The damping margin is tiny (``|mu| = exp(-pi / Q)``, 1 - 5e-5 for q2), which
Hill's method resolves since it works in scaled time to round-off. :func:`monodromy_multipliers`
integrates the variational equations along the harmonic orbit with ``solve_ivp`` (DOP853)
instead, as an independent check (``stability='monodromy'``; slower).
"""

from dataclasses import dataclass, replace
import math
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim.core import forces
from ring_gyro_sim.core.errors import ParameterError, SimulationError
from ring_gyro_sim.core.params import SimConfig
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

DENSE_SAMPLES = 1024
"""Samples per period used to measure ``max_t |x_i(t)|`` of an orbit."""


@dataclass(frozen=True)
class HarmonicOrbit:
    """
    One periodic orbit in harmonic-balance form.

    Attributes
    ----------
    frequency_hz : float
        Fundamental frequency ``omega / (2 pi)``, Hz.
    coefficients_m : ndarray, shape (n, 2 N_h + 1)
        Per coordinate ``[a_0, a_1, b_1, ..., a_Nh, b_Nh]`` of
        ``a_0 + sum_k a_k cos(k omega t) + b_k sin(k omega t)``, m.
    amplitude_m : ndarray, shape (n,)
        ``max_t |x_i(t)|`` over the period, m.
    floquet_multipliers : ndarray or None, shape (2 n,)
        Floquet multipliers (forced orbits), dimensionless; None for backbone points.

    """

    frequency_hz: float
    coefficients_m: np.ndarray
    amplitude_m: np.ndarray
    floquet_multipliers: Optional[np.ndarray] = None

    @property
    def harmonics(self) -> int:
        """N_h, the number of harmonics of the ansatz."""
        return (self.coefficients_m.shape[1] - 1) // 2

    @property
    def stable(self) -> Optional[bool]:
        """All Floquet multipliers inside the unit circle (None when not computed)."""
        if self.floquet_multipliers is None:
            return None
        return bool(np.all(np.abs(self.floquet_multipliers) < 1.0))

    def displacement(self, t_s) -> np.ndarray:
        """
        Coordinates at times ``t_s``.

        Parameters
        ----------
        t_s : array_like, shape (m,)
            Times, s (t = 0 is the phase of the drive / the turning point of a backbone).

        Returns
        -------
        ndarray, shape (n, m)
            Coordinates, m.

        """
        tau = 2.0 * math.pi * self.frequency_hz * np.atleast_1d(np.asarray(t_s, dtype=float))
        return self.coefficients_m @ _real_basis(tau, self.harmonics).T

    def velocity(self, t_s) -> np.ndarray:
        """Velocities (m/s) at times ``t_s`` (s), shape (n, m)."""
        h = self.harmonics
        omega = 2.0 * math.pi * self.frequency_hz
        tau = omega * np.atleast_1d(np.asarray(t_s, dtype=float))
        return omega * (self.coefficients_m @ _derivative(h).T) @ _real_basis(tau, h).T

    def initial_state(self) -> Tuple[np.ndarray, np.ndarray]:
        """Return ``(x, v)`` at t = 0 (m, m/s)."""
        return self.displacement(0.0)[:, 0], self.velocity(0.0)[:, 0]


def _real_basis(tau: np.ndarray, n_h: int) -> np.ndarray:
    """``[1, cos tau, sin tau, ..., cos N_h tau, sin N_h tau]``, shape (len(tau), 2 N_h + 1)."""
    k = np.arange(1, n_h + 1)
    e = np.empty((tau.size, 2 * n_h + 1))
    e[:, 0] = 1.0
    e[:, 1::2] = np.cos(np.outer(tau, k))
    e[:, 2::2] = np.sin(np.outer(tau, k))
    return e


def _derivative(n_h: int) -> np.ndarray:
    """d/dtau in the real basis, shape (2 N_h + 1, 2 N_h + 1)."""
    d = np.zeros((2 * n_h + 1, 2 * n_h + 1))
    for k in range(1, n_h + 1):
        c, s = 2 * k - 1, 2 * k
        d[c, s] = k   # (a cos + b sin)' = k b cos - k a sin
        d[s, c] = -k
    return d


def time_samples(taylor_terms: int, harmonics: int) -> int:
    """
    Return the number N of AFT time samples per period.

    Parameters
    ----------
    taylor_terms : int
        N_T (0: untruncated force).
    harmonics : int
        N_h.

    Returns
    -------
    int
        The smallest power of two above ``N_T N_h`` (exact projection of the polynomial
        force), or ``16 N_h`` rounded up to a power of two for the untruncated force.

    """
    need = 16 * harmonics if taylor_terms == 0 else max(taylor_terms, 2) * harmonics + 1
    return int(2 ** math.ceil(math.log2(max(need, 8))))


class Balance:
    """Harmonic-balance residual and Jacobian of one configuration (see the module)."""

    def __init__(self, config: SimConfig, harmonics: int, cosine_only: bool,
                 damped: bool, drive_m_s2: float) -> None:
        if harmonics < 1:
            raise ParameterError(f'harmonics: must be >= 1, got {harmonics}')
        self.model = forces.build_force_model(config)
        self.n = self.model.n_coordinates
        self.n_h = harmonics
        self.omega_n = 2.0 * math.pi * np.asarray(config.modes.coordinate_frequencies())
        zeta = 1.0 / (2.0 * np.asarray(config.modes.coordinate_quality_factors()))
        self.damping = 2.0 * zeta * self.omega_n if damped else np.zeros(self.n)
        self.n_t = time_samples(config.electrodes.taylor_terms, harmonics)
        full = np.arange(2 * harmonics + 1)
        self.cols = np.concatenate([[0], 2 * np.arange(1, harmonics + 1) - 1]) \
            if cosine_only else full
        if cosine_only and damped:
            raise ParameterError('the cosine-only ansatz is for the conservative system')
        self.h = self.cols.size
        tau = 2.0 * math.pi * np.arange(self.n_t) / self.n_t
        full_e = _real_basis(tau, harmonics)
        proj = full_e.T * (2.0 / self.n_t)
        proj[0] *= 0.5
        self.e = full_e[:, self.cols]
        self.ep = proj[self.cols]
        d = _derivative(harmonics)
        self.d = d[np.ix_(self.cols, self.cols)]
        self.d2 = (d @ d)[np.ix_(self.cols, self.cols)]
        self.force = np.zeros((self.n, self.h))
        if drive_m_s2:
            if self.n < 2:
                raise ParameterError('the drive acts on q2: needs at least 2 coordinates')
            self.force[1, 1] = drive_m_s2

    def nonlinear(self, c: np.ndarray, jac: bool = True):
        """AFT force coefficients (n, h) and d/dc (n, h, n, h) of the samples of ``c``."""
        x = c @ self.e.T
        acc = np.empty((self.n, self.n_t))
        jt = np.empty((self.n_t, self.n, self.n)) if jac else None
        for j in range(self.n_t):
            acc[:, j] = forces.nonlinear_acceleration(x[:, j], self.model)
            if jac:
                jt[j] = forces.jacobian(x[:, j], self.model)
        f = acc @ self.ep.T
        if not jac:
            return f, None
        df = np.einsum('kj,jil,jm->iklm', self.ep, jt, self.e, optimize=True)
        return f, df

    def linear(self, omega: float, i: int) -> np.ndarray:
        """Linear operator of coordinate i in the basis, 1/s^2."""
        return (omega ** 2 * self.d2 + self.damping[i] * omega * self.d
                + self.omega_n[i] ** 2 * np.eye(self.h))

    def residual(self, c: np.ndarray, omega: float, jac: bool = True):
        """
        Residual (n h,) in m/s^2, d/dc (n h, n h) and d/domega (n h,).

        Raises SimulationError when a sample leaves the force's range.
        """
        f, df = self.nonlinear(c, jac)
        r = np.empty((self.n, self.h))
        for i in range(self.n):
            r[i] = self.linear(omega, i) @ c[i] - f[i] - self.force[i]
        if not jac:
            return r.ravel(), None, None
        size = self.n * self.h
        jc = -df.reshape(size, size)
        dw = np.empty((self.n, self.h))
        for i in range(self.n):
            sl = slice(i * self.h, (i + 1) * self.h)
            jc[sl, sl] += self.linear(omega, i)
            dw[i] = (2.0 * omega * self.d2 + self.damping[i] * self.d) @ c[i]
        return r.ravel(), jc, dw.ravel()

    def full_coefficients(self, c: np.ndarray) -> np.ndarray:
        """Coefficients in the full basis [a0, a1, b1, ...], shape (n, 2 N_h + 1)."""
        out = np.zeros((self.n, 2 * self.n_h + 1))
        out[:, self.cols] = c
        return out

    def hill_multipliers(self, c: np.ndarray, omega: float,
                         jc: Optional[np.ndarray] = None) -> np.ndarray:
        """Floquet multipliers by Hill's method (full basis only), shape (2 n,)."""
        if jc is None:
            _, jc, _ = self.residual(c, omega)
        size = self.n * self.h
        damp = np.kron(np.diag(self.damping), np.eye(self.h)) / omega
        dd = 2.0 * np.kron(np.eye(self.n), self.d)
        a = np.zeros((2 * size, 2 * size))
        a[:size, size:] = np.eye(size)
        a[size:, :size] = -jc / omega ** 2
        a[size:, size:] = -(dd + damp)
        mu = np.linalg.eigvals(a)   # exponents in units of omega (scaled time)
        central = mu[np.argsort(np.abs(mu.imag), kind='stable')[:2 * self.n]]
        return np.exp(2.0 * math.pi * central)


def monodromy_multipliers(config: SimConfig, orbit: HarmonicOrbit,
                          rtol: float = 1e-11) -> np.ndarray:
    """
    Floquet multipliers of a periodic orbit from the variational equations.

    Parameters
    ----------
    config : SimConfig
        The configuration the orbit belongs to (linear part, damping, force).
    orbit : HarmonicOrbit
        The periodic orbit; its harmonic series gives ``x(t)`` along the period.
    rtol : float
        Relative tolerance of ``solve_ivp`` (DOP853), dimensionless.

    Returns
    -------
    ndarray, shape (2 n,)
        Eigenvalues of the monodromy matrix (state ``[x, v / omega]``), dimensionless.

    """
    model = forces.build_force_model(config)
    n = model.n_coordinates
    omega_n = 2.0 * math.pi * np.asarray(config.modes.coordinate_frequencies())
    damping = 1.0 / np.asarray(config.modes.coordinate_quality_factors()) * omega_n
    omega = 2.0 * math.pi * orbit.frequency_hz

    def rhs(t, y):
        x = orbit.displacement(t)[:, 0]
        k = forces.jacobian(x, model)
        k[np.diag_indices(n)] -= omega_n ** 2
        phi = y.reshape(2 * n, 2 * n)
        out = np.empty_like(phi)
        out[:n] = omega * phi[n:]
        out[n:] = (k @ phi[:n]) / omega - damping[:, None] * phi[n:]
        return out.ravel()

    sol = solve_ivp(rhs, (0.0, 1.0 / orbit.frequency_hz), np.eye(2 * n).ravel(),
                    method='DOP853', rtol=rtol, atol=rtol * 1e-3)
    if sol.status != 0:
        raise SimulationError(f'monodromy integration failed: {sol.message}')
    return np.linalg.eigvals(sol.y[:, -1].reshape(2 * n, 2 * n))


class _Curve:
    """Scaled unknowns ``y = [c / length, (omega - omega_ref) / omega_scale]`` of a balance."""

    def __init__(self, hb: Balance, length_m: float, omega_ref: float, omega_scale: float):
        self.hb = hb
        self.length = length_m
        self.omega_ref = omega_ref
        self.omega_scale = omega_scale
        self.size = hb.n * hb.h

    def unpack(self, y: np.ndarray):
        c = y[:self.size].reshape(self.hb.n, self.hb.h) * self.length
        return c, self.omega_ref + y[-1] * self.omega_scale

    def pack(self, c: np.ndarray, omega: float) -> np.ndarray:
        return np.concatenate([np.ravel(c) / self.length,
                               [(omega - self.omega_ref) / self.omega_scale]])

    def equations(self, y: np.ndarray):
        """Residual (size,) and Jacobian (size, size + 1) in scaled unknowns."""
        c, omega = self.unpack(y)
        r, jc, dw = self.hb.residual(c, omega)
        jac = np.empty((self.size, self.size + 1))
        jac[:, :-1] = jc * self.length
        jac[:, -1] = dw * self.omega_scale
        return r, jac

    def tangent(self, y: np.ndarray, direction: np.ndarray):
        """Return the unit tangent at ``y`` (oriented along ``direction``) and the Jacobian."""
        _, jac = self.equations(y)
        t = np.linalg.solve(np.vstack([jac, direction]), np.eye(self.size + 1)[-1])
        return t / np.linalg.norm(t), jac

    def coefficient_jacobian(self, jac: np.ndarray) -> np.ndarray:
        """Unscaled d(residual)/d(coefficients), 1/s^2, from a scaled Jacobian."""
        return jac[:, :-1] / self.length


def _newton(fun: Callable, y0: np.ndarray, tol: float = 1e-10, max_iter: int = 10):
    """Newton on a square system ``fun(y) -> (g, dg/dy)``; returns (y, iterations) or None."""
    y = y0.copy()
    for it in range(1, max_iter + 1):
        try:
            g, jac = fun(y)
            dy = np.linalg.solve(jac, -g)
        except (SimulationError, np.linalg.LinAlgError):
            return None
        if not np.all(np.isfinite(dy)):
            return None
        y = y + dy
        if np.max(np.abs(dy)) < tol:
            return y, it
    return None


def _continue(curve: _Curve, y0: np.ndarray, direction: np.ndarray, step: float,
              max_step: float, stop: Callable[[np.ndarray], bool],
              max_points: int = 2000, min_step: float = 1e-7,
              step_limit: Optional[Callable] = None) -> Tuple[List, str]:
    """
    Pseudo-arclength continuation from the solution ``y0`` (see the module).

    ``step_limit(y, t)``, if given, bounds the next step from the point and its tangent.
    Returns the list of ``(y, tangent, jacobian)`` along the curve and a status message
    ('' when ``stop`` ended it).
    """
    t, jac0 = curve.tangent(y0, direction)
    points = [(y0, t, jac0)]
    y = y0
    while len(points) < max_points:
        if stop(y):
            return points, ''
        if step_limit is not None:
            step = min(step, step_limit(y, t))
        while True:
            pred = y + step * t

            def aug(z, pred=pred, t=t):
                r, jac = curve.equations(z)
                return (np.concatenate([r / curve.omega_ref ** 2 / curve.length,
                                        [t @ (z - pred)]]),
                        np.vstack([jac / curve.omega_ref ** 2 / curve.length, t]))

            out = _newton(aug, pred)
            if out is not None:
                try:
                    t_new, jac_new = curve.tangent(out[0], t)
                except SimulationError:
                    t_new, jac_new = -t, None
                if jac_new is not None and (t_new @ t > 0.966 or step <= 4 * min_step):
                    break
            step *= 0.5
            if step < min_step:
                return points, (f'continuation stopped: step below {min_step:g} at '
                                f'{curve.unpack(y)[1] / (2 * math.pi):.6g} Hz '
                                '(force out of range or a sharp turn)')
        y, iterations = out
        points.append((y, t_new, jac_new))
        t = t_new
        if iterations <= 3:
            step = min(1.5 * step, max_step)
    return points, f'continuation stopped after {max_points} points'


def _amplitudes(hb: Balance, c: np.ndarray) -> np.ndarray:
    """``max_t |x_i|`` of coefficients in the balance's basis, m."""
    tau = 2.0 * math.pi * np.arange(DENSE_SAMPLES) / DENSE_SAMPLES
    e = _real_basis(tau, hb.n_h)[:, hb.cols]
    return np.max(np.abs(c @ e.T), axis=1)


def _orbit(hb: Balance, c: np.ndarray, omega: float, stability: Optional[str],
           config: SimConfig, jc: Optional[np.ndarray] = None) -> HarmonicOrbit:
    orbit = HarmonicOrbit(frequency_hz=omega / (2.0 * math.pi),
                          coefficients_m=hb.full_coefficients(c),
                          amplitude_m=_amplitudes(hb, c))
    if stability is None:
        return orbit
    if stability == 'hill':
        mu = hb.hill_multipliers(c, omega, jc)
    else:
        mu = monodromy_multipliers(config, orbit)
    return HarmonicOrbit(frequency_hz=orbit.frequency_hz, coefficients_m=orbit.coefficients_m,
                         amplitude_m=orbit.amplitude_m, floquet_multipliers=mu)


def _check_mode(config: SimConfig, mode: int) -> int:
    if not 1 <= mode <= config.modes.count:
        raise ParameterError(f'mode: must be between 1 and {config.modes.count}, got {mode}')
    return mode - 1


def _with_taylor_terms(config: SimConfig, taylor_terms: Optional[int]) -> SimConfig:
    if taylor_terms is None or taylor_terms == config.electrodes.taylor_terms:
        return config
    return replace(config, electrodes=replace(config.electrodes, taylor_terms=int(taylor_terms)))


@dataclass(frozen=True)
class Backbone:
    """
    Backbone (nonlinear normal mode) of the n-theta mode, eq. (33), Fig. 4.

    Attributes
    ----------
    mode : int
        n of the n-theta mode.
    taylor_terms : int
        N_T of the force (0: untruncated).
    harmonics : int
        N_h of the ansatz.
    amplitude_m : ndarray, shape (p,)
        ``max_t |q_mode(t)|`` of each point, m (increasing along the curve).
    frequency_hz : ndarray, shape (p,)
        Frequency of each point, Hz.
    orbits : tuple of HarmonicOrbit
        The periodic orbits (all coordinates).
    status : str
        Empty when the requested amplitude was reached, else why the continuation stopped.

    """

    mode: int
    taylor_terms: int
    harmonics: int
    amplitude_m: np.ndarray
    frequency_hz: np.ndarray
    orbits: Tuple[HarmonicOrbit, ...]
    status: str = ''

    def frequency_at(self, amplitude_m: float) -> float:
        """Frequency (Hz) at ``amplitude_m`` (m), by cubic interpolation between points."""
        a, f = self.amplitude_m, self.frequency_hz
        if not a[0] <= amplitude_m <= a[-1]:
            raise ParameterError(f'amplitude_m: {amplitude_m!r} outside the backbone '
                                 f'[{a[0]!r}, {a[-1]!r}]')
        return float(CubicSpline(a, f)(amplitude_m))

    def to_csv(self, path) -> None:
        """Write ``amplitude_m,frequency_hz`` rows to ``path``."""
        np.savetxt(path, np.column_stack([self.amplitude_m, self.frequency_hz]),
                   delimiter=',', header='amplitude_m,frequency_hz', comments='', fmt='%.10g')


def backbone(config: SimConfig, mode: int = 1, taylor_terms: Optional[int] = None,
             max_amplitude_m: float = 6.5e-6, harmonics: int = 12,
             start_amplitude_m: float = 0.02e-6, max_step: float = 0.25) -> Backbone:
    """
    Backbone of the n-theta mode by harmonic balance and pseudo-arclength continuation.

    Parameters
    ----------
    config : SimConfig
        All coordinates of the configuration take part (no damping, no drive).
    mode : int
        n of the n-theta mode (its cos coordinate).
    taylor_terms : int or None
        N_T to use instead of ``config.electrodes.taylor_terms`` (0: untruncated).
    max_amplitude_m : float
        Continue until ``max |q_mode| = max_amplitude_m``, m (the last point is solved there).
    harmonics : int
        N_h, harmonics of the ansatz.
    start_amplitude_m : float
        Fundamental amplitude of the first point (the linear mode), m.
    max_step : float
        Largest arclength step, in units of 1 um and ``f_mode / 100``.

    Returns
    -------
    Backbone
        Its ``status`` says why it stopped short of ``max_amplitude_m``, if it did: the force
        left its range (contact, ``|w| >= d_g`` for the series) or the amplitude turned back
        (near pull-in, e.g. about 8.4 um with the untruncated force: beyond, the harmonic
        series no longer represents the orbit and the points are not kept).

    Raises
    ------
    ParameterError
        Invalid ``mode``, ``taylor_terms`` or ``harmonics``.
    SimulationError
        No orbit at the start amplitude.

    """
    index = _check_mode(config, mode)
    config = _with_taylor_terms(config, taylor_terms)
    hb = Balance(config, harmonics, cosine_only=True, damped=False, drive_m_s2=0.0)
    omega0 = hb.omega_n[index]
    curve = _Curve(hb, 1e-6, omega0, 0.01 * omega0)
    fixed = index * hb.h + 1    # the cos(omega t) coefficient of q_mode
    c0 = np.zeros((hb.n, hb.h))
    c0[index, 1] = start_amplitude_m
    y0 = curve.pack(c0, omega0)
    pin = np.eye(curve.size + 1)[fixed]

    def first(z):
        r, jac = curve.equations(z)
        return np.concatenate([r, [z[fixed] - y0[fixed]]]), np.vstack([jac, pin])

    out = _newton(first, y0)
    if out is None:
        raise SimulationError(f'backbone: no periodic orbit at {start_amplitude_m:g} m')

    def amplitude(z):
        return _amplitudes(hb, curve.unpack(z)[0])[index]

    history = [0.0]

    def stop(z):
        a = amplitude(z)
        if a < history[-1]:
            return True   # turned back: reported below, the point is dropped
        history.append(a)
        return a >= max_amplitude_m

    points, status = _continue(curve, out[0], pin, 0.05, max_step, stop)
    ys = [p[0] for p in points]
    if not status and amplitude(ys[-1]) < max_amplitude_m:
        ys.pop()
        f_hz = curve.unpack(ys[-1])[1] / (2.0 * math.pi)
        status = (f'the amplitude turned back at {history[-1]:.4g} m, {f_hz:.6g} Hz: the '
                  'orbit nears pull-in, where the harmonic series stops converging')
    if not status and len(ys) > 1:
        last = _solve_at_amplitude(curve, index, ys[-2], ys[-1], max_amplitude_m)
        if last is not None:
            ys[-1] = last
    orbits = tuple(_orbit(hb, *curve.unpack(y), None, config) for y in ys)
    return Backbone(mode=mode, taylor_terms=config.electrodes.taylor_terms,
                    harmonics=harmonics,
                    amplitude_m=np.array([o.amplitude_m[index] for o in orbits]),
                    frequency_hz=np.array([o.frequency_hz for o in orbits]),
                    orbits=orbits, status=status)


def _solve_at_amplitude(curve: _Curve, index: int, y_low: np.ndarray, y_high: np.ndarray,
                        target_m: float) -> Optional[np.ndarray]:
    """Orbit of the curve with ``max |x_index| = target_m``, from two bracketing points."""
    hb = curve.hb
    tau = 2.0 * math.pi * np.arange(DENSE_SAMPLES) / DENSE_SAMPLES
    e = _real_basis(tau, hb.n_h)[:, hb.cols]
    a_lo = _amplitudes(hb, curve.unpack(y_low)[0])[index]
    a_hi = _amplitudes(hb, curve.unpack(y_high)[0])[index]
    w = (target_m - a_lo) / (a_hi - a_lo) if a_hi != a_lo else 1.0
    guess = y_low + w * (y_high - y_low)

    def fun(z):
        r, jac = curve.equations(z)
        x = curve.unpack(z)[0][index] @ e.T
        j = int(np.argmax(np.abs(x)))
        # envelope theorem: d max|x| / dc = sign(x(tau*)) e(tau*) at the maximum
        grad = np.zeros(curve.size + 1)
        grad[index * hb.h:(index + 1) * hb.h] = np.sign(x[j]) * e[j] * curve.length
        return (np.concatenate([r, [(abs(x[j]) - target_m) * curve.omega_ref ** 2]]),
                np.vstack([jac, grad * curve.omega_ref ** 2]))

    out = _newton(fun, guess)
    return None if out is None else out[0]


def backbone_frequency(config: SimConfig, amplitude_m: float, mode: int = 1,
                       taylor_terms: Optional[int] = None, harmonics: int = 12,
                       start_amplitude_m: float = 0.02e-6) -> float:
    """
    Backbone frequency (Hz) at ``max |q_mode| = amplitude_m`` (m), solved there exactly.

    Parameters
    ----------
    config : SimConfig
        The configuration.
    amplitude_m : float
        Amplitude ``max_t |q_mode(t)|``, m.
    mode : int
        n of the n-theta mode.
    taylor_terms : int or None
        N_T override (0: untruncated).
    harmonics : int
        N_h.
    start_amplitude_m : float
        Fundamental amplitude of the continuation's first point, m (below ``amplitude_m``).

    Returns
    -------
    float
        Frequency, Hz.

    """
    bb = backbone(config, mode, taylor_terms, max_amplitude_m=amplitude_m,
                  harmonics=harmonics, start_amplitude_m=start_amplitude_m)
    if bb.status or abs(bb.amplitude_m[-1] - amplitude_m) > 1e-9 * amplitude_m:
        raise SimulationError(f'backbone did not reach {amplitude_m:g} m: {bb.status}')
    return float(bb.frequency_hz[-1])


@dataclass(frozen=True)
class ForcedResponse:
    """
    Damped response to the drive ``A_e cos(2 pi f t)`` on q2 (Fig. 9), along the curve.

    Attributes
    ----------
    mode : int
        n of the coordinate whose amplitude is reported.
    drive_amplitude : float
        A_e, m/s^2.
    harmonics : int
        N_h of the ansatz.
    taylor_terms : int
        N_T of the force (0: untruncated).
    frequency_hz : ndarray, shape (p,)
        Drive frequency of each point, Hz (not monotonic: the curve folds).
    amplitude_m : ndarray, shape (p,)
        ``max_t |q_mode(t)|``, m.
    stable : ndarray of bool, shape (p,)
        All Floquet multipliers inside the unit circle.
    orbits : tuple of HarmonicOrbit
        The periodic orbits with their Floquet multipliers.
    fold_frequencies_hz : tuple of float
        Frequencies of the turning points (saddle-nodes) of the curve, ascending, Hz
        (where the drive frequency along the curve changes direction).
    stability_method : str
        'hill' or 'monodromy'.
    status : str
        Empty when the frequency range was covered, else why the continuation stopped.

    """

    mode: int
    drive_amplitude: float
    harmonics: int
    taylor_terms: int
    frequency_hz: np.ndarray
    amplitude_m: np.ndarray
    stable: np.ndarray
    orbits: Tuple[HarmonicOrbit, ...]
    fold_frequencies_hz: Tuple[float, ...]
    stability_method: str = 'hill'
    status: str = ''

    def crossings(self, frequency_hz: float) -> List[Tuple[int, float]]:
        """
        Segments of the curve that cross ``frequency_hz`` (Hz).

        Returns ``(k, w)`` pairs: the crossing is at ``w`` (0..1) between points k and k + 1.
        """
        f = self.frequency_hz
        out = []
        for k in range(f.size - 1):
            lo, hi = f[k], f[k + 1]
            if (lo - frequency_hz) * (hi - frequency_hz) > 0.0 or lo == hi:
                continue
            if hi == frequency_hz and k + 2 < f.size:
                continue   # counted on the next segment
            out.append((k, float((frequency_hz - lo) / (hi - lo))))
        return out

    def branches_at(self, frequency_hz: float) -> List[Tuple[float, bool]]:
        """
        Every ``(amplitude_m, stable)`` of the curve at ``frequency_hz`` (Hz), lowest first.

        Amplitudes (m) are interpolated linearly between the two points that bracket the
        frequency on each segment of the curve; stability is that of the nearer point
        (:func:`forced_orbits_at` solves them exactly).
        """
        a = self.amplitude_m
        return sorted((float(a[k] + w * (a[k + 1] - a[k])),
                       bool(self.stable[k] if w < 0.5 else self.stable[k + 1]))
                      for k, w in self.crossings(frequency_hz))

    def to_csv(self, path) -> None:
        """Write ``frequency_hz,amplitude_m,stable`` rows (stable as 1/0) to ``path``."""
        rows = np.column_stack([self.frequency_hz, self.amplitude_m,
                                self.stable.astype(float)])
        np.savetxt(path, rows, delimiter=',', header='frequency_hz,amplitude_m,stable',
                   comments='', fmt=['%.10g', '%.10g', '%d'])


def frf(config: SimConfig, mode: int = 2, f_range_hz: Sequence[float] = (15.70e3, 15.85e3),
        drive_amplitude: Optional[float] = None, harmonics: int = 3,
        taylor_terms: Optional[int] = None, stability: str = 'hill',
        max_points: int = 2000) -> ForcedResponse:
    """
    Compute the forced response around the 2theta resonance by HB and continuation.

    Parameters
    ----------
    config : SimConfig
        Modes, Q factors and electrodes (all coordinates take part).
    mode : int
        n of the coordinate whose amplitude is reported (the drive is always on q2).
    f_range_hz : (float, float)
        Drive-frequency range, Hz: the continuation starts at the low end from the linear
        response and runs, through the folds, until it passes the high end.
    drive_amplitude : float or None
        A_e, m/s^2 (default ``config.drive.amplitude``).
    harmonics : int
        N_h of the ansatz.
    taylor_terms : int or None
        N_T override (0: untruncated).
    stability : str
        'hill' (Hill's method, default) or 'monodromy' (variational equations, slower).
    max_points : int
        Upper bound on the number of continuation points.

    Returns
    -------
    ForcedResponse

    Raises
    ------
    ParameterError
        Invalid ``mode``, ``f_range_hz``, ``stability`` or a zero drive.
    SimulationError
        No orbit at the start frequency.

    """
    if stability not in ('hill', 'monodromy'):
        raise ParameterError(f"stability: must be 'hill' or 'monodromy', got {stability!r}")
    index = _check_mode(config, mode)
    f_lo, f_hi = float(f_range_hz[0]), float(f_range_hz[1])
    if not 0.0 < f_lo < f_hi:
        raise ParameterError(f'f_range_hz: need 0 < low < high, got {f_range_hz!r}')
    config = _with_taylor_terms(config, taylor_terms)
    a_e = config.drive.amplitude if drive_amplitude is None else float(drive_amplitude)
    if a_e == 0.0:
        raise ParameterError('drive_amplitude: the drive is off (0 m/s^2)')
    hb = Balance(config, harmonics, cosine_only=False, damped=True, drive_m_s2=a_e)
    w2 = hb.omega_n[1]
    q2 = config.modes.coordinate_quality_factors()[1]
    peak = abs(a_e) * q2 / w2 ** 2
    curve = _Curve(hb, peak, w2, w2 / q2)
    omega_lo, omega_hi = 2.0 * math.pi * f_lo, 2.0 * math.pi * f_hi
    # linear response at the start: (Omega^2 - w^2) a + c w b = A_e, -c w a + (...) b = 0
    c0 = np.zeros((hb.n, hb.h))
    det_a = w2 ** 2 - omega_lo ** 2
    det_b = hb.damping[1] * omega_lo
    c0[1, 1:3] = np.linalg.solve([[det_a, det_b], [-det_b, det_a]], [a_e, 0.0])
    y0 = curve.pack(c0, omega_lo)
    pin = np.eye(curve.size + 1)[-1]

    def first(z):
        r, jac = curve.equations(z)
        return np.concatenate([r, [z[-1] - y0[-1]]]), np.vstack([jac, pin])

    out = _newton(first, y0)
    if out is None:
        raise SimulationError(f'frf: no periodic orbit at {f_lo} Hz')
    span = (omega_hi - omega_lo) / curve.omega_scale
    drive = slice(hb.h, 2 * hb.h)   # the coefficients of q2, in units of the linear peak

    def step_limit(z, t):
        # The resonance is a spike (its width is 1 in these units, f / Q): a step may change
        # the q2 response by 10 % at most, and is at most 0.25 bandwidth near the peak.
        g = np.linalg.norm(z[drive])
        rate = abs(z[drive] @ t[drive]) / max(g, 1e-300)
        limit = 0.1 * (g + 0.01) / max(rate, 1e-300)
        return min(limit, 0.25) if g > 0.05 else limit

    points, status = _continue(curve, out[0], pin, 0.01 * span, span / 100.0,
                               lambda z: curve.unpack(z)[1] >= omega_hi,
                               max_points=max_points, step_limit=step_limit)
    orbits = tuple(_orbit(hb, *curve.unpack(y), stability, config,
                          curve.coefficient_jacobian(jac)) for y, _, jac in points)
    tangents = np.array([t[-1] for _, t, _ in points])
    freqs = np.array([o.frequency_hz for o in orbits])
    folds = []
    for k in range(len(points) - 1):
        if tangents[k] * tangents[k + 1] < 0.0:
            w = tangents[k] / (tangents[k] - tangents[k + 1])
            folds.append(float(freqs[k] + w * (freqs[k + 1] - freqs[k])))
    return ForcedResponse(mode=mode, drive_amplitude=a_e, harmonics=harmonics,
                          taylor_terms=config.electrodes.taylor_terms,
                          frequency_hz=freqs,
                          amplitude_m=np.array([o.amplitude_m[index] for o in orbits]),
                          stable=np.array([o.stable for o in orbits], dtype=bool),
                          orbits=orbits, fold_frequencies_hz=tuple(sorted(folds)),
                          stability_method=stability, status=status)


def forced_orbit(config: SimConfig, frequency_hz: float, guess: HarmonicOrbit,
                 drive_amplitude: Optional[float] = None,
                 stability: str = 'hill') -> HarmonicOrbit:
    """
    Solve the forced periodic orbit at a fixed drive frequency, by Newton from a guess.

    Parameters
    ----------
    config : SimConfig
        The configuration.
    frequency_hz : float
        Drive frequency, Hz.
    guess : HarmonicOrbit
        Starting orbit (e.g. a point of :func:`frf` next to ``frequency_hz``); its N_h is used.
    drive_amplitude : float or None
        A_e, m/s^2 (default ``config.drive.amplitude``).
    stability : str
        'hill' or 'monodromy'.

    Returns
    -------
    HarmonicOrbit

    """
    a_e = config.drive.amplitude if drive_amplitude is None else float(drive_amplitude)
    hb = Balance(config, guess.harmonics, cosine_only=False, damped=True, drive_m_s2=a_e)
    omega = 2.0 * math.pi * frequency_hz
    scale = max(float(np.max(np.abs(guess.coefficients_m))), 1e-12)

    def fun(z):
        r, jc, _ = hb.residual(z.reshape(hb.n, hb.h) * scale, omega)
        return r, jc * scale

    out = _newton(fun, guess.coefficients_m.ravel() / scale)
    if out is None:
        raise SimulationError(f'forced orbit at {frequency_hz} Hz did not converge')
    return _orbit(hb, out[0].reshape(hb.n, hb.h) * scale, omega, stability, config)


def forced_orbits_at(config: SimConfig, response: ForcedResponse, frequency_hz: float,
                     stability: Optional[str] = None) -> List[HarmonicOrbit]:
    """
    Every periodic orbit of a forced response at one drive frequency, solved exactly there.

    Parameters
    ----------
    config : SimConfig
        The configuration the response was computed for (its N_T is overridden by the
        response's).
    response : ForcedResponse
        The continuation result; each crossing of ``frequency_hz`` gives a starting guess
        (coefficients interpolated between the two bracketing points).
    frequency_hz : float
        Drive frequency, Hz.
    stability : str or None
        'hill' or 'monodromy' (default: the response's method).

    Returns
    -------
    list of HarmonicOrbit
        Sorted by ``max |q_mode|``, lowest first (one per branch: lower, unstable, upper).

    """
    config = _with_taylor_terms(config, response.taylor_terms)
    index = _check_mode(config, response.mode)
    orbits = []
    for k, w in response.crossings(frequency_hz):
        a, b = response.orbits[k], response.orbits[k + 1]
        guess = HarmonicOrbit(frequency_hz=frequency_hz,
                              coefficients_m=(1.0 - w) * a.coefficients_m
                              + w * b.coefficients_m,
                              amplitude_m=(1.0 - w) * a.amplitude_m + w * b.amplitude_m)
        orbits.append(forced_orbit(config, frequency_hz, guess, response.drive_amplitude,
                                   stability or response.stability_method))
    return sorted(orbits, key=lambda o: o.amplitude_m[index])
