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
The Simulator: state, inputs at exact simulation times, and chunked advancing.

Time
----
Simulation time is kept as an integer index of output samples (period ``P`` = integer ns,
``output.rate``); the state always sits on a sample time between calls. Each sample period is
integrated in ``n_sub`` equal steps ``h = P / n_sub`` (``h <= max_step``). Step times are
computed from integers, so cutting a run into 1 ms or 50 ms calls gives bit-identical samples.

Inputs and when they act
------------------------
* shock pulses (:meth:`Simulator.shock`): the half-sine starts at its exact time (ns), even
  between samples; the steps it overlaps are sub-stepped (``core/kernels/step.py``);
* base-acceleration samples (:meth:`Simulator.add_base_acceleration`): exact times, linear
  interpolation between consecutive samples, zero before the first and after the last;
* the angular rate of the sensor frame (``gyro.enabled``; :meth:`Simulator.set_rate` and
  ``scenario.rate_*``): a profile of knots, linear between them, 0 before the first and held
  after the last; a streamed value steps the rate at its exact time and replaces the knots
  after it. Each integration step uses the rate at its middle (so a step of the rate acts
  from the first step whose middle is past it: within h/2 of its time);
* drive changes, reset and parameter changes: at the first sample time at or after the
  requested time (the current time if none is given). Drive frequency changes keep the drive
  phase continuous.

An input for a time already simulated raises :class:`InputError` and changes nothing.

Contact / pull-in
-----------------
When the outer (or an active inner) gap closes, or the Taylor series leaves its range
(|w| >= d_g), the simulator stops integrating, sets :attr:`Simulator.status` to
:attr:`Status.CONTACT` (:attr:`Status.FAILED` for a non-finite state) with a message giving
the time and the angle, and from then on holds the ring where it touched (velocities zero)
while time still advances, as a pulled-in ring sticks. :meth:`Simulator.reset` recovers. No
output is ever NaN. :class:`Status` is a ``str`` enum: ``Status.RUNNING == 'running'`` and
``str(Status.CONTACT) == 'contact'``, so recorded and printed statuses are the plain words.

Failure
-------
The inputs are bounded so that the state stays finite (``core.params``: accelerations,
angular rates, voltages), but whatever produces a non-finite value anyway is a defined
failure, never a hole in the outputs: the kernel's own check (a non-finite state), a check of
what the electronics read in every stretch (the pick-off volts, the drive phase, the loops'
state) and one of every output of a call (:meth:`Simulator._finite`, one sum per array when
all is well). From the first such sample the status is :attr:`Status.FAILED`, with a message
naming what was not finite and when; the ring is held at rest (its channels those of rest),
the loops start again from their initial state if theirs was not finite, a sense chain that
produced a non-finite value is built again, and the electronics' outputs of that call hold
their last finite values. Calls go on with finite samples; :meth:`Simulator.reset` recovers.
The outcome depends only on the state, so a re-simulation reproduces it bit for bit;
:attr:`Simulator.nonfinite_failures` counts the failures.
"""

import bisect
import copy
from dataclasses import replace
import math
from typing import Any, Callable, List, Mapping, Optional, Tuple
import warnings

import numpy as np

from ring_gyro_sim.core import forces, kernels, noise, structure, thermal, vibration
from ring_gyro_sim.core.engine.base import (Design, Engine, GyroState, joined_outputs,
                                            joined_samples, Samples, Status)
from ring_gyro_sim.core.errors import InputError, SimulationError
from ring_gyro_sim.core.gyro import calibration as gyro_calibration, control, electronics, modes
from ring_gyro_sim.core.gyro.channel import SenseChain
from ring_gyro_sim.core.params import (BOLTZMANN, build_config, EPSILON_0, MAX_ACCELERATION,
                                       SimConfig, to_flat)
from ring_gyro_sim.core.rate_profile import RateProfile
from ring_gyro_sim.core.ring.environment import environment_of

THERMAL_UPDATE_S = 0.01
"""How often the die temperature is followed, s of simulated time (T2)."""
THERMAL_STEP_K = 0.01
"""How far the die moves before the device is rebuilt at its temperature, K (0.3 ppm of
frequency at -30 ppm/K: 5 mHz at 15.8 kHz, a twentieth of the sense mode's half-width)."""

_EMPTY = np.empty(0)
_NO_NOISE = np.empty((0, 1))

__all__ = ['STEPS_PER_PERIOD', 'STEP_HARMONICS', 'PULSE_SUBSTEPS_PER_DURATION',
           'GAP_GRID_POINTS_PER_MODE', 'ELECTRODE_GAUSS_POINTS', 'GAP_FLOOR_RATIO', 'Status',
           'default_max_step', 'joined_samples', 'GyroState', 'Samples', 'Simulator']


STEPS_PER_PERIOD = 8
"""Default steps per period of the fastest step-setting mode (see :func:`default_max_step`)."""
STEP_HARMONICS = 3
"""The modes up to n theta = 3 theta (and their companions) set the default step."""

PULSE_SUBSTEPS_PER_DURATION = 16
GAP_GRID_POINTS_PER_MODE = 32
"""
Angles per mode for the smallest gap, refined by a parabola: the error is below
``sum n^3 |q_n| delta^3 / (9 sqrt 3)`` for the grid spacing delta, ~1e-4 of q_n.
"""
ELECTRODE_GAUSS_POINTS = 8
"""
Gauss-Legendre angles per panel of an electrode (see :meth:`Simulator._build_outputs`); a
multiple of 4 (``kernels.output_channels`` sums four nodes per division).
"""
ELECTRODE_FINE_PANELS = 16
"""Finest level (a power of 2): panels per panel, for an electrode the ring comes close to."""
ELECTRODE_RTOL = 1e-7
"""Relative accuracy the electrode panels are chosen for (down to gaps of 0.01 d_g)."""
GAP_FLOOR_RATIO = 1e-3
"""In contact the capacitance integrand uses max(gap, 1e-3 d_g): finite, never inf."""


def default_max_step(config: SimConfig) -> float:
    """
    Largest step, s: ``integrator.max_step`` or 1/8 of the fastest period up to 3theta.

    The linear part is exact, so the step is set by the accuracy of the nonlinear coupling
    only, against the step's error budget (the largest error in any q, 20 ms after a 10 000 g
    shock, below 1e-4 of the peak q1 of a DOP853 reference at rtol 1e-10). At 1/8 of the
    period of the 3theta mode (5 us for the paper's 22 kHz) the error is 2.2e-6 with ``bm6``
    (the default; 3.3e-6 with the drive on, ``benchmarks/``) and 7.7e-5 with ``bm4``
    (``test/core/test_simulator.py``).

    Modes above 3theta do not shorten the step: the inputs (shocks, base acceleration, the
    drive) act on q1, q1s and q2 only, so the higher modes move only through the
    electrostatic coupling and stay small (N_R = 5 after a 10 000 g shock at 45 deg: q4 ~0.35
    um, q5 ~0.02 um against q1 ~4 um), and their own flow is exact at any step. Measured on
    N_R = 5 with companions (``benchmarks/nr5_companions.yaml``, drive on): 7.9e-6 of the peak
    q1 at this step (5 us; 59.2 kHz 5theta mode: omega h = 1.9), 1.5e-8 at the 1.67 us that
    1/8 of the 5theta period would give, at three times the cost.
    """
    if config.integrator.max_step > 0.0:
        return config.integrator.max_step
    count = config.modes.count
    f_max = max(f for i, f in enumerate(config.modes.coordinate_frequencies())
                if i % count < STEP_HARMONICS)
    return 1.0 / (STEPS_PER_PERIOD * f_max)


def coordinate_names(config: SimConfig) -> List[str]:
    """Return the names of the simulated coordinates: q1..qN, then q1s..qNs (companions)."""
    names = [f'q{n}' for n in range(1, config.modes.count + 1)]
    if config.modes.companions:
        names += [f'q{n}s' for n in range(1, config.modes.count + 1)]
    return names


def channel_names(config: SimConfig):
    """Return the channel names of the three block outputs (without the leading ``t``)."""
    electrodes = [f'e{i}' for i in range(config.electrodes.count)]
    return {'modal_displacement': coordinate_names(config),
            'radial_gap': electrodes + ['min'],
            'sense_electrodes': electrodes}


# Marks a pulse whose duration is that of the configuration in force when it starts.
_DURATION_AT_START = -1.0

# Pulses the cut scratch of a step holds before it is grown (2 cuts per pulse + 2).
_CUTS_PULSES = 4


def _check_acceleration(name: str, x: float, y: float = 0.0) -> None:
    """Refuse an in-plane acceleration (m/s^2) beyond ``core.params.MAX_ACCELERATION``."""
    magnitude = math.hypot(x, y)
    if magnitude > MAX_ACCELERATION:
        raise InputError(f'{name}: {magnitude:.6g} m/s^2 is beyond the physical bound of '
                         f'{MAX_ACCELERATION:.6g} m/s^2 (10^6 g: no ring survives such a shock; '
                         f'far beyond it the arithmetic of a contact overflows)')


def _first_nonfinite(*arrays: Optional[np.ndarray]) -> Optional[int]:
    """Return the first row with a non-finite value in any of ``arrays`` (None: all finite)."""
    for a in arrays:
        if a is not None and not math.isfinite(a.sum()):
            break  # (or a sum of finite values overflowed: checked below)
    else:
        return None  # the usual case: one pass over each array
    first = None
    for a in (a for a in arrays if a is not None and a.size):
        ok = np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
        if not ok.all():
            row = int(np.argmin(ok))
            first = row if first is None else min(first, row)
    return first


def _hold_last(arr: np.ndarray, first: int) -> None:
    """Hold the rows of ``arr`` from ``first`` at its last finite row before (0 if none)."""
    if first >= arr.shape[0]:
        return
    finite = np.flatnonzero(np.isfinite(arr[:first].reshape(first, -1)).all(axis=1))
    arr[first:] = arr[finite[-1]] if finite.size else 0.0


def _kernel_status(status: int) -> Status:
    """Translate a kernel's integer status (``kernels.STATUS_*``, not OK) to a :class:`Status`."""
    return Status.FAILED if status == kernels.STATUS_NONFINITE else Status.CONTACT


class Simulator(Engine):
    """
    Coupled modal equations of the ring (eq. 28), advanced in chunks.

    Parameters
    ----------
    config : SimConfig
        Validated configuration. ``scenario.shock_times`` / ``shock_peaks`` are scheduled.
    start_state : (q, v), optional
        Initial coordinates (m) and velocities (m/s); None: at rest.
    calibration : Calibration or None
        The rate output's held calibration (``core.gyro.calibration``, K1); None (default):
        the model's own readout (``ideal``). What ``gyro.calibration.source`` asks for is
        measured above the model (``core.bench.factory.for_config``), which ``Run`` does.

    Attributes
    ----------
    status : Status
        ``Status.RUNNING`` until a contact (``CONTACT``) or a numerical failure (``FAILED``);
        :attr:`message`, :attr:`contact_time_s` and :attr:`contact_theta_rad` say where.

    """

    name = 'full'

    @classmethod
    def refusal(cls, config: SimConfig) -> Optional[str]:
        """Return None: the full model runs every configuration (the engine contract)."""
        return None

    def __init__(self, config: SimConfig,
                 start_state: Optional[Tuple[np.ndarray, np.ndarray]] = None,
                 calibration: Optional[gyro_calibration.Calibration] = None) -> None:
        self.calibration: Optional[gyro_calibration.Calibration] = calibration
        self._config = config
        self.period_ns = config.run.output_period_ns
        self.period_s = self.period_ns * 1e-9
        # The die temperature (core.thermal, T2): the mechanics and the amplifiers are those
        # of the device at it (T3-T6), the loops' and the sense chain's constants those of
        # the device as configured, at the reference temperature.
        self.die = thermal.DieTemperature(config)
        self.device_temperature = self.die.kelvin
        self._thermal_live = bool(config.run.temperature_times)
        self._thermal_window = max(1, int(round(THERMAL_UPDATE_S / self.period_s)))
        self._build(thermal.device_at(config, self.device_temperature))
        n = self.model.n_coordinates
        self.q = np.zeros(n)
        self.v = np.zeros(n)
        self._acc = np.zeros(n)
        self.sample_index = 0
        self.status = Status.RUNNING
        self.message = ''
        self.contact_time_s = math.nan
        self.contact_theta_rad = math.nan
        self._pulses: List[Tuple[float, float, float, float]] = []
        # The streamed base-acceleration profile: stamps (ns, increasing) and values; samples
        # before _profile_head are over (see _profile_arrays).
        self._profile_t: List[int] = []
        self._profile_x: List[float] = []
        self._profile_y: List[float] = []
        self._profile_head = 0
        self._environment = environment_of(config)
        # The sine vibration's phase reference: its phase is continuous across a change of
        # its frequency (as the drive's), so a change moves the reference to its time.
        self._vibration_t_ref = 0.0
        self._vibration_phase = 0.0
        self.rate_profile = RateProfile.of(config)  # the angular rate of the sensor frame
        self._events: List[Tuple[int, int, Callable[[], None]]] = []
        self._event_seq = 0
        # The drive's amplitude and frequency are those of the configuration in force (the one
        # source); the phase reference moves when they change, so the phase is continuous.
        self._drive_t_ref = 0.0
        self._drive_phase = 0.0
        # The pick-off amplifiers (read by the loops and the sense chain alike), the loops
        # and the sense chain: the simulator owns them and rebuilds them with the
        # configuration (_apply_config).
        self.pickoff: Optional[electronics.PickOff] = None  # the amplifiers at the die's T
        self._held_pickoff: Optional[electronics.PickOff] = None  # as designed (T_ref)
        self.loop: Optional[control.DriveLoop] = None
        self.sense: Optional[SenseChain] = None
        self._loop_volts: Optional[np.ndarray] = None
        self._loop_phase: Optional[np.ndarray] = None
        if modes.of(config).closed or config.gyro.enabled:
            self._make_pickoffs(config)
        if modes.of(config).closed:
            self.loop = control.DriveLoop(config, self._held_pickoff)
            self._loop_volts = np.empty((self.loop.window, 2))
            self._loop_phase = np.empty(self.loop.window)
            self._drive_phase = self.loop.start(self.q, self.v, self._rate_at_start(),
                                                self._start_omega())
        self._drive = self._drive_args()
        self.pull_in_displacement = math.inf
        """Static pull-in displacement of the 1theta mode, m (computed with stops only)."""
        if config.stops.enabled:
            self._check_stops_against_pull_in(config)
        self.steps_taken = 0
        self.nonfinite_failures = 0
        """Times the run failed on a non-finite value (:attr:`Status.FAILED`; module doc)."""
        for at_ns, peak_x, peak_y in config.run.scheduled_shocks():
            self.shock(peak_x, peak_y, at_ns=at_ns)
        if start_state is not None:
            self._set_state(*start_state)
        self._start_state = (self.q.copy(), self.v.copy())
        if config.gyro.enabled:
            self.sense = SenseChain(config, self, self._start_state, self._held_pickoff,
                                    calibration=calibration)

    # ------------------------------------------------------------------ configuration
    def _check_stops_against_pull_in(self, config: SimConfig) -> None:
        """Warn when the stops lie beyond the static pull-in displacement."""
        self.pull_in_displacement = forces.static_pull_in_displacement(config, self.model)
        gap = config.electrodes.gap
        if config.stops.gap >= self.pull_in_displacement:
            warnings.warn(f'stops.gap: {config.stops.gap:.4g} m ({config.stops.gap / gap:.3f} '
                          f'd_g) lies beyond the static pull-in displacement of the 1theta '
                          f'mode, {self.pull_in_displacement:.4g} m '
                          f'({self.pull_in_displacement / gap:.3f} d_g): a ring pushed past '
                          f'it is pulled onto the stop and held there by the electrodes',
                          RuntimeWarning, stacklevel=3)

    def _make_pickoffs(self, config: SimConfig) -> None:
        """Build the amplifiers at the die's temperature and as designed (one when equal)."""
        noisy = config.gyro.enabled
        device = thermal.device_at(config, self.device_temperature)
        self.pickoff = electronics.PickOff(device, self, noisy=noisy)
        self._held_pickoff = (self.pickoff if device is config
                              else electronics.PickOff(config, self, noisy=noisy))

    def _start_omega(self) -> Optional[float]:
        """Return the NCO's start frequency on a die off the reference, rad/s (None: at it)."""
        if self.device_temperature == self._config.thermal.reference_temperature:
            return None
        return (2.0 * math.pi * self._config.drive.frequency
                * thermal.frequency_scale(self._config, self.device_temperature))

    def _follow_die(self) -> None:
        """
        Advance the die temperature to now; rebuild the device at it if it moved enough.

        The device (its linear coefficients, its force noise and its amplifiers, T3-T6) is
        rebuilt when the die has moved :data:`THERMAL_STEP_K` from the temperature it was
        built at; the loops, the sense chain and the calibration keep theirs.
        """
        kelvin = self.die.advance_to(self.time_s)
        if self.sense is not None:  # the die's temperature sensor, for the compensation
            self.sense.electronics.die_temperature = kelvin
        if abs(kelvin - self.device_temperature) < THERMAL_STEP_K:
            return
        self._build_device_at(kelvin)

    def _build_device_at(self, kelvin: float) -> None:
        """Rebuild the device's coefficients, force noise and amplifiers at ``kelvin`` (K)."""
        self.device_temperature = kelvin
        device = thermal.device_at(self._config, kelvin)
        self._build(device)
        if self.pickoff is not None:
            self.pickoff = electronics.PickOff(device, self, noisy=self._config.gyro.enabled)
        if self.status == Status.RUNNING:
            self._refresh_acceleration()

    def set_ambient(self, kelvin: float, at_ns: Optional[int] = None) -> None:
        """Set the ambient temperature (K) from a sample time on: a step, held (T1)."""
        if not (math.isfinite(kelvin) and kelvin > 0.0):
            raise InputError(f'temperature: must be a finite temperature above 0 K, got '
                             f'{kelvin!r}')

        def apply() -> None:
            self.die.advance_to(self.time_s)
            self.die.ambient.step(self.time_s, kelvin)
            self._thermal_live = True
        self._schedule(at_ns, apply)

    def _build(self, config: SimConfig) -> None:
        self.model = forces.build_force_model(config)
        f = np.asarray(config.modes.coordinate_frequencies())
        qf = np.asarray(config.modes.coordinate_quality_factors())
        self.omega = 2.0 * math.pi * f
        self.zeta = 1.0 / (2.0 * qf)
        h_max = default_max_step(config)
        self.n_sub = max(1, int(math.ceil(self.period_s / h_max - 1e-9)))
        self.h = self.period_s / self.n_sub
        self._a, self._b = kernels.splitting_coefficients(config.integrator.method)
        n = self.model.n_coordinates
        # Imperfect pairs (principal axes off the electrodes, core.structure.pair_matrices)
        # couple their two coordinates linearly: their exact flow is the pair's 4x4
        # (core.kernels.drift), the per-coordinate flows of those coordinates the identity.
        m = config.modes.count
        self.coupled_pairs = config.modes.coupled_pairs()
        pairs = np.array([(k - 1, m + k - 1) for k in self.coupled_pairs],
                         dtype=np.int64).reshape(-1, 2)
        coupled = np.zeros(n, dtype=np.bool_)
        coupled[pairs.ravel()] = True
        self._pair_matrices = [config.modes.pair_matrices(k) for k in self.coupled_pairs]
        systems = np.array([kernels.pair_system(k, c) for k, c in self._pair_matrices],
                           dtype=np.float64).reshape(-1, 16)
        prop = kernels.linear_propagators(self.omega, self.zeta, self._a * self.h)
        prop[:, coupled] = (1.0, 0.0, 0.0, 1.0)
        pair_prop = kernels.pair_propagators(systems, self._a * self.h)
        self._method = kernels.Method(period_s=self.period_s, n_sub=self.n_sub, h=self.h,
                                      a=self._a, b=self._b, prop=prop, omega=self.omega,
                                      zeta=self.zeta, coupled=coupled, pairs=pairs,
                                      pair_prop=pair_prop, pair_system=systems)
        old = getattr(self, '_stops', None)
        self._stops = forces.build_stops(config, self._a.size, pairs.shape[0],
                                         None if old is None else old.state)
        self._scratch = kernels.Scratch(
            work=np.empty(forces.scratch_size(self.model)), fe=np.empty(n),
            info=np.zeros(2, dtype=np.int64), tinfo=np.zeros(1),
            cuts=np.empty(2 * _CUTS_PULSES + 2), rot=np.empty((self._b.size, 2)),
            rot_sub=np.empty((self._b.size, 2)), prop_sub=np.empty_like(prop),
            pair_prop_sub=np.empty_like(pair_prop), pair_work=np.empty(32),
            # one row of the rotating kick's coefficients per gyroscopic pair (at most one
            # per mode, _build_rotation: kernels index it unchecked)
            turn=np.empty((self._b.size, config.modes.count, 4)), turn_key=np.full(2, np.nan))
        self.coordinates = coordinate_names(config)
        self._y_index = config.modes.count if config.modes.companions else -1
        # the mode's drive and sense coordinates (q2 and q2s; -1 where the ring has none)
        self._drive_index, self._sense_index = modes.of(config).axes(config)
        self._build_rotation(config)
        self._build_outputs(config)

    def _build_rotation(self, config: SimConfig) -> None:
        """Gyroscopic pairs, their coefficients and the force-noise levels (gyro.enabled)."""
        n_modes = config.modes.count
        self.gyro = bool(config.gyro.enabled)
        if self.gyro:
            self._pair_c = np.arange(n_modes, dtype=np.int64)
            self._pair_s = np.arange(n_modes, 2 * n_modes, dtype=np.int64)
            self._kappa = np.array([structure.gyroscopic_coefficient(n)
                                    for n in range(1, n_modes + 1)])
        else:
            self._pair_c = self._pair_s = np.empty(0, dtype=np.int64)
            self._kappa = np.empty(0)
        # Thermomechanical force noise (fluctuation-dissipation): one-sided force PSD
        # 4 k_B T m omega / Q per coordinate, i.e. a two-sided acceleration PSD
        # 2 k_B T omega / (m Q); a velocity impulse of that variance times h at the start
        # of every step has exactly that (flat) spectrum, and the exact linear flow between
        # impulses makes the sampled response that of white noise (equipartition:
        # <q^2> = k_B T / (m omega^2), tested).
        temp = config.gyro.temperature if self.gyro else 0.0
        masses = np.asarray(config.modal_masses(), dtype=np.float64)
        self._noise_sigma = np.sqrt(2.0 * BOLTZMANN * temp * self.omega * self.h
                                    / (masses * np.asarray(
                                        config.modes.coordinate_quality_factors())))
        self._noise_seed = int(config.gyro.noise_seed)
        # A coupled pair's damping C is a full 2x2 (structure.pair_matrices, P3): its force
        # noise has the covariance 2 k_B T h C / m per step (fluctuation-dissipation), the
        # pair's unit normals mixed by a Cholesky factor of it.
        self._noise_mix = []
        for (c, s_), (_, damping) in zip(self._method.pairs, self._pair_matrices):
            if temp > 0.0:
                scale = 2.0 * BOLTZMANN * temp * self.h / masses[c]
                self._noise_mix.append((c, s_, np.linalg.cholesky(scale * damping)))
                self._noise_sigma[[c, s_]] = math.sqrt(scale * np.trace(damping))

    def _build_outputs(self, config: SimConfig) -> None:
        e = config.electrodes
        k = e.count
        span = e.span or 2.0 * math.pi / k
        centres = 2.0 * math.pi * np.arange(k) / k
        h, s = self.model.harmonics, self.model.sine
        g = GAP_GRID_POINTS_PER_MODE * config.modes.count
        # Capacitance: composite Gauss-Legendre over each electrode (kernels.output_channels).
        # Panels: each covers at most half a period of the highest harmonic, where the rule's
        # remainder f^(2P) L^(2P+1) (P!)^4 / ((2P+1) ((2P)!)^3) for cos(n theta) is ~1e-15
        # of the integral (P = 8, n L = pi). Near contact 1/(d_g - w) has a pole at about
        # y = sqrt(2 g / |w''|) off the real axis (g the gap, |w''| <= sum n^2 |q_n|); the
        # rule's error falls like rho^(-2P) for the Bernstein ellipse of the panel that
        # avoids it, of semi-minor axis a (rho - 1/rho) / 2 for a panel half-length a.
        # rho^(-2P) = ELECTRODE_RTOL / 100 sets rho (the factor: the error's constant,
        # measured up to ~10 in test/core/test_outputs.py and the demo run); an electrode
        # is summed on fine panels when y < a (rho - 1/rho) / 2, i.e. when
        # g < refine_coeff * sum n^2 |q_n|.
        panels = max(1, math.ceil(config.modes.count * span / math.pi - 1e-9))  # 1e-9: round-off
        x, wts = np.polynomial.legendre.leggauss(ELECTRODE_GAUSS_POINTS)

        def composite(counts):
            local, weights = [], []
            for count in counts:
                a = 0.5 * span / count
                offsets = (2.0 * np.arange(count) + 1.0 - count) * a  # exactly 0 for one
                local.append((offsets[:, None] + a * x[None, :]).ravel())
                weights.append(np.tile(a * wts, count))
            angles = (centres[:, None] + np.concatenate(local)[None, :]).ravel()
            return (np.ascontiguousarray(forces.mode_shapes(h, s, angles).T),
                    np.concatenate(weights))
        electrode_shapes, weights = composite([panels])
        levels = 2 ** np.arange(1, int(math.log2(ELECTRODE_FINE_PANELS)) + 1)  # 2, 4, .. 16
        fine_shapes, fine_weights = composite([panels * r for r in levels])
        rho = (0.01 * ELECTRODE_RTOL) ** (-1.0 / (2 * ELECTRODE_GAUSS_POINTS))
        reach = 0.5 * span / panels * 0.5 * (rho - 1.0 / rho)
        d = self.model.gap
        self._output_geometry = kernels.OutputGeometry(
            gap=d,
            centre_shapes=np.ascontiguousarray(forces.mode_shapes(h, s, centres).T),
            ring_shapes=np.ascontiguousarray(
                forces.mode_shapes(h, s, 2.0 * math.pi * np.arange(g) / g).T),
            electrode_shapes=electrode_shapes,
            electrode_weights=np.tile(weights, k),  # one per angle (output_channels)
            fine_shapes=fine_shapes, fine_weights=fine_weights,
            curvature=np.asarray(h, dtype=np.float64) ** 2,
            refine_coeff=0.5 * reach * reach,
            cap_scale=e.relative_permittivity * EPSILON_0 * config.ring.length
            * config.outer_radius,
            gap_floor=GAP_FLOOR_RATIO * d)
        self._n_electrodes = k

    @property
    def config(self) -> SimConfig:
        """Return the configuration in force."""
        return self._config

    @property
    def random_vibration(self) -> Optional[vibration.RandomVibration]:
        """Return the random vibration in force (``scenario.vibration_psd_*``), None if none."""
        return None if self._environment is None else self._environment.random

    @property
    def drive_phase_at_start(self) -> float:
        """Return the drive's phase at t = 0, rad (0 open loop; closed loop the NCO's, C3)."""
        return self._drive_phase if self.sample_index == 0 else math.nan

    @property
    def time_ns(self) -> int:
        """Return the current simulation time, ns."""
        return self.sample_index * self.period_ns

    @property
    def time_s(self) -> float:
        """Return the current simulation time, s."""
        return self.time_ns * 1e-9

    @property
    def channel_names(self):
        """Channel names of the three block outputs (without the leading ``t``)."""
        return channel_names(self._config)

    def reconfigure(self, config: SimConfig, at_ns: Optional[int] = None) -> None:
        """
        Apply a new configuration (voltages, Q, drive, shock duration...) at a sample time.

        The coordinates must stay the same (number of modes, companions).
        """
        self._check_reconfigurable(config)
        self._schedule(at_ns, lambda: self._apply_config(config))

    def update_parameters(self, changes: Mapping[str, Any], at_ns: Optional[int] = None) -> None:
        """
        Apply changed parameters ``{dotted name: value}`` at a sample time.

        Unlike :meth:`reconfigure`, the changes are laid over the configuration in force *when
        they act*, so several changes scheduled ahead compose as they would have live. They
        are validated now against the current configuration (:class:`ParameterError` names
        the field) and again when they act.
        """
        changes = dict(changes)
        self._check_reconfigurable(build_config({**to_flat(self._config), **changes}))

        def apply() -> None:
            config = build_config({**to_flat(self._config), **changes})
            self._check_reconfigurable(config)
            self._apply_config(config)
        self._schedule(at_ns, apply)

    def _check_reconfigurable(self, config: SimConfig) -> None:
        if (config.modes.count != self._config.modes.count
                or config.modes.companions != self._config.modes.companions):
            raise InputError('modes: the number of coordinates cannot change at run time')
        if config.run.output_rate != self._config.run.output_rate:
            raise InputError('output.rate cannot change at run time')
        if config.control != self._config.control:
            raise InputError('control: the closed loop cannot change at run time')
        if self.loop is not None and (config.drive.amplitude != self._config.drive.amplitude
                                      or config.drive.frequency
                                      != self._config.drive.frequency):
            raise InputError(f'drive: the closed loop (control.mode: {config.control.mode}) '
                             'sets the drive; drive.amplitude and drive.frequency are its '
                             'start values')

    def _apply_config(self, config: SimConfig) -> None:
        old = self._config.drive
        if (config.drive.amplitude != old.amplitude
                or config.drive.frequency != old.frequency):
            self._rephase_drive()
        if config.run.vibration_frequency != self._config.run.vibration_frequency:
            self._rephase_vibration()
        self._environment = environment_of(config)
        self._config = config
        self._build(thermal.device_at(config, self.device_temperature))
        if self.pickoff is not None:  # the voltages set the amplifiers' gains
            self._make_pickoffs(config)
        if self.loop is not None:
            self.loop.pickoff = self._held_pickoff
        if self.sense is not None:  # the gains and the model's scale factor, state kept
            self.sense = SenseChain(config, self, self._start_state, self._held_pickoff,
                                    previous=self.sense)
        self._drive = self._drive_args()
        if self.status == Status.RUNNING:
            self._refresh_acceleration()

    # ------------------------------------------------------------------ inputs
    def _at_index(self, at_ns: Optional[int], what: str) -> int:
        if at_ns is None:
            return self.sample_index
        if at_ns < self.time_ns:
            raise InputError(f'{what}: time {at_ns * 1e-9:.9f} s is in the past '
                             f'(simulation time {self.time_s:.9f} s)')
        return -(-int(at_ns) // self.period_ns)

    def _schedule(self, at_ns: Optional[int], action: Callable[[], None]) -> None:
        index = self._at_index(at_ns, 'input')
        if index == self.sample_index:
            action()
            return
        self._events.append((index, self._event_seq, action))
        self._event_seq += 1
        self._events.sort(key=lambda e: (e[0], e[1]))

    def next_scheduled_s(self) -> float:
        """
        Return when the next scheduled input acts, s (inf: none).

        The start of a shock pulse that has not ended (one acting now: now), a scheduled
        input (a parameter, drive or temperature change) or a streamed base-acceleration
        sample: what a model that does not integrate them must hand over before
        (``core.engine.averaged.AveragedEngine``). The angular rate's profile is not among them.
        """
        now = self.time_s
        times = [max(t0, now) for t0, dur, _, _ in self._pulses if dur < 0.0 or t0 + dur > now]
        if self._events:
            times.append(self._events[0][0] * self.period_s)
        profile, head = self._profile_t, self._profile_head
        if head < len(profile) and (profile[-1] * 1e-9 > now or self._profile_x[-1] != 0.0
                                    or self._profile_y[-1] != 0.0):
            # the profile acts from its first sample still in use; its last value holds
            times.append(max(now, profile[head] * 1e-9))
        return min(times) if times else math.inf

    @property
    def has_environment(self) -> bool:
        """Whether a steady acceleration or a sine or random vibration acts at every sample."""
        return self._environment is not None

    def shock(self, peak_x: float, peak_y: float = 0.0, at_ns: Optional[int] = None,
              duration_s: Optional[float] = None) -> None:
        """
        Schedule a half-sine base-acceleration pulse (eq. 32).

        Parameters
        ----------
        peak_x, peak_y : float
            Peak base acceleration along x (theta = 0, drives q1) and y (drives q1s), m/s^2.
            It enters the equations as ``-a_b`` (the ring lags the base).
        at_ns : int, optional
            Start time, ns (default: now). Exact, need not be on the sample grid.
        duration_s : float, optional
            T_s, s (default: ``shock.duration``, or one tenth of the 2theta period, of the
            configuration in force when the pulse starts, so that a parameter change
            scheduled before it counts).

        """
        for name, val in (('shock.x', peak_x), ('shock.y', peak_y)):
            if not math.isfinite(val):
                raise InputError(f'{name}: must be finite, got {val!r}')
        _check_acceleration('shock', peak_x, peak_y)
        if peak_y != 0.0 and self._y_index < 0:
            raise InputError('shock.y: needs modes.companions (q1s) to act on')
        if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0.0):
            raise InputError(f'shock.duration: must be > 0, got {duration_s!r}')
        start_ns = self.time_ns if at_ns is None else int(at_ns)
        if start_ns < self.time_ns:
            raise InputError(f'shock: time {start_ns * 1e-9:.9f} s is in the past '
                             f'(simulation time {self.time_s:.9f} s)')
        dur = _DURATION_AT_START if duration_s is None else float(duration_s)
        self._pulses.append((start_ns * 1e-9, dur, float(peak_x), float(peak_y)))

    def add_base_acceleration(self, at_ns: int, ax: float, ay: float = 0.0) -> None:
        """Add one sample of a streamed base-acceleration profile (m/s^2) at ``at_ns``."""
        for name, val in (('base_acceleration.x', ax), ('base_acceleration.y', ay)):
            if not math.isfinite(val):
                raise InputError(f'{name}: must be finite, got {val!r}')
        _check_acceleration('base_acceleration', ax, ay)
        if ay != 0.0 and self._y_index < 0:
            raise InputError('base_acceleration.y: needs modes.companions (q1s) to act on')
        if at_ns < self.time_ns:
            raise InputError(f'base_acceleration: time {at_ns * 1e-9:.9f} s is in the past '
                             f'(simulation time {self.time_s:.9f} s)')
        if self._profile_t and at_ns <= self._profile_t[-1]:
            raise InputError('base_acceleration: stamps must increase')
        self._profile_t.append(int(at_ns))
        self._profile_x.append(float(ax))
        self._profile_y.append(float(ay))

    def set_rate(self, at_ns: int, rate: float) -> None:
        """
        Step the angular rate of the sensor frame to ``rate`` (rad/s about z) at ``at_ns``.

        The rate holds from then on; knots of the profile after ``at_ns`` are discarded (a
        streamed value takes over from the scheduled profile). A rate beyond the model's
        range (``SimConfig.max_input_rate``) is refused.
        """
        if not self.gyro:
            raise InputError('angular_rate: needs gyro.enabled (the rotation acts on the '
                             'gyroscope only)')
        if not math.isfinite(rate):
            raise InputError(f'angular_rate.z: must be finite, got {rate!r}')
        refusal = self._config.rate_range_refusal('angular_rate.z', rate)
        if refusal is not None:
            raise InputError(refusal)
        at_ns = int(at_ns)
        if at_ns < self.time_ns:
            raise InputError(f'angular_rate: time {at_ns * 1e-9:.9f} s is in the past '
                             f'(simulation time {self.time_s:.9f} s)')
        self.rate_profile.step(at_ns, rate)

    def set_drive(self, amplitude: Optional[float] = None, frequency_hz: Optional[float] = None,
                  at_ns: Optional[int] = None) -> None:
        """Change the drive amplitude (m/s^2) and/or frequency (Hz) at a sample time."""
        if amplitude is not None and not math.isfinite(amplitude):
            raise InputError(f'drive.amplitude: must be finite, got {amplitude!r}')
        if amplitude is not None:
            _check_acceleration('drive.amplitude', amplitude)
        if frequency_hz is not None and not (math.isfinite(frequency_hz)
                                             and frequency_hz >= 0.0):
            raise InputError(f'drive.frequency: must be finite and >= 0, got {frequency_hz!r}')
        if amplitude not in (None, 0.0) and self._drive_index < 0:
            raise InputError('drive.amplitude: drives the 2theta mode, needs 2 modes')
        if self.loop is not None:
            raise InputError(f'drive: the closed loop (control.mode: {self._config.control.mode}) '
                             'sets the drive; its set-point is control.agc_setpoint')
        self._at_index(at_ns, 'drive')

        def apply() -> None:
            drive = self._config.drive
            amp = drive.amplitude if amplitude is None else float(amplitude)
            freq = drive.frequency if frequency_hz is None else float(frequency_hz)
            self._rephase_drive()
            self._config = replace(self._config,
                                   drive=replace(drive, amplitude=amp, frequency=freq))
            self._drive = self._drive_args()
        self._schedule(at_ns, apply)

    def _rephase_drive(self) -> None:
        """Move the drive's phase reference to now, before its amplitude or frequency change."""
        t = self.time_s
        d = self._drive
        phase = d.omega * (t - d.t_ref) + d.phase
        self._drive_phase = math.fmod(phase, 2.0 * math.pi)
        self._drive_t_ref = t

    def _rephase_vibration(self) -> None:
        """Move the sine vibration's phase reference to now, before its frequency changes."""
        t = self.time_s
        omega = 2.0 * math.pi * self._config.run.vibration_frequency
        phase = omega * (t - self._vibration_t_ref) + self._vibration_phase
        self._vibration_phase = math.fmod(phase, 2.0 * math.pi)
        self._vibration_t_ref = t

    def _drive_args(self) -> kernels.Drive:
        """
        Return the kernels' drive from the current phase reference.

        Open loop the configuration's; closed loop the loops' commands (``core.gyro.control``).
        """
        if self.loop is not None:
            omega, force, rb_amp, rb_lag = self.loop.commands()
            return kernels.Drive(amplitude=float(force), omega=float(omega),
                                 t_ref=float(self._drive_t_ref),
                                 phase=float(self._drive_phase), index=self._drive_index,
                                 sense_index=(self._sense_index if self.loop.rebalance
                                              else -1),
                                 sense_amplitude=float(rb_amp), sense_phase=float(rb_lag))
        drive = self._config.drive
        return kernels.Drive(amplitude=float(drive.amplitude),
                             omega=2.0 * math.pi * float(drive.frequency),
                             t_ref=float(self._drive_t_ref), phase=float(self._drive_phase),
                             index=self._drive_index)

    def reset(self, at_ns: Optional[int] = None) -> None:
        """
        Put the ring back at rest (and clear a contact) at a sample time.

        Everything pending is discarded: shock pulses (over or to come), the base-acceleration
        profile (a new one may start at any stamp) and the drive / parameter changes
        scheduled after it. The drive itself keeps its amplitude, frequency and phase, and the
        sensor frame keeps rotating (the angular-rate profile is the motion of the case, not
        a state of the ring).
        """
        def apply() -> None:
            self.q[:] = 0.0
            self.v[:] = 0.0
            self._acc[:] = 0.0
            self._pulses = []
            self._profile_t, self._profile_x, self._profile_y = [], [], []
            self._profile_head = 0
            self._events = []
            self.status = Status.RUNNING
            self.message = ''
            self.contact_time_s = math.nan
            self.contact_theta_rad = math.nan
            self._stops.state[kernels.STOP_IN_CONTACT] = 0  # at rest: off the stops
        self._schedule(at_ns, apply)

    def set_state(self, q: np.ndarray, v: np.ndarray) -> None:
        """
        Set the coordinates (m) and velocities (m/s) now.

        At t = 0 this is the start state: the loops start in lock there and the sense chain
        is built at its operating point (as ``Simulator(config, start_state)`` does).
        """
        self._set_state(q, v)
        if self.sample_index == 0:
            self._start_state = (self.q.copy(), self.v.copy())
            if self.sense is not None:
                self.sense = SenseChain(self._config, self, self._start_state,
                                        self._held_pickoff, calibration=self.calibration)

    def _set_state(self, q: np.ndarray, v: np.ndarray) -> None:
        q = np.asarray(q, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        n = self.model.n_coordinates
        for name, arr in (('q', q), ('v', v)):
            if arr.shape != (n,) or not np.all(np.isfinite(arr)):
                raise InputError(f'{name}: expected {n} finite values')
        old_q, old_v = self.q.copy(), self.v.copy()
        self.q[:] = q
        self.v[:] = v
        try:
            self._refresh_acceleration()
        except SimulationError:
            self.q[:] = old_q
            self.v[:] = old_v
            raise
        if self.loop is not None and self.sample_index == 0:
            # The loops start in lock at the state (core.gyro.control.DriveLoop.start).
            self._drive_phase = self.loop.start(self.q, self.v, self._rate_at_start(),
                                                self._start_omega())
            self._drive_t_ref = 0.0
            self._drive = self._drive_args()

    @property
    def output_geometry(self) -> kernels.OutputGeometry:
        """Return the output channels' geometry in force (gaps, electrode panels)."""
        return self._output_geometry

    @property
    def thermal_live(self) -> bool:
        """Whether the die is followed (a temperature profile or a set ambient, T2)."""
        return self._thermal_live

    def drive_phase_now(self) -> float:
        """Return the drive's (the NCO's) phase now, rad in [0, 2 pi)."""
        d = self._drive
        return math.fmod(d.omega * (self.time_s - d.t_ref) + d.phase, 2.0 * math.pi)

    def design(self) -> Design:
        """Return what the gyroscope is now (the engine contract: what another derives from)."""
        return Design(config=self._config, model=self.model,
                      output_geometry=self._output_geometry, pickoff=self.pickoff,
                      loop=self.loop,
                      low_pass=(self.sense.electronics.low_pass if self.sense is not None
                                else None),
                      period_ns=int(self.period_ns),
                      device_temperature=float(self.device_temperature))

    def export_state(self) -> GyroState:
        """
        Return the gyroscope's state now, at a loop update (the engine contract).

        The coordinates, the loops' state, the NCO's phase, the rebalance output's filter,
        the last ``~/rate`` sample, copies of the die and the flicker bank, the device's
        temperature and the rate profile in force from now on.

        Raises
        ------
        InputError
            Not the closed-loop gyroscope, or not at a loop update.

        """
        loop, sense = self.loop, self.sense
        if loop is None or sense is None:
            raise InputError('export_state: the state at a loop update is the closed-loop '
                             "gyroscope's")
        if self.sample_index % loop.window:
            raise InputError(f'export_state: sample {self.sample_index} is not a loop update '
                             f'(a whole number of {loop.window} samples)')
        el = sense.electronics
        rate, quadrature = el.latest_outputs()
        return GyroState(sample_index=int(self.sample_index), q=self.q.copy(), v=self.v.copy(),
                         loop=loop.state(), nco_phase=self.drive_phase_now(), harmonics=None,
                         rebalance_state=el.rebalance_state(), latest_rate=rate,
                         latest_quadrature=quadrature, die=copy.deepcopy(self.die),
                         flicker=copy.deepcopy(el.flicker),
                         device_temperature=float(self.device_temperature),
                         rate_knots=self.rate_profile.knots_from(self.time_s),
                         thermal_live=bool(self._thermal_live),
                         die_reading=el.die_temperature)

    def import_state(self, state: GyroState) -> None:
        """
        Go on from a state taken outside the full model at a later loop update (a hand-back).

        The clock jumps to ``state.sample_index``; the coordinates, the loops, the drive's
        phase reference (the NCO's phase now), the sense chain's filters, the die and the
        flicker bank take the given state. The noises are addressed by sample index, so
        they go on as if the stretch had been simulated. Nothing the skipped stretch would
        have acted on may be pending in it.

        Raises
        ------
        InputError
            Not the closed-loop gyroscope, not running, not at a loop update (now or at
            ``state.sample_index``), an index before now, or a scheduled input, shock,
            streamed base acceleration or environment in the skipped stretch.

        """
        loop, sense = self.loop, self.sense
        if loop is None or sense is None or not loop.rebalance:
            raise InputError('import_state: a hand-back needs the closed-loop gyroscope with '
                             'force-to-rebalance')
        if self.status != Status.RUNNING or self.in_stop_contact:
            raise InputError(f'import_state: the run is {self.status.value}, not free and running')
        index = int(state.sample_index)
        if index < self.sample_index or index % loop.window or self.sample_index % loop.window:
            raise InputError(f'import_state: sample {index} must be a loop update at or after now '
                             f'(sample {self.sample_index})')
        end_s = index * self.period_s
        skipped = ([at for at, _, _ in self._events if at < index]
                   + [t0 for t0, dur, _, _ in self._pulses   # dur is set at its start
                      if t0 < end_s and (t0 >= self.time_s or t0 + dur > self.time_s)]
                   + [at for at in self._profile_t[self._profile_head:]
                      if at < index * self.period_ns])
        if skipped or self._environment is not None:
            raise InputError('import_state: an input, a shock, a base acceleration or an '
                             'environment acts in the skipped stretch; the full model must '
                             'simulate it')
        self.sample_index = index
        self.die = state.die
        if (state.device_temperature is not None
                and state.device_temperature != self.device_temperature):
            self._build_device_at(float(state.device_temperature))
        self._follow_die()
        self._set_state(state.q, state.v)
        loop.set_state(state.loop)
        self._drive_phase = math.fmod(float(state.nco_phase), 2.0 * math.pi)
        self._drive_t_ref = self.time_s
        self._drive = self._drive_args()
        # the next sample's phase: the kernels' phase at sample i is that of (i + 1) T
        step = self._drive.omega * self.period_s
        sense.electronics.resume(index, state.harmonics, self._drive_phase + step, step,
                                 state.rebalance_state, state.latest_rate,
                                 state.latest_quadrature, state.flicker)

    def _refresh_acceleration(self) -> None:
        self._acc[:] = forces.nonlinear_acceleration(self.q, self.model)
        if self._stops.gap > 0.0:  # the force the first kick takes includes the stops'
            kernels.stop_accel(self.q, self.v, self._stops, self._acc, False)
            self._stops.state[kernels.STOP_IN_CONTACT] = self._stops.state[
                kernels.STOP_LAST_CONTACT]

    @property
    def impacts(self) -> int:
        """Impacts on the mechanical stops so far: entries into contact (``kernels.stops``)."""
        return int(self._stops.state[kernels.STOP_IMPACTS])

    @property
    def in_stop_contact(self) -> bool:
        """Whether the ring touched a stop at the end of the last step."""
        return bool(self._stops.state[kernels.STOP_IN_CONTACT])

    @property
    def stop_substeps(self) -> int:
        """Sub-steps taken near the stops so far (their cost, ``kernels.stops`` S4)."""
        return int(self._stops.state[kernels.STOP_SUBSTEPS])

    # ------------------------------------------------------------------ advancing
    def advance(self, seconds: float) -> Samples:
        """Advance by ``seconds`` (rounded to whole output samples) and return the samples."""
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise InputError(f'seconds: must be finite and >= 0, got {seconds!r}')
        return self.advance_samples(int(round(seconds / self.period_s)))

    def advance_samples(self, n_samples: int, between: Optional[Callable[[], None]] = None,
                        channels: bool = True) -> Samples:
        """
        Advance by ``n_samples`` output periods; returns samples at the new times.

        Parameters
        ----------
        n_samples : int
            Output periods to advance.
        between : callable, optional
            Called after every stretch integrated (a call is cut at events and, closed loop,
            at every loop update: 1 ms), so that a caller can do something on time while a
            long call runs (the node sends the ``~/rate`` messages that are due). It must not
            touch the simulator. No cut is added for it: cutting the open loop's stretches
            every 1 ms cost the gyroscope a third of its speed in Python overhead.
        channels : bool
            The engine contract's (``core.engine.base``): the full model computes the gaps
            and capacitances whatever it is told, since its pick-off reads them.

        """
        n = self.model.n_coordinates
        out_q = np.empty((n_samples, n))
        out_v = np.empty((n_samples, n))
        phase = rate = rows = arrays = volts = None
        loop = self.loop
        if self.gyro or loop is not None:
            phase = np.empty(n_samples)
            rate = np.empty(n_samples)
        force_noise = pickoff_noise = None
        sensed = []  # the sense chain's outputs per stretch
        if self.pickoff is not None:
            # The electronics read every stretch as it is integrated, with the configuration
            # in force over it: the channels, the amplifiers' volts (computed once for the
            # loops and the sense chain), their noise for the whole call (addressed by sample
            # index, so the same as per stretch).
            arrays = self.channel_arrays(n_samples)
            volts = np.empty((n_samples, 2))
            pickoff_noise = self.pickoff.noise(self.sample_index, n_samples)
        if loop is not None:
            rows = np.empty((n_samples, len(control.CONTROL_CHANNELS)))
            # The normals of the whole call at once (addressed by sample index, so the same
            # as per stretch; scaled per stretch, by the levels then in force): a generator
            # per 1 ms stretch cost more than its numbers.
            force_noise = self._unit_force_noise(n_samples)
        # The sample times: the block's, and the drive phase's per stretch.
        t = (np.arange(self.sample_index, self.sample_index + n_samples) + 1) * self.period_s
        done = 0
        rate_version = None
        while done < n_samples:
            self._run_due_events()
            stop = n_samples - done
            if self._events:
                stop = min(stop, self._events[0][0] - self.sample_index)
            if self._thermal_live:  # (T2) the die's temperature, every THERMAL_UPDATE_S
                since = self.sample_index % self._thermal_window
                if since == 0:
                    self._follow_die()
                stop = min(stop, self._thermal_window - since)
            if loop is not None:  # (C1) cut at the loop's updates
                stop = min(stop, loop.window - self.sample_index % loop.window)
            if phase is not None and stop > 0:
                # The drive is constant over the stretch (events and loop updates cut it).
                d = self._drive
                np.add(d.omega * (t[done:done + stop] - d.t_ref), d.phase,
                       out=phase[done:done + stop])
                if rate_version != self.rate_profile.version:
                    # The knots change only by set_rate (between calls) or by a compaction
                    # of past ones (same values): the rates of all the call's samples left
                    # at once (per 1 ms loop stretch its numpy calls cost ~50 us).
                    rate_version = self.rate_profile.version
                    self._rates(self.sample_index, n_samples - done, rate[done:])
            first = self.sample_index
            noise_part = None
            if force_noise is not None:
                noise_part = self._scaled_noise(
                    force_noise[done * self.n_sub:(done + stop) * self.n_sub])
            self._integrate(stop, out_q[done:done + stop], out_v[done:done + stop],
                            noise_part)
            if arrays is not None and stop > 0:
                part = slice(done, done + stop)
                self._channels(out_q[part], kernels.Channels(*(c[part] for c in arrays)))
                self.pickoff.clean_volts(arrays.capacitance[part], out=volts[part])
                if pickoff_noise is not None:
                    volts[part] += pickoff_noise[part]
                row = None
                if loop is not None:
                    row = loop.row()  # the loops' state, constant over the stretch
                    rows[part] = row
                # What the electronics read must be finite (module doc, "Failure"): one sum of
                # the volts, of the loops' row and of the drive's scalars, a few us a stretch.
                d = self._drive
                bad = None
                if not (math.isfinite(volts[part].sum()) and math.isfinite(d.omega + d.phase)
                        and (row is None or math.isfinite(row.sum()))):
                    read = {'pick-off volts': volts[part], 'drive phase': phase[part],
                            'loop state': None if rows is None else rows[part]}
                    bad = _first_nonfinite(*read.values())
                if bad is not None:
                    held = slice(done + bad, done + stop)
                    self._fail(float(t[done + bad]), ' and '.join(
                        name for name, arr in read.items()
                        if arr is not None and _first_nonfinite(arr) is not None))
                    self._hold_at_rest(t, held, out_q, out_v, arrays, phase, rows)
                    self.pickoff.clean_volts(arrays.capacitance[held], out=volts[held])
                    if pickoff_noise is not None:
                        volts[held] += pickoff_noise[held]
                if loop is not None:
                    self._feed_loop(first, volts[part], phase[part])
                if self.sense is not None:
                    sensed.append(self.sense.process(first, t[part], volts[part], phase[part],
                                                     None if rows is None else rows[part]))
            done += stop
            if between is not None:
                between()
        self._run_due_events()
        if arrays is None:
            return self._finite(self._samples(t, out_q, out_v, phase if self.gyro else None,
                                              rate))
        gap, min_gap, cap = arrays
        demod = rate_output = None
        if self.sense is not None:
            demod, rate_output = joined_outputs(t, sensed)
        return self._finite(Samples(t=t, q=out_q, v=out_v, gap=gap, min_gap=min_gap,
                                    capacitance=cap, drive_phase=phase,
                                    applied_rate=rate if self.gyro else None, control=rows,
                                    demod=demod, rate_output=rate_output,
                                    die_temperature=self.die.advance_to(self.time_s)))

    # ------------------------------------------------------------------ failure
    def _fail(self, t_s: float, what: str) -> None:
        """
        Fail the run on a non-finite ``what`` at ``t_s`` (s): the ring held at rest from then.

        The loops start again from their initial state at rest, with the drive's phase
        reference at ``t_s``, if their own state is not finite; ``~/reset`` recovers.
        """
        before = f', after {self.status}: {self.message}' if self.status != Status.RUNNING else ''
        self.status = Status.FAILED
        self.contact_time_s = t_s
        self.contact_theta_rad = math.nan
        self.message = f'non-finite {what} (numerical failure), t = {t_s:.9f} s{before}'
        self.nonfinite_failures += 1
        self.q[:] = 0.0
        self.v[:] = 0.0
        self._acc[:] = 0.0
        if self.loop is not None and not (self.loop.finite() and math.isfinite(self._drive_phase)
                                          and math.isfinite(self._drive_t_ref)):
            self._drive_phase = self.loop.restart(self.q, self.v, self._rate_at_start(),
                                                  self._start_omega())
            self._drive_t_ref = t_s
            self._drive = self._drive_args()

    def _hold_at_rest(self, t: np.ndarray, held: slice, out_q: np.ndarray, out_v: np.ndarray,
                      channels: kernels.Channels, phase: Optional[np.ndarray],
                      rows: Optional[np.ndarray]) -> None:
        """Overwrite the samples ``held`` of a call with those of the ring held by a failure."""
        out_q[held] = self.q
        out_v[held] = 0.0
        self._channels(out_q[held], kernels.Channels(*(c[held] for c in channels)))
        if phase is not None:
            d = self._drive
            np.add(d.omega * (t[held] - d.t_ref), d.phase, out=phase[held])
        if rows is not None:
            rows[held] = self.loop.row()

    def _finite(self, s: Samples) -> Samples:
        """
        Return ``s`` with every value finite: a non-finite one fails the run (module doc).

        From the first sample with a non-finite value on, the ring is held at rest (its
        channels those of rest), and the electronics' outputs (loop rows, demodulator, rate)
        hold their last finite values (0 if none in the call); a sense chain that produced a
        non-finite value is built again at the start state, so the next call is finite.
        """
        # What goes out (the velocities do not; the kernel keeps them finite with q).
        sample_arrays = (s.q, s.gap, s.min_gap, s.capacitance, s.drive_phase, s.applied_rate,
                         s.control, None if s.demod is None else s.demod.values)
        rate = s.rate_output
        rate_arrays = () if rate is None else (rate.rate, rate.quadrature)
        bad = _first_nonfinite(*sample_arrays)
        bad_rate = _first_nonfinite(*rate_arrays) if rate_arrays else None
        if bad is None and bad_rate is None:
            return s
        sense_failed = bad_rate is not None or (
            s.demod is not None and _first_nonfinite(s.demod.values) is not None)
        n = len(s)
        first = n if bad is None else bad
        if bad_rate is not None:  # the rate's samples lie on the output grid
            first = min(first, int(np.searchsorted(s.t, rate.t[bad_rate] - 0.5 * self.period_s)))
        first = min(first, n - 1)
        what = [name for name, arr in zip(
            ('coordinate', 'radial gap', 'smallest gap', 'capacitance', 'drive phase',
             'angular rate', 'loop row', 'demodulator'), sample_arrays)
            if arr is not None and _first_nonfinite(arr) is not None]
        if bad_rate is not None:
            what.append('rate output')
        if self.status != Status.FAILED or self.contact_time_s > s.t[first]:
            self._fail(float(s.t[first]), ' and '.join(what))
        held = slice(first, n)
        channels = kernels.Channels(gap=s.gap, min_gap=s.min_gap, capacitance=s.capacitance)
        self._hold_at_rest(s.t, held, s.q, s.v, channels, s.drive_phase, None)
        for arr in (s.applied_rate, s.control, None if s.demod is None else s.demod.values):
            if arr is not None:
                _hold_last(arr, first)
        if rate is not None:
            from_rate = int(np.searchsorted(rate.t, s.t[first] - 0.5 * self.period_s))
            for arr in rate_arrays:
                _hold_last(arr, from_rate)
        if self.sense is not None and sense_failed:
            self.sense = SenseChain(self._config, self, self._start_state, self.pickoff)
        return s

    def _feed_loop(self, first: int, volts: np.ndarray, phase: np.ndarray) -> None:
        """Collect a stretch into the loop period; at its end, update the loop (C1, C2)."""
        loop = self.loop
        at = first % loop.window
        count = volts.shape[0]
        self._loop_volts[at:at + count] = volts
        self._loop_phase[at:at + count] = phase
        if at + count < loop.window or self.status != Status.RUNNING:
            return
        loop.update(self._loop_volts, self._loop_phase, self.time_s)
        self._rephase_drive()
        self._drive = self._drive_args()

    def _run_due_events(self) -> None:
        while self._events and self._events[0][0] <= self.sample_index:
            _, _, action = self._events.pop(0)
            action()

    def _integrate(self, count: int, out_q: np.ndarray, out_v: np.ndarray,
                   force_noise: Optional[np.ndarray] = None) -> None:
        # Cut at events (advance_samples), so the configuration is constant over the call.
        if count <= 0:
            return
        if self.status != Status.RUNNING:
            out_q[:] = self.q
            out_v[:] = 0.0
            self.sample_index += count
            return
        t_start = self.sample_index * self.period_s
        t_end = (self.sample_index + count) * self.period_s
        pulses = []
        for p in self._pulses:
            if p[1] == _DURATION_AT_START and p[0] < t_end:
                # Starts in this stretch, over which the configuration is constant (one
                # starting at t_end waits for the events due then).
                p = (p[0], self._config.shock_duration_s, p[2], p[3])
            if p[1] == _DURATION_AT_START or p[0] + p[1] >= t_start:
                pulses.append(p)
        self._pulses = pulses
        active = [p for p in pulses if p[0] < t_end]  # one starting at t_end acts later
        pulse_arr = np.array(active, dtype=np.float64).reshape(-1, 4)
        pulse_max_sub = (float(np.min(pulse_arr[:, 1])) / PULSE_SUBSTEPS_PER_DURATION
                         if len(active) else self.h)
        prof_t, prof_x, prof_y = self._base_arrays(t_start, t_end, count)
        rate_t, rate_w = self.rate_profile.stretch(t_start, t_end)
        forcing = kernels.Forcing(pulses=pulse_arr, pulse_max_sub=pulse_max_sub,
                                  profile_t=prof_t, profile_x=prof_x, profile_y=prof_y,
                                  y_index=self._y_index, rate_t=rate_t, rate_w=rate_w,
                                  pair_c=self._pair_c, pair_s=self._pair_s, kappa=self._kappa,
                                  noise=(self._force_noise(count) if force_noise is None
                                         else force_noise), stops=self._stops)
        scratch = self._scratch
        if scratch.cuts.size < 2 * len(active) + 2:
            scratch = self._scratch = scratch._replace(cuts=np.empty(2 * len(active) + 2))
        scratch.info[:] = 0
        completed = kernels.run_samples(self.q, self.v, self._acc, self.sample_index, count,
                                        self._method, self.model.kernel, self._drive, forcing,
                                        scratch, out_q, out_v)
        self.steps_taken += completed * self.n_sub
        if scratch.info[0] != 0:
            status = int(scratch.info[0])
            theta = forces.contact_angle(self.model, scratch.info)
            self._enter_contact(status, theta, float(scratch.tinfo[0]))
            out_q[completed:] = self.q
            out_v[completed:] = 0.0
        self.sample_index += count

    def _enter_contact(self, status: int, theta: float, t: float) -> None:
        self.status = _kernel_status(status)
        if self.status == Status.FAILED:
            self.nonfinite_failures += 1
        self.contact_time_s = t
        self.contact_theta_rad = theta
        self.message = f'{kernels.describe_status(status, theta)}, t = {t:.9f} s'
        if not np.all(np.isfinite(self.q)) or not np.all(np.isfinite(self.v)):
            self.q[:] = 0.0  # never expose NaN; the status says it failed
        self.v[:] = 0.0

    def _force_noise(self, count: int) -> np.ndarray:
        """Velocity impulses (m/s) of the thermomechanical noise for ``count`` samples."""
        z = self._unit_force_noise(count)
        if z is None:
            return _NO_NOISE
        return self._scaled_noise(z)

    def _scaled_noise(self, z: np.ndarray) -> np.ndarray:
        """
        Return the velocity impulses (m/s) of unit normals ``z`` (rows: steps).

        Each coordinate's normal times its level; a coupled pair's two normals mixed by the
        Cholesky factor of its noise covariance (``_build_rotation``).
        """
        out = np.ascontiguousarray(z * self._noise_sigma[None, :])
        for c, s_, factor in self._noise_mix:
            (f_cc, f_cs), (f_sc, f_ss) = factor.tolist()
            z_c, z_s = z[:, c], z[:, s_]
            out[:, c] = f_cc * z_c + f_cs * z_s
            out[:, s_] = f_sc * z_c + f_ss * z_s
        return out

    def _unit_force_noise(self, count: int) -> Optional[np.ndarray]:
        """Return the force noise's standard normals, shape (count n_sub, n); None: no noise."""
        sigma = self._noise_sigma
        if count <= 0 or not np.any(sigma > 0.0):
            return None
        n = sigma.size
        z = noise.block_normals(self._noise_seed, noise.STREAM_BROWNIAN, self.sample_index,
                                count, self.n_sub * n)
        return z.reshape(count * self.n_sub, n)

    def _base_arrays(self, t_start: float, t_end: float, count: int):
        """
        Return the base acceleration (s, m/s^2, m/s^2) of a stretch of ``count`` samples.

        The streamed profile (:meth:`_profile_arrays`) plus the environment of the scenario
        (``scenario.vibration_*``, ``scenario.acceleration``; :func:`environment_of`),
        evaluated at every output sample from two before the stretch to two after it (the
        kernel's stages stay within two steps of it) and at the streamed samples there: the
        kernel interpolates the sum linearly. The sine is evaluated at every time of the
        grid, the random vibration (a table of output samples) interpolated linearly onto
        the streamed samples' times. The values at a time do not depend on how the run is
        cut, so neither does the result; the environment in force over the stretch is the
        one of the last change (changes cut the stretches).
        """
        prof_t, prof_x, prof_y = self._profile_arrays(t_start, t_end)
        env = self._environment
        if env is None:
            return prof_t, prof_x, prof_y
        index = np.arange(self.sample_index - 2, self.sample_index + count + 3)
        t = index * self.period_s
        if prof_t.size:
            inside = prof_t[(prof_t > t[0]) & (prof_t < t[-1])]
            grid = np.union1d(t, inside)
            x = np.interp(grid, prof_t, prof_x, left=0.0, right=0.0)
            y = np.interp(grid, prof_t, prof_y, left=0.0, right=0.0)
        else:
            grid, x, y = t, np.zeros(t.size), np.zeros(t.size)
        (steady_x, steady_y), (peak_x, peak_y) = env.steady, env.sine_peak
        if env.omega > 0.0 and (peak_x != 0.0 or peak_y != 0.0):
            wave = np.sin(env.omega * (grid - self._vibration_t_ref) + self._vibration_phase)
        else:
            wave = np.zeros(grid.size)
        x = x + steady_x + peak_x * wave
        y = y + steady_y + peak_y * wave
        if env.random is not None:
            a = env.random.at(index)
            if grid.size != t.size:
                a = np.interp(grid, t, a)
            x += env.direction[0] * a
            y += env.direction[1] * a
        return grid, x, y

    def environment_at(self, index: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the scenario's base acceleration (m/s^2, x and y) at output sample ``index``.

        As the kernel sees it at those samples under the environment in force now (not the
        streamed ``~/base_acceleration``); zeros without an environment.
        """
        index = np.asarray(index, dtype=np.int64)
        x, y = np.zeros(index.shape), np.zeros(index.shape)
        env = self._environment
        if env is None:
            return x, y
        t = index * self.period_s
        (steady_x, steady_y), (peak_x, peak_y) = env.steady, env.sine_peak
        wave = (np.sin(env.omega * (t - self._vibration_t_ref) + self._vibration_phase)
                if env.omega > 0.0 else np.zeros(t.shape))
        x = x + steady_x + peak_x * wave
        y = y + steady_y + peak_y * wave
        if env.random is not None:
            a = env.random.at(index)
            x += env.direction[0] * a
            y += env.direction[1] * a
        return x, y

    def _profile_arrays(self, t_start: float, t_end: float):
        """
        Return the profile samples (s, m/s^2, m/s^2) that a stretch [t_start, t_end] can use.

        From the last sample at or before ``t_start`` to the first one past ``t_end`` plus
        two steps (splitting stages may sit slightly outside their step): the kernel
        interpolates between neighbours only, so the result is that of the whole profile,
        and the cost of a stretch does not grow with the samples still to come. Samples
        before it are over; the lists are compacted once they hold mostly such samples.
        """
        times = self._profile_t
        head = self._profile_head
        if head >= len(times):
            empty = np.empty(0)
            return empty, empty, empty
        keep = max(head, bisect.bisect_right(times, t_start, lo=head,
                                             key=lambda t_ns: t_ns * 1e-9) - 1)
        if keep > 4096 and 2 * keep > len(times):
            for name in ('_profile_t', '_profile_x', '_profile_y'):
                setattr(self, name, getattr(self, name)[keep:])
            times, keep = self._profile_t, 0
        self._profile_head = keep
        end = min(len(times), bisect.bisect_right(times, t_end + 2.0 * self.h, lo=keep,
                                                  key=lambda t_ns: t_ns * 1e-9) + 1)
        return (np.array(times[keep:end], dtype=np.float64) * 1e-9,
                np.array(self._profile_x[keep:end], dtype=np.float64),
                np.array(self._profile_y[keep:end], dtype=np.float64))

    # ------------------------------------------------------------------ outputs
    def channel_arrays(self, n_s: int) -> kernels.Channels:
        k = self._n_electrodes
        return kernels.Channels(gap=np.empty((n_s, k)), min_gap=np.empty(n_s),
                                capacitance=np.empty((n_s, k)))

    def _channels(self, q: np.ndarray, out: kernels.Channels) -> None:
        kernels.output_channels(q, self._output_geometry, out)

    def _samples(self, t: np.ndarray, q: np.ndarray, v: np.ndarray,
                 drive_phase: Optional[np.ndarray] = None,
                 rate: Optional[np.ndarray] = None) -> Samples:
        out = self.channel_arrays(len(t))
        self._channels(q, out)
        return Samples(t=t, q=q, v=v, gap=out.gap, min_gap=out.min_gap,
                       capacitance=out.capacitance, drive_phase=drive_phase,
                       applied_rate=rate, die_temperature=self.die.kelvin)

    def _rates(self, first: int, count: int, rate_out: np.ndarray) -> None:
        """Set ``rate_out`` to the angular rate (rad/s) at samples ``first ..`` on."""
        t_ns = (np.arange(first, first + count, dtype=np.int64) + 1) * self.period_ns
        rate_out[:] = self.rates_at(t_ns)

    def _rate_at_start(self) -> float:
        return float(self.rates_at(np.zeros(1, np.int64))[0])

    def rates_at(self, t_ns: np.ndarray) -> np.ndarray:
        """
        Angular rate of the profile (rad/s) at the times ``t_ns`` (ns; after a step there).

        ``Samples.applied_rate`` holds these values at the sample times.
        """
        return self.rate_profile.at(t_ns)

    def outputs_for(self, q: np.ndarray) -> Samples:
        """
        Output channels of given coordinates, without advancing or changing the state.

        Parameters
        ----------
        q : array_like, shape (n,) or (S, n)
            Coordinates, m, columns as :attr:`coordinates`.

        Returns
        -------
        Samples
            ``t`` = the current time on every row; ``v`` = 0 (velocities do not enter the
            channels); ``gap``, ``min_gap`` and ``capacitance`` exactly as the published blocks
            compute them for these coordinates.

        """
        q = np.array(q, dtype=np.float64, ndmin=2)
        n = self.model.n_coordinates
        if q.ndim != 2 or q.shape[1] != n or not np.all(np.isfinite(q)):
            raise InputError(f'q: expected {n} finite values per row '
                             f'({", ".join(self.coordinates)}), got shape {q.shape}')
        q = np.ascontiguousarray(q)
        return self._samples(np.full(len(q), self.time_s), q, np.zeros_like(q))

    def energy(self) -> float:
        """Conserved energy of the undamped, unforced system at the current state, J."""
        return forces.mechanical_energy(self.q, self.v, self.omega, self.model)
