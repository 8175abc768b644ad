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
Compiled kernels: the electrostatic force and the time stepper.

Method
------
The equations of motion (eq. 28) are ``x'' = L(x, x') + a_nl(x) + a_ext(t)`` with
``L = -(omega/Q) x' - omega^2 x`` linear and per coordinate. They are split into

* **A**, the damped linear oscillators, propagated *exactly* (closed-form 2x2 flow per
  coordinate: no phase error, no numerical damping whatever the step);
* **B**, the kick ``v += tau * (a_nl(x) + a_ext(t))`` by the electrostatic force (which
  depends on positions only) and the external forcing (shock, base acceleration, drive).

Because the B-flow depends on positions only and A is at most linear in velocities,
``[B, [B, [B, A]]] = 0``: the splitting has the Runge-Kutta-Nystrom structure, so the
optimised symmetric RKN splittings of Blanes & Moan (2002, J. Comput. Appl. Math. 142,
313-330) apply, in BAB form with the last kick's force reused as the next step's first
(FSAL): ``bm6`` = SRKN_11^b (order 6, 11 force evaluations per step), ``bm4`` = SRKN_6^b
(order 4, 6 evaluations), ``strang`` (order 2, 1 evaluation). Undamped, the method is
symplectic: the energy error stays bounded (no drift), which the tests check.

In a rotating sensor frame (``gyro.enabled`` with a rate) B also holds the Coriolis term,
linear in the velocities, and is integrated exactly as well (:func:`_kick_rotating`); the
commutator identity above then no longer holds exactly, so the RKN order is not guaranteed
for the rotation's part. It is small (``2 kappa Omega / omega`` ~ 1e-5 of the oscillators'
rates at 300 deg/s) and measured: ``test/core/test_rotation.py`` holds the 1e-4 budget
against DOP853 with 2.2e-6 while the frame spins up to 50 rad/s.

Error budget (measured in ``test/core/test_simulator.py`` and ``benchmarks/``): the error is
proportional to the nonlinear force (the linear part is exact) times ``(omega h)^p``. At the
default step (see ``simulator.default_max_step``) the paper configuration stays within 1e-4 of
the peak q1 of a DOP853 reference at rtol 1e-10 over 20 ms after a 10 000 g shock.
Steps that overlap a shock pulse are cut into sub-steps of at most ``T_s / 16`` so the
half-sine (whose derivative jumps at both ends) is resolved.

Everything is float64 and SI. Kernels take arrays and scalars grouped by what they are, in
named tuples (:class:`Force`, :class:`Drive`, :class:`Forcing`, :class:`Method`,
:class:`Scratch`), so that a call reads like its meaning and two arrays cannot be swapped
silently (a tuple in the wrong place does not compile); ``core/simulator.py`` builds them
(once per configuration where they do not change), validates inputs, calls the kernels, and
checks the result. A state that leaves
the model's range stops the kernel with a status code and the index of the angle (never NaN).
The two entry points (``run_samples``, ``output_channels``) release the GIL, so that a
recorder thread can serialise and compress while they run.

Cost
----
Measured on the paper configuration (N_R = 3, N_T = 10, bm6, one 5 us step per 200 kHz
sample; ``benchmarks/bench_simulator.py``, ``doc/performance.md``; 2026-12-03, an Intel host):
~0.55 us per step in this kernel, of which 11 stages at ~46 ns (force evaluation at 18
angles, the degree-9 series by Estrin's scheme, kick, drift and external force; strict IEEE
arithmetic: no fast-math, so results do not depend on the vector width) and ~37 ns per step
(drive phasor, loop, the last kick); :func:`output_channels` adds ~135 ns per sample. The
stages form one chain of dependent operations (each force needs the previous drift, each
drift the previous kick), so the latency of that chain, not the number of operations, sets
the cost: what shortens the chain pays (the series 18 -> 8 dependent operations, the angle
values in one pass, kick and drift fused: 62 -> 46 ns per stage in one session). What the
code is shaped by, each measured:

* numba's reference counting: a function that takes arrays and has branches increments and
  decrements every array argument atomically on every call unless its pruning pass can prove
  the pairs redundant. ``run_samples`` is compiled with ``_nrt=False`` (it allocates
  nothing), which removed 29 % of the run time; :func:`output_channels` copies each sample's
  coordinates instead of taking a (reference-counted) view per sample;
* the force's common case (:func:`_force`) has no branch that stores, returns early or calls
  out (such a branch doubled its cost, ~65 -> ~130 ns); :func:`_force_any` decides between
  it and the out-of-line :func:`_force_general` before either runs, so that a state with
  excited companions (sine content) does not evaluate the common case first for nothing
  (N_R = 3 with companions: 4.4 -> 2.4 us per sample);
* floating-point min, max and sum reductions do not vectorise without fast-math (each is a
  chain of dependent operations): the range check counts the angles outside (-1, 1) as
  integers (:func:`_all_inside`), the smallest gap's grid maximum is found in independent
  lanes (:func:`_first_argmax`; the maximum is exact in any order), and the projections sum
  each coordinate in a register, the coordinates as independent chains;
* the series is evaluated by Estrin's scheme written out for 4, 8, 12 or 16 coefficients
  (:func:`_series_values`), one loop over the angles with the coefficients in registers: a
  loop over the coefficient blocks inside it, or the blocks in passes over the angles, cost
  more than Horner's rule (measured 75 and 90-160 ns against 58 ns per stage); longer series
  take Horner's rule three degrees per pass (:func:`_horner`);
* the angle values take six or three coordinates per pass (:func:`_angle_values`): one
  pass per coordinate stored and reloaded them on the chain; the range check over the angles
  runs only when ``sum |q_n|`` reaches the gap (:data:`_REACH_INSIDE`);
* tried and not kept (no gain or a loss, measured in one session): two partial sums in the
  projection (566 -> 688 ns per sample), a tree of 8 lanes, the representatives padded to a
  multiple of 4 (48 angles instead of 36), the rotating kick fused with the drift;
* the pieces of a step (:func:`_cut_step`, :func:`_step`, :func:`_kick_drift`,
  :func:`_external`, :func:`_force`) are ``inline='always'``: inlined, they cost the same as
  the loop written out (measured, best of N in one session); called, a step passed ~20 array
  structures every step (~25 % of a Strang run). :func:`_force_general` inlined as well was
  no faster;
* named tuples cost nothing inside the kernel, but numba's dispatcher types each one on
  every call from Python (~1 us each, ~4 us per :func:`run_samples` call: 0.2 % of a 10 ms
  chunk of the paper configuration, more for very short calls);
* loops over the angles run innermost on coordinate-major arrays (``(n, angles)``) so that
  they vectorise; a loop that only zeroes a short array compiled to a ``memset`` call.
"""

import math
from typing import NamedTuple

from numba import njit
import numpy as np

__all__ = ['STATUS_OK', 'STATUS_OUTER_CONTACT', 'STATUS_INNER_CONTACT', 'STATUS_SERIES_RANGE',
           'STATUS_NONFINITE', 'NEEDS_GENERAL', 'Force', 'Drive', 'Forcing', 'Method', 'Scratch',
           'ESTRIN_MAX_SLOTS', 'estrin_layout', 'orbit_angle', 'describe_status',
           'splitting_coefficients', 'linear_propagators', 'member_basis', 'nl_accel',
           'drive_phasor', 'run_samples', 'output_channels', 'pickoff_volts', 'iq_fit']

STATUS_OK = 0
STATUS_OUTER_CONTACT = 1
STATUS_INNER_CONTACT = 2
STATUS_SERIES_RANGE = 3
STATUS_NONFINITE = 4

_STATUS_TEXT = {
    STATUS_OUTER_CONTACT: 'outer electrode contact (outer gap closed)',
    STATUS_INNER_CONTACT: 'inner electrode contact (inner gap closed)',
    STATUS_SERIES_RANGE: 'displacement beyond the range of the Taylor series (|w| >= d_g)',
    STATUS_NONFINITE: 'non-finite state (numerical failure)',
}


class Force(NamedTuple):
    """
    The electrostatic force as the kernels take it (``forces.ForceModel.kernel``).

    Built once per configuration by :func:`ring_gyro_sim.core.forces.build_force_model`.

    Attributes
    ----------
    kbasis : ndarray, shape (n, 4 R)
        Mode shapes at the four orbit members, signed, divided by d_g (:func:`member_basis`).
    projection : ndarray, shape (n, R)
        ``weight_j phi_i(theta_j) / m_i``, rad/kg.
    signs : ndarray, shape (2, n)
        Parity (+1.0 or -1.0) of each coordinate under orbit member 1 (theta -> pi - theta)
        and member 2 (theta -> -theta).
    poly : ndarray, shape (D + 1,)
        Coefficients of P(u), N (truncated model).
    taylor_terms : int
        N_T (0 = untruncated).
    outer, inner : float
        ``A_eps r_o V_o^2`` and ``A_eps r_i V_i^2``, J/rad.
    fold : bool
        Linear (k <= 2) terms removed.
    inner_contact : bool
        An inner electrode is present: ``u <= -1`` is contact there.
    gap : float
        d_g, m.
    series : ndarray, shape (S,)
        The coefficients :func:`_series_values` evaluates by Estrin's scheme
        (:func:`estrin_layout`): those of ``P(u) / u^2`` when ``series_u2``, else of P,
        zero-padded to S = 4, 8, 12 or 16; S = 0: Horner's rule on ``poly`` (longer series).
    series_u2 : bool
        P's first two coefficients are exactly 0 (the linear terms folded): ``P = u^2 Q(u)``.

    """

    kbasis: np.ndarray
    projection: np.ndarray
    signs: np.ndarray
    poly: np.ndarray
    taylor_terms: int
    outer: float
    inner: float
    fold: bool
    inner_contact: bool
    gap: float
    series: np.ndarray
    series_u2: bool


class Drive(NamedTuple):
    """
    The 2theta drive ``A cos(omega (t - t_ref) + phase)`` on coordinate ``index``.

    Attributes
    ----------
    amplitude : float
        A, m/s^2 (0.0: off).
    omega : float
        Angular frequency, rad/s.
    t_ref : float
        Time of the last change, s.
    phase : float
        Phase at ``t_ref``, rad.
    index : int
        The driven coordinate (q2), -1 for none.
    sense_index : int
        The coordinate of the rebalance force (q2s, force-to-rebalance of the closed loop,
        ``core.control``), -1 for none.
    sense_amplitude, sense_phase : float
        The rebalance force ``B cos(omega (t - t_ref) + phase - beta)``: B (m/s^2) and the
        lag beta (rad) behind the drive's phase.

    """

    amplitude: float
    omega: float
    t_ref: float
    phase: float
    index: int
    sense_index: int = -1
    sense_amplitude: float = 0.0
    sense_phase: float = 0.0


class Forcing(NamedTuple):
    """
    Base acceleration over one call of :func:`run_samples`: shock pulses and a sampled profile.

    Attributes
    ----------
    pulses : ndarray, shape (P, 4)
        Half-sine pulses: start (s), duration (s), peak x and peak y (m/s^2).
    pulse_max_sub : float
        Longest sub-step inside a pulse, s.
    profile_t, profile_x, profile_y : ndarray, shape (S,)
        Sampled base acceleration: times (s, increasing) and x, y values (m/s^2); S may be 0.
    y_index : int
        The coordinate y acts on (q1s), -1 for none (x acts on coordinate 0).
    rate_t, rate_w : ndarray, shape (R,)
        Angular rate of the sensor frame about z: knot times (s, non-decreasing; a repeated
        time is a step) and rates (rad/s), linear between knots, 0 before the first, held
        after the last (:func:`_rate_at`); R = 0: no rotation (the kick is the plain one).
    pair_c, pair_s : ndarray of int64, shape (P,)
        The cos and sin coordinate of each gyroscopic pair (q_n, q_n^s).
    kappa : ndarray, shape (P,)
        Their Coriolis coefficients 2 n / (n^2 + 1) (``structure.gyroscopic_coefficient``).
    noise : ndarray, shape (T, n)
        Velocity increments (m/s) added at the start of each step of the call, row
        ``s n_sub + j`` for step j of sample s (the force noise); T = 0: none.

    """

    pulses: np.ndarray
    pulse_max_sub: float
    profile_t: np.ndarray
    profile_x: np.ndarray
    profile_y: np.ndarray
    y_index: int
    rate_t: np.ndarray
    rate_w: np.ndarray
    pair_c: np.ndarray
    pair_s: np.ndarray
    kappa: np.ndarray
    noise: np.ndarray


class Method(NamedTuple):
    """
    The integration method of a configuration: time grid, splitting, linear propagators.

    Attributes
    ----------
    period_s : float
        Output sample period, s.
    n_sub : int
        Steps per sample period.
    h : float
        Step, s (``period_s / n_sub``).
    a, b : ndarray, shapes (s,), (s + 1,)
        Drift and kick coefficients (:func:`splitting_coefficients`).
    prop : ndarray, shape (s, n, 4)
        Exact linear flows of the drifts ``a h`` (:func:`linear_propagators`).
    omega, zeta : ndarray, shape (n,)
        Natural angular frequencies (rad/s) and damping ratios, for the sub-steps' flows.

    """

    period_s: float
    n_sub: int
    h: float
    a: np.ndarray
    b: np.ndarray
    prop: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray


class Scratch(NamedTuple):
    """
    Work buffers and status outputs of :func:`run_samples` (allocated once per configuration).

    Attributes
    ----------
    work : ndarray, shape (>= 8 R,)
        Scratch of the force.
    fe : ndarray, shape (n,)
        External acceleration of a stage.
    info : ndarray of int64, shape (2,)
        Kernel status and the column of ``kbasis`` where it happened (:func:`nl_accel`).
    tinfo : ndarray, shape (1,)
        Time of the stage that left the range, s.
    cuts : ndarray, shape (>= 2 P + 2,)
        Cut times of a step (:func:`_cut_step`).
    rot, rot_sub : ndarray, shape (s + 1, 2)
        Drive rotations of the stages of a step and of a sub-step (:func:`_stage_rotations`).
    prop_sub : ndarray, shape (s, n, 4)
        Propagators of a sub-step.
    turn : ndarray, shape (s + 1, >= P, 4)
        The rotating kick's coefficients (dimensionless) per kick and gyroscopic pair (P
        pairs, ``Forcing.kappa``; :func:`_turn_coefficients`), for ``turn_key``.
    turn_key : ndarray, shape (2,)
        ``(Omega, hs)`` of ``turn``: the rate (rad/s) and the (sub)step (s); NaN: none
        (:func:`run_samples` sets it at each call, whose configuration may be another).

    """

    work: np.ndarray
    fe: np.ndarray
    info: np.ndarray
    tinfo: np.ndarray
    cuts: np.ndarray
    rot: np.ndarray
    rot_sub: np.ndarray
    prop_sub: np.ndarray
    turn: np.ndarray
    turn_key: np.ndarray


def orbit_angle(theta_rep: float, member: int) -> float:
    """
    Angle (rad, in [0, 2 pi)) of orbit member k of a representative angle.

    The members, in the one order the kernels use: ``theta, pi - theta, -theta, pi + theta``
    (member 3 is the composition of members 1 and 2).
    """
    angle = (theta_rep, math.pi - theta_rep, -theta_rep, math.pi + theta_rep)[member]
    return angle % (2.0 * math.pi)


def describe_status(status: int, theta_rad: float) -> str:
    """Human text for a kernel status and the angle where it happened."""
    text = _STATUS_TEXT.get(status, f'unknown status {status}')
    return f'{text} at theta = {math.degrees(theta_rad):.1f} deg'


def splitting_coefficients(method: str):
    """
    Drift (``a``) and kick (``b``) coefficients of a BAB splitting, ``len(b) = len(a) + 1``.

    The last coefficient of each half is derived from the consistency conditions
    (``sum a = sum b = 1``) rather than copied.
    """
    if method == 'strang':
        return np.array([1.0]), np.array([0.5, 0.5])
    if method == 'bm4':  # Blanes & Moan 2002, SRKN_6^b
        b = [0.0829844064174052, 0.396309801498368, -0.0390563049223486]
        a = [0.245298957184271, 0.604872665711080]
        a.append(0.5 - sum(a))
        b.append(1.0 - 2.0 * sum(b))
        return np.array(a + a[::-1]), np.array(b + b[-2::-1])
    if method == 'bm6':  # Blanes & Moan 2002, SRKN_11^b
        b = [0.0414649985182624, 0.198128671918067, -0.0400061921041533,
             0.0752539843015807, -0.0115113874206879]
        b.append(0.5 - sum(b))
        a = [0.123229775946271, 0.290553797799558, -0.127049212625417,
             -0.246331761062075, 0.357208872795928]
        middle = 1.0 - 2.0 * sum(a)
        return np.array(a + [middle] + a[::-1]), np.array(b + b[::-1])
    raise ValueError(f'integrator.method: unknown method {method!r}')


def linear_propagators(omega: np.ndarray, zeta: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """
    Exact flow of ``x'' + 2 zeta omega x' + omega^2 x = 0`` over each time ``tau``.

    Parameters
    ----------
    omega : ndarray, shape (n,)
        Natural angular frequencies, rad/s.
    zeta : ndarray, shape (n,)
        Damping ratios 1 / (2 Q), < 1.
    taus : ndarray, shape (s,)
        Durations, s (may be negative: some splitting drifts go backwards).

    Returns
    -------
    ndarray, shape (s, n, 4)
        ``[xx, xv, vx, vv]`` with ``x1 = xx x0 + xv v0`` and ``v1 = vx x0 + vv v0``.

    """
    wd = omega * np.sqrt(1.0 - zeta ** 2)
    out = np.empty((taus.size, omega.size, 4))
    for k, tau in enumerate(taus):
        e = np.exp(-zeta * omega * tau)
        c = np.cos(wd * tau)
        s = np.sin(wd * tau)
        r = zeta * omega / wd
        out[k, :, 0] = e * (c + r * s)
        out[k, :, 1] = e * s / wd
        out[k, :, 2] = -e * omega ** 2 * s / wd
        out[k, :, 3] = e * (c - r * s)
    return out


@njit(cache=True)
def _p_of_u(u, poly, taylor_terms, outer, inner, fold, gap):
    """P(u) = dE/dw per radian at ``u = w / d_g`` (see ``core/forces.py``), N/rad."""
    if taylor_terms > 0:
        p = 0.0
        for d in range(poly.size - 1, -1, -1):
            p = p * u + poly[d]
        return p
    uo = 1.0 - u
    if fold:
        go = u * u * (3.0 - 2.0 * u) / (uo * uo)
    else:
        go = 1.0 / (uo * uo) - 1.0
    if inner == 0.0:
        # No inner electrode: w <= -d_g is a valid state, and (1 + u)^2 may be 0.
        return outer * go / gap
    ui = 1.0 + u
    if fold:
        gi = u * u * (3.0 + 2.0 * u) / (ui * ui)
    else:
        gi = 1.0 / (ui * ui) - 1.0
    return (outer * go - inner * gi) / gap


@njit(cache=True)
def _range_status(u, inner_contact, taylor_terms):
    if not math.isfinite(u):
        return STATUS_NONFINITE
    if u >= 1.0:
        return STATUS_OUTER_CONTACT
    if u <= -1.0:
        if inner_contact:
            return STATUS_INNER_CONTACT
        if taylor_terms > 0:
            return STATUS_SERIES_RANGE
    return STATUS_OK


@njit(cache=True, inline='always')
def _horner(poly, u, p, m):
    """
    ``p[:m] = P(u[:m])`` by Horner's rule, three degrees per pass over the angles.

    Each value gets the same operations in the same order as the one-degree-per-pass loop
    (``p = p u + c`` from the top coefficient down); three per pass keep ``p`` in a
    register for three of them instead of storing and reloading it every degree.
    """
    d = poly.size - 1
    top = poly[d]
    d -= 1
    rest = (d + 1) % 3
    if rest == 1:
        c0 = poly[d]
        for k in range(m):
            p[k] = top * u[k] + c0
        d -= 1
    elif rest == 2:
        c0 = poly[d]
        c1 = poly[d - 1]
        for k in range(m):
            uk = u[k]
            p[k] = (top * uk + c0) * uk + c1
        d -= 2
    elif d >= 2:  # the first three degrees from the top coefficient, without storing it
        c0 = poly[d]
        c1 = poly[d - 1]
        c2 = poly[d - 2]
        for k in range(m):
            uk = u[k]
            p[k] = ((top * uk + c0) * uk + c1) * uk + c2
        d -= 3
    else:
        for k in range(m):
            p[k] = top
    while d >= 2:
        c0 = poly[d]
        c1 = poly[d - 1]
        c2 = poly[d - 2]
        for k in range(m):
            uk = u[k]
            p[k] = ((p[k] * uk + c0) * uk + c1) * uk + c2
        d -= 3


ESTRIN_MAX_SLOTS = 16
"""Longest series (coefficients, zero-padded to a multiple of 4) evaluated by Estrin's scheme."""


def estrin_layout(poly: np.ndarray):
    """
    Lay out the coefficients ``poly`` of P(u) as :func:`_series_values` takes them.

    Returns ``(series, u2)``: with ``poly[0] == poly[1] == 0`` (the folded model, eq. 26's
    terms removed) ``P(u) = u^2 Q(u)`` and ``series`` holds Q's coefficients, else P's; zero
    padded at the top to 4, 8, 12 or 16 (a zero coefficient adds an exact 0.0, so the
    padding changes no value). Longer series give an empty ``series``: Horner's rule.
    """
    poly = np.asarray(poly, dtype=np.float64)
    u2 = bool(poly.size > 2 and poly[0] == 0.0 and poly[1] == 0.0)
    q = poly[2:] if u2 else poly
    slots = 4 * ((q.size + 3) // 4)
    if slots > ESTRIN_MAX_SLOTS:
        return np.zeros(0), u2
    series = np.zeros(slots)
    series[:q.size] = q
    return series, u2


@njit(cache=True, inline='always')
def _series_values(series, u2f, poly, u, p, m):
    """
    ``p[:m] = P(u[:m])``: Estrin's scheme in blocks of four coefficients, or Horner's rule.

    The dependency chain of Horner's rule is one multiply and one add per degree (degree 9:
    18 operations, ~72 cycles, the longest part of a stage); Estrin's scheme pairs the
    coefficients, ``(c0 + c1 u) + u^2 (c2 + c3 u)``, and combines the blocks with ``u^4`` and
    ``u^8``: 4 levels for 16 coefficients. Written out per slot count, with the coefficients
    in registers and one loop over the angles, so that it vectorises over them (a loop over
    the blocks inside the loop over the angles cost 30 % more than Horner, measured). The
    operations and their order are fixed (strict IEEE, no fast-math): the values do not
    depend on the vector width. ``series`` and ``u2f`` from :func:`estrin_layout`; an empty
    ``series``: Horner on ``poly`` (:func:`_horner`).
    """
    slots = series.size
    one = 1.0
    if slots == 4:
        c0, c1, c2, c3 = series[0], series[1], series[2], series[3]
        for k in range(m):
            x = u[k]
            x2 = x * x
            scale = x2 if u2f else one
            p[k] = ((c0 + c1 * x) + x2 * (c2 + c3 * x)) * scale
    elif slots == 8:
        c0, c1, c2, c3 = series[0], series[1], series[2], series[3]
        c4, c5, c6, c7 = series[4], series[5], series[6], series[7]
        for k in range(m):
            x = u[k]
            x2 = x * x
            x4 = x2 * x2
            scale = x2 if u2f else one
            b0 = (c0 + c1 * x) + x2 * (c2 + c3 * x)
            b1 = (c4 + c5 * x) + x2 * (c6 + c7 * x)
            p[k] = (b0 + x4 * b1) * scale
    elif slots == 12:
        c0, c1, c2, c3 = series[0], series[1], series[2], series[3]
        c4, c5, c6, c7 = series[4], series[5], series[6], series[7]
        c8, c9, c10, c11 = series[8], series[9], series[10], series[11]
        for k in range(m):
            x = u[k]
            x2 = x * x
            x4 = x2 * x2
            scale = x2 if u2f else one
            b0 = (c0 + c1 * x) + x2 * (c2 + c3 * x)
            b1 = (c4 + c5 * x) + x2 * (c6 + c7 * x)
            b2 = (c8 + c9 * x) + x2 * (c10 + c11 * x)
            p[k] = ((b0 + x4 * b1) + (x4 * x4) * b2) * scale
    elif slots == 16:
        c0, c1, c2, c3 = series[0], series[1], series[2], series[3]
        c4, c5, c6, c7 = series[4], series[5], series[6], series[7]
        c8, c9, c10, c11 = series[8], series[9], series[10], series[11]
        c12, c13, c14, c15 = series[12], series[13], series[14], series[15]
        for k in range(m):
            x = u[k]
            x2 = x * x
            x4 = x2 * x2
            scale = x2 if u2f else one
            b0 = (c0 + c1 * x) + x2 * (c2 + c3 * x)
            b1 = (c4 + c5 * x) + x2 * (c6 + c7 * x)
            b2 = (c8 + c9 * x) + x2 * (c10 + c11 * x)
            b3 = (c12 + c13 * x) + x2 * (c14 + c15 * x)
            p[k] = ((b0 + x4 * b1) + (x4 * x4) * (b2 + x4 * b3)) * scale
    else:
        _horner(poly, u, p, m)


@njit(cache=True, inline='always')
def _all_inside(u, m):
    """
    Whether every one of ``u[:m]`` is finite and inside (-1, 1): the common case.

    ``|u| < 1`` is false for NaN and infinities too. Counted as integers, so that the loop
    vectorises (a floating-point min, max or sum is a chain of dependent operations without
    fast-math: ~15 ns of a 66 ns force evaluation on the paper configuration).
    """
    outside = 0
    for k in range(m):
        outside += 0 if abs(u[k]) < 1.0 else 1
    return outside == 0


@njit(cache=True, inline='always')
def _first_out_of_range(u, m, inner_contact, taylor_terms, info):
    """
    Index of the first of ``u[:m]`` outside the model's range (-1: all in range).

    The status goes to ``info[0]``; one min/max pass decides the common case.
    """
    if _all_inside(u, m):
        return -1
    for k in range(m):
        status = _range_status(u[k], inner_contact, taylor_terms)
        if status != STATUS_OK:
            info[0] = status
            return k
    return -1


def member_basis(basis: np.ndarray, signs: np.ndarray, gap: float) -> np.ndarray:
    """
    Lay out the mode shapes for the kernels: ``(n, 4 R)``, scaled by ``1 / d_g``.

    Row i holds coordinate i at the four orbit members in their order (:func:`orbit_angle`:
    ``[theta, pi - theta, -theta, pi + theta]``), block k of R multiplied by the parity of the
    coordinate under member k (``signs[0]`` for k = 1, ``signs[1]`` for k = 2, both for
    k = 3), so that ``u = x @ kbasis`` gives ``w / d_g`` at all 4 R angles: column
    ``k R + j`` is member k of representative j. The first two blocks are all a state
    without sine content needs (then ``u(-theta) == u(theta)``), and they are a contiguous
    prefix of each row.
    """
    s1 = signs[0][:, None]
    s2 = signs[1][:, None]
    b = basis.T / gap
    return np.ascontiguousarray(np.concatenate([b, s1 * b, s2 * b, s2 * s1 * b], axis=1))


@njit(cache=True, inline='always')
def _angle_values(x, kbasis, m, u):
    """
    Set ``u[:m] = x @ kbasis[:, :m]``, w at the first m angles (loops vectorise over k).

    In units of d_g with :func:`member_basis`, in m with plain mode shapes. The sum over
    the coordinates runs in their order, ``((x0 b0 + x1 b1) + x2 b2) + ...``: the first six
    (N_R = 3 with companions) or three (without) in one pass over the angles, the rest
    three per pass (one pass per coordinate stored and reloaded u on the stage's critical
    path: the paper configuration's stage 54 -> 46 ns, the gyroscope's 117 -> 104 ns). A
    later group of three coordinates at exactly 0 (companions never excited) is skipped, as
    is a single one at the end: it would add exact zeros.
    """
    n = x.size
    x0 = x[0]
    if n >= 6:
        x1 = x[1]
        x2 = x[2]
        x3 = x[3]
        x4 = x[4]
        x5 = x[5]
        for k in range(m):
            u[k] = (((((kbasis[0, k] * x0 + kbasis[1, k] * x1) + kbasis[2, k] * x2)
                      + kbasis[3, k] * x3) + kbasis[4, k] * x4) + kbasis[5, k] * x5)
        i = 6
    elif n >= 3:
        x1 = x[1]
        x2 = x[2]
        for k in range(m):
            u[k] = (kbasis[0, k] * x0 + kbasis[1, k] * x1) + kbasis[2, k] * x2
        i = 3
    else:
        for k in range(m):
            u[k] = kbasis[0, k] * x0
        i = 1
    while i + 3 <= n:
        xa = x[i]
        xb = x[i + 1]
        xc = x[i + 2]
        if xa != 0.0 or xb != 0.0 or xc != 0.0:
            for k in range(m):
                u[k] = ((u[k] + kbasis[i, k] * xa) + kbasis[i + 1, k] * xb) \
                    + kbasis[i + 2, k] * xc
        i += 3
    while i < n:
        xi = x[i]
        if xi != 0.0:
            for k in range(m):
                u[k] += kbasis[i, k] * xi
        i += 1


@njit(cache=True, _nrt=False)
def _force_general(x, force, work, out, info):
    """
    :func:`nl_accel` at all four orbit members: states with sine content, and N_T = 0.

    Kept out of line: the common case (:func:`_force`) stays small.
    """
    kbasis = force.kbasis
    projection = force.projection
    signs = force.signs
    n = x.size
    r = kbasis.shape[1] // 4
    m = 4 * r
    u = work[:m]
    p = work[m:2 * m]
    reach = 0.0
    for i in range(n):
        reach += abs(x[i])
    _angle_values(x, kbasis, m, u)
    k = -1
    if not (reach < _REACH_INSIDE * force.gap):  # see _REACH_INSIDE; N_T = 0 too
        k = _first_out_of_range(u, m, force.inner_contact, force.taylor_terms, info)
    if k >= 0:
        info[1] = k
        return
    if force.taylor_terms > 0:
        _series_values(force.series, force.series_u2, force.poly, u, p, m)
    else:
        for k in range(m):
            p[k] = _p_of_u(u[k], force.poly, force.taylor_terms, force.outer, force.inner,
                           force.fold, force.gap)
    # out[i] = sum_j projection[i, j] ((P0 + s1 P1) + s2 (P2 + s1 P3)), summed over j in
    # order. The four parity combinations are formed once per j, into the scratch the
    # angles' u held (a loop over j that vectorises): s1 P and s2 (...) with s = +-1 are
    # exact negations, so each is the same value bit for bit as formed per coordinate.
    # Then one chain of r adds per coordinate, in registers (the chains are independent).
    comb = work[:m]
    for j in range(r):
        e_p = p[j] + p[r + j]
        e_m = p[j] - p[r + j]
        f_p = p[2 * r + j] + p[3 * r + j]
        f_m = p[2 * r + j] - p[3 * r + j]
        comb[j] = e_p + f_p  # (s1, s2) = (+, +)
        comb[r + j] = e_p - f_p  # (+, -)
        comb[2 * r + j] = e_m + f_m  # (-, +)
        comb[3 * r + j] = e_m - f_m  # (-, -)
    for i in range(n):
        block = (0 if signs[0, i] > 0.0 else 2) + (0 if signs[1, i] > 0.0 else 1)
        base = block * r
        acc = 0.0
        for j in range(r):
            acc += projection[i, j] * comb[base + j]
        out[i] = acc


_REACH_INSIDE = 1.0 - 1e-9
"""
``sum |x_i| < _REACH_INSIDE d_g`` puts every angle inside the series' range: ``|w| <= sum
|q_n|`` (``|cos|, |sin| <= 1``), and the factor covers the rounding of the angle values
(n ulps of ``|w|``), so that the range check over the angles (:func:`_all_inside`, ~4 ns of
a ~54 ns stage on the paper configuration) runs only when the ring is within that of the
gap.
"""

NEEDS_GENERAL = -1
"""``info[0]`` of :func:`_force` when the state needs :func:`_force_general`."""


@njit(cache=True, inline='always')
def _force(x, force, work, out, info):
    """
    Take the common case of :func:`nl_accel`, inline: the Taylor series, no sine content.

    Then ``u(-theta) == u(theta)`` bit for bit and only the members theta and pi - theta are
    evaluated (2 R angles, the half-circle rule), with the same arithmetic per value as
    :func:`_force_general`. Every loop runs over the angles innermost, on separate
    stretches of ``work``. A state this path does not cover (sine content, N_T = 0, out of
    range) leaves ``out`` unchanged and sets ``info[0] = NEEDS_GENERAL``; otherwise
    ``info[0] = 0``.

    Written without branches around the work: measured in the step loop, a conditional store
    or call in here (the fallback, an early return) doubles its cost (~65 -> ~130 ns on the
    paper configuration), so the fallback is the caller's (:func:`nl_accel`, :func:`_step`).
    """
    kbasis = force.kbasis
    projection = force.projection
    signs = force.signs
    poly = force.poly
    n = x.size
    r = kbasis.shape[1] // 4
    m = 2 * r
    u = work[:m]
    p = work[4 * r:4 * r + m]
    even = force.taylor_terms > 0
    reach = 0.0
    for i in range(n):
        if signs[1, i] < 0.0 and x[i] != 0.0:
            even = False
        reach += abs(x[i])
    _angle_values(x, kbasis, m, u)
    ok = even and (reach < _REACH_INSIDE * force.gap or _all_inside(u, m))
    _series_values(force.series, force.series_u2, poly, u, p, m)
    for i in range(n):
        s1 = signs[0, i]
        s2 = signs[1, i]
        acc = 0.0
        if s2 > 0.0:  # odd under theta -> -theta (the sine companions): exactly 0
            for j in range(r):
                half = p[j] + s1 * p[r + j]
                acc += projection[i, j] * (half + half)
        out[i] = acc if ok else out[i]
    info[0] = 0 if ok else NEEDS_GENERAL


@njit(cache=True, inline='always')
def _force_any(x, force, work, out, info):
    """
    Take :func:`nl_accel`'s two paths, inline: the common one or the general one.

    :func:`_force` for a state without sine content, else (or when it declines)
    :func:`_force_general`, called; ``info[0] != 0`` after it: out of range. The sine
    content is checked first, so that a state with excited companions does not pay for the
    common case's evaluation before the general one.
    """
    even = True
    for c in range(x.size):
        if force.signs[1, c] < 0.0 and x[c] != 0.0:
            even = False
    if even:
        _force(x, force, work, out, info)
    else:
        info[0] = NEEDS_GENERAL
    if info[0] != 0:
        info[0] = 0
        _force_general(x, force, work, out, info)


@njit(cache=True)
def nl_accel(x, force, work, out, info):
    """
    Electrostatic generalised force / modal mass at ``x`` (see ``core/forces.py``).

    The quadrature angles come in orbits ``{theta, pi - theta, -theta, pi + theta}``
    (members 0 to 3, :func:`orbit_angle`); only a representative ``theta_j`` in [0, pi/2] is
    stored (R of them). ``force.signs[0, i]`` (``force.signs[1, i]``) is the parity, +1 or
    -1, of coordinate i under theta -> pi - theta (theta -> -theta); ``force.kbasis``
    (:func:`member_basis`) holds the mode shapes at the four members with those signs
    applied. The force on a coordinate combines the four values of P as
    ``(P0 + s1 P1) + s2 (P2 + s1 P3)``, so a sum that is zero by symmetry (symmetric
    electrodes, a state without sine or without even coordinates) is exactly 0.0, not
    round-off.

    :func:`_force` takes the common case, :func:`_force_general` the rest (:func:`_step`
    makes the same two calls itself). ``work`` is scratch of at least ``8 R`` floats; ``out``
    (n,) receives the accelerations (m/s^2). On a state out of range ``info[0]`` gets the
    status, ``info[1]`` the column ``k R + j`` of ``kbasis`` (member k of representative j),
    and ``out`` is left unchanged.
    """
    _force_any(x, force, work, out, info)


@njit(cache=True, _nrt=False)
def _profile_accel(t, profile_t, profile_x, profile_y):
    """Interpolate the sampled base acceleration (x, y) linearly at ``t``, m/s^2."""
    n_prof = profile_t.size
    if not (profile_t[0] <= t <= profile_t[n_prof - 1]):
        return 0.0, 0.0
    k = np.searchsorted(profile_t, t, side='right') - 1
    if k >= n_prof - 1:
        return profile_x[n_prof - 1], profile_y[n_prof - 1]
    f = (t - profile_t[k]) / (profile_t[k + 1] - profile_t[k])
    return (profile_x[k] + f * (profile_x[k + 1] - profile_x[k]),
            profile_y[k] + f * (profile_y[k + 1] - profile_y[k]))


@njit(cache=True, inline='always')
def _external(t, t_mid, forcing, base_x, base_y, drive_index, drive_c, drive_s, rot_c, rot_s,
              sense_index, sense_c, sense_s, fe):
    """
    External acceleration at time ``t`` (s) into ``fe`` (m/s^2).

    Only ``fe[0]``, ``fe[forcing.y_index]``, ``fe[drive_index]`` and ``fe[sense_index]``
    (distinct) are written;
    the other entries stay at the zero :func:`run_samples` puts there (zeroing all of ``fe``
    every stage compiled to a call of memset).

    Base acceleration ``a_b`` enters as ``-a_b`` on q_1 (x) and q_1^s (y) (eq. 27). Whether a
    pulse acts is decided at the middle ``t_mid`` of the current (sub)step, which never
    straddles a pulse's start or end; inside it the half-sine formula is used at every stage,
    so stages that some splittings place outside the step (negative drifts) see the smooth
    continuation, not a kink. ``base_x, base_y`` is the sampled profile at ``t``
    (:func:`_profile_accel`, called by :func:`_step`: a call in here, even one not taken,
    costs every stage ~30 ns).

    The drive ``A cos(omega (t - t_ref) + phase)`` on q_2 is ``drive_c rot_c - drive_s rot_s``:
    ``drive_c, drive_s = A cos, A sin`` of the phase at the start of the step (one cos and one
    sin per step, :func:`_step`) and ``rot_c, rot_s`` the cos and sin of ``omega`` times the
    stage's offset in the step (:func:`_stage_rotations`), by the angle-sum formula. The
    rebalance force on ``sense_index`` (the closed loop's, ``Drive.sense_amplitude``) is the
    same with its own phasor ``sense_c, sense_s``.
    """
    pulses = forcing.pulses
    ax = base_x
    ay = base_y
    for p in range(pulses.shape[0]):
        start = pulses[p, 0]
        dur = pulses[p, 1]
        if start <= t_mid <= start + dur:
            s = math.sin(math.pi * (t - start) / dur)
            ax += pulses[p, 2] * s
            ay += pulses[p, 3] * s
    fe[0] = -ax
    if forcing.y_index >= 0:
        fe[forcing.y_index] = -ay
    if drive_index >= 0:
        fe[drive_index] = drive_c * rot_c - drive_s * rot_s
    if sense_index >= 0:
        fe[sense_index] = sense_c * rot_c - sense_s * rot_s


@njit(cache=True, inline='always')
def drive_phasor(t, amp, omega, t_ref, phase):
    """Return ``(A cos, A sin)`` of the drive's phase ``omega (t - t_ref) + phase`` at ``t``."""
    if amp == 0.0:
        return 0.0, 0.0
    angle = omega * (t - t_ref) + phase
    return amp * math.cos(angle), amp * math.sin(angle)


@njit(cache=True)
def _stage_rotations(a, h, drive_omega, rot):
    """
    ``rot[i] = (cos, sin)(drive_omega c_i h)`` for the kick times ``t + c_i h`` of a step.

    ``c_0 = 0``, ``c_i = a_0 + ... + a_{i-1}`` and the last kick at exactly ``c = 1``.
    """
    c = 0.0
    for i in range(a.size):
        rot[i, 0] = math.cos(drive_omega * c * h)
        rot[i, 1] = math.sin(drive_omega * c * h)
        c += a[i]
    rot[a.size, 0] = math.cos(drive_omega * h)
    rot[a.size, 1] = math.sin(drive_omega * h)


@njit(cache=True)
def _fill_propagators(omega, zeta, a, tau, prop):
    """In-kernel version of :func:`linear_propagators` for the drifts ``a * tau``."""
    for i in range(a.size):
        dt = a[i] * tau
        for c in range(omega.size):
            wd = omega[c] * math.sqrt(1.0 - zeta[c] * zeta[c])
            e = math.exp(-zeta[c] * omega[c] * dt)
            co = math.cos(wd * dt)
            si = math.sin(wd * dt)
            r = zeta[c] * omega[c] / wd
            prop[i, c, 0] = e * (co + r * si)
            prop[i, c, 1] = e * si / wd
            prop[i, c, 2] = -e * omega[c] * omega[c] * si / wd
            prop[i, c, 3] = e * (co - r * si)


@njit(cache=True, inline='always')
def _kick(v, acc, fe, kick):
    """Kick (B): ``v += kick (a_nl + a_ext)``, ``kick`` = a stage's coefficient times the step."""
    for c in range(v.size):
        v[c] += kick * (acc[c] + fe[c])


@njit(cache=True, inline='always')
def _rate_at(t, rate_t, rate_w):
    """
    Angular rate (rad/s) and its derivative (rad/s^2) at ``t`` from the knots of the profile.

    Linear between knots, 0 before the first, held after the last; at a repeated knot time
    (a step) the value after the step, with derivative 0.
    """
    n = rate_t.size
    if t < rate_t[0]:
        return 0.0, 0.0
    k = np.searchsorted(rate_t, t, side='right') - 1
    if k >= n - 1:
        return rate_w[n - 1], 0.0
    dt = rate_t[k + 1] - rate_t[k]
    slope = (rate_w[k + 1] - rate_w[k]) / dt
    return rate_w[k] + slope * (t - rate_t[k]), slope


@njit(cache=True, inline='always')
def _turn_coefficients(b, hs, w, kappa, turn):
    """
    ``turn[i, p] = (cos theta, sin theta, sin theta / theta, (1 - cos theta) / theta)``.

    With ``theta = 2 kappa_p Omega b_i hs``, the rotating kick's angle of pair ``p`` at kick
    ``i`` (:func:`_kick_rotating`). Below ``|theta| = 1e-3`` (``Omega tau < 6e-4``: 5 700
    deg/s at a 5 us kick) the trigonometric functions are their Taylor series to the first
    neglected term ``theta^6 / 720 < 1.4e-21``. They depend on the rate and the step only,
    so a step at the same rate as the last one reuses them (:func:`_step`).
    """
    for i in range(b.size):
        kick = b[i] * hs
        for p in range(kappa.size):
            theta = 2.0 * kappa[p] * w * kick
            th2 = theta * theta
            if abs(theta) < 1e-3:
                turn[i, p, 0] = 1.0 - th2 * (0.5 - th2 / 24.0)
                turn[i, p, 1] = theta * (1.0 - th2 * (1.0 / 6.0 - th2 / 120.0))
                turn[i, p, 2] = 1.0 - th2 * (1.0 / 6.0 - th2 / 120.0)
                turn[i, p, 3] = theta * (0.5 - th2 * (1.0 / 24.0 - th2 / 720.0))
            else:
                co = math.cos(theta)
                si = math.sin(theta)
                turn[i, p, 0] = co
                turn[i, p, 1] = si
                turn[i, p, 2] = si / theta
                turn[i, p, 3] = (1.0 - co) / theta


@njit(cache=True, inline='always')
def _kick_rotating(q, v, acc, fe, kick, w, wdot, forcing, turn, i):
    """
    Kick (B) in the rotating sensor frame: the exact flow of ``q' = 0``, ``v' = a + G v``.

    ``a`` is the force (``acc + fe``) plus the centrifugal and angular-acceleration terms,
    ``Omega^2 q_c + kappa Omega' q_s`` on a cos coordinate and ``Omega^2 q_s - kappa Omega' q_c``
    on its sin partner, and ``G v`` the Coriolis term ``(+2 kappa Omega v_s, -2 kappa Omega
    v_c)`` (``structure.gyroscopic_coefficient``, eqs. G5-G6). With the positions fixed over
    a kick this is linear with constant coefficients, integrated exactly: with
    ``theta = 2 kappa Omega tau``, ``z = v_c + i v_s`` and ``alpha = a_c + i a_s``,
    ``z(tau) = e^{-i theta} z + tau (sin theta / theta - i (1 - cos theta) / theta) alpha``,
    the coefficients of kick ``i`` in ``turn[i]`` (:func:`_turn_coefficients`). The
    splitting stays the RKN pair of the module docstring with B now linear in velocity; its
    error is measured against DOP853 with the rotation in ``test/core/test_rotation.py``.
    Every coordinate belongs to a pair (``gyro.enabled`` needs ``modes.companions``).
    """
    for p in range(forcing.pair_c.size):
        ic = forcing.pair_c[p]
        js = forcing.pair_s[p]
        kap = forcing.kappa[p]
        a_c = acc[ic] + fe[ic] + w * w * q[ic] + kap * wdot * q[js]
        a_s = acc[js] + fe[js] + w * w * q[js] - kap * wdot * q[ic]
        co = turn[i, p, 0]
        si = turn[i, p, 1]
        s1 = turn[i, p, 2]
        s2 = turn[i, p, 3]
        vc = v[ic]
        vs = v[js]
        v[ic] = co * vc + si * vs + kick * (s1 * a_c + s2 * a_s)
        v[js] = co * vs - si * vc + kick * (s1 * a_s - s2 * a_c)


@njit(cache=True, inline='always')
def _drift(q, v, prop, i):
    """Drift (A): apply the exact linear flow ``prop[i]`` of drift ``i`` of the splitting."""
    for c in range(q.size):
        x0 = q[c]
        v0 = v[c]
        q[c] = prop[i, c, 0] * x0 + prop[i, c, 1] * v0
        v[c] = prop[i, c, 2] * x0 + prop[i, c, 3] * v0


@njit(cache=True, inline='always')
def _kick_drift(q, v, acc, fe, kick, prop, i):
    """
    Kick (B) then drift (A) of drift ``i``: :func:`_kick` and :func:`_drift` in one.

    The new position is ``(xx x + xv v) + (xv kick) a`` (``a = acc + fe``): the force reaches
    it through one multiply and one add instead of the kick's three operations and the
    drift's two (the stage's chain of dependent operations is its cost).
    """
    for c in range(q.size):
        a = acc[c] + fe[c]
        x0 = q[c]
        v0 = v[c]
        xv = prop[i, c, 1]
        q[c] = (prop[i, c, 0] * x0 + xv * v0) + (xv * kick) * a
        v[c] = prop[i, c, 2] * x0 + prop[i, c, 3] * (v0 + kick * a)


@njit(cache=True, inline='always')
def _step(q, v, acc, ts, hs, prop, rot, method, force, drive, forcing, scratch):
    """
    One BAB splitting step of length ``hs`` from ``ts`` (module docstring), in place.

    ``prop`` and ``rot`` are the step's propagators and drive rotations (those of ``h`` or of
    a sub-step). ``acc`` holds the force at the start (FSAL) and gets the force at the end.
    Returns False when a stage leaves the model's range: then ``scratch.info`` holds the
    status and the angle, ``scratch.tinfo[0]`` the stage's time, and ``q, v`` that stage's
    (finite) values.
    """
    a = method.a
    b = method.b
    n_stages = a.size
    fe = scratch.fe
    info = scratch.info
    t_mid = ts + 0.5 * hs
    drive_c, drive_s = drive_phasor(ts, drive.amplitude, drive.omega, drive.t_ref, drive.phase)
    sense_c = 0.0
    sense_s = 0.0
    if drive.sense_index >= 0:
        sense_c, sense_s = drive_phasor(ts, drive.sense_amplitude, drive.omega, drive.t_ref,
                                        drive.phase - drive.sense_phase)
    tt = ts
    base_x = 0.0
    base_y = 0.0
    w = 0.0
    wdot = 0.0
    if forcing.rate_t.size > 0:
        w, wdot = _rate_at(t_mid, forcing.rate_t, forcing.rate_w)
    rotating = w != 0.0 or wdot != 0.0
    turn = scratch.turn
    if rotating and not (w == scratch.turn_key[0] and hs == scratch.turn_key[1]):
        _turn_coefficients(b, hs, w, forcing.kappa, turn)
        scratch.turn_key[0] = w
        scratch.turn_key[1] = hs
    for i in range(n_stages):
        if forcing.profile_t.size > 0:
            base_x, base_y = _profile_accel(tt, forcing.profile_t, forcing.profile_x,
                                            forcing.profile_y)
        _external(tt, t_mid, forcing, base_x, base_y, drive.index, drive_c, drive_s,
                  rot[i, 0], rot[i, 1], drive.sense_index, sense_c, sense_s, fe)
        if rotating:
            _kick_rotating(q, v, acc, fe, b[i] * hs, w, wdot, forcing, turn, i)
            _drift(q, v, prop, i)
        else:
            _kick_drift(q, v, acc, fe, b[i] * hs, prop, i)
        tt += hs * a[i]
        # nl_accel written out: its fallback is called from here, not from an inlined
        # function (see _force).
        _force_any(q, force, scratch.work, acc, info)
        if info[0] != 0:
            scratch.tinfo[0] = tt
            return False
    if forcing.profile_t.size > 0:
        base_x, base_y = _profile_accel(ts + hs, forcing.profile_t, forcing.profile_x,
                                        forcing.profile_y)
    _external(ts + hs, t_mid, forcing, base_x, base_y, drive.index, drive_c, drive_s,
              rot[n_stages, 0], rot[n_stages, 1], drive.sense_index, sense_c, sense_s, fe)
    if rotating:
        _kick_rotating(q, v, acc, fe, b[n_stages] * hs, w, wdot, forcing, turn, n_stages)
    else:
        _kick(v, acc, fe, b[n_stages] * hs)
    return True


@njit(cache=True, inline='always')
def _cut_step(t, t1, pulses, cuts):
    """
    Cut the step ``[t, t1]`` at the starts and ends of the pulses that fall inside it.

    ``cuts[:n_cuts]`` gets the cut times in increasing order, ``t`` and ``t1`` included.
    Returns ``(n_cuts, active)``: ``active`` when a pulse overlaps the step (otherwise the
    cuts are just ``t, t1``).
    """
    n_cuts = 0
    cuts[n_cuts] = t
    n_cuts += 1
    active = False
    for p in range(pulses.shape[0]):
        ps = pulses[p, 0]
        pe = ps + pulses[p, 1]
        if ps < t1 and pe > t:
            active = True
            if ps > t:
                cuts[n_cuts] = ps
                n_cuts += 1
            if pe < t1:
                cuts[n_cuts] = pe
                n_cuts += 1
    cuts[n_cuts] = t1
    n_cuts += 1
    if active:
        for g in range(1, n_cuts):  # insertion sort (a few entries)
            value = cuts[g]
            e = g - 1
            while e >= 0 and cuts[e] > value:
                cuts[e + 1] = cuts[e]
                e -= 1
            cuts[e + 1] = value
    return n_cuts, active


@njit(cache=True, nogil=True, _nrt=False)
def run_samples(q, v, acc, k0, n_samples, method, force, drive, forcing, scratch, out_q, out_v):
    """
    Advance ``n_samples`` output periods from sample index ``k0``.

    Each step is one BAB splitting step (:func:`_step`) of length ``method.h``, the force of
    its last kick reused as the first of the next (FSAL, in ``acc``). Step times are computed
    from integer indices (``k period + j h``), so the result does not depend on how a run is
    cut into calls. A step that overlaps a shock pulse is cut at the pulse's start and end
    (:func:`_cut_step`; the half-sine's derivative jumps there) and each piece into equal
    sub-steps of at most ``forcing.pulse_max_sub`` seconds, so the method keeps its order.
    Returns the number of samples completed; on a state out of range it stops early with
    ``scratch.info`` / ``scratch.tinfo`` set and ``q, v`` at the last stage (finite).

    Parameters
    ----------
    q, v, acc : ndarray, shape (n,)
        Coordinates (m), velocities (m/s) and the force at ``q`` (m/s^2), advanced in place.
    k0, n_samples : int
        Sample index of the state and number of samples to advance.
    method : Method
        Time grid, splitting coefficients and propagators of the configuration.
    force : Force
        The electrostatic force (``forces.ForceModel.kernel``).
    drive : Drive
        The 2theta drive in force over the call.
    forcing : Forcing
        Shock pulses and the sampled base acceleration over the call.
    scratch : Scratch
        Work buffers and status; ``scratch.cuts`` holds at least ``2 P + 2`` floats for the
        P pulses of ``forcing``.
    out_q, out_v : ndarray, shape (n_samples, n)
        The state at the end of each sample period.

    Notes
    -----
    The pieces (:func:`_cut_step`, :func:`_step`, :func:`_force`, ...) are inlined
    (``inline='always'``): called, a step passed ~20 array structures every step (~25 % of a
    Strang run). The kernel is compiled without numba's reference counting (``_nrt=False``;
    it allocates nothing): with it, every step paid an atomic increment and decrement of each
    array argument (measured 29 % of the run time).

    """
    fe = scratch.fe
    for c in range(q.size):
        fe[c] = 0.0
    scratch.turn_key[0] = np.nan  # another call's coefficients may be another config's
    h = method.h
    cuts = scratch.cuts
    _stage_rotations(method.a, h, drive.omega, scratch.rot)
    for s in range(n_samples):
        k = k0 + s
        for j in range(method.n_sub):
            t = k * method.period_s + j * h
            if forcing.noise.shape[0] > 0:
                row = s * method.n_sub + j
                for c in range(q.size):
                    v[c] += forcing.noise[row, c]
            n_cuts, active = _cut_step(t, t + h, forcing.pulses, cuts)
            for g in range(n_cuts - 1):
                # The plain step (no pulse): one piece of exactly h with the step's own
                # propagators; a piece of a pulse step: m sub-steps with their own.
                m = 1
                hs = h
                prop = method.prop
                rot = scratch.rot
                if active:
                    length = cuts[g + 1] - cuts[g]
                    if length <= 0.0:
                        continue
                    m = max(1, int(math.ceil(length / forcing.pulse_max_sub - 1e-9)))
                    hs = length / m
                    _fill_propagators(method.omega, method.zeta, method.a, hs,
                                      scratch.prop_sub)
                    _stage_rotations(method.a, hs, drive.omega, scratch.rot_sub)
                    prop = scratch.prop_sub
                    rot = scratch.rot_sub
                for r in range(m):
                    if not _step(q, v, acc, cuts[g] + r * hs, hs, prop, rot, method, force,
                                 drive, forcing, scratch):
                        return s
        for c in range(q.size):
            out_q[s, c] = q[c]
            out_v[s, c] = v[c]
    return n_samples


_LANES = 8

_RING_MAX_MARGIN = 1e-3
"""
Bound on the error of the ring's smallest gap (grid and parabola, :func:`output_channels`) in
units of ``sum n^2 |q_n|``: the third derivative of w is at most ``n_max sum n^2 |q_n|``, so
the error ``|w_3| delta^3 / (9 sqrt 3)`` is at most ``n_max delta^3 / (9 sqrt 3)`` of it, with
``n_max delta <= 2 pi / 32`` (``simulator.GAP_GRID_POINTS_PER_MODE``): below 5e-4.
"""


@njit(cache=True, inline='always')
def _first_argmax(w, m, lanes):
    """
    Index of the first largest of ``w[:m]`` (finite values), as a scan with ``>`` finds it.

    The maximum is exact whatever the order of comparisons, so it is found in
    :data:`_LANES` independent lanes (a loop that vectorises; a scan is one chain of
    dependent compares), then its first index, looked for a block of :data:`_LANES` at a
    time (a count of equal values per block vectorises; a scan of single values for it cost
    ~25 ns per sample on the paper configuration).
    """
    if m < _LANES:
        best = 0
        for g in range(1, m):
            if w[g] > w[best]:
                best = g
        return best
    for c in range(_LANES):
        lanes[c] = w[c]
    full = m - m % _LANES
    for g0 in range(_LANES, full, _LANES):
        for c in range(_LANES):
            lanes[c] = max(lanes[c], w[g0 + c])
    top = lanes[0]
    for c in range(1, _LANES):
        top = max(top, lanes[c])
    for g in range(full, m):
        top = max(top, w[g])
    for g0 in range(0, full, _LANES):
        hits = 0
        for c in range(_LANES):
            hits += 1 if w[g0 + c] == top else 0
        if hits > 0:
            for c in range(_LANES):
                if w[g0 + c] == top:
                    return g0 + c
    for g in range(full, m):
        if w[g] == top:
            return g
    return 0


@njit(cache=True, nogil=True)
def output_channels(q, gap, centre_shapes, ring_shapes, electrode_shapes, electrode_weights,
                    fine_shapes, fine_weights, curvature, refine_coeff, cap_scale, gap_floor,
                    out_gap, out_min, out_cap):
    """
    Outer gaps, smallest gap and electrode capacitances of every sample.

    The shapes are stored coordinate-major so that every loop runs over the angles
    innermost and vectorises.

    Accuracy (``test/core/test_outputs.py``, against dense sampling and ``quad``): the
    centre gaps are exact to round-off and stop at 0 in contact; the smallest gap is within
    ``|w'''| delta^3 / (9 sqrt 3)`` of ``d_g - max w`` (``delta`` the grid spacing,
    ``|w'''| <= sum n^3 |q_n|``). Each capacitance is a composite Gauss-Legendre sum whose
    panels keep the relative error below 1e-7 down to gaps of 0.01 d_g: every panel
    covers at most half a period of the highest harmonic, and an electrode whose smallest
    node gap g is below ``refine_coeff * sum n^2 |q_n|`` is summed again on the first finer
    level whose panels number at least ``sqrt(refine_coeff * sum n^2 |q_n| / g)`` per panel
    (``simulator.py`` derives the coefficient). In contact the integrand is
    ``1 / max(gap, gap_floor)``: finite.

    Parameters
    ----------
    q : ndarray, shape (S, n)
        Coordinates of the samples, m.
    gap : float
        d_g, m.
    centre_shapes : ndarray, shape (n, K)
        Mode shapes at the electrode centres.
    ring_shapes : ndarray, shape (n, G)
        Mode shapes on G equally spaced angles; the maximum of w is refined by a parabola
        through the best grid angle and its neighbours.
    electrode_shapes : ndarray, shape (n, K * P)
        Mode shapes at the P Gauss-Legendre angles (all panels) of each electrode.
    electrode_weights : ndarray, shape (K * P,)
        Their weights (Gauss-Legendre weights times the half panel length), rad, the same P
        for every electrode (repeated, so that one loop runs over all K * P angles); P a
        multiple of 4 (the sum takes four nodes per division).
    fine_shapes : ndarray, shape (n, K * F)
        Mode shapes at the F = (2 + 4 + ... + R) P angles of each electrode's finer levels:
        each panel cut into 2, then 4, ... R panels, one level after the other.
    fine_weights : ndarray, shape (F,)
        Their weights, rad.
    curvature : ndarray, shape (n,)
        n^2 of each coordinate: ``sum n^2 |q_n|`` bounds ``|w''|``.
    refine_coeff : float
        An electrode is refined when its smallest node gap < ``refine_coeff * sum n^2 |q_n|``.
    cap_scale : float
        eps eps_0 l r_o, F m / rad.
    gap_floor : float
        Smallest gap used in 1 / gap (contact keeps the capacitance finite), m.
    out_gap, out_min, out_cap : ndarray
        (S, K) gaps (m), (S,) smallest gap (m), (S, K) capacitances (F).

    """
    n_s, n = q.shape
    n_k = centre_shapes.shape[1]
    n_g = ring_shapes.shape[1]
    n_e = electrode_shapes.shape[1]
    n_p = n_e // n_k
    n_f = fine_weights.size
    max_level = 2
    while (2 * max_level - 2) * n_p < n_f:
        max_level *= 2
    wg = np.empty(n_g)
    we = np.empty(n_e)
    wq = np.empty(n_e // 4)
    w_top = np.empty(n_k)
    lanes = np.empty(_LANES)
    qs = np.empty(n)
    for s in range(n_s):
        for k in range(n_k):
            w = 0.0
            for i in range(n):
                w += centre_shapes[i, k] * q[s, i]
            out_gap[s, k] = max(gap - w, 0.0)
        for i in range(n):  # a copy, not a view: a view per sample is reference counted
            qs[i] = q[s, i]
        _angle_values(qs, ring_shapes, n_g, wg)
        best = _first_argmax(wg, n_g, lanes)
        y0 = wg[best - 1 if best > 0 else n_g - 1]
        y1 = wg[best]
        y2 = wg[best + 1 if best < n_g - 1 else 0]
        den = y0 - 2.0 * y1 + y2
        w_max = y1
        if den < 0.0:
            w_max = y1 - 0.125 * (y2 - y0) * (y2 - y0) / den
        out_min[s] = max(gap - w_max, 0.0)
        _angle_values(qs, electrode_shapes, n_e, we)
        c2 = 0.0
        for i in range(n):
            c2 += curvature[i] * abs(qs[i])
        # No electrode node can be nearer than the ring's smallest gap (less the parabola's
        # error, _RING_MAX_MARGIN): far from contact the nodes' own maxima are not needed to
        # know that no electrode is refined.
        near = gap - w_max < (refine_coeff + _RING_MAX_MARGIN) * c2
        for k in range(n_k):
            top = -np.inf
            if near:
                top = we[k * n_p]
                for j in range(1, n_p):
                    top = max(top, we[k * n_p + j])
            w_top[k] = top
        # sum_j weight_j / gap_j four nodes at a time, as one fraction:
        # (a/x + b/y) + (c/z + d/t) = ((a y + b x) z t + (c t + d z) x y) / (x y z t), one
        # division for four (64 per sample on the paper configuration cost ~30 ns); the gaps
        # are >= gap_floor, so the products neither underflow nor lose accuracy (a few ulps
        # of the sum of positive terms). One loop over every group: it vectorises.
        for g in range(n_e // 4):
            e = 4 * g
            x = max(gap - we[e], gap_floor)
            y = max(gap - we[e + 1], gap_floor)
            z = max(gap - we[e + 2], gap_floor)
            t = max(gap - we[e + 3], gap_floor)
            xy = x * y
            zt = z * t
            num = ((electrode_weights[e] * y + electrode_weights[e + 1] * x) * zt
                   + (electrode_weights[e + 2] * t + electrode_weights[e + 3] * z) * xy)
            wq[g] = num / (xy * zt)
        for k in range(n_k):
            c = 0.0
            g_top = gap - w_top[k]
            if g_top < refine_coeff * c2:
                # Halve the panels until their half-length is within reach of the pole:
                # (panels)^2 >= refine_coeff * c2 / g_top, at most the finest level.
                need = refine_coeff * c2 / max(g_top, gap_floor)
                level = 2
                start = 0
                while level < max_level and level * level < need:
                    start += level * n_p
                    level *= 2
                base = k * n_f + start
                for j in range(level * n_p):
                    w = 0.0
                    for i in range(n):
                        w += fine_shapes[i, base + j] * qs[i]
                    c += fine_weights[start + j] / max(gap - w, gap_floor)
            else:
                for j in range(n_p // 4):
                    c += wq[k * (n_p // 4) + j]
            out_cap[s, k] = cap_scale * c


@njit(cache=True, nogil=True)
def pickoff_volts(capacitance, rest, volts_per_farad, out):
    """
    ``out[s, j] = sum_e (C[s, e] - C0[e]) G[e, j]``: the pick-off amplifiers' outputs (E1), V.

    Summed over the electrodes in their order, row by row, so that a sample's value does not
    depend on how many samples a call holds: ``numpy.matmul`` goes through BLAS, whose kernels
    for one row and for many round differently (a run cut into calls of 1 sample and one of
    12 000 samples differed in the last bits of the demodulator's output).

    Parameters
    ----------
    capacitance : ndarray, shape (S, K)
        Electrode capacitances, F.
    rest : ndarray, shape (K,)
        Their rest values, F.
    volts_per_farad : ndarray, shape (K, J)
        Gains, V/F.
    out : ndarray, shape (S, J)
        The outputs, V.

    """
    n_s, n_k = capacitance.shape
    n_j = volts_per_farad.shape[1]
    for s in range(n_s):
        for j in range(n_j):
            acc = 0.0
            for e in range(n_k):
                acc += (capacitance[s, e] - rest[e]) * volts_per_farad[e, j]
            out[s, j] = acc


@njit(cache=True, nogil=True)
def iq_fit(phase, volts, coef):
    """
    Least squares of each column of ``volts`` on ``cos(phase), sin(phase), 1``, into ``coef``.

    The closed loop's synchronous demodulator (``core/control.py``, C2): the normal equations
    (3 x 3, summed over the samples in their order) solved by Cramer's rule, for every column
    at once. One compiled loop instead of ``np.linalg.solve`` on numpy's products (~40 us of
    Python and BLAS per 1 ms loop period, measured 2026-12-03).

    Parameters
    ----------
    phase : ndarray, shape (N,)
        NCO phase at each sample, rad.
    volts : ndarray, shape (N, J)
        The signals, V.
    coef : ndarray, shape (3, J)
        ``(a, b, c)`` of ``a cos(phase) + b sin(phase) + c`` per column, V.

    """
    n = phase.size
    n_j = volts.shape[1]
    scc = 0.0
    scs = 0.0
    sc = 0.0
    sss = 0.0
    ss = 0.0
    for j in range(n_j):
        coef[0, j] = 0.0
        coef[1, j] = 0.0
        coef[2, j] = 0.0
    for k in range(n):
        c = math.cos(phase[k])
        s = math.sin(phase[k])
        scc += c * c
        scs += c * s
        sc += c
        sss += s * s
        ss += s
        for j in range(n_j):
            value = volts[k, j]
            coef[0, j] += c * value
            coef[1, j] += s * value
            coef[2, j] += value
    m = float(n)
    # the cofactors of the symmetric matrix [[scc, scs, sc], [scs, sss, ss], [sc, ss, m]]
    c00 = sss * m - ss * ss
    c01 = sc * ss - scs * m
    c02 = scs * ss - sss * sc
    c11 = scc * m - sc * sc
    c12 = scs * sc - scc * ss
    c22 = scc * sss - scs * scs
    det = scc * c00 + scs * c01 + sc * c02
    for j in range(n_j):
        r0 = coef[0, j]
        r1 = coef[1, j]
        r2 = coef[2, j]
        coef[0, j] = (c00 * r0 + c01 * r1 + c02 * r2) / det
        coef[1, j] = (c01 * r0 + c11 * r1 + c12 * r2) / det
        coef[2, j] = (c02 * r0 + c12 * r1 + c22 * r2) / det
