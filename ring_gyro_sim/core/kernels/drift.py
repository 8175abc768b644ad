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
vv)`` for drift i and coordinate c: a linear part that couples coordinates (a pair's 2x2
stiffness block, whose flow is then 4x4) changes the layout here.
"""

import math

from numba import njit
import numpy as np

__all__ = ['linear_propagators']


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
