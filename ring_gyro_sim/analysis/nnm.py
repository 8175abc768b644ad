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

from dataclasses import dataclass, field, replace
import math
from typing import List, Sequence
import warnings

import numpy as np
from ring_gyro_sim.core import electronics, forces, structure
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.params import SimConfig
from scipy.integrate import solve_ivp
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


class _Model:
    def __init__(self, config: SimConfig) -> None:
        self.model = forces.build_force_model(config)
        self.omega = 2.0 * math.pi * np.asarray(config.modes.coordinate_frequencies())
        self.n = self.model.n_coordinates

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        x, v = y[:self.n], y[self.n:]
        a = -self.omega ** 2 * x + forces.nonlinear_acceleration(x, self.model)
        return np.concatenate([v, a])

    def half_orbit(self, x0: np.ndarray, t_half: float, dense: bool = False):
        y0 = np.concatenate([x0, np.zeros(self.n)])
        return solve_ivp(self.rhs, (0.0, t_half), y0, method='DOP853', rtol=1e-11,
                         atol=1e-18, dense_output=dense)


def _solve_point(m: _Model, index: int, start: float, guess_others: np.ndarray,
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
    m = _Model(config)
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
    m = _Model(config)
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
                            mode: int = 1) -> float:
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

    """
    def miss(volts: float) -> float:
        c = replace(config, electrodes=replace(config.electrodes, outer_voltage=volts))
        return frequency_at_amplitude(c, amplitude_m, mode) - target_hz

    return float(brentq(miss, bracket_v[0], bracket_v[1], xtol=1e-4))


@dataclass(frozen=True)
class ForcedOrbit:
    """
    Periodic response to the 2theta drive ``A_e cos(2 pi f t)`` (eq. 28, damped).

    Attributes
    ----------
    frequency_hz : float
        Drive frequency, Hz.
    amplitude_m : ndarray, shape (n,)
        max |x_i| over the period, m.
    initial_state : ndarray, shape (2 n,)
        ``[x, v]`` at a time where the drive phase is 0 (m, m/s).
    floquet_multipliers : ndarray, shape (2 n_c,)
        Eigenvalues of the monodromy matrix of the cos coordinates (n_c of them): the
        stability of the branch.
    companion_multipliers : ndarray, shape (2 n_s,)
        With the sine companions (n_s), the eigenvalues of their block of the monodromy
        matrix (empty without them). At an orbit without sine content the matrix is block
        diagonal: by the theta -> -theta symmetry the cos equations are even and the sine
        equations odd in the sine coordinates.

    """

    frequency_hz: float
    amplitude_m: np.ndarray
    initial_state: np.ndarray
    floquet_multipliers: np.ndarray
    companion_multipliers: np.ndarray = field(default_factory=lambda: np.empty(0))

    @property
    def branch_stable(self) -> bool:
        """Return whether the multipliers of the cos coordinates lie inside the unit circle."""
        return bool(np.all(np.abs(self.floquet_multipliers) < 1.0))

    @property
    def stable(self) -> bool:
        """All Floquet multipliers, the companions' included, inside the unit circle."""
        return self.branch_stable and bool(np.all(np.abs(self.companion_multipliers) < 1.0))


def forced_orbit(config: SimConfig, frequency_hz: float, amplitude_guess_m: float,
                 drive_amplitude: float) -> ForcedOrbit:
    """
    Periodic orbit of the driven, damped system by shooting over one drive period.

    Parameters
    ----------
    config : SimConfig
        Modes, Q factors and electrodes of the model.
    frequency_hz : float
        Drive frequency, Hz.
    amplitude_guess_m : float
        Guess of the q2 amplitude, m: the start is ``q2 = a sin``-phased (resonant branch),
        so a guess near the upper branch converges to it.
    drive_amplitude : float
        A_e, m/s^2.

    With the sine companions the orbit is solved without them and then embedded with the
    companions at exactly 0: the drive has no sine content, and by the ring's symmetry the
    force on every companion is then exactly zero, so the equations of the cos coordinates are
    those of the model without companions. (Solved in the full space, each degenerate cos/sin
    pair makes the shooting Jacobian nearly singular and the residual, a small difference of
    large states, carries the integrator's error: the solve stalled.) Only the companions'
    block of the monodromy matrix is then added (:class:`ForcedOrbit`).

    """
    if config.modes.companions:
        # The scheduled shocks do not enter the orbit; one off the x axis needs companions.
        # Nor does a rotation (a gyroscope's sense response is added by drive_initial_state).
        cos_only = forced_orbit(_cos_only(config), frequency_hz, amplitude_guess_m,
                                drive_amplitude)
    m = _Model(config)
    n = m.n
    zeta = 1.0 / (2.0 * np.asarray(config.modes.coordinate_quality_factors()))
    w = 2.0 * math.pi * frequency_hz
    period = 1.0 / frequency_hz
    scale = np.concatenate([np.full(n, amplitude_guess_m), np.full(n, amplitude_guess_m * w)])

    def rhs(t, y):
        x, v = y[:n], y[n:]
        a = (-m.omega ** 2 * x - 2.0 * zeta * m.omega * v
             + forces.nonlinear_acceleration(x, m.model))
        a[1] += drive_amplitude * math.cos(w * t)
        return np.concatenate([v, a])

    def flow(y0):
        return solve_ivp(rhs, (0.0, period), y0, method='DOP853', rtol=1e-12, atol=1e-20)

    def monodromy_eigenvalues(y0, rows):
        """Eigenvalues of the block ``rows`` of the period map's Jacobian (finite differences)."""
        base = flow(y0).y[rows, -1]
        block = np.empty((rows.size, rows.size))
        for col, k in enumerate(rows):
            dy = np.zeros(2 * n)
            dy[k] = 1e-6 * scale[k]
            block[:, col] = (flow(y0 + dy).y[rows, -1] - base) / dy[k]
        return np.linalg.eigvals(block)

    if config.modes.companions:
        half = n // 2
        y0 = np.zeros(2 * n)
        y0[:half] = cos_only.initial_state[:half]
        y0[n:n + half] = cos_only.initial_state[half:]
        sine_rows = np.concatenate([np.arange(half, n), np.arange(n + half, 2 * n)])
        return ForcedOrbit(frequency_hz=frequency_hz,
                           amplitude_m=np.concatenate([cos_only.amplitude_m, np.zeros(half)]),
                           initial_state=y0, floquet_multipliers=cos_only.floquet_multipliers,
                           companion_multipliers=monodromy_eigenvalues(y0, sine_rows))

    def residual(z):
        y0 = z * scale
        sol = flow(y0)
        return (sol.y[:, -1] - y0) / scale

    z0 = np.zeros(2 * n)
    z0[n + 1] = 1.0  # q2 = a sin(w t): v2(0) = a w, the resonant (upper) branch at the peak
    z, _, ier, msg = fsolve(residual, z0, full_output=True, xtol=1e-13)
    if ier != 1 and np.max(np.abs(residual(z))) > 1e-9:
        raise SimulationError(f'forced orbit at {frequency_hz} Hz did not converge: {msg}')
    y0 = z * scale
    mu = monodromy_eigenvalues(y0, np.arange(2 * n))  # for the stability test
    sol = solve_ivp(rhs, (0.0, period), y0, method='DOP853', rtol=1e-12, atol=1e-20,
                    dense_output=True)
    tt = np.linspace(0.0, period, 1001)
    amp = np.max(np.abs(sol.sol(tt)[:n]), axis=1)
    return ForcedOrbit(frequency_hz=frequency_hz, amplitude_m=amp, initial_state=y0,
                       floquet_multipliers=mu)


def _cos_only(config: SimConfig) -> SimConfig:
    """Return the resonator of the cos coordinates: no companions, rotation, loops or shocks."""
    return replace(config, modes=replace(config.modes, companions=False),
                   gyro=replace(config.gyro, enabled=False),
                   control=replace(config.control, drive_loop='open', rebalance=False),
                   run=replace(config.run, shock_times=(), shock_peaks=(), shock_angles=(),
                               rate_times=(), rate_values=()))


def lock_frequency(config: SimConfig, amplitude_m: float) -> float:
    """
    Return the frequency (Hz) the closed loop's PLL locks to at the drive amplitude (m).

    The 2theta backbone there (``hbm.backbone_frequency`` of the cos coordinates, no
    damping): with the phase held at 90 degrees the forced response sits on it to
    ``O(1 / Q^2)`` (``test/core/test_control.py`` compares it with the PLL's).
    ``drive.frequency`` when the amplitude is 0.
    """
    if amplitude_m <= 0.0:
        return float(config.drive.frequency)
    from ring_gyro_sim.analysis import hbm  # hbm imports the plotting layer
    return hbm.backbone_frequency(_cos_only(config), amplitude_m, mode=2,
                                  start_amplitude_m=min(0.02e-6, 0.5 * amplitude_m))


def drive_initial_state(config: SimConfig):
    """
    Return the initial ``(x, v)`` for ``drive.start_on`` (None for 'rest' or with the drive off).

    The state is the stable periodic response to the initial drive at drive phase 0 (t = 0),
    on the branch asked for: the shooting starts from the peak amplitude
    ``A_e Q_2 / (omega omega_2)`` for the upper branch and from a tenth of it for the lower.

    With the sine companions, the branch is that of the cos coordinates (the orbit has no sine
    content, :func:`forced_orbit`) and must be stable there. The companions can still be
    unstable: the standing 2theta wave of the upper branch is parametrically unstable to its
    degenerate sin(2 theta) partner (default device at 15 798.6 Hz: largest multiplier
    1.0000376, growth 0.59 /s; the whirling of a driven ring). The state is returned with a
    warning then: in the simulator the companions stay exactly 0 until a sine disturbance (a y
    shock or base acceleration) lets the instability grow.

    Raises
    ------
    SimulationError
        No stable orbit was found on that branch (e.g. outside the bistable range).

    """
    d = config.drive
    if d.start_on == 'rest' or d.amplitude == 0.0 or d.frequency == 0.0:
        return None
    w2 = 2.0 * math.pi * config.modes.frequencies[1]
    w = 2.0 * math.pi * d.frequency
    peak = abs(d.amplitude) * config.modes.quality_factors[1] / (w * w2)
    guess = peak if d.start_on == 'upper_branch' else 0.1 * peak
    orbit = forced_orbit(config, d.frequency, guess, d.amplitude)
    if not orbit.branch_stable:
        raise SimulationError(f'drive.start_on: no stable {d.start_on} orbit found at '
                              f'{d.frequency} Hz (found q2 = {orbit.amplitude_m[1]:.3e} m, '
                              f'unstable)')
    if not orbit.stable:
        mu = float(np.max(np.abs(orbit.companion_multipliers)))
        warnings.warn(f'drive.start_on: the {d.start_on} orbit at {d.frequency} Hz is '
                      f'unstable to the sine companions (largest Floquet multiplier '
                      f'{mu:.7f}, growth {math.log(mu) * d.frequency:.3g} /s); they stay '
                      f'exactly 0 until a sine disturbance (y shock or base acceleration)',
                      RuntimeWarning, stacklevel=2)
    n = config.modes.count * (2 if config.modes.companions else 1)
    return with_rate_response(config, (orbit.initial_state[:n], orbit.initial_state[n:]))


def with_rate_response(config: SimConfig, state):
    """
    Return a copy of a drive orbit's start state with the pair's response to the rate at t = 0.

    ``state`` is the ``(x, v)`` of :func:`drive_initial_state` for the same device at zero
    rate (the orbit of the resting sensor: it does not depend on the rate), so that runs of
    one device at several rates share one shooting (``ring_gyro characterize``); the result
    is what :func:`drive_initial_state` returns at the rate of ``config``.
    """
    x = np.array(state[0], dtype=np.float64)
    v = np.array(state[1], dtype=np.float64)
    if config.gyro.enabled and not config.control.rebalance:
        # With force-to-rebalance the loop holds the sense mode at 0 from the start (its
        # force starts at the Coriolis force of the rate at t = 0: core.control, C6).
        _add_sense_response(config, x, v)
    return x, v


def _add_sense_response(config: SimConfig, x: np.ndarray, v: np.ndarray) -> None:
    """
    Put the 2theta pair in its steady linear response to the rate at t = 0, in place.

    The orbit is that of the resting sensor (no sine content). With the sensor rotating at
    ``Omega_0`` from the start the pair would otherwise need several ``2 Q / omega`` (1.3 s
    for the default Q) to settle. In phasors at the drive frequency (``q = Re(C e^{i w t})``,
    drive force ``Re(F e^{i w t})`` with F the drive amplitude, phase 0 at t = 0), the drive
    mode's response at the operating point is ``D = F / C_0`` (C_0 from the orbit's state at
    t = 0: its softening included), the sense mode's ``D_s = w_s^2 - w^2 + i w w_s / Q_s``,
    and the Coriolis terms (eqs. G5-G6 of ``structure.gyroscopic_coefficient``) couple them
    with ``g = 2 kappa Omega_0 w``::

        D C - i g S = F,    D_s S + i g C = 0
        =>  C = F / (D - g^2 / D_s),    S = -i g C / D_s

    (matched modes at resonance: ``S / C = -2 kappa Omega_0 Q / w`` and the drive amplitude
    falls by ``1 / (1 + (2 kappa Omega_0 Q / w)^2)``: 3.2 % at 10 deg/s for the default Q).
    S itself is taken about the drive orbit (``core.electronics.orbit_sense_response``: the
    linear S above with the sense mode softened and pumped by the drive's amplitude).
    The other coordinates keep the orbit's values; what remains is a transient of the order
    of the pair's nonlinearity (doc/gyroscope.md).
    """
    times, rates = config.run.rate_times, config.run.rate_values
    # The rate at t = 0 (after a step at 0): the last knot at 0, else 0 before a later knot.
    at_zero = [w for t, w in zip(times, rates) if t == 0.0]
    rate0 = at_zero[-1] if at_zero else 0.0
    if rate0 == 0.0 or config.modes.count < 2 or config.drive.amplitude == 0.0:
        return
    m = config.modes.count
    w = 2.0 * math.pi * config.drive.frequency
    c0 = complex(x[1], -v[1] / w)  # q2 = Re(c0 e^{i w t}), q2' = Re(i w c0 e^{i w t})
    if config.control.closed:
        # The closed loop holds the drive's amplitude (no drop) at the PLL's lock
        # frequency, where the sense mode is driven.
        config = replace(config, drive=replace(config.drive, frequency=lock_frequency(
            config, abs(c0))))
        w = 2.0 * math.pi * config.drive.frequency
    f = config.modes.coordinate_frequencies()
    qf = config.modes.coordinate_quality_factors()
    ws, qs = 2.0 * math.pi * f[m + 1], qf[m + 1]
    d = config.drive.amplitude / c0
    d_s = ws * ws - w * w + 1j * w * ws / qs
    g = 2.0 * structure.gyroscopic_coefficient(2) * rate0 * w
    c = c0 if config.control.closed else config.drive.amplitude / (d - g * g / d_s)
    # The sense response about the drive orbit (electronics.orbit_sense_response: the sense
    # mode softened and pumped by the drive's amplitude), per unit rate and drive phase.
    per_rate = electronics.orbit_sense_response(config, forces.build_force_model(config),
                                                abs(c))
    s = rate0 * per_rate * c / abs(c)
    x[1] += (c - c0).real
    v[1] += (1j * w * (c - c0)).real
    x[m + 1] += s.real
    v[m + 1] += (1j * w * s).real
