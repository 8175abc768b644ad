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
The drift (A): the exact flow of the damped linear oscillators.

``x'' + 2 zeta omega x' + omega^2 x = 0`` has a closed-form flow over any time tau, a 2x2
matrix per coordinate (:func:`linear_propagators`): no phase error and no numerical damping
whatever the step. A splitting step applies it once per drift (:func:`_drift`), fused with the
kick before it where the kick is the plain one (:func:`_kick_drift`); the sub-steps of a step
cut by a shock pulse have their own, computed in the kernel (:func:`_fill_propagators`).

This module is the one place that knows the propagators' layout, ``prop[i, c] = (xx, xv, vx,
vv)`` for drift i and coordinate c.

Coupled pairs
    An imperfect mode pair (a split or a damping mismatch whose principal axes are not on the
    electrodes: ``structure.pair_matrices``) has a full 2x2 stiffness ``K`` and damping ``C``
    per unit modal mass: its linear part couples ``q_n`` and ``q_n^s``. Its flow is the exact
    4x4 ``expm(A tau)`` of ``(q_c, q_s, v_c, v_s)' = A (q_c, q_s, v_c, v_s)``,
    ``A = [[0, I], [-K, -C]]`` (:func:`pair_propagators`, ``pair_prop[i, p]`` row-major),
    applied after the per-coordinate flow by :func:`_pair_drift`; the per-coordinate flows of
    the pair's two coordinates are the identity then (``coupled`` of
    :func:`_fill_propagators`). Both the steps' flows and the sub-steps' are the scaling and
    squaring of :func:`_expm4` (``test/core/kernels/test_drift.py`` compares it with
    ``scipy.linalg.expm``, which costs 2.5 ms a 4x4: a device rebuilt as its die warms
    must not pay that). A configuration without coupled pairs runs
    the same operations as before, bit for bit.
"""

import math

from numba import njit
import numpy as np

__all__ = ['linear_propagators', 'pair_propagators', 'pair_system']


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


def pair_system(stiffness: np.ndarray, damping: np.ndarray) -> np.ndarray:
    """
    Return ``A = [[0, I], [-K, -C]]`` of a coupled pair, row-major, shape (16,).

    ``stiffness`` K (rad/s)^2 and ``damping`` C (1/s): 2x2 per unit modal mass
    (``structure.pair_matrices``); the state is ``(q_c, q_s, v_c, v_s)``.
    """
    a = np.zeros((4, 4))
    a[0, 2] = a[1, 3] = 1.0
    a[2:, :2] = -np.asarray(stiffness, dtype=np.float64)
    a[2:, 2:] = -np.asarray(damping, dtype=np.float64)
    return a.ravel()


def pair_propagators(systems: np.ndarray, taus: np.ndarray) -> np.ndarray:
    """
    Exact flows ``expm(A tau)`` of coupled pairs over each time ``tau`` (module docstring).

    Parameters
    ----------
    systems : ndarray, shape (p, 16)
        Each pair's ``A`` (:func:`pair_system`).
    taus : ndarray, shape (s,)
        Durations, s.

    Returns
    -------
    ndarray, shape (s, p, 16)
        Row-major 4x4 flows.

    """
    out = np.empty((taus.size, systems.shape[0], 16))
    work = np.empty(32)
    for k, tau in enumerate(taus):
        for p, system in enumerate(systems):
            _expm4(np.ascontiguousarray(system), float(tau), out[k, p], work)
    return out


@njit(cache=True)
def _expm4(system, tau, out, work):
    """
    ``expm(A tau)`` of a pair's 4x4 ``A`` (row-major 16) by scaling and squaring, into ``out``.

    Balanced first: with ``w0`` the square root of the larger stiffness, the state
    ``(w0 q, v)`` has the system ``B = D A D^-1`` (``D = diag(w0, w0, 1, 1)``) whose entries
    are all of the order of a frequency, so ``B tau`` is halved only until its largest row sum
    is at most 0.25 (once or twice for a step), its exponential taken by the Taylor series to
    degree 16 (remainder below ``0.25^17 / 17!``: 1e-25) and squared back, and the flow is
    ``D^-1 expm(B tau) D``. ``work`` (32 floats) is scratch: the kernel allocates nothing.
    """
    w0 = math.sqrt(max(abs(system[8]), abs(system[13]), 1e-300))
    term = work[:16]
    nxt = work[16:]
    # B tau into out (scaled below): rows/cols 0-1 are positions (times w0), 2-3 velocities
    for r in range(4):
        for c in range(4):
            scale = 1.0
            if r < 2 and c >= 2:
                scale = w0
            elif r >= 2 and c < 2:
                scale = 1.0 / w0
            nxt[4 * r + c] = system[4 * r + c] * scale * tau
    norm = 0.0
    for r in range(4):
        row = 0.0
        for c in range(4):
            row += abs(nxt[4 * r + c])
        norm = max(norm, row)
    squarings = 0
    factor = 1.0
    while norm * factor > 0.25:
        factor *= 0.5
        squarings += 1
    bmat = out  # B tau / 2^s, kept in out while the series is summed into term
    for k in range(16):
        bmat[k] = nxt[k] * factor
    # the series sum_j (B tau)^j / j!, accumulated in work[16:]; term holds the last power
    for k in range(16):
        term[k] = 1.0 if k % 5 == 0 else 0.0
    acc16 = work[16:]
    for k in range(16):
        acc16[k] = term[k]
    for j in range(1, 17):
        # term <- term @ bmat / j, written back in place row by row
        for r in range(4):
            t0 = term[4 * r]
            t1 = term[4 * r + 1]
            t2 = term[4 * r + 2]
            t3 = term[4 * r + 3]
            for c in range(4):
                term[4 * r + c] = (t0 * bmat[c] + t1 * bmat[4 + c] + t2 * bmat[8 + c]
                                   + t3 * bmat[12 + c]) / j
        for k in range(16):
            acc16[k] += term[k]
    for _ in range(squarings):
        for r in range(4):
            t0 = acc16[4 * r]
            t1 = acc16[4 * r + 1]
            t2 = acc16[4 * r + 2]
            t3 = acc16[4 * r + 3]
            for c in range(4):
                term[4 * r + c] = (t0 * acc16[c] + t1 * acc16[4 + c] + t2 * acc16[8 + c]
                                   + t3 * acc16[12 + c])
        for k in range(16):
            acc16[k] = term[k]
    for r in range(4):
        for c in range(4):
            scale = 1.0
            if r < 2 and c >= 2:
                scale = 1.0 / w0
            elif r >= 2 and c < 2:
                scale = w0
            out[4 * r + c] = acc16[4 * r + c] * scale


@njit(cache=True)
def _fill_pair_propagators(systems, a, tau, prop, work):
    """In-kernel version of :func:`pair_propagators` for the drifts ``a * tau``."""
    for i in range(a.size):
        for p in range(systems.shape[0]):
            _expm4(systems[p], a[i] * tau, prop[i, p], work)


@njit(cache=True, inline='always')
def _pair_drift(q, v, pair_prop, pairs, i):
    """Apply the coupled pairs' exact 4x4 flows of drift ``i`` (module docstring)."""
    for p in range(pairs.shape[0]):
        c = pairs[p, 0]
        s = pairs[p, 1]
        x0 = q[c]
        x1 = q[s]
        x2 = v[c]
        x3 = v[s]
        m = pair_prop[i, p]
        q[c] = m[0] * x0 + m[1] * x1 + m[2] * x2 + m[3] * x3
        q[s] = m[4] * x0 + m[5] * x1 + m[6] * x2 + m[7] * x3
        v[c] = m[8] * x0 + m[9] * x1 + m[10] * x2 + m[11] * x3
        v[s] = m[12] * x0 + m[13] * x1 + m[14] * x2 + m[15] * x3


@njit(cache=True)
def _fill_propagators(omega, zeta, a, tau, prop, coupled):
    """
    In-kernel version of :func:`linear_propagators` for the drifts ``a * tau``.

    The coordinates of coupled pairs (``coupled[c]`` true) get the identity: their flow is
    the pair's (:func:`_pair_drift`).
    """
    for i in range(a.size):
        dt = a[i] * tau
        for c in range(omega.size):
            if coupled[c]:
                prop[i, c, 0] = 1.0
                prop[i, c, 1] = 0.0
                prop[i, c, 2] = 0.0
                prop[i, c, 3] = 1.0
                continue
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
    Kick (B) then drift (A) of drift ``i``: :func:`step._kick` and :func:`_drift` in one.

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
