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
Electrostatic generalised force of the ring (eqs. 18-26), evaluated by exact quadrature.

Conventions
-----------
Coordinates ``x = [q_1 .. q_N, q_1^s .. q_N^s]`` (the companions only when enabled); the
radial displacement is ``w(theta) = sum_n q_n cos(n theta) + q_n^s sin(n theta)`` (eq. 2) and
``u = w / d_g``. Outward ``w`` closes the OUTER gap ``d_g - w`` and opens the inner one.

The electrostatic energy (eq. 21) is ``E_c = A_eps * int_0^{2 pi} e(u(theta)) d theta`` with

* truncated (``N_T >= 3``): ``e(u) = sum_{k=0}^{N_T} (r_o V_o^2 + (-1)^k r_i V_i^2) u^k``;
* untruncated (``N_T = 0``): ``e(u) = r_o V_o^2 / (1 - u) + r_i V_i^2 / (1 + u)``.

The generalised force is ``+dE_c/dq`` (eq. 23, right-hand side: it softens). The terms
``k <= 2`` are removed when the Table 1 frequencies already contain the linear electrostatic
stiffness (``fold_linear_stiffness``, the paper's choice, section 3.1): the k = 0, 1 terms give
no force (the modes have zero mean), the k = 2 term is K_c of eq. (26). What remains is
``-F_nl`` of eq. (28), divided by the modal mass of each coordinate.

Quadrature
----------
``int_0^{2 pi} e'(u) phi_i d theta`` is evaluated by the trapezoidal rule on M equally spaced
angles. It is exact for trigonometric polynomials of degree < M; with the Taylor series the
integrand ``u^(k-1) cos(n theta)`` has degree at most ``N_T * N_R``, so
``M = N_T * N_R + 1`` points give the exact polynomial force (the eq. 35 test checks every
coefficient). The untruncated integrand is analytic for ``|u| < 1``; its Fourier coefficients
fall like ``rho^m`` with ``rho = (1 - sqrt(1 - a^2)) / a`` for ``a = max |u|`` per harmonic,
so ``M = 128 * N_R`` gives round-off accuracy up to ``|u| ~ 0.95``.

The M angles (M a multiple of 4) fall into orbits
``{theta, pi - theta, -theta, pi + theta}`` (members 0 to 3,
:func:`ring_gyro_sim.core.kernels.orbit_angle`) of the ring's symmetries; the kernel stores
one representative per orbit in [0, pi/2] and assembles ``w`` and the force at the four
members with exact sign flips (``parity`` of each coordinate). Sums that vanish by symmetry
then vanish exactly in floating point: symmetric
electrodes keep q2 = 0 bit for bit after a q1 shock from rest (eq. 36), an x shock keeps the
sine companions at 0. Without companions the two members +-theta are equal and P is
evaluated at two angles per orbit, which is the cost of the plain half-circle rule.
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ring_gyro_sim.core import kernels
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.params import SimConfig

__all__ = ['SYMMETRY_TOLERANCE', 'ForceModel', 'coordinate_harmonics', 'mode_shapes',
           'quadrature_points', 'coordinate_parity', 'build_force_model',
           'nonlinear_acceleration', 'scratch_size', 'contact_angle', 'full_grid', 'jacobian',
           'electrostatic_energy', 'mechanical_energy', 'build_stops',
           'PULL_IN_GRID', 'static_pull_in_displacement']

SYMMETRY_TOLERANCE = 1e-12
"""r_o V_o^2 and r_i V_i^2 closer than this (relative) are taken as equal: users write
symmetric voltages as ``V_i = V_o sqrt(r_o / r_i)``, which rounds; treating them as exactly
symmetric makes the even terms vanish exactly (q2 stays 0 bit for bit, eq. 36)."""


@dataclass(frozen=True)
class ForceModel:
    """
    Flat arrays of the electrostatic force, as the kernels take them.

    Attributes
    ----------
    harmonics : ndarray of int, shape (n,)
        Harmonic number n of every coordinate.
    sine : ndarray of bool, shape (n,)
        True for the sin(n theta) companions.
    theta : ndarray, shape (R,)
        Orbit representatives in [0, pi/2], rad (R = M/4 + 1).
    weights : ndarray, shape (R,)
        Trapezoidal weight per orbit member, rad (halved at 0 and pi/2, whose orbits have
        two distinct members counted twice).
    parity : ndarray of int, shape (n,)
        Symmetry class of each coordinate: bit b set = odd under orbit member ``2**b``, i.e.
        bit 0 = odd under theta -> pi - theta, bit 1 = odd under theta -> -theta (sine).
    signs : ndarray, shape (2, n)
        The same as +-1.0: parity under theta -> pi - theta and under theta -> -theta.
    m_points : int
        M, the number of quadrature angles on the full circle.
    basis : ndarray, shape (R, n)
        ``phi_i(theta_j)`` (cos or sin) at the representatives.
    kbasis : ndarray, shape (n, 4 R)
        The same at the four orbit members, signed and divided by d_g, as the kernels take it
        (:func:`ring_gyro_sim.core.kernels.member_basis`).
    projection : ndarray, shape (n, R)
        ``weight_j phi_i(theta_j) / m_i``, rad/kg.
    poly : ndarray, shape (D + 1,)
        Coefficients of ``P(u) = A_eps / d_g * e'(u)`` in powers of u, N (truncated model).
    energy_poly : ndarray, shape (D + 2,)
        Coefficients of ``A_eps * e(u)`` in powers of u, J/rad (truncated model).
    outer, inner : float
        ``A_eps r_o V_o^2`` and ``A_eps r_i V_i^2``, J/rad.
    gap : float
        d_g, m.
    taylor_terms : int
        N_T (0 = untruncated).
    fold : bool
        Linear (k <= 2) terms removed.
    inner_contact : bool
        An inner electrode is present (V_i != 0): ``u <= -1`` is contact there.
    masses : ndarray, shape (n,)
        Generalised masses, kg.
    kernel : kernels.Force
        The arrays and numbers above that the force kernels take, as one argument.

    """

    harmonics: np.ndarray
    sine: np.ndarray
    theta: np.ndarray
    weights: np.ndarray
    parity: np.ndarray
    signs: np.ndarray
    m_points: int
    basis: np.ndarray
    kbasis: np.ndarray
    projection: np.ndarray
    poly: np.ndarray
    energy_poly: np.ndarray
    outer: float
    inner: float
    gap: float
    taylor_terms: int
    fold: bool
    inner_contact: bool
    masses: np.ndarray
    kernel: kernels.Force

    @property
    def n_coordinates(self) -> int:
        """Return the number of simulated coordinates."""
        return int(self.harmonics.size)


def coordinate_harmonics(n_modes: int, companions: bool):
    """Harmonic numbers and sine flags of the coordinates ``[q_1..q_N, q_1^s..q_N^s]``."""
    harmonics = np.arange(1, n_modes + 1, dtype=np.int64)
    sine = np.zeros(n_modes, dtype=np.bool_)
    if companions:
        harmonics = np.concatenate([harmonics, harmonics])
        sine = np.concatenate([sine, np.ones(n_modes, dtype=np.bool_)])
    return harmonics, sine


def mode_shapes(harmonics: np.ndarray, sine: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``phi_i(theta_j)``, shape (len(theta), n): cos(n theta) or sin(n theta)."""
    arg = np.outer(theta, harmonics)
    return np.where(sine[None, :], np.sin(arg), np.cos(arg))


def quadrature_points(n_modes: int, taylor_terms: int) -> int:
    """Return the number M of quadrature angles on the circle (a multiple of 4, see the module)."""
    if taylor_terms == 0:
        return 128 * n_modes
    m = max(taylor_terms * n_modes + 1, 8 * n_modes + 1)
    return 4 * ((m + 3) // 4)


def coordinate_parity(harmonics: np.ndarray, sine: np.ndarray) -> np.ndarray:
    """Symmetry class of each coordinate (see :class:`ForceModel`)."""
    odd_reflection = np.where(sine, harmonics % 2 == 0, harmonics % 2 == 1)
    return (odd_reflection.astype(np.int64) + 2 * sine.astype(np.int64)).astype(np.int64)


def build_force_model(config: SimConfig) -> ForceModel:
    """Assemble the :class:`ForceModel` of a configuration."""
    e = config.electrodes
    n_modes = config.modes.count
    harmonics, sine = coordinate_harmonics(n_modes, config.modes.companions)
    masses = np.asarray(config.modal_masses(), dtype=np.float64)
    m_points = quadrature_points(n_modes, e.taylor_terms)
    parity = coordinate_parity(harmonics, sine)
    signs = np.ascontiguousarray(np.stack([np.where(parity & 1, -1.0, 1.0),
                                           np.where(parity & 2, -1.0, 1.0)]))
    reps = m_points // 4 + 1
    theta = 2.0 * np.pi * np.arange(reps) / m_points
    weights = np.full(reps, 2.0 * np.pi / m_points)
    weights[0] *= 0.5
    weights[-1] *= 0.5
    basis = np.ascontiguousarray(mode_shapes(harmonics, sine, theta))
    projection = np.ascontiguousarray(weights[None, :] * basis.T / masses[:, None])
    a_eps = config.a_eps
    outer = a_eps * config.outer_radius * e.outer_voltage ** 2
    inner = a_eps * config.inner_radius * e.inner_voltage ** 2
    if inner != outer and abs(inner - outer) <= SYMMETRY_TOLERANCE * max(inner, outer):
        inner = outer  # symmetric electrodes up to the rounding of the inputs (eq. 36)
    fold = e.fold_linear_stiffness
    k_min = 3 if fold else 1
    n_t = e.taylor_terms
    poly = np.zeros(max(n_t, 1), dtype=np.float64)
    energy_poly = np.zeros(max(n_t, 1) + 1, dtype=np.float64)
    for k in range(k_min, n_t + 1):
        c_k = outer + (-1) ** k * inner
        poly[k - 1] = k * c_k / e.gap
        energy_poly[k] = c_k
    kbasis = kernels.member_basis(basis, signs, e.gap)
    inner_contact = bool(e.inner_voltage != 0.0)
    series, series_u2 = kernels.estrin_layout(poly)
    kernel = kernels.Force(kbasis=kbasis, projection=projection, signs=signs, poly=poly,
                           taylor_terms=int(n_t), outer=float(outer), inner=float(inner),
                           fold=bool(fold), inner_contact=inner_contact, gap=float(e.gap),
                           series=series, series_u2=series_u2)
    return ForceModel(harmonics=harmonics, sine=sine, theta=theta, weights=weights,
                      parity=parity, signs=signs, m_points=m_points, basis=basis,
                      kbasis=kbasis, projection=projection, poly=poly, energy_poly=energy_poly,
                      outer=outer, inner=inner, gap=e.gap, taylor_terms=n_t, fold=fold,
                      inner_contact=inner_contact, masses=masses, kernel=kernel)


def _check_state(x: np.ndarray, model: ForceModel) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (model.n_coordinates,):
        raise ValueError(f'x: expected shape ({model.n_coordinates},), got {x.shape}')
    if not np.all(np.isfinite(x)):
        raise ValueError('x: must be finite')
    return np.ascontiguousarray(x)


def nonlinear_acceleration(x: np.ndarray, model: ForceModel) -> np.ndarray:
    """
    Electrostatic generalised force divided by the modal masses, m/s^2.

    This is ``-F_nl`` of eq. (28) (the linear part excluded when folded).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Coordinates, m.
    model : ForceModel
        Precomputed basis, projection and electrode data (:func:`build_force_model`).

    Returns
    -------
    ndarray, shape (n,)

    Raises
    ------
    SimulationError
        The state is out of the model's range (contact or ``|w| >= d_g`` for the series).

    """
    x = _check_state(x, model)
    out = np.zeros_like(x)
    work = np.empty(scratch_size(model))
    info = np.zeros(2, dtype=np.int64)
    kernels.nl_accel(x, model.kernel, work, out, info)
    if info[0] != 0:
        raise SimulationError(kernels.describe_status(int(info[0]), contact_angle(model, info)))
    return out


def scratch_size(model: ForceModel) -> int:
    """Floats of scratch the force kernel needs."""
    return 8 * model.theta.size


def contact_angle(model: ForceModel, info) -> float:
    """Angle (rad) encoded in a kernel's ``info[1]`` (column ``k R + j`` of ``kbasis``)."""
    member, rep = divmod(int(info[1]), model.theta.size)
    return kernels.orbit_angle(float(model.theta[rep]), member)


def full_grid(model: ForceModel):
    """All M quadrature angles (rad), their weights (rad) and mode shapes (M, n)."""
    theta = 2.0 * np.pi * np.arange(model.m_points) / model.m_points
    weights = np.full(model.m_points, 2.0 * np.pi / model.m_points)
    return theta, weights, mode_shapes(model.harmonics, model.sine, theta)


def jacobian(x: np.ndarray, model: ForceModel) -> np.ndarray:
    """d(nonlinear_acceleration)/dx, shape (n, n), 1/s^2 (exact by the same quadrature)."""
    x = _check_state(x, model)
    _, weights, basis = full_grid(model)
    u = basis @ x / model.gap
    dp = _poly_derivative(u, model)
    return ((basis.T * (weights * dp)[None, :]) @ basis) / model.masses[:, None]


def _poly_derivative(u: np.ndarray, model: ForceModel) -> np.ndarray:
    """dP/dw at the quadrature points, N/m."""
    if model.taylor_terms:
        d = np.polynomial.polynomial.polyder(model.poly)
        return np.polynomial.polynomial.polyval(u, d) / model.gap
    o, i = model.outer, model.inner
    if model.fold:
        val = o * (2.0 / (1.0 - u) ** 3 - 2.0) + i * (2.0 / (1.0 + u) ** 3 - 2.0)
    else:
        val = o * 2.0 / (1.0 - u) ** 3 + i * 2.0 / (1.0 + u) ** 3
    return val / model.gap ** 2


def electrostatic_energy(x: np.ndarray, model: ForceModel) -> float:
    """Nonlinear electrostatic energy ``E_c`` (terms of the force only), J."""
    x = _check_state(x, model)
    _, weights, basis = full_grid(model)
    u = basis @ x / model.gap
    if model.taylor_terms:
        e = np.polynomial.polynomial.polyval(u, model.energy_poly)
    else:
        if model.fold:
            eo = u ** 3 / (1.0 - u)
            ei = -u ** 3 / (1.0 + u)
        else:
            eo = 1.0 / (1.0 - u) - 1.0
            ei = 1.0 / (1.0 + u) - 1.0
        e = model.outer * eo + model.inner * ei
    return float(np.dot(weights, e))


def mechanical_energy(x: np.ndarray, v: np.ndarray, omega: np.ndarray,
                      model: ForceModel) -> float:
    """
    Conserved energy of the undamped, unforced system, J.

    ``H = sum_i m_i (v_i^2 + omega_i^2 x_i^2) / 2 - E_c(x)``.
    """
    m = model.masses
    return float(0.5 * np.sum(m * (v ** 2 + (omega * x) ** 2)) - electrostatic_energy(x, model))


def build_stops(config: SimConfig, stages: int, n_pairs: int,
                state: Optional[np.ndarray] = None) -> 'kernels.Stops':
    """
    Assemble the mechanical stops of a configuration as the kernels take them.

    ``stages`` is the splitting's number of drifts, ``n_pairs`` the coupled pairs' count (the
    sub-steps' propagators have their shapes); ``state`` the counters to keep (a rebuild at
    another die temperature keeps the impacts counted), None: new ones. Without stops
    (``stops.gap`` 0) the arrays are placeholders the kernels never read.
    """
    n = len(config.modal_masses())
    if state is None:
        state = np.zeros(4, dtype=np.int64)
    s = config.stops
    if not s.enabled:
        return kernels.Stops(gap=0.0, unload=1.0, basis=np.zeros((n, 1)),
                             projection=np.zeros((n, 1)), max_sub=0.0, w=np.zeros(1),
                             f=np.zeros(1), index=np.zeros(1, dtype=np.int64),
                             save=np.zeros((3, n)), prop=np.zeros((1, n, 4)),
                             pair_prop=np.zeros((1, max(n_pairs, 1), 16)),
                             rot=np.zeros((1, 2)), key=np.full(2, np.nan), state=state)
    harmonics, sine = coordinate_harmonics(config.modes.count, config.modes.companions)
    masses = np.asarray(config.modal_masses(), dtype=np.float64)
    m = kernels.stop_angles(config.modes.count)
    theta = 2.0 * np.pi * np.arange(m) / m
    basis = np.ascontiguousarray(mode_shapes(harmonics, sine, theta).T)
    radius = config.ring.radius
    projection = np.ascontiguousarray(
        (2.0 * np.pi * radius * s.stiffness / m) * basis / masses[:, None])
    return kernels.Stops(
        gap=float(s.gap), unload=float(s.restitution ** 2), basis=basis,
        projection=projection,
        max_sub=kernels.stop_max_substep(s.stiffness, radius, float(np.min(masses))),
        w=np.zeros(m), f=np.zeros(m), index=np.zeros(m, dtype=np.int64), save=np.zeros((3, n)),
        prop=np.zeros((stages, n, 4)), pair_prop=np.zeros((stages, n_pairs, 16)),
        rot=np.zeros((stages + 1, 2)), key=np.full(2, np.nan), state=state)


PULL_IN_GRID = 2000
"""Displacements of the scan of :func:`static_pull_in_displacement`, over [0, d_g)."""


def static_pull_in_displacement(config: SimConfig, model: ForceModel) -> float:
    """
    Return the static pull-in displacement of the 1theta mode, m (inf: none below d_g).

    The 1theta mode is the one a shock drives. Alone and held still, its restoring
    acceleration is ``R(q) = omega_1^2 q - a_nl,1(q)`` (eq. 28 without time derivatives,
    the other coordinates at 0): the electrostatic force softens it and R has a maximum at
    the static pull-in displacement, beyond which no static load is balanced and the ring
    is pulled onto whatever it meets. Found on :data:`PULL_IN_GRID` displacements of
    ``[0, 0.999 d_g]`` (to 5e-4 d_g), with the model's own force (N_T terms or untruncated).
    On the default device (78 V, N_T = 10): 0.702 d_g (0.674 d_g untruncated).
    """
    gap = config.electrodes.gap
    omega = 2.0 * np.pi * config.modes.coordinate_frequencies()[0]
    best_q, best_r = 0.0, -np.inf
    x = np.zeros(model.n_coordinates)
    for q in np.linspace(0.0, 0.999 * gap, PULL_IN_GRID):
        x[0] = q
        r = omega * omega * q - nonlinear_acceleration(x, model)[0]
        if r <= best_r:
            return float(best_q)
        best_q, best_r = q, r
    return np.inf
