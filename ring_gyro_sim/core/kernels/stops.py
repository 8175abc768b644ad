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
The mechanical stops' contact force: a hysteretic penalty on the modes.

The stops are two continuous rings at the radial clearance g_s = ``stops.gap``, one outside
the ring and one inside (the electrodes lie beyond them, at d_g > g_s). At an angle theta the
penetration is ``delta = |w| - g_s`` where ``|w(theta)| > g_s``, ``w = sum_i q_i phi_i``
(``phi_i`` = cos n theta or sin n theta, eq. 2). The stop pushes back with a force per unit
length of the circumference (S1)::

    f(theta) = -sign(w) k_s delta s,   s = 1 while delta grows (loading),
                                       s = e^2 while it shrinks (unloading)

with k_s = ``stops.stiffness`` (N/m^2) and e = ``stops.restitution``. Whether delta grows is
the sign of ``sign(w) wdot(theta)``, ``wdot = sum_i v_i phi_i``. Projected on the modes as the
electrostatic force is (eq. 23's generalised force, per modal mass m_i; the trapezoidal rule on
M equal angles)::

    a_i = (r / m_i) int f(theta) phi_i(theta) dtheta
        ~ sum_j (2 pi r k_s / (M m_i)) phi_i(theta_j) f_j / k_s                              (S2)

The restitution (S3). At every angle the force is a spring of stiffness k_s while it is
loaded and e^2 k_s while it unloads: a point that goes in and comes out once stores
``k_s delta_max^2 / 2`` and gives back ``e^2`` of it. In an impact in which every point of the
contact arc goes in and out once (a single mode, whose penetration at every angle rises and
falls with its coordinate) the ring gives the stop exactly (1 - e^2) of the energy it stored,
whatever the arc, the stiffness or the speed: the normal kinetic energy after the impact is
e^2 of that before (the mode's own spring and the electrostatic force are conservative and
give back over the contact what they took). That is why this law and not a linear
spring-dashpot: the arc of a ring against a circular stop widens with the penetration (the
modal force of a 1theta impact grows as delta^{3/2}, Hertz-like), and a spring-dashpot's
restitution, exp(-zeta pi / sqrt(1 - zeta^2)), holds only for a linear contact; here it would
depend on the impact speed. The force never pulls (no sticking at release, the flaw of a
spring-dashpot), and it needs no state beyond (q, v): a run re-simulates bit for bit from its
state.

The step (S4). The contact is stiff: its angular frequency is at most
``omega_c = sqrt(k_s r pi / m_min)`` (the whole circle in contact, the lightest mode: the
contact's Hessian is below ``k_s r int phi phi^T dtheta = k_s r pi I``), so a contact lasts
at least ``pi / omega_c``. A step that may touch a stop (:func:`may_touch`, a Taylor bound of
``|w|`` over the step at every angle) is cut into sub-steps of at most
``pi / (omega_c STOP_SUBSTEPS_PER_CONTACT)``, as steps are cut at shock pulses; a full
step that finds a stage in contact anyway is taken again in sub-steps from its start
(:data:`REFINE`), so that no contact is ever integrated with the full step.

Impacts (S5) are counted at the ends of (sub-)steps: an end in contact (some angle beyond g_s)
after one that was not is one impact.
"""

import math
from typing import NamedTuple

from numba import njit
import numpy as np

__all__ = ['Stops', 'STOP_SUBSTEPS_PER_CONTACT', 'STOP_MIN_ANGLES', 'REFINE', 'IN_CONTACT',
           'IMPACTS', 'LAST_CONTACT', 'SUBSTEPS', 'stop_angles', 'stop_max_substep',
           'stop_accel']

STOP_SUBSTEPS_PER_CONTACT = 16
"""Sub-steps per shortest contact half-period ``pi / omega_c`` (S4)."""
STOP_MIN_ANGLES = 512
"""
Fewest angles of the stops' grid: at 512 (0.70 deg) a 1theta impact 1 % of d_g deep at
0.6 d_g has ~30 angles in its arc, and a rigid translation between two angles touches the
stop 0.2 nm farther than at one (``g_s (1 / cos(pi / M) - 1)``).
"""

REFINE = -2
"""``info[0]`` of a full step that found a stage in contact: it is taken again in sub-steps."""

IN_CONTACT, IMPACTS, LAST_CONTACT, SUBSTEPS = 0, 1, 2, 3
"""Entries of ``Stops.state``: in contact at the last step's end, impacts counted, the last
force evaluation in contact, contact sub-steps taken."""


class Stops(NamedTuple):
    """
    The stops as the kernels take them (``forces.build_stops`` builds it).

    Attributes
    ----------
    gap : float
        g_s, m; 0.0: no stops (the kernels skip everything here).
    unload : float
        e^2, the unloading stiffness over the loading one (S1).
    basis : ndarray, shape (n, M)
        phi_i(theta_j) at M equal angles ``theta_j = 2 pi j / M``.
    projection : ndarray, shape (n, M)
        ``2 pi r k_s phi_i(theta_j) / (M m_i)``, 1/s^2 (S2).
    max_sub : float
        Longest sub-step of a step that may touch a stop, s (S4).
    w, f : ndarray, shape (M,)
        Scratch: w at the angles, the forces of the angles in contact.
    index : ndarray of int64, shape (M,)
        Scratch: the angles in contact.
    save : ndarray, shape (3, n)
        q, v and the force at the start of a step, to take it again (:data:`REFINE`).
    prop, pair_prop, rot : ndarray
        The sub-steps' propagators and drive rotations (shapes of ``Method.prop``,
        ``Method.pair_prop`` and ``Scratch.rot``).
    key : ndarray, shape (2,)
        ``(h, drive omega)`` the sub-step's arrays hold (NaN: none).
    state : ndarray of int64, shape (4,)
        :data:`IN_CONTACT`, :data:`IMPACTS`, :data:`LAST_CONTACT`, :data:`SUBSTEPS`.

    """

    gap: float
    unload: float
    basis: np.ndarray
    projection: np.ndarray
    max_sub: float
    w: np.ndarray
    f: np.ndarray
    index: np.ndarray
    save: np.ndarray
    prop: np.ndarray
    pair_prop: np.ndarray
    rot: np.ndarray
    key: np.ndarray
    state: np.ndarray


def stop_angles(n_modes: int) -> int:
    """Return the number M of angles of the stops' grid (a multiple of 4)."""
    m = max(STOP_MIN_ANGLES, 128 * n_modes)
    return 4 * ((m + 3) // 4)


def stop_max_substep(stiffness: float, radius: float, lightest_mass: float) -> float:
    """Return the longest sub-step near a stop, s: ``pi / (omega_c n)`` (S4)."""
    omega_c = math.sqrt(stiffness * radius * math.pi / lightest_mass)
    return math.pi / (omega_c * STOP_SUBSTEPS_PER_CONTACT)


@njit(cache=True, _nrt=False)
def stop_accel(q, v, stops, acc, full_step):
    """
    Add the stops' force per modal mass at ``(q, v)`` to ``acc`` (S1, S2).

    Returns 0 when no angle is in contact, 1 when the force was added, 2 (nothing added)
    when ``full_step`` and some angle is in contact: the caller takes the step again in
    sub-steps (:data:`REFINE`). Sets ``state[LAST_CONTACT]``. ``sum |q_i| <= g_s`` bounds
    ``|w|`` at every angle, so the common case costs one pass over the coordinates.
    """
    n = q.size
    gap = stops.gap
    reach = 0.0
    for i in range(n):
        reach += abs(q[i])
    if reach <= gap:
        stops.state[LAST_CONTACT] = 0
        return 0
    basis = stops.basis
    w = stops.w
    m = w.size
    for j in range(m):
        w[j] = basis[0, j] * q[0]
    for i in range(1, n):
        qi = q[i]
        for j in range(m):
            w[j] += basis[i, j] * qi
    index = stops.index
    count = 0
    for j in range(m):
        if abs(w[j]) > gap:
            index[count] = j
            count += 1
    if count == 0:
        stops.state[LAST_CONTACT] = 0
        return 0
    stops.state[LAST_CONTACT] = 1
    if full_step:
        return 2
    f = stops.f
    unload = stops.unload
    for c in range(count):
        j = index[c]
        wj = w[j]
        wd = 0.0
        for i in range(n):
            wd += basis[i, j] * v[i]
        if wj > 0.0:  # the outer stop: f = -k delta, delta = w - g_s, loading while wdot > 0
            f[c] = -(wj - gap) * (1.0 if wd > 0.0 else unload)
        else:  # the inner stop: f = +k delta, delta = -g_s - w, loading while wdot < 0
            f[c] = (-gap - wj) * (1.0 if wd < 0.0 else unload)
    projection = stops.projection
    for i in range(n):
        total = 0.0
        for c in range(count):
            total += projection[i, index[c]] * f[c]
        acc[i] += total
    return 1


@njit(cache=True, _nrt=False)
def may_touch(q, v, acc, omega, h, stops):
    """
    Whether the ring may reach a stop within ``h`` from ``(q, v)`` (S4's prediction).

    First ``sum_i |q_i| + h |v_i| < g_s``: no. Else, at every angle of the grid, the Taylor
    bound ``|w| + h |wdot| + h^2 |wddot| / 2`` with ``wddot = sum_i (acc_i - omega_i^2 q_i)
    phi_i`` (the force and the mode's own spring) against g_s. A miss is caught by the step
    itself (:data:`REFINE`): this only spares the full steps that would be taken again.
    """
    n = q.size
    reach = 0.0
    for i in range(n):
        reach += abs(q[i]) + h * abs(v[i])
    if reach < stops.gap:
        return False
    basis = stops.basis
    m = stops.w.size
    half = 0.5 * h * h
    for j in range(m):
        w = 0.0
        wd = 0.0
        wdd = 0.0
        for i in range(n):
            b = basis[i, j]
            w += b * q[i]
            wd += b * v[i]
            wdd += b * (acc[i] - omega[i] * omega[i] * q[i])
        if abs(w) + h * abs(wd) + half * abs(wdd) >= stops.gap:
            return True
    return False
