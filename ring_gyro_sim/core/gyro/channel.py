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
The sense chain of a gyroscope run: the electronics at the drive's operating point.

The :class:`~ring_gyro_sim.core.engine.full.Simulator` owns its :class:`SenseChain` as it owns
the drive loop: it builds it at the start state, feeds it every stretch it integrates (the
pick-off amplifiers' volts, which the loops read too, the drive phase, the loops' rows) and
builds it again whenever a parameter change acts, so that the amplifiers' gains follow the
bias voltage and the model's scale factor follows the device as a physical sense chain's
would. The running state (the filters, the flicker bank, the latest outputs) carries over:
a parameter change does not restart the electronics.

The operating point (drive amplitude A and phase p, ``q2 = A cos(phi_drive + p)``) is that of
the start (``operating_point.drive_operating_point``). Closed loop, the drive sits at the
PLL's lock point, ``q2 = X sin(phi)``, at the AGC's set-point (``core.gyro.control``, C3,
C5), on the backbone: the scale factor is that of the sense mode driven there (at
``config/gyro.yaml`` the lock frequency is 0.017 Hz below ``drive.frequency``, a seventh of
the sense mode's half-width, which moves the scale factor by 0.55 %).
"""

from dataclasses import replace
import math
from typing import Any, Dict, Optional, Tuple

import numpy as np
from ring_gyro_sim.core.gyro import validity
from ring_gyro_sim.core.gyro.calibration import Calibration
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.core.gyro.electronics import (deg_per_h_to_rad_per_s, DemodSamples,
                                                 RateSamples, SenseElectronics)
from ring_gyro_sim.core.gyro.operating_point import drive_operating_point, lock_frequency
from ring_gyro_sim.core.params import SimConfig

__all__ = ['SenseChain']


class SenseChain:
    """
    The sense electronics of a run at its operating point (``gyro.enabled``).

    Parameters
    ----------
    config : SimConfig
        The configuration in force.
    sim : Simulator
        The simulator that owns the chain (rest capacitances, gains, the loops, the rate).
    start_state : (q, v)
        The run's start state, m and m/s: it sets the operating point.
    pickoff : electronics.PickOff
        The amplifiers (shared with the drive loop).
    previous : SenseChain, optional
        The chain this one replaces after a parameter change: its operating point, its
        running state and its calibration are taken over.
    calibration : Calibration, optional
        The held calibration of the rate output (``core.gyro.calibration``, K1); None: the
        model's own readout (``ideal``).

    """

    def __init__(self, config: SimConfig, sim, start_state, pickoff,
                 previous: Optional['SenseChain'] = None,
                 calibration: Optional[Calibration] = None) -> None:
        if previous is not None:
            amp, phase = previous.operating_point
        else:
            amp, phase = drive_operating_point(config, start_state)
        self.operating_point: Tuple[float, float] = (amp, phase)
        self.lock_frequency_hz: Optional[float] = None
        electronics_config = config
        if sim.loop is not None:
            amp, phase = sim.loop.setpoint_m, -0.5 * math.pi
            self.lock_frequency_hz = lock_frequency(config, amp)
            electronics_config = replace(config, drive=replace(
                config.drive, frequency=self.lock_frequency_hz))
        self.drive_amplitude_m = amp
        self.drive_phase_rad = phase
        start_rate = float(sim.rates_at(np.zeros(1, np.int64))[0])
        self.electronics = SenseElectronics(electronics_config, sim, amp, phase,
                                            start_rate=start_rate, pickoff=pickoff)
        self._rebalance_columns = [CONTROL_CHANNELS.index(name) for name in (
            'rebalance_rate_rad_s', 'rebalance_quadrature_rad_s', 'rebalance_c', 'rebalance_s')]
        self._force_columns = [CONTROL_CHANNELS.index(name)
                               for name in ('rebalance_c', 'rebalance_s')]
        self._loop_columns = [CONTROL_CHANNELS.index(name) for name in
                              ('locked', 'rebalance_on', 'amplitude_m', 'frequency_hz')]
        self._setpoint_m = sim.loop.setpoint_m if sim.loop is not None else 0.0
        self._force_limit = float(config.control.drive_limit)
        self._dc_partial = 0.0    # the shock detector's state (_shock_detector)
        self._dc_last: Optional[float] = None
        el = self.electronics
        # The open-loop sense readout's scale factor holds at the drive frequency it was
        # set at: the sense mode's half-power half-width (Hz) scales the NCO's departure
        # from its steady frequency (tracked while quiet).
        self._half_width_hz = el.sense_omega / (2.0 * el.sense_quality_factor) / (2.0 * math.pi)
        self._nco_reference: Optional[float] = None
        self._nco_mean: Optional[float] = None
        self._nco_smoothing = 2.0 * math.pi * self._half_width_hz / config.gyro.output_rate
        self.validity = validity.RateValidity(
            el.rate_variance(), deg_per_h_to_rad_per_s(config.gyro.bias_instability),
            el.bandwidth_hz, config.gyro.output_rate,
            0.0 if el.rebalance else el.rate_quadrature_per_rate,
            resolution=config.gyro.resolution)
        if previous is not None:
            calibration = previous.electronics.calibration
        self.electronics.calibration = calibration
        if calibration is not None and not el.rebalance:
            # (K1) the ratiometric readout is relative to the drive pick-off's amplitude at
            # zero rate: the one the calibration was made with, else the operating point's
            # taken back to zero rate through the pair's linear response (E8), so that a run
            # that starts under a rate reads it as one started at rest and then turned
            el.readout_reference_v = (calibration.readout_reference_v
                                      if calibration.readout_reference_v > 0.0
                                      else el.drive_pickoff_nominal_v
                                      * el.expected_drive_ratio(0.0))
        if previous is not None:
            self.electronics.continue_from(previous.electronics)
            self.validity.continue_from(previous.validity)
            self._dc_partial = previous._dc_partial
            self._dc_last = previous._dc_last
            self._nco_reference = previous._nco_reference
            self._nco_mean = previous._nco_mean
            return
        if sim.loop is not None and self.electronics.rebalance:
            # the output filter starts at the forces that hold the start state (C6)
            loop = sim.loop
            self.electronics.start_rebalance(np.array([
                loop.rebalance_rate, loop.rebalance_quadrature, *loop.rebalance_force]))
        w = 2.0 * math.pi * config.drive.frequency
        # A start state without drive motion (rest) keeps the default: the filters at the
        # linear operating point the drive will build up to.
        q, v = start_state
        if w > 0.0 and (float(q[1]) != 0.0 or float(v[1]) != 0.0):
            # The demodulator's outputs of the start state (q = Re(c e^{i psi}), psi the
            # reference's phase at t = 0: the drive's phase then, 0 open loop and the NCO's
            # closed loop, plus p; I = G Re(c e^{-i psi}), Q = -G Im(c e^{-i psi})), so that
            # the filters start settled.
            el = self.electronics
            psi = phase + sim.drive_phase_at_start
            turn = complex(math.cos(psi), -math.sin(psi))

            def phasor(index):
                return complex(float(q[index]), -float(v[index]) / w) * turn
            # the sense amplifier reads the sense coordinate and, misaligned, the drive's
            # (E1b); its reference is off by the phase error (E3b)
            sense = (el.electronic_gain * phasor(el.sense_index)
                     + el.pickoff.sense_cross_gain * phasor(el.drive_index))
            sense *= complex(math.cos(el.phase_error), -math.sin(el.phase_error))
            drive = el.drive_gain * phasor(el.drive_index)
            el.start_outputs(np.array([sense.real, -sense.imag, drive.real, -drive.imag]))

    def process(self, first_index: int, t: np.ndarray, volts: np.ndarray,
                drive_phase: np.ndarray, control: Optional[np.ndarray]
                ) -> Tuple[DemodSamples, RateSamples]:
        """
        Return the demodulator's channels and the rate output of consecutive samples.

        ``volts`` the amplifiers' outputs (K, 2) at global samples ``first_index ..``,
        ``drive_phase`` the drive's phase there (rad), ``control`` the loops' rows
        (``Samples.control``; None open loop).
        """
        rebalance = None
        if self.electronics.rebalance:
            rebalance = control[:, self._rebalance_columns]
        demod, rate = self.electronics.process_volts(first_index, t, volts, drive_phase,
                                                     rebalance)
        at = np.searchsorted(t, rate.t)
        shock = self._shock_detector(volts[:, 1], at)
        if len(rate) == 0:
            return demod, rate
        codes = self._reasons(rate.rate, demod.values[at],
                              None if control is None else control[at])
        codes[(codes == 0) & shock] = validity.REASONS.index('shock on the pick-offs')
        variance = self.validity.samples(rate.t, rate.rate, rate.quadrature, codes,
                                         rate.saturated)
        return demod, replace(rate, variance=variance)

    def judge(self, rate: RateSamples, control: np.ndarray) -> RateSamples:
        """
        Return ``rate`` with each sample's variance judged from the loops' rows alone.

        The rate samples of a stretch the averaged model produced
        (``core.engine.averaged.AveragedEngine``), with
        ``control`` the loops' rows in force at each of them: the closed loop's reasons
        (V1: lock, qualification, force limit, amplitude) and the variance (V2-V5) as
        :meth:`process` judges them. The shock detector is not run (no pick-off volts: the
        averaged model runs only where no shock acts); it takes up its last level again.
        """
        if len(rate) == 0:
            return rate
        codes = self._reasons(rate.rate, None, control)
        variance = self.validity.samples(rate.t, rate.rate, rate.quadrature, codes,
                                         rate.saturated)
        return replace(rate, variance=variance)

    def _shock_detector(self, drive_volts: np.ndarray, picks: np.ndarray) -> np.ndarray:
        """
        Tell per rate sample whether the drive pick-off shows a shock's onset (V1).

        The drive amplifier reads the cos 2theta electrodes: a displacement of the ring (the
        1theta mode, which a shock rings) changes their gaps in opposite senses, and the
        capacitance's curvature turns its square into a DC level (``2 q_1^2 / d_g^3`` per
        electrode pair) that the drive's own oscillation does not have. The mean of the
        amplifier's output over each rate period (the samples since the previous rate
        sample, carried across calls) keeps ``~1 / (2 pi f_drive T)`` (1 %) of the drive's
        oscillation; a change of it from one period to the next beyond
        :data:`validity.SHOCK_DC_TOLERANCE` of the drive pick-off's amplitude flags the
        sample at once, before the loops or the filtered signals react. The 1theta mode's
        ringing then decays over seconds (``2 Q_1 / omega_1``): the level changes slowly and
        the loops' own signals judge the rest.
        """
        sums = np.concatenate([[0.0], np.cumsum(drive_volts)])
        flags = np.zeros(picks.size, dtype=bool)
        limit = validity.SHOCK_DC_TOLERANCE * self.electronics.drive_pickoff_nominal_v
        d = self.electronics.decimation
        previous = 0
        for k, p in enumerate(picks.tolist()):
            dc = (sums[p + 1] - sums[previous] + (self._dc_partial if k == 0 else 0.0)) / d
            previous = p + 1
            flags[k] = self._dc_last is not None and abs(dc - self._dc_last) > limit
            self._dc_last = dc
        self._dc_partial = (sums[-1] - sums[previous]
                            + (self._dc_partial if picks.size == 0 else 0.0))
        return flags

    def _reasons(self, rate: np.ndarray, demod: np.ndarray,
                 control: Optional[np.ndarray]) -> np.ndarray:
        """
        Return per rate sample why it is not a measurement (``validity.REASONS``; 0: it is).

        Closed loop: the PLL's lock (C4), the rebalance loop's qualification (C8b) and its
        force against ``control.drive_limit`` (C8), the AGC's amplitude against its
        set-point, and without rebalance the NCO's detuning from the frequency the open-loop
        sense readout's scale factor holds at (the NCO's steady
        frequency, frozen through a disturbance, against its mean over the sense mode's time
        constant: :meth:`_detuning`); open loop: the drive pick-off against the pair's linear
        response at the measured rate (E8).
        """
        codes = np.zeros(rate.size, dtype=np.int64)
        tol = validity.DRIVE_TOLERANCE
        if control is not None:
            locked, rebalance_on, amplitude, nco = (control[:, k] for k in self._loop_columns)
            off_point = (np.abs(amplitude / self._setpoint_m - 1.0) > tol
                         if self._setpoint_m > 0.0 else np.ones(rate.size, bool))
            codes[off_point] = 3
            if self.electronics.rebalance:
                # A force held at control.drive_limit no longer nulls the sense mode: the
                # reading is the limit's, not the rate's (C8)
                force = np.abs(control[:, self._force_columns]).max(axis=1)
                codes[force >= self._force_limit] = validity.REASONS.index(
                    'rebalance force at its limit')
                codes[rebalance_on == 0.0] = 2
            codes[locked == 0.0] = 1
            if not self.electronics.rebalance:
                self._detuning(nco, codes)
            return codes
        el = self.electronics
        nominal = el.drive_pickoff_nominal_v
        if nominal <= 0.0:
            codes[:] = 3
            return codes
        ratio = np.hypot(demod[:, 2], demod[:, 3]) / nominal
        for k, r in enumerate(rate.tolist()):
            expected = el.expected_drive_ratio(r)
            if expected <= 0.0 or abs(ratio[k] / expected - 1.0) > tol:
                codes[k] = 3
        return codes

    def _detuning(self, nco: np.ndarray, codes: np.ndarray) -> None:
        """
        Flag the open-loop sense readout's samples whose drive is detuned (V1), in place.

        The sense mode follows the drive's frequency through its own low-pass (time constant
        ``1 / (2 pi half-width)``), so the NCO's jitter inside the PLL's bandwidth does not
        reach it: the NCO is averaged over that time. Until the first disturbance the
        readout is settled wherever the loops hold the drive; at a disturbance the NCO's
        mean frequency then is kept as the reference, and afterwards a sample is detuned
        while the mean is more than :data:`validity.DETUNING_TOLERANCE` half-widths away
        from it (the reference follows the mean, slowly, once the output is quiet again).
        """
        if self._nco_mean is None:
            self._nco_mean = float(nco[0])
        mean = np.empty(nco.size)
        for k, f in enumerate(nco.tolist()):
            self._nco_mean += self._nco_smoothing * (f - self._nco_mean)
            mean[k] = self._nco_mean
        reason = validity.REASONS.index('drive detuned from the sense mode')
        disturbed = bool(codes.any()) or self.validity.state.reason not in (
            '', validity.REASONS[reason])
        if self._nco_reference is None:
            if disturbed:
                self._nco_reference = float(mean[0])
            return
        detuned = (np.abs(mean - self._nco_reference)
                   > validity.DETUNING_TOLERANCE * self._half_width_hz)
        codes[detuned & (codes == 0)] = reason
        if not disturbed and not detuned.any():
            self._nco_reference += self.validity.tracking * nco.size * (
                self._nco_mean - self._nco_reference)

    def diagnostics_values(self) -> Dict[str, Any]:
        """
        Return the rate channel's state for ``/diagnostics``.

        The electronics' values, the calibration in force (``calibration_source``, and when
        held ``calibration_bias_rad_s``, ``calibration_scale_factor`` with its
        ``calibration_scale_factor_unit``) and the latest rate sample's standing
        (``core.gyro.validity``): ``rate_valid``, ``rate_sigma_rad_s``, ``rate_band_rad_s``
        (the stated band of its error) and ``rate_invalid_reason``.
        """
        out = self.electronics.diagnostics_values()
        state = self.validity.state
        held = self.electronics.calibration
        if held is None:
            out['calibration_source'] = 'ideal'
        else:
            out.update({f'calibration_{k}': v for k, v in held.to_dict().items()})
        out.update({'rate_valid': bool(state.valid), 'rate_sigma_rad_s': float(state.sigma),
                    'rate_band_rad_s': float(state.band),
                    'rate_invalid_reason': state.reason})
        return out
