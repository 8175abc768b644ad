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
The averaged model's kernels: the pair's first harmonics and the closed-loop slow flow.

Used by ``core.engine.averaged`` (S3-S10): the first harmonics of the force and of the pick-off,
and the closed-loop slow flow stepped loop period by loop period.

First harmonics in closed form (S3, S4)
    At a quadrature angle the displacement of the pair is ``w = Re(Z e^{i phi})`` with
    ``Z = b_c A_c + b_s A_s`` (the mode shapes there). The first harmonic of a power
    ``(r cos psi)^k``, k odd, is ``2^{1-k} C(k, (k-1)/2) r^k cos psi``; so the truncated
    force ``P(u) = sum_k p_k u^k`` has the first harmonic ``Z D(|Z|^2)`` with
    ``D(s) = sum_{k odd} p_k 2^{1-k} C(k, (k-1)/2) s^{(k-1)/2}`` (S3), exact: the
    alternating-frequency-time sum of ``harmonic_balance`` at 16 phases gives the same to
    round-off. The pick-off integrates ``1 / (d - w)``, whose first harmonic is
    ``2 Z / ((d + s) s)``, ``s = sqrt(d^2 - |Z|^2)`` (the generating function of the
    Chebyshev series of ``1 / (d - r cos psi)``) (S4): exact for the same quadrature nodes
    as the full model's capacitances.

The sums over angles, merged (the closed loop's speed)
    With real shapes, ``|Z|^2 = a^2 |B_c|^2 + 2 a b Re(B_c conj B_s) + b^2 |B_s|^2`` at
    every angle: the angles that the ring's symmetry maps onto each other share
    ``(a^2, 2 a b, b^2)``, so one ``D(s)`` per group serves them, with their weights summed
    (:func:`harmonic_groups`; 36 force angles in 8 groups, 64 pick-off nodes in 16, on the
    default gyroscope). :func:`force_grouped` and :func:`pickoff_grouped` are the closed
    loop's; :func:`force_harmonic` and :func:`pickoff_harmonic`, the per-angle sums, their
    reference (``test_averaged``: equal to round-off).
"""

import math
from typing import NamedTuple

from numba import njit
import numpy as np

__all__ = ['EnvelopeModel', 'force_grouped', 'force_harmonic', 'harmonic_groups',
           'pickoff_grouped', 'pickoff_harmonic', 'run_periods', 'stretch_samples',
           'LOOP_STATE_SIZE']


class EnvelopeModel(NamedTuple):
    """
    The closed-loop slow flow as :func:`run_periods` takes it (built by ``core.engine.averaged``).

    Attributes
    ----------
    fb_c, fb_s : ndarray, shape (M,)
        The pair's mode shapes at the force's M quadrature angles, over d_g.
    fw_c, fw_s : ndarray, shape (M,)
        The projections onto q2 and q2s (weights, parities and modal masses), rad/kg.
    dcoef : ndarray, shape (D,)
        ``D(s)`` of (S3), coefficients of ``s^0, s^1, ...``, N/rad.
    fgroups : ndarray, shape (G, 7)
        The force's angles merged by symmetry (:func:`harmonic_groups` of ``fb_*``,
        ``fw_*``).
    pb_c, pb_s : ndarray, shape (P,)
        The pair's mode shapes at the electrodes' quadrature nodes, m/m.
    pg_drive, pg_sense : ndarray, shape (P,)
        Volts per farad of each node's electrode times its weight and ``eps eps_0 l r_o``.
    pgroups : ndarray, shape (H, 7)
        The electrodes' nodes merged by symmetry (:func:`harmonic_groups` of ``pb_* / d_g``,
        ``pg_* / d_g``).
    gap : float
        d_g, m.
    omega_c : float
        ``2 pi drive.frequency``, rad/s: the NCO's centre (C3).
    omega_frame : float
        The frame frequency of the envelopes' velocity, rad/s (S1, S5, S12): ``omega_c``
        times the frequencies' factor at the device's temperature.
    stiffness, damping : ndarray, shape (2, 2)
        K and C of the pair (S2).
    kappa : float
        The Coriolis coefficient.
    rate_times, rate_values : ndarray
        The rate profile's knots (``scenario.rate_*``), s and rad/s.
    window : int
        Output samples per loop period (``N`` of C1).
    period : float
        The loop period, s.
    pll_kp, pll_ki, agc_kp, agc_ki, rb_kp, rb_ki : float
        The loops' gains (C3, C5, C6).
    omega_range, lock_threshold, drive_limit, setpoint : float
        ``2 pi control.pll_range``, rad; ``control.lock_threshold``; ``control.drive_limit``;
        the AGC's set-point, m.
    rebalance : bool
        ``control.mode: rebalance``.
    sense_phase_error : float
        ``gyro.phase_error``, rad.
    drive_gain, sense_gain : float
        The held amplifiers' gains at rest, V/m.
    f_state, f_input, out_state, out_input : ndarray
        The output low-pass over one loop period of a held input (a linear map of its
        state ``(S,)``: ``state' = f_state @ state + f_input u``, output at the period's
        last sample ``out_state @ state + out_input u``).
    qualify, disqualify : float
        ``REBALANCE_QUALIFY``, ``REBALANCE_DISQUALIFY`` (C8b).
    qualify_periods, lock_periods : int
        ``REBALANCE_QUALIFY_PERIODS``, ``LOCK_PERIODS`` (C4, C8b).
    max_rotation : float
        Largest ``|lambda| h`` of a Runge-Kutta step (S6).

    """

    fb_c: np.ndarray
    fb_s: np.ndarray
    fw_c: np.ndarray
    fw_s: np.ndarray
    dcoef: np.ndarray
    fgroups: np.ndarray
    pb_c: np.ndarray
    pb_s: np.ndarray
    pg_drive: np.ndarray
    pg_sense: np.ndarray
    pgroups: np.ndarray
    gap: float
    omega_c: float
    omega_frame: float
    stiffness: np.ndarray
    damping: np.ndarray
    kappa: float
    rate_times: np.ndarray
    rate_values: np.ndarray
    window: int
    period: float
    pll_kp: float
    pll_ki: float
    agc_kp: float
    agc_ki: float
    rb_kp: float
    rb_ki: float
    omega_range: float
    lock_threshold: float
    drive_limit: float
    setpoint: float
    rebalance: bool
    sense_phase_error: float
    drive_gain: float
    sense_gain: float
    f_state: np.ndarray
    f_input: np.ndarray
    out_state: np.ndarray
    out_input: np.ndarray
    qualify: float
    disqualify: float
    qualify_periods: int
    lock_periods: int
    max_rotation: float


# The loops' state (C3-C8b), one float array.
PLL_I, AGC_I, RB_IC, RB_IS, OMEGA, FORCE, SC, SS, PHASE_ERR, AMP, RB_RATE, RB_QUAD, \
    LOCKED, RB_ON, LOCKING, QUALIFYING, NCO_PHASE = range(17)
LOOP_STATE_SIZE = 17


GROUP_TOLERANCE = 1e-14
"""Angles whose ``(a^2, 2 a b, b^2)`` agree to this (relative to the largest) share one
``D(s)`` in :func:`harmonic_groups`: the ring's symmetric angles, whose shapes differ by the
round-off of their cosines."""


def harmonic_groups(shape_c, shape_s, weight_c, weight_s) -> np.ndarray:
    """
    Return the angles of (S3) or (S4) merged by their ``|Z|^2``, rows (G, 7).

    Row ``(alpha, beta, gamma, W_ca, W_cb, W_sa, W_sb)``: a group's ``|Z|^2 = alpha P +
    beta Q + gamma R`` and its members' summed weights.

    ``sum_m w_m Z_m D(|Z_m|^2)`` with ``Z_m = a_m B_c + b_m B_s`` (``a``, ``b`` real shapes,
    ``w`` real weights) is ``B_c G_a + B_s G_b``, ``G_x = sum_m w_m x_m D(s_m)``, and
    ``s_m = a_m^2 P + 2 a_m b_m Q + b_m^2 R`` with ``P = |B_c|^2``, ``Q = Re(B_c conj B_s)``,
    ``R = |B_s|^2`` (|Z|^2 of real shapes), exact. The angles that the ring's symmetry maps
    onto each other (the force's four members, the electrodes' mirror nodes) have the same
    ``(a^2, 2 a b, b^2)`` up to :data:`GROUP_TOLERANCE`: one ``D(s)`` serves them all,
    with the sums of their ``w x`` (``math.fsum``; a sum within 1e-13 of its terms'
    magnitudes is round-off of one the symmetry makes zero: 0.0). 36 force angles make 8
    groups, 64 pick-off nodes 16, on the default gyroscope. What the symmetry makes zero
    across groups (the sine force of a state without sine content, from mirror groups of
    opposite weights) is zero to the round-off of their sum (~1e-17 of the force), not
    exactly as :func:`force_harmonic`'s member order keeps it.
    """
    a = np.asarray(shape_c, dtype=float)
    b = np.asarray(shape_s, dtype=float)
    key = np.stack([a * a, 2.0 * a * b, b * b], axis=1)
    tol = GROUP_TOLERANCE * float(np.max(np.abs(key)))
    free = np.ones(a.size, dtype=bool)
    rows = []
    for m in range(a.size):
        if not free[m]:
            continue
        members = free & np.all(np.abs(key - key[m]) <= tol, axis=1)
        free &= ~members
        row = list(key[m])
        for terms in (weight_c * a, weight_c * b, weight_s * a, weight_s * b):
            t = np.asarray(terms, dtype=float)[members]
            value = math.fsum(t)
            row.append(value if abs(value) > 1e-13 * math.fsum(np.abs(t)) else 0.0)
        rows.append(row)
    return np.array(rows, dtype=float).reshape(-1, 7)


@njit(cache=True, inline='always')
def _grouped(a_c, a_s, groups, series, top):
    """
    Return the two sums of :func:`harmonic_groups`' ``groups`` and the largest ``|Z|^2``.

    ``(B_c G_a + B_s G_b, B_c G_sa + B_s G_sb, max s)`` with ``D(s) = sum_{k <= top}
    series_k s^k``, in real arithmetic.

    One loop of fixed length over the groups, each an independent Horner chain (no
    branches: the stages' chain of evaluations is latency-bound).
    """
    cr, ci, sr, si = a_c.real, a_c.imag, a_s.real, a_s.imag
    p = cr * cr + ci * ci
    q = cr * sr + ci * si
    r = sr * sr + si * si
    g0 = g1 = g2 = g3 = 0.0
    reach = 0.0
    for n in range(groups.shape[0]):
        x = groups[n, 0] * p + groups[n, 1] * q + groups[n, 2] * r
        reach = max(reach, x)
        d = series[top]
        for k in range(top - 1, -1, -1):
            d = d * x + series[k]
        g0 += groups[n, 3] * d
        g1 += groups[n, 4] * d
        g2 += groups[n, 5] * d
        g3 += groups[n, 6] * d
    return (complex(g0 * cr + g1 * sr, g0 * ci + g1 * si),
            complex(g2 * cr + g3 * sr, g2 * ci + g3 * si), reach)


@njit(cache=True, inline='always')
def _member(cr, ci, sr, si, b_c, b_s, dcoef, nd):
    """Return ``Z D(|Z|^2)`` of (S3) at one angle as (real, imag); NaN beyond the range."""
    zr = b_c * cr + b_s * sr
    zi = b_c * ci + b_s * si
    s = zr * zr + zi * zi
    if s >= 1.0:
        return np.nan, np.nan
    d = dcoef[nd - 1]
    for i in range(nd - 2, -1, -1):
        d = d * s + dcoef[i]
    return zr * d, zi * d


@njit(cache=True)
def force_harmonic(a_c, a_s, fb_c, fb_s, fw_c, fw_s, dcoef):
    """
    Return N(A) of the pair, ``(N_c, N_s)`` m/s^2, by (S3); NaN when out of range.

    ``fb_*`` at the 4 R angles in the force kernel's member order, ``fw_*`` (4 R,) the
    projections times the members' parities: summed per representative as the force
    kernel sums, ``(h0 + s1 h1) + s2 (h2 + s1 h3)``, so that what is zero by symmetry (the
    sine force of a state without sine content) is exactly 0.0. Real arithmetic (numba's
    complex product checks for infinities).
    """
    cr, ci, sr, si = a_c.real, a_c.imag, a_s.real, a_s.imag
    ncr = nci = nsr = nsi = 0.0
    nd = dcoef.size
    r = fb_c.size // 4
    for j in range(r):
        h0r, h0i = _member(cr, ci, sr, si, fb_c[j], fb_s[j], dcoef, nd)
        h1r, h1i = _member(cr, ci, sr, si, fb_c[r + j], fb_s[r + j], dcoef, nd)
        h2r, h2i = _member(cr, ci, sr, si, fb_c[2 * r + j], fb_s[2 * r + j], dcoef, nd)
        h3r, h3i = _member(cr, ci, sr, si, fb_c[3 * r + j], fb_s[3 * r + j], dcoef, nd)
        w0, w1, w2, w3 = fw_c[j], fw_c[r + j], fw_c[2 * r + j], fw_c[3 * r + j]
        ncr += (w0 * h0r + w1 * h1r) + (w2 * h2r + w3 * h3r)
        nci += (w0 * h0i + w1 * h1i) + (w2 * h2i + w3 * h3i)
        w0, w1, w2, w3 = fw_s[j], fw_s[r + j], fw_s[2 * r + j], fw_s[3 * r + j]
        nsr += (w0 * h0r + w1 * h1r) + (w2 * h2r + w3 * h3r)
        nsi += (w0 * h0i + w1 * h1i) + (w2 * h2i + w3 * h3i)
    if not (math.isfinite(ncr) and math.isfinite(nsr)):
        return complex(np.nan, np.nan), complex(np.nan, np.nan)
    return complex(ncr, nci), complex(nsr, nsi)


@njit(cache=True, inline='always')
def force_grouped(a_c, a_s, fgroups, dcoef):
    """
    Return :func:`force_harmonic`'s N(A) by merged angles, to round-off; NaN out of range.

    ``fgroups`` :func:`harmonic_groups` of ``(fb_c, fb_s, fw_c, fw_s)``. Out of range as
    :func:`force_harmonic`: an angle at ``|Z|^2 >= 1`` (contact; every angle is in a
    group, to :data:`GROUP_TOLERANCE`), or a result not finite.
    """
    n_c, n_s, reach = _grouped(a_c, a_s, fgroups, dcoef, dcoef.size - 1)
    if reach < 1.0 and math.isfinite(n_c.real + n_c.imag + n_s.real + n_s.imag):
        return n_c, n_s
    return complex(np.nan, np.nan), complex(np.nan, np.nan)


PICKOFF_SERIES = np.array([math.comb(2 * k + 1, k) / 4.0 ** k for k in range(12)])
"""``c_k = C(2k+1, k) / 4^k``: ``2 / ((1 + sqrt(1 - x)) sqrt(1 - x)) = sum_k c_k x^k`` (S4)."""
PICKOFF_SERIES_REACH = 0.05
"""Largest ``x = |Z|^2 / d^2`` summed by the series: ``c_12 x^12 < 1e-16`` there; below it
the fewest terms whose first left out is below 1e-17 (5 at the default drive, x = 1.6e-3)."""


@njit(cache=True, inline='always')
def _series_top(reach):
    """
    Return the last term of (S4)'s series summed at ``reach``: ``reach^(top + 1) < 1e-17``.

    (``c_k < 2`` for ``k <= 12``: the first term left out is below 2e-17 of the sum.)
    """
    if reach > 0.0:
        return min(11, max(1, int(math.ceil(-17.0 / math.log10(reach))) - 1))
    return 11


@njit(cache=True)
def pickoff_harmonic(a_c, a_s, pb_c, pb_s, pg_drive, pg_sense, gap):
    """
    Return the amplifiers' first harmonics ``(V_drive, V_sense)``, V, by (S4).

    ``2 Z / ((d + s) s) = (Z / d^2) sum_k c_k x^k`` (:data:`PICKOFF_SERIES`) while every
    node's ``x = |Z|^2 / d^2`` is below :data:`PICKOFF_SERIES_REACH` (bounded by
    ``(|A_c| + |A_s|)^2 / d^2``: the shapes are cosines and sines), to round-off; else the
    closed form. NaN at or beyond contact.
    """
    v_d = 0j
    v_s = 0j
    d2 = gap * gap
    reach = (abs(a_c) + abs(a_s)) ** 2 / d2
    if reach < PICKOFF_SERIES_REACH:
        c = PICKOFF_SERIES
        cr, ci, sr, si = a_c.real, a_c.imag, a_s.real, a_s.imag
        inv = 1.0 / d2
        top = _series_top(reach)
        dr = di = er = ei = 0.0
        for j in range(pb_c.size):
            zr = pb_c[j] * cr + pb_s[j] * sr
            zi = pb_c[j] * ci + pb_s[j] * si
            x = (zr * zr + zi * zi) * inv
            g = c[top]
            for k in range(top - 1, -1, -1):
                g = g * x + c[k]
            dr += pg_drive[j] * zr * g
            di += pg_drive[j] * zi * g
            er += pg_sense[j] * zr * g
            ei += pg_sense[j] * zi * g
        v_d = complex(dr, di)
        v_s = complex(er, ei)
        return v_d / d2, v_s / d2
    for j in range(pb_c.size):
        z = pb_c[j] * a_c + pb_s[j] * a_s
        r2 = z.real * z.real + z.imag * z.imag
        if r2 >= d2:
            return complex(np.nan, np.nan), complex(np.nan, np.nan)
        s = math.sqrt(d2 - r2)
        h = 2.0 * z / ((gap + s) * s)
        v_d += pg_drive[j] * h
        v_s += pg_sense[j] * h
    return v_d, v_s


@njit(cache=True, inline='always')
def pickoff_grouped(a_c, a_s, pgroups, pb_c, pb_s, pg_drive, pg_sense, gap):
    """
    Return :func:`pickoff_harmonic`'s ``(V_drive, V_sense)`` by merged nodes, to round-off.

    Within :data:`PICKOFF_SERIES_REACH`, the same series to the same last term
    (``_series_top``) over the nodes merged by :func:`harmonic_groups` (``pgroups`` of
    ``(pb_c / d, pb_s / d, pg_drive / d, pg_sense / d)``: ``x = |Z|^2 / d^2`` and the
    ``1 / d^2`` in the weights); beyond it, :func:`pickoff_harmonic` itself (the closed
    form, NaN at contact).
    """
    reach = (abs(a_c) + abs(a_s)) ** 2 / (gap * gap)
    if reach < PICKOFF_SERIES_REACH:
        v_d, v_s, _ = _grouped(a_c, a_s, pgroups, PICKOFF_SERIES, _series_top(reach))
        return v_d, v_s
    return pickoff_harmonic(a_c, a_s, pb_c, pb_s, pg_drive, pg_sense, gap)


@njit(cache=True, inline='always')
def _rate(t, times, values):
    """Return the rate profile's value (rad/s) and slope at t (``core.rate_profile``)."""
    n = times.size
    if n == 0:
        return 0.0, 0.0
    if t >= times[n - 1]:
        return values[n - 1], 0.0
    k = np.searchsorted(times, t, side='right') - 1
    if k < 0:
        return 0.0, 0.0
    if k >= n - 1:
        return values[n - 1], 0.0
    slope = (values[k + 1] - values[k]) / (times[k + 1] - times[k])
    return values[k] + slope * (t - times[k]), slope


@njit(cache=True, inline='always')
def _rate_before(t, times, values):
    """
    Return the rate profile's left limit (rad/s) and slope at t.

    The value an RK4 step ending at t takes for its last stage: a step of the profile at t
    acts from t on (``kernels.forcing._rate_at``), not over the step that ends there.
    """
    n = times.size
    if n == 0:
        return 0.0, 0.0
    if t > times[n - 1]:
        return values[n - 1], 0.0
    k = np.searchsorted(times, t, side='left') - 1
    if k < 0:
        return 0.0, 0.0
    slope = (values[k + 1] - values[k]) / (times[k + 1] - times[k])
    return values[k] + slope * (t - times[k]), slope


@njit(cache=True, inline='always')
def _next_knot(t, end, times):
    """Return the first knot of the rate profile after t and before ``end``, else ``end``."""
    k = np.searchsorted(times, t, side='right')
    if k < times.size and times[k] < end:
        return times[k]
    return end


@njit(cache=True, inline='always')
def _derivative(m, rate, slope, b_c, b_s, delta, f_c, f_s):
    """Return B' of (S5) in the NCO's frame: the slow flow (S2) less ``i delta B``."""
    w = m.omega_frame
    k = m.stiffness
    c = m.damping
    n_c, n_s = force_grouped(b_c, b_s, m.fgroups, m.dcoef)
    kr = m.kappa * rate
    ks = m.kappa * slope
    # (S2) less i delta B, in real arithmetic: the bracket is X - i omega Y with
    # X = (omega^2 + Omega^2 - K) B - kappa Omega' J B + N + F and Y = (C + 2 kappa Omega J) B,
    # J = [[0, -1], [1, 0]]; B' = -(i / (2 omega)) X - Y / 2 - i delta B
    diag = w * w + rate * rate
    cr, ci, sr, si = b_c.real, b_c.imag, b_s.real, b_s.imag
    xcr = (diag - k[0, 0]) * cr - k[0, 1] * sr + ks * sr + n_c.real + f_c.real
    xci = (diag - k[0, 0]) * ci - k[0, 1] * si + ks * si + n_c.imag + f_c.imag
    xsr = (diag - k[1, 1]) * sr - k[1, 0] * cr - ks * cr + n_s.real + f_s.real
    xsi = (diag - k[1, 1]) * si - k[1, 0] * ci - ks * ci + n_s.imag + f_s.imag
    ycr = c[0, 0] * cr + (c[0, 1] - 2.0 * kr) * sr
    yci = c[0, 0] * ci + (c[0, 1] - 2.0 * kr) * si
    ysr = c[1, 1] * sr + (c[1, 0] + 2.0 * kr) * cr
    ysi = c[1, 1] * si + (c[1, 0] + 2.0 * kr) * ci
    half = 0.5 / w
    return (complex(half * xci - 0.5 * ycr + delta * ci, -half * xcr - 0.5 * yci - delta * cr),
            complex(half * xsi - 0.5 * ysr + delta * si, -half * xsr - 0.5 * ysi - delta * sr))


@njit(cache=True, inline='always')
def _update(m, st, x_c, x_s, y_c, y_s):
    """One loop update from the period's measurements, as ``DriveLoop.update`` (C3-C8b)."""
    dt = m.period
    e = math.atan2(x_c, x_s)
    st[PLL_I] += m.pll_ki * e * dt
    st[PLL_I] = min(max(st[PLL_I], -m.omega_range), m.omega_range)
    offset = m.pll_kp * e + st[PLL_I]
    clamped = abs(offset) >= m.omega_range
    st[OMEGA] = m.omega_c + min(max(offset, -m.omega_range), m.omega_range)
    st[PHASE_ERR] = e
    if st[LOCKED] > 0.5:
        locked = abs(e) < m.lock_threshold and not clamped
        st[LOCKING] = 0.0
    else:
        if abs(e) < 0.5 * m.lock_threshold and not clamped:
            st[LOCKING] += 1.0
        else:
            st[LOCKING] = 0.0
        locked = st[LOCKING] >= m.lock_periods
    st[LOCKED] = 1.0 if locked else 0.0
    amp = math.hypot(x_c, x_s)
    st[AMP] = amp
    err = m.setpoint - amp
    raw = m.agc_kp * err + st[AGC_I] + m.agc_ki * err * dt
    if not ((raw > m.drive_limit and err > 0.0) or (raw < 0.0 and err < 0.0)):
        st[AGC_I] += m.agc_ki * err * dt
    st[FORCE] = min(max(m.agc_kp * err + st[AGC_I], 0.0), m.drive_limit)
    if st[RB_ON] > 0.5:
        on = locked and amp >= m.disqualify * m.setpoint
        st[QUALIFYING] = 0.0
    elif m.rebalance:
        if locked and amp >= m.qualify * m.setpoint:
            st[QUALIFYING] += 1.0
        else:
            st[QUALIFYING] = 0.0
        on = st[QUALIFYING] >= m.qualify_periods
    else:
        on = False
    st[RB_ON] = 1.0 if on else 0.0
    if m.rebalance and not on:
        st[SC] = st[SS] = st[RB_RATE] = st[RB_QUAD] = 0.0
    elif m.rebalance:
        if m.sense_phase_error != 0.0:
            ce, se = math.cos(m.sense_phase_error), math.sin(m.sense_phase_error)
            y_c, y_s = y_c * ce - y_s * se, y_c * se + y_s * ce
        lim = m.drive_limit
        i_c = min(max(st[RB_IC] - m.rb_ki * y_s * dt, -lim), lim)
        i_s = min(max(st[RB_IS] + m.rb_ki * y_c * dt, -lim), lim)
        st[RB_IC] = i_c
        st[RB_IS] = i_s
        st[SC] = min(max(i_c - m.rb_kp * y_s, -lim), lim)
        st[SS] = min(max(i_s + m.rb_kp * y_c, -lim), lim)
        scale = 2.0 * m.kappa * st[OMEGA] * amp
        st[RB_RATE] = st[SC] / scale if amp > 0.0 else 0.0
        st[RB_QUAD] = st[SS] / scale if amp > 0.0 else 0.0


@njit(cache=True)
def run_periods(m, env, st, filt, first_period, count, decimate, noise, out_t, out_env,
                out_loop, out_filtered):
    """
    Advance the slow flow and the loops by ``count`` loop periods (S5-S10).

    ``env`` (2,) complex: B in the NCO's frame (S5); ``st`` the loops' state
    (:data:`LOOP_STATE_SIZE`); ``filt`` (4, S) the output low-pass's state of the four
    rebalance channels (rate, quadrature, S_c, S_s); ``first_period`` the index of the
    first period (period p ends at ``(p + 1) T``). Every ``decimate``-th period end is an
    output (row r: the time, B, the loops' state after the update, the filtered channels at
    the period's last sample). ``noise`` (count, 8): per period, the thermomechanical
    force's first harmonics on q2 and q2s (re, im, re, im; m/s^2, S9), held over the period
    and added to the commands, and the fit's errors on the drive and sense amplifiers' first
    harmonics (re, im, re, im; V, S10), added to what the loops read; ``(0, 8)``: no noise
    (the arithmetic of a noiseless run unchanged). Returns the number of outputs written, or
    ``-1 - p`` when period p left the force's range (NaN).
    """
    h_period = m.period
    written = 0
    u = np.empty(4)
    new = np.empty(filt.shape[1])
    for p in range(count):
        index = first_period + p
        t0 = index * h_period
        delta = st[OMEGA] - m.omega_frame
        # the commands of this period (C6): the drive on q2, the rebalance on q2s
        f_c = complex(st[FORCE], 0.0)
        f_s = complex(st[SC], -st[SS])
        if m.sense_phase_error != 0.0:
            f_s *= complex(math.cos(m.sense_phase_error), math.sin(m.sense_phase_error))
        noisy = noise.shape[0] > 0
        if noisy:  # (S9) the force noise's first harmonics over this period
            f_c += complex(noise[p, 0], noise[p, 1])
            f_s += complex(noise[p, 2], noise[p, 3])
        # (S6) RK4 substeps: |lambda| h below max_rotation, cut at the rate profile's
        # knots (a step or a kink inside an RK4 step would be smeared over its stages)
        b_c = env[0]
        b_s = env[1]
        scale = abs(delta) + abs(m.omega_frame - math.sqrt(m.stiffness[0, 0])) \
            + abs(m.omega_frame - math.sqrt(m.stiffness[1, 1])) + 1e-4 * m.omega_frame
        mean_c = 0j
        mean_s = 0j
        t_end = t0 + h_period
        a = t0
        while a < t_end:
            piece_end = _next_knot(a, t_end, m.rate_times)
            sub = max(1, int(math.ceil(scale * (piece_end - a) / m.max_rotation)))
            h = (piece_end - a) / sub
            h6 = h / 6.0
            w6 = h / (6.0 * h_period)
            for k in range(sub):
                t = a + k * h
                t_next = piece_end if k == sub - 1 else t + h
                r1, g1 = _rate(t, m.rate_times, m.rate_values)
                r2, g2 = _rate(t + 0.5 * h, m.rate_times, m.rate_values)
                r4, g4 = _rate_before(t_next, m.rate_times, m.rate_values)
                k1c, k1s = _derivative(m, r1, g1, b_c, b_s, delta, f_c, f_s)
                y2c = b_c + 0.5 * h * k1c
                y2s = b_s + 0.5 * h * k1s
                k2c, k2s = _derivative(m, r2, g2, y2c, y2s, delta, f_c, f_s)
                y3c = b_c + 0.5 * h * k2c
                y3s = b_s + 0.5 * h * k2s
                k3c, k3s = _derivative(m, r2, g2, y3c, y3s, delta, f_c, f_s)
                y4c = b_c + h * k3c
                y4s = b_s + h * k3s
                k4c, k4s = _derivative(m, r4, g4, y4c, y4s, delta, f_c, f_s)
                # (S7) the period's mean of B by the same quadrature (the integral of B as a
                # state of the same Runge-Kutta step)
                mean_c += (b_c + 2.0 * y2c + 2.0 * y3c + y4c) * w6
                mean_s += (b_s + 2.0 * y2s + 2.0 * y3s + y4s) * w6
                b_c = b_c + (k1c + 2.0 * k2c + 2.0 * k3c + k4c) * h6
                b_s = b_s + (k1s + 2.0 * k2s + 2.0 * k3s + k4s) * h6
            a = piece_end
        if not (math.isfinite(b_c.real + b_c.imag + b_s.real + b_s.imag)):
            return -1 - index
        env[0] = b_c
        env[1] = b_s
        # the NCO's phase at the period's end (the simulator's re-phasing, C3)
        st[NCO_PHASE] = np.fmod(st[OMEGA] * h_period + st[NCO_PHASE], 2.0 * math.pi)
        # (S8) the output low-pass over the period's held rows, before the update
        u[0] = st[RB_RATE]
        u[1] = st[RB_QUAD]
        u[2] = st[SC]
        u[3] = st[SS]
        is_out = (index + 1) % decimate == 0
        for ch in range(4):
            if is_out:
                y = m.out_input * u[ch]
                for i in range(filt.shape[1]):
                    y += m.out_state[i] * filt[ch, i]
                out_filtered[written, ch] = y
            for i in range(filt.shape[1]):
                acc = m.f_input[i] * u[ch]
                for j in range(filt.shape[1]):
                    acc += m.f_state[i, j] * filt[ch, j]
                new[i] = acc
            for i in range(filt.shape[1]):
                filt[ch, i] = new[i]
        # (S7) the measurement: the pick-off's first harmonics of the period's mean,
        # fitted as x_c cos(phi) + x_s sin(phi) (C2): x_c = Re, x_s = -Im
        v_d, v_s = pickoff_grouped(mean_c, mean_s, m.pgroups, m.pb_c, m.pb_s, m.pg_drive,
                                   m.pg_sense, m.gap)
        if not math.isfinite(v_d.real + v_s.real):
            return -1 - index
        if noisy:  # (S10) the fit's errors from the amplifiers' noise
            v_d += complex(noise[p, 4], noise[p, 5])
            v_s += complex(noise[p, 6], noise[p, 7])
        _update(m, st, v_d.real / m.drive_gain, -v_d.imag / m.drive_gain,
                v_s.real / m.sense_gain, -v_s.imag / m.sense_gain)
        if is_out:
            out_t[written] = (index + 1) * h_period
            out_env[written, 0] = b_c
            out_env[written, 1] = b_s
            for i in range(LOOP_STATE_SIZE):
                out_loop[written, i] = st[i]
            written += 1
    return written


@njit(cache=True, nogil=True)
def stretch_samples(env, starts, omega, window, period, omega_frame, dc, q_out, v_out,
                    phase_out, demod_out):
    """
    Write the samples of an averaged stretch from its loop updates (R1, R3).

    ``core.engine.averaged.AveragedEngine`` derives them.

    Parameters
    ----------
    env : ndarray of complex, shape (P + 1, 2)
        The pair's envelopes at the stretch's start and at the end of each of its P periods.
    starts : ndarray, shape (P,)
        The NCO's phase at the start of each period, rad.
    omega : ndarray, shape (P,)
        The NCO's angular frequency over each period, rad/s.
    window : int
        Samples per period.
    period : float
        The sample period, s.
    omega_frame : float
        The frame's angular frequency (S1), rad/s.
    dc : ndarray, shape (P + 1, 4)
        The demodulator's outputs at the start and at the end of each period.
    q_out, v_out : ndarray, shape (P * window, 2)
        The pair's coordinates (m) and velocities (m/s) at every sample, written.
    phase_out : ndarray, shape (P * window,)
        The NCO's phase at every sample, rad in [0, 2 pi), written.
    demod_out : ndarray, shape (P * window, 4)
        The demodulator's outputs at every sample, written.

    """
    two_pi = 2.0 * math.pi
    for p in range(omega.size):
        w = omega[p]
        start = starts[p]
        # e^{i phi} turned by e^{i w P} per sample (one cos and sin per period, not per
        # sample: the product's rounding grows to ~window ulps over a period)
        step_c = math.cos(w * period)
        step_s = math.sin(w * period)
        c = math.cos(start)
        s = math.sin(start)
        for j in range(1, window + 1):
            i = p * window + j - 1
            frac = j / window
            phi = start + w * j * period
            phi -= two_pi * math.floor(phi / two_pi)
            phase_out[i] = phi
            c, s = c * step_c - s * step_s, s * step_c + c * step_s
            for m in range(2):
                b = env[p, m] + (env[p + 1, m] - env[p, m]) * frac
                q_out[i, m] = b.real * c - b.imag * s
                v_out[i, m] = -omega_frame * (b.real * s + b.imag * c)
            for ch in range(4):
                demod_out[i, ch] = dc[p, ch] + (dc[p + 1, ch] - dc[p, ch]) * frac
