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
The time stepper: the kicks, one splitting step, and :func:`run_samples`.

:func:`run_samples` advances whole output periods (its docstring says how steps are placed and
cut at shock pulses); :func:`_step` is one BAB step (the package docstring gives the method),
made of the kicks (:func:`_kick`, or :func:`_kick_rotating` in a rotating frame), the drifts
(:mod:`ring_gyro_sim.core.kernels.drift`) and the force
(:mod:`ring_gyro_sim.core.kernels.force`) at each stage.
"""

import math
from typing import NamedTuple

from numba import njit
import numpy as np

from ring_gyro_sim.core.kernels.drift import (_drift, _fill_pair_propagators, _fill_propagators,
                                              _kick_drift, _pair_drift)
from ring_gyro_sim.core.kernels.force import _force_any
from ring_gyro_sim.core.kernels.forcing import (_external, _profile_accel, _rate_at,
                                                _stage_rotations, _step_phasors)
from ring_gyro_sim.core.kernels.stops import (IMPACTS, IN_CONTACT, LAST_CONTACT,
                                              may_touch, REFINE, stop_accel, SUBSTEPS)

__all__ = ['Scratch', 'run_samples']


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
        Kernel status and the column of ``kbasis`` where it happened (:func:`force.nl_accel`).
    tinfo : ndarray, shape (1,)
        Time of the stage that left the range, s.
    cuts : ndarray, shape (>= 2 P + 2,)
        Cut times of a step (:func:`_cut_step`).
    rot, rot_sub : ndarray, shape (s + 1, 2)
        Drive rotations of the stages of a step and of a sub-step
        (:func:`forcing._stage_rotations`).
    prop_sub : ndarray, shape (s, n, 4)
        Propagators of a sub-step.
    pair_prop_sub : ndarray, shape (s, p, 16)
        The coupled pairs' propagators of a sub-step.
    pair_work : ndarray, shape (32,)
        Scratch of the pairs' in-kernel exponentials.
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
    pair_prop_sub: np.ndarray
    pair_work: np.ndarray
    turn: np.ndarray
    turn_key: np.ndarray


class Span(NamedTuple):
    """
    One step or sub-step as :func:`_step` takes it: start, length, propagators, rotations.

    Attributes
    ----------
    t : float
        Start, s.
    h : float
        Length, s.
    prop : ndarray, shape (s, n, 4)
        The drifts' exact linear flows for this length (``Method.prop`` for the plain step,
        ``Scratch.prop_sub`` for a sub-step).
    rot : ndarray, shape (s + 1, 2)
        The drive rotations of its stages (``Scratch.rot`` or ``Scratch.rot_sub``).
    pair_prop : ndarray, shape (s, p, 16)
        The coupled pairs' flows for this length (``Method.pair_prop``, or
        ``Scratch.pair_prop_sub``).

    """

    t: float
    h: float
    prop: np.ndarray
    rot: np.ndarray
    pair_prop: np.ndarray


@njit(cache=True, inline='always')
def _kick(v, acc, fe, kick):
    """Kick (B): ``v += kick (a_nl + a_ext)``, ``kick`` = a stage's coefficient times the step."""
    for c in range(v.size):
        v[c] += kick * (acc[c] + fe[c])


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
def _kick_rotating(q, v, acc, fe, kick, rate, forcing, turn):
    """
    Kick (B) in the rotating sensor frame: the exact flow of ``q' = 0``, ``v' = a + G v``.

    ``rate`` is ``(Omega, Omega')``, the frame's rate (rad/s) and its derivative (rad/s^2);
    ``a`` is the force (``acc + fe``) plus the centrifugal and angular-acceleration terms,
    ``Omega^2 q_c + kappa Omega' q_s`` on a cos coordinate and ``Omega^2 q_s - kappa Omega' q_c``
    on its sin partner, and ``G v`` the Coriolis term ``(+2 kappa Omega v_s, -2 kappa Omega
    v_c)`` (``structure.gyroscopic_coefficient``, eqs. G5-G6). With the positions fixed over
    a kick this is linear with constant coefficients, integrated exactly: with
    ``theta = 2 kappa Omega tau``, ``z = v_c + i v_s`` and ``alpha = a_c + i a_s``,
    ``z(tau) = e^{-i theta} z + tau (sin theta / theta - i (1 - cos theta) / theta) alpha``,
    the coefficients of this kick in ``turn``, one row per pair (row ``i`` of
    ``Scratch.turn`` for kick ``i``, :func:`_turn_coefficients`). The
    splitting stays the RKN pair of the package docstring with B now linear in velocity; its
    error is measured against DOP853 with the rotation in ``test/core/test_rotation.py``.
    Every coordinate belongs to a pair (``gyro.enabled`` needs ``modes.companions``).
    """
    w = rate[0]
    wdot = rate[1]
    for p in range(forcing.pair_c.size):
        ic = forcing.pair_c[p]
        js = forcing.pair_s[p]
        kap = forcing.kappa[p]
        a_c = acc[ic] + fe[ic] + w * w * q[ic] + kap * wdot * q[js]
        a_s = acc[js] + fe[js] + w * w * q[js] - kap * wdot * q[ic]
        co = turn[p, 0]
        si = turn[p, 1]
        s1 = turn[p, 2]
        s2 = turn[p, 3]
        vc = v[ic]
        vs = v[js]
        v[ic] = co * vc + si * vs + kick * (s1 * a_c + s2 * a_s)
        v[js] = co * vs - si * vc + kick * (s1 * a_s - s2 * a_c)


@njit(cache=True, inline='always')
def _step(q, v, acc, span, method, force, drive, forcing, scratch, full_step):
    """
    One BAB splitting step over ``span`` (package docstring), in place.

    With stops (``forcing.stops.gap > 0``) their force is added to the electrostatic one at
    every stage (``stops.stop_accel``); a ``full_step`` that finds a stage in contact stops
    with ``info[0] = stops.REFINE`` (taken again in sub-steps, :func:`_advance_span`).

    ``span`` is the step or sub-step (:class:`Span`): its start, its length and its
    propagators and drive rotations. ``acc`` holds the force at the start (FSAL) and gets the
    force at the end.
    Returns False when a stage leaves the model's range: then ``scratch.info`` holds the
    status and the angle, ``scratch.tinfo[0]`` the stage's time, and ``q, v`` that stage's
    (finite) values.
    """
    ts = span.t
    hs = span.h
    prop = span.prop
    rot = span.rot
    a = method.a
    b = method.b
    n_stages = a.size
    fe = scratch.fe
    info = scratch.info
    t_mid = ts + 0.5 * hs
    phasors = _step_phasors(ts, drive)
    tt = ts
    base = (0.0, 0.0)
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
            base = _profile_accel(tt, forcing.profile_t, forcing.profile_x, forcing.profile_y)
        _external(tt, t_mid, base, (rot[i, 0], rot[i, 1]), forcing, drive, phasors, fe)
        if rotating:
            _kick_rotating(q, v, acc, fe, b[i] * hs, (w, wdot), forcing, turn[i])
            _drift(q, v, prop, i)
        else:
            _kick_drift(q, v, acc, fe, b[i] * hs, prop, i)
        _pair_drift(q, v, span.pair_prop, method.pairs, i)
        tt += hs * a[i]
        # nl_accel written out: its fallback is called from here, not from an inlined
        # function (see _force).
        _force_any(q, force, scratch.work, acc, info)
        if info[0] != 0:
            scratch.tinfo[0] = tt
            return False
        if forcing.stops.gap > 0.0:
            if stop_accel(q, v, forcing.stops, acc, full_step) == 2:
                info[0] = REFINE
                scratch.tinfo[0] = tt
                return False
    if forcing.profile_t.size > 0:
        base = _profile_accel(ts + hs, forcing.profile_t, forcing.profile_x, forcing.profile_y)
    _external(ts + hs, t_mid, base, (rot[n_stages, 0], rot[n_stages, 1]), forcing, drive,
              phasors, fe)
    if rotating:
        _kick_rotating(q, v, acc, fe, b[n_stages] * hs, (w, wdot), forcing, turn[n_stages])
    else:
        _kick(v, acc, fe, b[n_stages] * hs)
    return True


@njit(cache=True, inline='always')
def _advance_span(q, v, acc, span, method, force, drive, forcing, scratch):
    """
    Take ``span`` as one :func:`_step`, or, near a stop, as sub-steps (``kernels.stops``, S4).

    Without stops, one step. With them, a span that may reach a stop (``stops.may_touch``)
    is cut into equal sub-steps of at most ``stops.max_sub``; one that may not is
    taken whole, from a saved start, and taken again in sub-steps if a stage touched a stop
    (:data:`stops.REFINE`). The ends of the (sub-)steps count the impacts (S5). Returns what
    :func:`_step` returns.
    """
    stops = forcing.stops
    on = stops.gap > 0.0
    n = q.size
    full = True
    save = stops.save
    if on:
        full = not may_touch(q, v, acc, method.omega, span.h, stops)
        if full:
            for c in range(n):
                save[0, c] = q[c]
                save[1, c] = v[c]
                save[2, c] = acc[c]
    m = 1
    sub = span
    r = 0
    while r < m:
        if not full:
            if r == 0:
                m = max(1, int(math.ceil(span.h / stops.max_sub - 1e-9)))
                hs = span.h / m
                if not (hs == stops.key[0] and drive.omega == stops.key[1]):
                    _fill_propagators(method.omega, method.zeta, method.a, hs, stops.prop,
                                      method.coupled)
                    _fill_pair_propagators(method.pair_system, method.a, hs, stops.pair_prop,
                                           scratch.pair_work)
                    _stage_rotations(method.a, hs, drive.omega, stops.rot)
                    stops.key[0] = hs
                    stops.key[1] = drive.omega
            hs = span.h / m
            sub = Span(t=span.t + r * hs, h=hs, prop=stops.prop, rot=stops.rot,
                       pair_prop=stops.pair_prop)
            stops.state[SUBSTEPS] += 1
        if not _step(q, v, acc, sub, method, force, drive, forcing, scratch, full and on):
            if not (on and scratch.info[0] == REFINE):
                return False
            scratch.info[0] = 0
            for c in range(n):
                q[c] = save[0, c]
                v[c] = save[1, c]
                acc[c] = save[2, c]
            full = False
            r = 0
            continue
        if on:
            now = stops.state[LAST_CONTACT]
            if now != 0 and stops.state[IN_CONTACT] == 0:
                stops.state[IMPACTS] += 1
            stops.state[IN_CONTACT] = now
        r += 1
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
    The pieces (:func:`_cut_step`, :func:`_step`, :func:`force._force`, ...) are inlined
    (``inline='always'``): called, a step would pass ~20 array structures every step. The
    kernel is compiled without numba's reference counting (``_nrt=False``; it allocates
    nothing): with it, every step would pay an atomic increment and decrement of each array
    argument.

    """
    fe = scratch.fe
    for c in range(q.size):
        fe[c] = 0.0
    scratch.turn_key[0] = np.nan  # another call's coefficients may be another config's
    forcing.stops.key[0] = np.nan  # and so may the stops' sub-step arrays
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
                pair_prop = method.pair_prop
                rot = scratch.rot
                if active:
                    length = cuts[g + 1] - cuts[g]
                    if length <= 0.0:
                        continue
                    m = max(1, int(math.ceil(length / forcing.pulse_max_sub - 1e-9)))
                    hs = length / m
                    _fill_propagators(method.omega, method.zeta, method.a, hs,
                                      scratch.prop_sub, method.coupled)
                    _fill_pair_propagators(method.pair_system, method.a, hs,
                                           scratch.pair_prop_sub, scratch.pair_work)
                    _stage_rotations(method.a, hs, drive.omega, scratch.rot_sub)
                    prop = scratch.prop_sub
                    pair_prop = scratch.pair_prop_sub
                    rot = scratch.rot_sub
                for r in range(m):
                    span = Span(t=cuts[g] + r * hs, h=hs, prop=prop, rot=rot,
                                pair_prop=pair_prop)
                    if not _advance_span(q, v, acc, span, method, force, drive, forcing,
                                         scratch):
                        return s
        for c in range(q.size):
            out_q[s, c] = q[c]
            out_v[s, c] = v[c]
    return n_samples
