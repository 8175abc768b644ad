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
The electrostatic force kernel: the generalised force per modal mass at a state.

:func:`nl_accel` is the entry point (its docstring gives the definition); the step inlines its
two paths itself. :class:`Force` holds the model as the kernels take it
(``forces.build_force_model`` builds it); the quadrature angles come in orbits of the ring's
symmetries (:func:`orbit_angle`, :func:`member_basis`); P(u) is a series evaluated by Estrin's
scheme (:func:`estrin_layout`, :func:`_series_values`) or Horner's rule (:func:`_horner`), or
the closed form when untruncated (:func:`_p_of_u`); :func:`_angle_values` gives w at the
angles (the output channels use it too); :func:`_force` is the common case, inlined,
:func:`_force_general` the rest, out of line, and :func:`_force_any` picks one.
"""

import math
from typing import NamedTuple

from numba import njit
import numpy as np

from ring_gyro_sim.core.kernels.status import (STATUS_INNER_CONTACT, STATUS_NONFINITE,
                                               STATUS_OK, STATUS_OUTER_CONTACT,
                                               STATUS_SERIES_RANGE)

__all__ = ['NEEDS_GENERAL', 'Force', 'ESTRIN_MAX_SLOTS', 'estrin_layout', 'orbit_angle',
           'member_basis', 'nl_accel']


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


def orbit_angle(theta_rep: float, member: int) -> float:
    """
    Angle (rad, in [0, 2 pi)) of orbit member k of a representative angle.

    The members, in the one order the kernels use: ``theta, pi - theta, -theta, pi + theta``
    (member 3 is the composition of members 1 and 2).
    """
    angle = (theta_rep, math.pi - theta_rep, -theta_rep, math.pi + theta_rep)[member]
    return angle % (2.0 * math.pi)


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
    18 dependent operations, the longest part of a stage); Estrin's scheme pairs the
    coefficients, ``(c0 + c1 u) + u^2 (c2 + c3 u)``, and combines the blocks with ``u^4`` and
    ``u^8``: 4 levels for 16 coefficients. Written out per slot count, with the coefficients
    in registers and one loop over the angles, so that it vectorises over them (a loop over
    the blocks inside the loop over the angles does not keep them in registers and is slower
    than Horner's rule). The
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
    fast-math).
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


@njit(cache=True, inline='always')
def _angle_values(x, kbasis, m, u):
    """
    Set ``u[:m] = x @ kbasis[:, :m]``, w at the first m angles (loops vectorise over k).

    In units of d_g with :func:`member_basis`, in m with plain mode shapes. The sum over
    the coordinates runs in their order, ``((x0 b0 + x1 b1) + x2 b2) + ...``: the first six
    (N_R = 3 with companions) or three (without) in one pass over the angles, the rest
    three per pass (one pass per coordinate would store and reload u on the stage's critical
    path). A
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
(n ulps of ``|w|``), so that the range check over the angles (:func:`_all_inside`, a pass over
them on the stage's critical path) runs only when the ring is within that of the gap.
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

    Written without branches around the work: inlined in the step loop, a conditional store
    or call in here (the fallback, an early return) makes this path much slower
    (``doc/performance.md``), so the fallback is the caller's (:func:`nl_accel`,
    :func:`step._step`).
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

    :func:`_force` takes the common case, :func:`_force_general` the rest (:func:`step._step`
    makes the same two calls itself). ``work`` is scratch of at least ``8 R`` floats; ``out``
    (n,) receives the accelerations (m/s^2). On a state out of range ``info[0]`` gets the
    status, ``info[1]`` the column ``k R + j`` of ``kbasis`` (member k of representative j),
    and ``out`` is left unchanged.
    """
    _force_any(x, force, work, out, info)
