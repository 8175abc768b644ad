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
The external forcing of a stage: drive, rebalance force, shock pulses, base acceleration, rate.

:class:`Drive` (the 2theta drive and the closed loop's rebalance force) and :class:`Forcing`
(shock pulses, the sampled base acceleration, the rotation of the sensor frame, the force
noise) are what :func:`ring_gyro_sim.core.kernels.step.run_samples` takes; :func:`_external`
writes the acceleration of one stage, from the drive's phasor at the step's start
(:func:`drive_phasor`) turned by the stage's rotation (:func:`_stage_rotations`).
"""

import math
from typing import NamedTuple

from numba import njit
import numpy as np

from ring_gyro_sim.core.kernels.stops import Stops

__all__ = ['Drive', 'Forcing', 'drive_phasor']


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
    The forcing over one call of :func:`step.run_samples`: shocks, base acceleration, rotation.

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
    stops : Stops
        The mechanical stops (``kernels.stops``; ``gap`` 0.0: none).

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
    stops: Stops


class DrivePhasors(NamedTuple):
    """
    The drive's and the rebalance force's phasors at the start of a step (:func:`_step_phasors`).

    A stage's value is the phasor turned by the stage's offset in the step
    (:func:`_stage_rotations`), by the angle-sum formula (:func:`_external`): one cos and one
    sin per step instead of one per stage.

    Attributes
    ----------
    drive_c, drive_s : float
        ``A cos, A sin`` of the drive's phase at the step's start (:func:`drive_phasor`), m/s^2.
    sense_c, sense_s : float
        The same of the rebalance force (``Drive.sense_amplitude``, lagging the drive by
        ``Drive.sense_phase``); 0.0 without one.

    """

    drive_c: float
    drive_s: float
    sense_c: float
    sense_s: float


@njit(cache=True, inline='always')
def drive_phasor(t, amp, omega, t_ref, phase):
    """Return ``(A cos, A sin)`` of the drive's phase ``omega (t - t_ref) + phase`` at ``t``."""
    if amp == 0.0:
        return 0.0, 0.0
    angle = omega * (t - t_ref) + phase
    return amp * math.cos(angle), amp * math.sin(angle)


@njit(cache=True, inline='always')
def _step_phasors(t, drive):
    """Return the :class:`DrivePhasors` of a :class:`Drive` at ``t``, the start of a step."""
    drive_c, drive_s = drive_phasor(t, drive.amplitude, drive.omega, drive.t_ref, drive.phase)
    sense_c = 0.0
    sense_s = 0.0
    if drive.sense_index >= 0:
        sense_c, sense_s = drive_phasor(t, drive.sense_amplitude, drive.omega, drive.t_ref,
                                        drive.phase - drive.sense_phase)
    return DrivePhasors(drive_c, drive_s, sense_c, sense_s)


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
def _external(t, t_mid, base, rot, forcing, drive, phasors, fe):
    """
    External acceleration of the stage at time ``t`` (s) into ``fe`` (m/s^2).

    Only ``fe[0]``, ``fe[forcing.y_index]``, ``fe[drive.index]`` and ``fe[drive.sense_index]``
    (distinct) are written; the other entries stay at the zero :func:`step.run_samples` puts
    there (zeroing all of ``fe`` every stage compiled to a call of memset).

    Base acceleration ``a_b`` enters as ``-a_b`` on q_1 (x) and q_1^s (y) (eq. 27). Whether a
    pulse acts is decided at the middle ``t_mid`` of the current (sub)step, which never
    straddles a pulse's start or end; inside it the half-sine formula is used at every stage,
    so stages that some splittings place outside the step (negative drifts) see the smooth
    continuation, not a kink. ``base`` is ``(x, y)`` of the sampled profile at ``t``
    (:func:`_profile_accel`, called by :func:`step._step`: a call in here, even one not taken,
    would cost every stage).

    The drive ``A cos(omega (t - t_ref) + phase)`` on q_2 is ``drive_c rot_c - drive_s rot_s``:
    ``phasors`` holds ``drive_c, drive_s = A cos, A sin`` of the phase at the start of the
    step (:class:`DrivePhasors`) and ``rot = (rot_c, rot_s)`` the cos and sin of ``omega``
    times the stage's offset in the step (:func:`_stage_rotations`), by the angle-sum formula.
    The rebalance force on ``drive.sense_index`` (the closed loop's,
    ``Drive.sense_amplitude``) is the same with its own phasor ``sense_c, sense_s``.
    """
    pulses = forcing.pulses
    ax = base[0]
    ay = base[1]
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
    if drive.index >= 0:
        fe[drive.index] = phasors.drive_c * rot[0] - phasors.drive_s * rot[1]
    if drive.sense_index >= 0:
        fe[drive.sense_index] = phasors.sense_c * rot[0] - phasors.sense_s * rot[1]
