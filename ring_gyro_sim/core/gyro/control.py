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

r"""
The closed-loop drive: a PLL and an AGC on the 2theta mode, and force-to-rebalance (C1-C9).

Real CVG electronics do not drive open loop: a phase-locked loop keeps the drive force at
the drive mode's resonance as it moves (the electrostatic softening, a shock), and an
automatic gain control holds the vibration amplitude. ``control.mode: closed_loop``
replaces the paper's fixed ``A cos(omega t)`` by these loops; ``control.mode: rebalance`` adds
a third loop that holds the sense mode at zero and reads the rate from its force.

Timing (C1)
    The loops are digital, updated every ``N = output.rate / control.rate`` output samples
    (a loop period ``T = N P``, 1 ms by default), at the fixed global sample indices
    ``k = m N - 1`` (``m = 1, 2, ...``): the simulator cuts its stretches there, so the result
    does not depend on how a run is cut into blocks. What a loop measures over period ``m``
    sets the commands of period ``m + 1``: a delay of one period, from the centre of the
    window the measurement averages to the centre of the period the command is held over
    (the averaging and the hold add no delay of their own about those centres).

Sensing (C2)
    The loops read the pick-off amplifiers (``electronics.PickOff``: the electrodes'
    capacitances, the same noise samples as the sense chain), not the modal coordinates: a
    shock's gap changes reach the loops as they would reach real electronics. Over each
    period both voltages are fitted by least squares to ``a cos(phi) + b sin(phi) + c``,
    ``phi`` the NCO phase at each sample (a synchronous demodulator that rejects the
    ``2 omega`` product exactly for a steady sinusoid, where a boxcar over a non-whole
    number of cycles leaks ~0.5 %). Divided by the amplifiers' gains at rest
    (``PickOff.drive_gain``, ``sense_gain``) this gives the displacements
    ``q2 ~ x_c cos(phi) + x_s sin(phi)`` and ``q2s ~ y_c cos(phi) + y_s sin(phi)``.

PLL (C3)
    The drive force is ``F cos(phi)``. At resonance the displacement lags by 90 degrees:
    ``q2 = X sin(phi)``. The phase detector is ``e = atan2(x_c, x_s)`` (0 at lock, > 0 below
    resonance). Near resonance the resonator's phase obeys ``e' = -e / tau - (omega -
    omega_n)``, ``tau = 2 Q / omega``; the PI loop filter
    ``omega = omega_c + K_p e + K_i int e dt`` with ``K_p = 2 pi B_pll``,
    ``K_i = K_p^2 / 4`` (the zero a quarter of the crossover below it: 76 degrees of phase
    margin less the delay's ``2 pi B_pll T``, 7 degrees at 20 Hz and 1 ms) closes a
    loop of crossover ``B_pll`` (``control.pll_bandwidth``). The NCO (``omega``) is limited
    to ``omega_c +- 2 pi control.pll_range``, ``omega_c`` = ``drive.frequency``; its phase is
    continuous (the simulator re-phases the drive at each update).

Lock detector (C4)
    With hysteresis, as lock detectors are built: locked, it stays locked while
    ``|e| < control.lock_threshold`` and the NCO is inside its range; unlocked, it locks again
    once ``|e|`` has stayed below half the threshold, the NCO inside its range, for
    :data:`LOCK_PERIODS` consecutive periods. While a PLL slips cycles after a shock its
    phase error sweeps through zero: without the hysteresis the detector (and the loops it
    qualifies) switched on and off every few periods. A loss of lock is reported with its time
    (``lost_lock_at_s``, the first), and so is the return.

AGC (C5)
    Amplitude ``X = hypot(x_c, x_s)``. At resonance the envelope obeys
    ``X' = -X / tau + F / (2 omega)``; the PI ``F = K_p (X_set - X) + K_i int (X_set - X)``
    with ``K_p = 4 pi omega B_agc`` and ``K_i = K_p (2 pi B_agc) / 4`` has crossover ``B_agc``.
    ``F`` is limited to ``[0, control.drive_limit]``, the integrator frozen while the output
    sits at a limit in the direction of the error (anti-windup). The integrator starts at
    ``drive.amplitude`` (the open-loop force that holds the start state), the set-point is
    ``control.agc_setpoint`` or, when 0, the start state's amplitude
    (``hypot(q2, q2' / omega)``; from rest the linear response ``F Q / omega^2``).

Force-to-rebalance (C6-C8)
    The Coriolis acceleration on the sense mode is ``-2 kappa Omega q2'``
    (``structure.gyroscopic_coefficient``), with ``q2 = X sin(phi)``:
    ``-2 kappa Omega omega X cos(phi)``. A force ``S_c cos(phi) + S_s sin(phi)`` on q2s
    cancels it; at match ``S_c cos(phi)`` moves ``y_s`` (gain ``+1 / (2 omega)`` per unit
    time, as the drive) and ``S_s sin(phi)`` moves ``y_c`` (gain ``-1 / (2 omega)``), so::

        S_c = -(K_p y_s + K_i int y_s),  S_s = +(K_p y_c + K_i int y_c)              (C6)

    with the AGC's gains at ``B_rb`` (``control.rebalance_bandwidth``). With the sense mode
    held at zero the rate is read from the force that holds it::

        Omega = S_c / (2 kappa omega X)                                               (C7)

    (``omega`` the NCO's, ``X`` the measured amplitude): a scale factor set by the geometry
    (kappa), the NCO and the AGC, not by the sense mode's Q or its detuning. ``S_s`` is the
    quadrature force. The integrators start at the values that hold the start state
    (``S_c = 2 kappa Omega_0 omega X``, ``Omega_0`` the rate at t = 0). (C8) The rate's
    bandwidth is that of the loop, ``B_rb``, against ``omega / (2 Q)`` open loop (0.12 Hz).
    (C8b) The rebalance loop runs only on a qualified drive: it is switched on once the PLL
    has been locked and the drive amplitude at least :data:`REBALANCE_QUALIFY` of its
    set-point for :data:`REBALANCE_QUALIFY_PERIODS` consecutive periods, and off as soon as
    lock is lost or the amplitude falls below :data:`REBALANCE_DISQUALIFY` (hysteresis: it
    switched on and off with +-5 300 deg/s spikes 2-4 s after a 10 000 g shock without).
    While it is off the rebalance force is 0 and its integrators hold (``rebalance_on`` of
    :data:`CONTROL_CHANNELS` is 0 and ``~/rate`` says it is not a measurement,
    ``core.gyro.validity``): referenced to an NCO that no longer follows the drive, the loop pumped
    up to ``control.drive_limit`` into the sense mode (a 10 000 g shock at
    ``config/gyro.yaml`` kept the PLL out of lock for 9.6 s with it against 3.8 s without),
    and (C7) divides by the amplitude, which a shock collapses. The rebalance rate reads 0
    then, and ``/diagnostics`` says why (``pll_locked``, ``drive_amplitude_m``).

Outputs (C9)
    :data:`CONTROL_CHANNELS`, held over each period at the values in force during it (the
    commands) and the last measurement (phase error, amplitude, rate), are
    ``Samples.control``; the rebalance rate (C7) replaces the sense channel in ``~/rate``
    (``electronics.SenseElectronics``).
"""

from dataclasses import dataclass
import math
from typing import Any, Dict, Optional, Tuple

import numpy as np
from ring_gyro_sim.core import kernels, structure
from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.params import SimConfig


__all__ = ['CONTROL_CHANNELS', 'ControlSamples', 'DriveLoop', 'amplitude_gains',
           'rebalance_response', 'update_rows']

CONTROL_CHANNELS = ('frequency_hz', 'phase_error_rad', 'amplitude_m', 'drive_force',
                    'rebalance_c', 'rebalance_s', 'rebalance_rate_rad_s',
                    'rebalance_quadrature_rad_s', 'locked', 'rebalance_on')
"""Columns of ``Samples.control`` (C9): NCO frequency (Hz), phase error (rad), measured drive
amplitude (m), drive force amplitude (m/s^2), rebalance forces (m/s^2), the rebalance rate
and quadrature (rad/s, C7; 0 without it), 1.0 while locked (C4) and 1.0 while the
rebalance loop runs (C8b)."""

KAPPA_2 = structure.gyroscopic_coefficient(2)
REBALANCE_QUALIFY = 0.5
"""The rebalance loop is switched on once the drive amplitude is at least this part of its
set-point (C8b)."""
REBALANCE_DISQUALIFY = 0.4
"""The rebalance loop is switched off when the drive amplitude falls below this part (C8b)."""
REBALANCE_QUALIFY_PERIODS = 20
"""Loop periods the drive must stay qualified before rebalance runs: 20 ms at 1 kHz, 2.5 time
constants of the 20 Hz PLL (C8b)."""
LOCK_PERIODS = 10
"""Loop periods the phase error must stay within half the threshold to lock again (C4)."""


@dataclass(frozen=True)
class ControlSamples:
    """
    The loops' updates within one block (``~/control``), one row per update (C9).

    Attributes
    ----------
    t : ndarray, shape (M,)
        Update times, s: the end of each loop period (every ``output.rate / control.rate``-th
        sample time).
    values : ndarray, shape (M, len(CONTROL_CHANNELS))
        The loops' state right after each update (the commands of the next period and the
        measurement of the one that ended).

    """

    t: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)


def update_rows(first_index: int, t: np.ndarray, rows: np.ndarray, window: int,
                period_s: float) -> ControlSamples:
    """
    Return the updates inside a block from its per-sample rows (``Samples.control``).

    Sample ``k`` (at ``(k + 1) P``) holds what is in force during it; the update at the end
    of sample ``k = m N - 1`` shows in sample ``m N``, so an update at time ``m N P`` is
    read from the first sample of the next period. An update at a block's last sample time
    is in the next block's first row (reported there, at its own time).
    """
    index = first_index + np.arange(rows.shape[0])
    pick = np.nonzero((index % window == 0) & (index > 0))[0]
    return ControlSamples(t=t[pick] - period_s, values=rows[pick])


def amplitude_gains(omega: float, bandwidth_hz: float) -> Tuple[float, float]:
    """
    ``(K_p, K_i)`` of an amplitude loop of crossover ``bandwidth_hz`` at ``omega`` (C5).

    The envelope plant ``1 / (2 omega) / (s + 1 / tau)`` crosses over at ``K_p / (2 omega)``;
    the PI's zero sits a quarter of the crossover below it.
    """
    w_b = 2.0 * math.pi * bandwidth_hz
    kp = 2.0 * omega * w_b
    return kp, kp * w_b / 4.0


def rebalance_response(config: SimConfig, f_hz: np.ndarray, pole_hz: float) -> np.ndarray:
    """
    Closed-loop response of the rebalance loop from the sense force to its output (C6, C8).

    In the demodulated frame the sense plant is ``P(s) = (1 / (2 omega)) / (s + p)``
    (``p = 2 pi pole_hz``, the sense mode's half-power half-width), the controller
    ``C(s) = K_p + K_i / s`` with the loop's delay of one period (C1); ``T = C P e^{-s D} /
    (1 + C P e^{-s D})`` at ``s = 2 pi i f``. Continuous-time: the loop's sampling is
    left out (its bandwidth is at most a twentieth of its rate).
    """
    c = config.control
    omega = 2.0 * math.pi * config.drive.frequency
    kp, ki = amplitude_gains(omega, c.rebalance_bandwidth)
    s = 2j * math.pi * np.asarray(f_hz, dtype=np.float64)
    s = np.where(s == 0.0, 1e-30j, s)
    delay = 1.0 / c.rate
    loop = (kp + ki / s) * (0.5 / omega) / (s + 2.0 * math.pi * pole_hz) * np.exp(-s * delay)
    return loop / (1.0 + loop)


class DriveLoop:
    """
    PLL, AGC and force-to-rebalance of the 2theta pair (module docstring, C1-C9).

    Parameters
    ----------
    config : SimConfig
        The run's configuration (``control.*``, ``drive.*``, modes).
    pickoff : electronics.PickOff
        The amplifiers the loops read.

    """

    def __init__(self, config: SimConfig, pickoff) -> None:
        c = config.control
        self.config = config
        self.pickoff = pickoff
        self.window = int(round(config.run.output_rate / c.rate))
        self.period_s = self.window / config.run.output_rate
        self.omega_c = 2.0 * math.pi * config.drive.frequency
        self.omega_range = 2.0 * math.pi * c.pll_range
        self.lock_threshold = float(c.lock_threshold)
        self.drive_limit = float(c.drive_limit)
        mode = modes.of(c)
        self.rebalance = bool(mode.rebalance)
        # the coordinates the loops drive and null, and their pair (q2, q2s: the 2theta pair)
        self.drive_index, self.sense_index = mode.axes(config)
        self.drive_order = mode.drive_order
        self.sense_phase_error = float(config.gyro.phase_error)  # the sense reference's (E3b)
        kp = 2.0 * math.pi * c.pll_bandwidth
        self.pll_gains = (kp, kp * kp / 4.0)
        self.agc_gains = amplitude_gains(self.omega_c, c.agc_bandwidth)
        self.rebalance_gains = amplitude_gains(self.omega_c, c.rebalance_bandwidth)
        self.setpoint_m = float(c.agc_setpoint)
        self._setpoint_given = c.agc_setpoint > 0.0
        if not self._setpoint_given:
            self.setpoint_m = self.linear_amplitude()
        self._initial_state()
        self._locking = 0        # periods in a row within half the threshold (C4)
        self._qualifying = 0     # periods in a row with a qualified drive (C8b)
        self.lost_lock_at_s: Optional[float] = None
        self.relocked_at_s: Optional[float] = None
        self.unlocked_since_s: Optional[float] = None
        self.unlocked_periods = 0
        self.updates = 0

    def _initial_state(self) -> None:
        """Set the loops' state (integrators, commands, measurements) as at construction."""
        self.pll_integral = 0.0          # rad/s
        self.agc_integral = float(abs(self.config.drive.amplitude))  # m/s^2
        self.rb_integral = np.zeros(2)   # (S_c, S_s), m/s^2
        self._coef = np.empty((3, 2))  # the C2 fit of a period: (cos, sin, 1) x (sense, drive)
        self.omega = self.omega_c
        self.force = self.agc_integral
        self.rebalance_force = np.zeros(2)
        self.phase_error = 0.0
        self.amplitude = self.setpoint_m
        self.rebalance_rate = 0.0
        self.rebalance_quadrature = 0.0
        self.locked = True
        self.rebalance_on = self.rebalance

    STATE = ('pll_integral', 'agc_integral', 'rb_integral', 'omega', 'force',
             'rebalance_force', 'phase_error', 'amplitude', 'rebalance_rate',
             'rebalance_quadrature', 'locked', 'rebalance_on', 'locking', 'qualifying')
    """The names of the loops' state after an update (:meth:`state`, :meth:`set_state`)."""

    def state(self) -> Dict[str, Any]:
        """
        Return the loops' state after their last update: name -> value (:data:`STATE`).

        ``locking`` and ``qualifying`` are the periods in a row the lock (C4) and the
        rebalance's qualification (C8b) have counted; the rest are the attributes of the
        same names. What an engine hands to another at a loop update.
        """
        out = {name: getattr(self, name) for name in self.STATE[:-2]}
        out['rb_integral'] = self.rb_integral.copy()
        out['rebalance_force'] = self.rebalance_force.copy()
        out['locking'] = self._locking
        out['qualifying'] = self._qualifying
        return out

    def set_state(self, state: Dict[str, Any]) -> None:
        """
        Take the loops' state of :meth:`state` (another engine's at the same loop update).

        Raises
        ------
        InputError
            A name that is not one of :data:`STATE`.

        """
        unknown = sorted(set(state) - set(self.STATE))
        if unknown:
            raise InputError(f'loop state: the loops have no state {unknown[0]!r}')
        for name, value in state.items():
            if name == 'locking':
                self._locking = int(value)
            elif name == 'qualifying':
                self._qualifying = int(value)
            elif isinstance(getattr(self, name), np.ndarray):
                getattr(self, name)[:] = value
            else:
                setattr(self, name, type(getattr(self, name))(value))

    def linear_amplitude(self) -> float:
        """Return the drive mode's linear response to ``drive.amplitude`` at resonance, m."""
        f2 = 2.0 * math.pi * self.config.modes.coordinate_frequencies()[self.drive_index]
        q2 = self.config.modes.coordinate_quality_factors()[self.drive_index]
        return abs(self.config.drive.amplitude) * q2 / (f2 * f2)

    def start(self, q: np.ndarray, v: np.ndarray, rate: float,
              omega: Optional[float] = None) -> float:
        """
        Start the loops in lock at a state; return the NCO's phase at t = 0, rad.

        ``q, v`` the start coordinates and velocities, ``rate`` the angular rate at t = 0
        (rad/s). With the drive moving, ``q2 = Re(c e^{i omega t})``, the NCO starts at
        ``arg(c) + pi / 2`` (the lock point ``q2 = X sin(phi)``: no phase transient), the
        set-point (when not given) at ``|c|``, the AGC's integrator at the resonant part
        ``F |sin(arg c)|`` of the open-loop force that held the state (its lag was
        ``arg c``), the rebalance force at the Coriolis force of ``rate``. A state without
        drive motion keeps the linear set-point and starts at phase 0. ``omega`` (rad/s):
        the NCO's start frequency, its integrator holding it (default ``drive.frequency``;
        a die away from the reference temperature moves the device, core.thermal).
        """
        if omega is not None:
            self.pll_integral = min(max(omega - self.omega_c, -self.omega_range),
                                    self.omega_range)
            self.omega = self.omega_c + self.pll_integral
        w = self.omega_c  # the start state is the drive orbit at drive.frequency
        d = self.drive_index
        c = complex(float(q[d]), -float(v[d]) / w)
        phase = 0.0
        force = float(abs(self.config.drive.amplitude))
        if abs(c) > 0.0:
            psi = math.atan2(c.imag, c.real)
            phase = math.fmod(psi + 0.5 * math.pi, 2.0 * math.pi)
            force *= abs(math.sin(psi))
            if not self._setpoint_given:
                self.setpoint_m = abs(c)
        self.agc_integral = self.force = min(force, self.drive_limit)
        self.amplitude = self.setpoint_m
        if self.rebalance:
            self.rb_integral[:] = (2.0 * KAPPA_2 * rate * w * self.setpoint_m, 0.0)
            if self.drive_order in self.config.modes.coupled_pairs():
                # An imperfect pair forces the sense mode with -K_sc q2 - C_sc q2' too
                # (structure.pair_matrices): q2 = X sin(phi) needs S_s = K_sc X, and
                # C_sc w X more of S_c.
                stiffness, damping = self.config.modes.pair_matrices(self.drive_order)
                self.rb_integral[0] += damping[1, 0] * w * self.setpoint_m
                self.rb_integral[1] += stiffness[1, 0] * self.setpoint_m
            if self.config.gyro.sense_misalignment:
                # The loop holds the sense mode at tan(2 delta) q2 (E1b): q2s = mu X sin(phi)
                # needs S_c = mu C_ss w X more and S_s = mu (K_ss - w^2) X more
                mu = math.tan(2.0 * math.radians(self.config.gyro.sense_misalignment))
                s = self.sense_index
                w_s = 2.0 * math.pi * self.config.modes.coordinate_frequencies()[s]
                c_ss = w_s / self.config.modes.coordinate_quality_factors()[s]
                self.rb_integral[0] += mu * c_ss * w * self.setpoint_m
                self.rb_integral[1] += mu * (w_s * w_s - w * w) * self.setpoint_m
            self.rebalance_force[:] = self.rb_integral
            self.rebalance_rate = float(rate)
            scale = 2.0 * KAPPA_2 * w * self.setpoint_m
            imperfect = (self.drive_order in self.config.modes.coupled_pairs()
                         or bool(self.config.gyro.sense_misalignment))
            if imperfect and scale > 0.0:
                self.rebalance_rate = float(self.rb_integral[0] / scale)
                self.rebalance_quadrature = float(self.rb_integral[1] / scale)
        return phase

    def restart(self, q: np.ndarray, v: np.ndarray, rate: float,
                omega: Optional[float] = None) -> float:
        """
        Start the loops again from their initial state at a state (after a failure).

        As :meth:`start` on a new loop, but the lock detector's history is kept. Returns the
        NCO's phase at the state, rad.
        """
        self._initial_state()
        return self.start(q, v, rate, omega)

    def finite(self) -> bool:
        """Tell whether the loops' state is all finite numbers: outputs (C9) and integrators."""
        return bool(np.all(np.isfinite(self.row()))
                    and math.isfinite(self.pll_integral) and math.isfinite(self.agc_integral)
                    and np.all(np.isfinite(self.rb_integral)))

    def commands(self) -> Tuple[float, float, float, float]:
        """Return ``(omega, F, B, beta)``: NCO (rad/s), drive force and rebalance force/lag."""
        sc, ss = self.rebalance_force
        # the rebalance modulator's reference is the sense channel's, off by its error
        return (self.omega, self.force, math.hypot(sc, ss),
                math.atan2(ss, sc) - self.sense_phase_error)

    def row(self) -> np.ndarray:
        """Return the :data:`CONTROL_CHANNELS` values in force now."""
        return np.array([self.omega / (2.0 * math.pi), self.phase_error, self.amplitude,
                         self.force, self.rebalance_force[0], self.rebalance_force[1],
                         self.rebalance_rate, self.rebalance_quadrature,
                         1.0 if self.locked else 0.0, 1.0 if self.rebalance_on else 0.0])

    def update(self, volts: np.ndarray, phase: np.ndarray, t_end_s: float) -> None:
        """
        Measure one loop period and set the commands of the next (C2-C7).

        Parameters
        ----------
        volts : ndarray, shape (N, 2)
            The pick-off amplifiers' outputs over the period (``electronics.PickOff``:
            sense, drive), V.
        phase : ndarray, shape (N,)
            The NCO phase ``phi`` of the drive force at each sample, rad.
        t_end_s : float
            Time at the end of the period, s (the lock detector's time stamps).

        """
        if volts.shape != (self.window, 2) or phase.shape != (self.window,):
            raise InputError(f'volts: one loop period of {self.window} samples expected, '
                             f'got shape {volts.shape}')
        # (C2) least squares on cos, sin, 1 through the normal equations (3 x 3)
        coef = self._coef
        kernels.iq_fit(np.ascontiguousarray(phase, dtype=np.float64),
                       np.ascontiguousarray(volts, dtype=np.float64), coef)  # (3, 2)
        x_c, x_s = coef[0, 1] / self.pickoff.drive_gain, coef[1, 1] / self.pickoff.drive_gain
        dt = self.period_s
        self.updates += 1
        # (C3) PLL
        e = math.atan2(x_c, x_s)
        kp, ki = self.pll_gains
        self.pll_integral += ki * e * dt
        self.pll_integral = min(max(self.pll_integral, -self.omega_range), self.omega_range)
        offset = kp * e + self.pll_integral
        clamped = abs(offset) >= self.omega_range
        self.omega = self.omega_c + min(max(offset, -self.omega_range), self.omega_range)
        self.phase_error = e
        # (C4) lock detector, with hysteresis
        if self.locked:
            locked = abs(e) < self.lock_threshold and not clamped
            self._locking = 0
        else:
            self._locking = self._locking + 1 if (abs(e) < 0.5 * self.lock_threshold
                                                  and not clamped) else 0
            locked = self._locking >= LOCK_PERIODS
        if not locked:
            self.unlocked_periods += 1
            if self.locked:
                self.unlocked_since_s = t_end_s
                if self.lost_lock_at_s is None:
                    self.lost_lock_at_s = t_end_s
        elif not self.locked:
            self.relocked_at_s = t_end_s
            self.unlocked_since_s = None
        self.locked = locked
        # (C5) AGC
        amp = math.hypot(x_c, x_s)
        self.amplitude = amp
        err = self.setpoint_m - amp
        kp, ki = self.agc_gains
        raw = kp * err + self.agc_integral + ki * err * dt
        if not ((raw > self.drive_limit and err > 0.0) or (raw < 0.0 and err < 0.0)):
            self.agc_integral += ki * err * dt
        self.force = min(max(kp * err + self.agc_integral, 0.0), self.drive_limit)
        # (C6, C7) force-to-rebalance; (C8b) on a qualified drive only, with hysteresis
        if self.rebalance_on:
            self.rebalance_on = locked and amp >= REBALANCE_DISQUALIFY * self.setpoint_m
            self._qualifying = 0
        elif self.rebalance:
            qualified = locked and amp >= REBALANCE_QUALIFY * self.setpoint_m
            self._qualifying = self._qualifying + 1 if qualified else 0
            self.rebalance_on = self._qualifying >= REBALANCE_QUALIFY_PERIODS
        if self.rebalance and not self.rebalance_on:
            self.rebalance_force[:] = 0.0
            self.rebalance_rate = self.rebalance_quadrature = 0.0
        elif self.rebalance:
            gain = self.pickoff.sense_gain
            y_c, y_s = coef[0, 0] / gain, coef[1, 0] / gain
            if self.sense_phase_error:  # demodulated against the sense reference phi + error
                ce, se = math.cos(self.sense_phase_error), math.sin(self.sense_phase_error)
                y_c, y_s = y_c * ce - y_s * se, y_c * se + y_s * ce
            kp, ki = self.rebalance_gains
            lim = self.drive_limit
            i_c = min(max(float(self.rb_integral[0]) - ki * y_s * dt, -lim), lim)
            i_s = min(max(float(self.rb_integral[1]) + ki * y_c * dt, -lim), lim)
            self.rb_integral[:] = (i_c, i_s)
            self.rebalance_force[:] = (min(max(i_c - kp * y_s, -lim), lim),
                                       min(max(i_s + kp * y_c, -lim), lim))
            scale = 2.0 * KAPPA_2 * self.omega * amp
            self.rebalance_rate = self.rebalance_force[0] / scale if amp > 0.0 else 0.0
            self.rebalance_quadrature = self.rebalance_force[1] / scale if amp > 0.0 else 0.0

    def diagnostics_values(self) -> Dict[str, object]:
        """Return the loops' state for ``/diagnostics`` and the run summary."""
        return {
            'pll_locked': bool(self.locked),
            'pll_frequency_hz': float(self.omega / (2.0 * math.pi)),
            'pll_phase_error_rad': float(self.phase_error),
            'pll_lost_lock': self.lost_lock_at_s is not None,
            'pll_lock_lost_at_s': self.lost_lock_at_s,
            'pll_relocked_at_s': self.relocked_at_s,
            'agc_drive_force_m_s2': float(self.force),
            'agc_effort': float(self.force / self.drive_limit),
            'drive_amplitude_m': float(self.amplitude),
            'drive_setpoint_m': float(self.setpoint_m),
            'rebalance_force_m_s2': float(math.hypot(*self.rebalance_force)),
            'rebalance_on': bool(self.rebalance_on),
        }
