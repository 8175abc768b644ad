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

The :class:`~ring_gyro_sim.core.simulator.Simulator` owns its :class:`SenseChain` as it owns
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
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.core.gyro.electronics import DemodSamples, RateSamples, SenseElectronics
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
        The chain this one replaces after a parameter change: its operating point and its
        running state are taken over.

    """

    def __init__(self, config: SimConfig, sim, start_state, pickoff,
                 previous: Optional['SenseChain'] = None) -> None:
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
        self._rebalance_columns = [CONTROL_CHANNELS.index('rebalance_rate_rad_s'),
                                   CONTROL_CHANNELS.index('rebalance_quadrature_rad_s')]
        if previous is not None:
            self.electronics.continue_from(previous.electronics)
            return
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
            out = []
            for index, gain in ((el.sense_index, el.electronic_gain),
                                (el.drive_index, el.drive_gain)):
                c = complex(float(q[index]), -float(v[index]) / w) * turn
                out += [gain * c.real, -gain * c.imag]
            el.start_outputs(np.array(out))

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
        return self.electronics.process_volts(first_index, t, volts, drive_phase, rebalance)

    def diagnostics_values(self) -> Dict[str, Any]:
        """Return the rate channel's state for ``/diagnostics``."""
        return self.electronics.diagnostics_values()
