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
The drive's operating point: the start state a run begins in, and where the loops lock.

A run that starts on a branch of the 2theta drive (``drive.start_on``) begins in the stable
periodic response to the drive (:func:`drive_orbit`, by shooting over one drive period); a
gyroscope turning at t = 0 also has its sense mode in its steady response to that rate
(:func:`with_rate_response`). :func:`start_state` is what ``Run(config)`` calls: the orbit
of the resting sensor (:func:`resting_orbit`) is memoised per device and drive (it does not
depend on the rate, the scenario or the noise), so that many runs of one device (the
datasheet's rate table, a sweep over shocks, a population's re-runs) shoot once.
:func:`lock_frequency` is where the closed loop's PLL sits (the 2theta backbone at the AGC's
set-point) and :func:`drive_operating_point` the drive's amplitude and phase the sense
electronics are built for.
"""

from collections import OrderedDict
from dataclasses import dataclass, field, replace
import math
import threading
from typing import Callable, Optional, Tuple
import warnings

import numpy as np
from ring_gyro_sim.core import forces, harmonic_balance, structure
from ring_gyro_sim.core.errors import SimulationError
from ring_gyro_sim.core.gyro import electronics, modes
from ring_gyro_sim.core.params import SimConfig
from ring_gyro_sim.core.ring.environment import environment_of
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

__all__ = ['ForcedOrbit', 'ModalEquations', 'ORBIT_MEMO_SIZE', 'cos_only', 'drive_orbit',
           'with_environment_response',
           'drive_operating_point', 'forced_orbit', 'lock_frequency', 'remember_orbit',
           'resting_orbit', 'start_state', 'with_rate_response']

ORBIT_MEMO_SIZE = 16
"""Drive orbits :func:`start_state` keeps (least recently used dropped first)."""

State = Tuple[np.ndarray, np.ndarray]


class ModalEquations:
    """
    The undamped, unforced modal equations (eq. 33) of a configuration, for shooting.

    ``rhs`` is ``[v, -Omega^2 x + a_nl(x)]`` (m/s, m/s^2); ``half_orbit`` integrates from rest
    at ``x0`` over ``t_half`` (DOP853, rtol 1e-11).
    """

    def __init__(self, config: SimConfig) -> None:
        self.model = forces.build_force_model(config)
        self.omega = 2.0 * math.pi * np.asarray(config.modes.coordinate_frequencies())
        self.n = self.model.n_coordinates

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        """Return the time derivative of ``y = [x, v]``."""
        x, v = y[:self.n], y[self.n:]
        a = -self.omega ** 2 * x + forces.nonlinear_acceleration(x, self.model)
        return np.concatenate([v, a])

    def half_orbit(self, x0: np.ndarray, t_half: float, dense: bool = False):
        """Return ``solve_ivp``'s solution from rest at ``x0`` (m) over ``t_half`` (s)."""
        y0 = np.concatenate([x0, np.zeros(self.n)])
        return solve_ivp(self.rhs, (0.0, t_half), y0, method='DOP853', rtol=1e-11,
                         atol=1e-18, dense_output=dense)


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
        # Nor does a rotation (a gyroscope's sense response is added by with_rate_response).
        resonator = forced_orbit(cos_only(config), frequency_hz, amplitude_guess_m,
                                 drive_amplitude)
    m = ModalEquations(config)
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
        y0[:half] = resonator.initial_state[:half]
        y0[n:n + half] = resonator.initial_state[half:]
        sine_rows = np.concatenate([np.arange(half, n), np.arange(n + half, 2 * n)])
        return ForcedOrbit(frequency_hz=frequency_hz,
                           amplitude_m=np.concatenate([resonator.amplitude_m, np.zeros(half)]),
                           initial_state=y0, floquet_multipliers=resonator.floquet_multipliers,
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


def cos_only(config: SimConfig) -> SimConfig:
    """
    Return the resonator of the cos coordinates: no companions, rotation, loops or shocks.

    Each cos coordinate keeps its own frequency and Q (``coordinate_frequencies``: in an
    imperfect pair the diagonal of its matrices, P2, P3), its coupling to the companion is
    dropped with the companion.
    """
    m = config.modes.count
    cos_modes = replace(config.modes, companions=False,
                        frequencies=tuple(config.modes.coordinate_frequencies()[:m]),
                        quality_factors=tuple(config.modes.coordinate_quality_factors()[:m]),
                        frequency_axes=(), damping_axes=())
    return replace(config, modes=cos_modes,
                   gyro=replace(config.gyro, enabled=False),
                   control=replace(config.control, mode='open_loop'),
                   run=replace(config.run, shock_times=(), shock_peaks=(), shock_angles=(),
                               rate_times=(), rate_values=()))


def lock_frequency(config: SimConfig, amplitude_m: float) -> float:
    """
    Return the frequency (Hz) the closed loop's PLL locks to at the drive amplitude (m).

    The 2theta backbone there (``harmonic_balance.backbone_frequency`` of the cos coordinates, no
    damping): with the phase held at 90 degrees the forced response sits on it to
    ``O(1 / Q^2)`` (``test/core/gyro/test_control.py`` compares it with the PLL's).
    ``drive.frequency`` when the amplitude is 0.
    """
    if amplitude_m <= 0.0:
        return float(config.drive.frequency)
    return harmonic_balance.backbone_frequency(
        cos_only(config), amplitude_m, mode=2, start_amplitude_m=min(0.02e-6, 0.5 * amplitude_m))


def drive_orbit(config: SimConfig):
    """
    Return the resting sensor's ``(x, v)`` on ``drive.start_on`` (None: 'rest' or drive off).

    The state is the stable periodic response to the initial drive at drive phase 0 (t = 0),
    on the branch asked for, of the sensor at rest (no rotation: :func:`start_state` adds the
    response to the rate at t = 0): the shooting starts from the peak amplitude
    ``A_e Q_2 / (omega omega_2)`` for the upper branch and from a tenth of it for the lower.

    With the sine companions, the branch is that of the cos coordinates (the orbit has no sine
    content, :func:`forced_orbit`) and must be stable there. The companions can still be
    unstable: the standing 2theta wave of the upper branch is parametrically unstable to its
    degenerate sin(2 theta) partner (the paper's device at 15 798.6 Hz: largest multiplier
    1.0000376, growth 0.59 /s; the whirling of a driven ring). Open loop the state is returned
    with a warning then: the companions stay exactly 0 until a sine disturbance (a rate, a y
    shock or base acceleration) lets the instability grow. The closed loop
    (a closed ``control.mode``) holds the drive's phase and amplitude, and the whirl does
    not develop (doc/control.md): no warning.

    Raises
    ------
    SimulationError
        No stable orbit was found on that branch (e.g. outside the bistable range).

    """
    d = config.drive
    if d.start_on == 'rest' or d.amplitude == 0.0 or d.frequency == 0.0:
        return None
    w2 = 2.0 * math.pi * config.modes.coordinate_frequencies()[1]
    w = 2.0 * math.pi * d.frequency
    peak = abs(d.amplitude) * config.modes.coordinate_quality_factors()[1] / (w * w2)
    guess = peak if d.start_on == 'upper_branch' else 0.1 * peak
    orbit = forced_orbit(config, d.frequency, guess, d.amplitude)
    if not orbit.branch_stable:
        raise SimulationError(f'drive.start_on: no stable {d.start_on} orbit found at '
                              f'{d.frequency} Hz (found q2 = {orbit.amplitude_m[1]:.3e} m, '
                              f'unstable)')
    if not orbit.stable and not modes.of(config).closed:
        mu = float(np.max(np.abs(orbit.companion_multipliers)))
        warnings.warn(f'drive.start_on: the {d.start_on} orbit at {d.frequency} Hz is '
                      f'unstable to the sine companions (largest Floquet multiplier '
                      f'{mu:.7f}, growth {math.log(mu) * d.frequency:.3g} /s); they stay '
                      f'exactly 0 until a sine disturbance (y shock or base acceleration)',
                      RuntimeWarning, stacklevel=2)
    n = config.modes.count * (2 if config.modes.companions else 1)
    return orbit.initial_state[:n].copy(), orbit.initial_state[n:].copy()


def with_rate_response(config: SimConfig, state):
    """
    Return a copy of a drive orbit's start state with the pair's response to the rate at t = 0.

    ``state`` is the ``(x, v)`` of :func:`drive_orbit` for the same device (the orbit of the
    resting sensor: it does not depend on the rate), so that runs of one device at several
    rates share one shooting (:func:`start_state`).
    """
    x = np.array(state[0], dtype=np.float64)
    v = np.array(state[1], dtype=np.float64)
    if config.gyro.enabled and not modes.of(config).rebalance:
        # With force-to-rebalance the loop holds the sense mode at 0 from the start (its
        # force starts at the Coriolis force of the rate at t = 0: core.gyro.control, C6).
        _add_sense_response(config, x, v)
    elif config.gyro.enabled and config.gyro.sense_misalignment:
        # ... at 0 of what its misaligned amplifier reads (E1b): cos(2 delta) q2s -
        # sin(2 delta) q2, so the sense mode sits at q2s = tan(2 delta) q2
        m = config.modes.count
        mu = math.tan(2.0 * math.radians(config.gyro.sense_misalignment))
        x[m + 1] += mu * x[1]
        v[m + 1] += mu * v[1]
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
    An imperfect pair (``structure.pair_matrices``) adds its linear coupling
    ``a_sc = K_sc + i w C_sc`` (and ``a_cs``): ``D C + (a_cs - i g) S = F``,
    ``(a_sc + i g) C + D_s S = 0`` with ``D_s`` of the pair's diagonal, also at zero rate.
    S itself is taken about the drive orbit (``electronics.orbit_sense_response``: the
    linear S above with the sense mode softened and pumped by the drive's amplitude).
    The other coordinates keep the orbit's values; what remains is a transient of the order
    of the pair's nonlinearity (doc/gyroscope.md).
    """
    times, rates = config.run.rate_times, config.run.rate_values
    # The rate at t = 0 (after a step at 0): the last knot at 0, else 0 before a later knot.
    at_zero = [w for t, w in zip(times, rates) if t == 0.0]
    rate0 = at_zero[-1] if at_zero else 0.0
    coupled = 2 in config.modes.coupled_pairs()
    if (rate0 == 0.0 and not coupled) or config.modes.count < 2 or config.drive.amplitude == 0.0:
        return
    m = config.modes.count
    w = 2.0 * math.pi * config.drive.frequency
    c0 = complex(x[1], -v[1] / w)  # q2 = Re(c0 e^{i w t}), q2' = Re(i w c0 e^{i w t})
    if modes.of(config).closed:
        # The closed loop holds the drive's amplitude (no drop) at the PLL's lock
        # frequency, where the sense mode is driven.
        config = replace(config, drive=replace(config.drive, frequency=lock_frequency(
            config, abs(c0))))
        w = 2.0 * math.pi * config.drive.frequency
    d = config.drive.amplitude / c0
    g = 2.0 * structure.gyroscopic_coefficient(2) * rate0 * w
    if coupled:
        # An imperfect pair (structure.pair_matrices) couples its coordinates linearly too:
        # rows c and s of [K - w^2 + i w (C + G)] X = F e_c, G the Coriolis terms.
        stiffness, damping = config.modes.pair_matrices(2)
        d_s = stiffness[1, 1] - w * w + 1j * w * damping[1, 1]
        a_sc = stiffness[1, 0] + 1j * w * damping[1, 0]
        a_cs = stiffness[0, 1] + 1j * w * damping[0, 1]
    else:
        f = config.modes.coordinate_frequencies()
        qf = config.modes.coordinate_quality_factors()
        ws, qs = 2.0 * math.pi * f[m + 1], qf[m + 1]
        d_s = ws * ws - w * w + 1j * w * ws / qs
        a_sc = a_cs = 0.0
    c = c0 if modes.of(config).closed else config.drive.amplitude / (
        d - (a_cs - 1j * g) * (a_sc + 1j * g) / d_s)
    # The sense response about the drive orbit (electronics.orbit_sense_response: the sense
    # mode softened and pumped by the drive's amplitude), per unit rate and drive phase, and
    # the pair's linear response to its own coupling.
    s = -a_sc * c / d_s
    if rate0 != 0.0:
        per_rate = electronics.orbit_sense_response(config, forces.build_force_model(config),
                                                    abs(c))
        s += rate0 * per_rate * c / abs(c)
    x[1] += (c - c0).real
    v[1] += (1j * w * (c - c0)).real
    x[m + 1] += s.real
    v[m + 1] += (1j * w * s).real


_MEMO: 'OrderedDict[tuple, Optional[State]]' = OrderedDict()
_MEMO_LOCK = threading.Lock()


def with_environment_response(config: SimConfig, state):
    """
    Return a copy of a start state with the 1theta pair on its answer to the environment.

    The scenario's base acceleration (``core.ring.environment.environment_of``: a steady ``a``, a
    sine ``A sin(w t)`` and a random multisine ``sum_k A_k cos(w_k t + phi_k)`` along the
    vibration's direction) forces the 1theta pair as eq. (27):
    ``q1'' + c q1' + k q1 = -a_x(t)`` (``q1s`` with ``a_y``), ``k`` the coordinate's linear
    stiffness at rest (``omega_1^2`` less the unfolded electrostatic term, eq. 26) and
    ``c = omega_1 / Q_1``. Started at rest the pair rings at ``omega_1`` for
    ``2 Q_1 / omega_1`` (3.4 s): by ``a / k`` after a steady acceleration's step, by
    ``w / omega_1`` of the forced amplitude after a sine's, and by half the random answer's
    variance again on average. Here the pair starts on the linear steady (periodic) answer
    instead: ``-a / k``, plus per line the phasor ``-H C`` at t = 0 with
    ``H = 1 / (k - w^2 + i c w)`` and ``C`` the line's complex amplitude (``-i A`` for the sine,
    ``A_k e^{i phi_k}`` for the multisine) times the linear interpolant's
    ``sinc^2(f / output.rate)``, as the kernel sees it. What remains is the nonlinear answer's
    transient (the other modes' static and slow parts, which the electrostatic coupling brings
    in from t = 0). ``state`` is ``(x, v)`` (None: the ring at rest); the others are kept.
    """
    env = environment_of(config)
    frequencies = config.modes.coordinate_frequencies()
    if state is None:
        x, v = np.zeros(len(frequencies)), np.zeros(len(frequencies))
    else:
        x = np.array(state[0], dtype=np.float64)
        v = np.array(state[1], dtype=np.float64)
    if env is None:
        return x, v
    rate = config.run.output_rate
    w = np.array([env.omega], dtype=np.float64)
    lines = np.array([-1j], dtype=np.complex128)  # A sin(w t) = Re(-i A e^{i w t}) per unit A
    if env.random is not None:
        rv = env.random
        w = np.concatenate([w, 2.0 * math.pi * rv.lines * rv.df])
        lines = np.concatenate([lines, rv.amplitudes * np.exp(1j * rv.phases)])
    lines = lines * np.sinc(w / (2.0 * math.pi * rate)) ** 2
    quality = config.modes.coordinate_quality_factors()
    jac = forces.jacobian(np.zeros(x.size), forces.build_force_model(config))
    axes = [(0, env.steady[0], env.sine_peak[0], env.direction[0])]
    if config.modes.companions:
        axes.append((config.modes.count, env.steady[1], env.sine_peak[1], env.direction[1]))
    for i, steady, peak, direction in axes:
        omega = 2.0 * math.pi * frequencies[i]
        k = omega * omega - jac[i, i]
        h = 1.0 / (k - w * w + 1j * (omega / quality[i]) * w)
        c = lines * np.concatenate([[peak], np.full(w.size - 1, direction)])
        x[i] += -steady / k - float(np.real(np.sum(h * c)))
        v[i] += -float(np.real(np.sum(1j * w * h * c)))
    return x, v


def _orbit_key(config: SimConfig) -> tuple:
    """Return what the resting sensor's orbit depends on: the device and the drive."""
    return (config.modes, config.ring, config.legs, config.electrodes, config.drive,
            modes.of(config).closed)


def resting_orbit(config: SimConfig,
                  log: Optional[Callable[[str], None]] = None) -> Optional[State]:
    """
    Return :func:`drive_orbit` of ``config``, memoised per device and drive.

    :data:`ORBIT_MEMO_SIZE` orbits are kept in this process (least recently used dropped
    first); ``log`` is told when one is computed (it takes seconds). The companions'
    instability warning of :func:`drive_orbit` is given once per orbit. The returned arrays
    are shared: do not change them (:func:`with_rate_response` copies).

    Raises
    ------
    SimulationError
        No stable orbit on that branch (:func:`drive_orbit`).

    """
    d = config.drive
    if d.start_on == 'rest' or d.amplitude == 0.0 or d.frequency == 0.0:
        return None
    key = _orbit_key(config)
    with _MEMO_LOCK:
        if key in _MEMO:
            _MEMO.move_to_end(key)
            return _MEMO[key]
    if log is not None:
        log(f'computing the start state ({d.start_on} of the drive at {d.frequency:.6g} Hz, '
            f'{d.amplitude:g} m/s^2): a few seconds')
    orbit = drive_orbit(config)
    remember_orbit(config, orbit)
    return orbit


def remember_orbit(config: SimConfig, orbit: Optional[State]) -> None:
    """
    Keep ``orbit`` as the :func:`resting_orbit` of ``config`` in this process.

    For a caller that computed it elsewhere (a sweep's setup task on another worker), so that
    the runs of that device here do not shoot again.
    """
    with _MEMO_LOCK:
        _MEMO[_orbit_key(config)] = orbit
        _MEMO.move_to_end(_orbit_key(config))
        while len(_MEMO) > ORBIT_MEMO_SIZE:
            _MEMO.popitem(last=False)


def start_state(config: SimConfig,
                log: Optional[Callable[[str], None]] = None) -> Optional[State]:
    """
    Return the start state ``(q m, v m/s)`` of ``drive.start_on`` (None: the ring at rest).

    The resting sensor's orbit (:func:`resting_orbit`, memoised) with the pair's response to
    the rate at t = 0 (:func:`with_rate_response`, per call) and, under a scenario's
    environment, the 1theta pair on its answer to it (:func:`with_environment_response`): a
    sensor switched on in a steady acceleration or a vibration has been in it, so a run does
    not start with the step that would ring the 1theta mode for ``2 Q_1 / omega_1``. ``log``
    as :func:`resting_orbit`.
    """
    orbit = resting_orbit(config, log)
    state = None if orbit is None else with_rate_response(config, orbit)
    if environment_of(config) is None:
        return state
    return with_environment_response(config, state)


def drive_operating_point(config: SimConfig, state: Optional[State]) -> Tuple[float, float]:
    """
    Return ``(A, p)``: q2 = A cos(phi_drive(t) + p) at the start (m, rad).

    From the start state when q2 moves (the ``drive.start_on`` orbit: its softening
    included; the drive's phase is 0 at t = 0), else the linear response of the 2theta mode
    ``F / (omega_2^2 - omega^2 + i omega omega_2 / Q_2)`` it will settle to from rest.
    """
    w = 2.0 * math.pi * config.drive.frequency
    if state is not None and w > 0.0:
        q, v = state
        c = complex(float(q[1]), -float(v[1]) / w)
        if abs(c) > 0.0:
            return abs(c), math.atan2(c.imag, c.real)
    f2 = 2.0 * math.pi * config.modes.coordinate_frequencies()[1]
    q2 = config.modes.coordinate_quality_factors()[1]
    c = config.drive.amplitude / complex(f2 * f2 - w * w, w * f2 / q2)
    return abs(c), math.atan2(c.imag, c.real)
