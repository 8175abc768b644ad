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
Nonlinear normal modes of the conservative system (eq. 33) by shooting, and V_o calibration.

Method
------
Eq. (33), ``x'' + Omega^2 x = a_nl(x)``, is reversible: an orbit that starts at rest and is
at rest again half a period later is periodic. For the n-theta mode at amplitude ``A`` the
unknowns are the other coordinates at the start, ``x_j(0)`` (j != n), and the half period
``T/2``; the equations are ``v(T/2) = 0`` (one per coordinate). They are solved with
``scipy.optimize.fsolve`` on ``solve_ivp(DOP853, rtol=1e-11)`` trajectories, by continuation
in amplitude from the linear mode. The frequency is ``1 / T`` and the amplitude is
``max_t |x_n(t)|`` over the orbit (both turning points are checked).

This gives the backbone of Fig. 4 on the configuration that is simulated (all its modes),
which is what the default outer voltage is calibrated on (:func:`calibrate_outer_voltage`).
"""

from dataclasses import dataclass, replace
from typing import Callable, List, Optional, Sequence

import numpy as np
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.gyro.operating_point import ModalEquations
from ring_gyro_sim.core.params import SimConfig
from scipy.optimize import brentq, fsolve


@dataclass(frozen=True)
class NonlinearModePoint:
    """
    One periodic orbit of eq. (33).

    Attributes
    ----------
    amplitude_m : float
        max |x_n| over the orbit, m.
    frequency_hz : float
        1 / period, Hz.
    initial_state_m : ndarray, shape (n,)
        Coordinates at the turning point t = 0 (velocities are zero), m.
    residual : float
        max |v(T/2)| / (omega_n A), dimensionless (convergence check).

    """

    amplitude_m: float
    frequency_hz: float
    initial_state_m: np.ndarray
    residual: float


def _solve_point(m: ModalEquations, index: int, start: float, guess_others: np.ndarray,
                 guess_half: float) -> NonlinearModePoint:
    others = [j for j in range(m.n) if j != index]
    scale = abs(start)

    def unpack(z):
        x0 = np.zeros(m.n)
        x0[index] = start
        x0[others] = z[:-1] * scale
        return x0, z[-1] * guess_half

    def residual(z):
        x0, t_half = unpack(z)
        try:
            sol = m.half_orbit(x0, t_half)
        except SimulationError:
            return np.full(m.n, 1e3)
        if sol.status != 0:
            return np.full(m.n, 1e3)
        return sol.y[m.n:, -1] / (m.omega[index] * scale)

    z0 = np.concatenate([guess_others / scale, [1.0]])
    z, _, ier, msg = fsolve(residual, z0, full_output=True, xtol=1e-12)
    res = float(np.max(np.abs(residual(z))))
    if ier != 1 and res > 1e-8:
        raise SimulationError(f'nonlinear mode at {start:.3e} m did not converge: {msg}')
    x0, t_half = unpack(z)
    sol = m.half_orbit(x0, t_half, dense=True)
    tt = np.linspace(0.0, t_half, 2001)
    amplitude = float(np.max(np.abs(sol.sol(tt)[index])))
    return NonlinearModePoint(amplitude_m=amplitude, frequency_hz=1.0 / (2.0 * t_half),
                              initial_state_m=x0, residual=res)


def nonlinear_mode(config: SimConfig, amplitudes_m: Sequence[float],
                   mode: int = 1) -> List[NonlinearModePoint]:
    """
    Points of the nonlinear normal mode (backbone) of the ``mode``-theta coordinate.

    Parameters
    ----------
    config : SimConfig
        All coordinates of the configuration take part (Ritz order, companions).
    amplitudes_m : sequence of float
        Increasing starting amplitudes ``x_n(0)``, m (continuation goes through them).
    mode : int
        n of the n-theta mode (its cos coordinate).

    Returns
    -------
    list of NonlinearModePoint

    """
    m = ModalEquations(config)
    index = mode - 1
    if not 0 <= index < config.modes.count:
        raise ValueError(f'mode: must be between 1 and {config.modes.count}, got {mode}')
    others = np.zeros(m.n - 1)
    half = 0.5 / config.modes.frequencies[index]
    points = []
    for a in amplitudes_m:
        p = _solve_point(m, index, float(a), others, half)
        points.append(p)
        others = np.delete(p.initial_state_m, index)
        half = 0.5 / p.frequency_hz
    return points


def frequency_at_amplitude(config: SimConfig, amplitude_m: float, mode: int = 1,
                           steps: int = 12) -> float:
    """Backbone frequency (Hz) at ``max |x_n| = amplitude_m``, by continuation and secant."""
    starts = list(np.linspace(amplitude_m / steps, amplitude_m, steps))
    points = nonlinear_mode(config, starts, mode)
    m = ModalEquations(config)
    index = mode - 1
    p = points[-1]
    others = np.delete(p.initial_state_m, index)
    start = amplitude_m
    # The orbit's max |x_n| can exceed its start when the other turning point is larger:
    # adjust the start until the measured amplitude matches.
    for _ in range(8):
        if abs(p.amplitude_m - amplitude_m) < 1e-6 * amplitude_m:
            break
        start *= amplitude_m / p.amplitude_m
        p = _solve_point(m, index, start, others, 0.5 / p.frequency_hz)
        others = np.delete(p.initial_state_m, index)
    return p.frequency_hz


def calibrate_outer_voltage(config: SimConfig, target_hz: float = 10.6e3,
                            amplitude_m: float = 6e-6, bracket_v=(40.0, 120.0),
                            mode: int = 1,
                            progress: Optional[Callable[[int, float, float], None]] = None
                            ) -> float:
    """
    Outer voltage (V) at which the backbone passes through (amplitude, target frequency).

    Parameters
    ----------
    config : SimConfig
        Configuration to calibrate on (its N_R, N_T and electrodes; V_o is varied).
    target_hz : float
        Backbone frequency at ``amplitude_m``, Hz (Fig. 4: about 10.6 kHz at about 6 um).
    amplitude_m : float
        Amplitude (max |q_mode| over the period) at which the frequency is matched, m.
    bracket_v : (float, float)
        Voltage bracket, V.
    mode : int
        n of the calibrated n-theta mode (1: the 1theta mode).
    progress : callable, optional
        Called after each backbone evaluation (seconds each, about 12 in all) with its count
        (from 1), the voltage (V) and the frequency found (Hz).

    """
    count = 0

    def miss(volts: float) -> float:
        nonlocal count
        c = replace(config, electrodes=replace(config.electrodes, outer_voltage=volts))
        frequency = frequency_at_amplitude(c, amplitude_m, mode)
        count += 1
        if progress is not None:
            progress(count, volts, frequency)
        return frequency - target_hz

    return float(brentq(miss, bracket_v[0], bracket_v[1], xtol=1e-4))
