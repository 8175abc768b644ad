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
What an engine is: the contract the full and the averaged model keep, and what they exchange.

An engine advances one gyroscope by whole output samples and returns them as
:class:`Samples`. ``run.Run`` picks the engine of each stretch (``core.engine.handoff``) and
hands the gyroscope from one to the other at a loop update, as a :class:`GyroState`. No
engine reads another's private fields: what the averaged model needs of the full model is its
:class:`Design` (what the gyroscope is, built at a die temperature) and its exported state.

The contract (:class:`Engine`)
------------------------------
``name``
    The engine's name in ``integrator.fidelity`` and in the run's hand-offs.
``refusal(config)``
    Why this engine cannot run the gyroscope of ``config`` at all (None: it can).
``sample_index``, ``time_ns``
    The global index of the next sample and the simulation time, ns.
``advance_samples(count, between=None, channels=True)``
    Advance by ``count`` output samples; ``between`` is called between the stretches of one
    call (the node drains its inputs there); ``channels`` False lets an engine leave out the
    gaps and capacitances nobody keeps (``Samples.smallest_gap`` then stands for them).
``next_scheduled_s()``
    When the next thing scheduled in the engine acts, s (inf: nothing).
``export_state()`` / ``import_state(state)``
    The gyroscope's state at a loop update, out of and into the engine.
"""

import abc
from dataclasses import dataclass
import enum
import math
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim.core.gyro import electronics
from ring_gyro_sim.core.params import SimConfig

__all__ = ['Design', 'Engine', 'GyroState', 'Samples', 'Status', 'joined_outputs',
           'joined_samples']


class Status(str, enum.Enum):
    """
    State of a :class:`Simulator` (its :attr:`Simulator.status`).

    A ``str`` enum: each member equals its value (``Status.RUNNING == 'running'``) and
    ``str()`` / f-strings give the value, so diagnostics and summaries carry the plain word.
    """

    RUNNING = 'running'
    """Integrating."""
    CONTACT = 'contact'
    """A gap closed or the Taylor series left its range: the ring is held where it touched."""
    FAILED = 'failed'
    """A value became non-finite (a numerical failure): the ring is held at rest."""

    def __str__(self) -> str:
        """Return the value (``'running'``), not ``'Status.RUNNING'``."""
        return self.value


def joined_outputs(t: np.ndarray,
                   parts) -> Tuple[electronics.DemodSamples, electronics.RateSamples]:
    """Join the sense chain's outputs of consecutive stretches into those of the call."""
    if len(parts) == 1:
        return parts[0]
    demod = [d.values for d, _ in parts] or [np.empty((0, len(electronics.DEMOD_CHANNELS)))]
    rates = [r for _, r in parts]

    def column(name):
        return np.concatenate([getattr(r, name) for r in rates]) if rates else np.empty(0)
    judged = [r.variance for r in rates if len(r)]
    variance = np.concatenate(judged) if judged else None
    saturated = None
    if any(r.saturated is not None for r in rates):  # a stretch without a range: none did
        saturated = np.concatenate([np.zeros(len(r), bool) if r.saturated is None
                                    else r.saturated for r in rates])
    return (electronics.DemodSamples(t=t, values=np.concatenate(demod)),
            electronics.RateSamples(t=column('t'), rate=column('rate'),
                                    quadrature=column('quadrature'), variance=variance,
                                    saturated=saturated))


def joined_samples(parts: Sequence['Samples']) -> 'Samples':
    """Join the samples of consecutive stretches (of one run) into those of the whole."""
    def cat(name):
        arrays = [getattr(p, name) for p in parts]
        return None if any(a is None for a in arrays) else np.concatenate(arrays)
    t = cat('t')
    demod = rate_output = None
    if all(p.demod is not None and p.rate_output is not None for p in parts):
        demod, rate_output = joined_outputs(t, [(p.demod, p.rate_output) for p in parts])
    min_gap = cat('min_gap')
    return Samples(t=t, q=cat('q'), v=cat('v'), gap=cat('gap'), min_gap=min_gap,
                   capacitance=cat('capacitance'), drive_phase=cat('drive_phase'),
                   applied_rate=cat('applied_rate'), control=cat('control'), demod=demod,
                   rate_output=rate_output, die_temperature=parts[-1].die_temperature,
                   smallest_gap=(None if min_gap is not None
                                 else min(p.least_gap() for p in parts)))


@dataclass(frozen=True)
class GyroState:
    """
    The gyroscope's state at a loop update: what one engine hands to another.

    :meth:`Engine.export_state` gives it, :meth:`Engine.import_state` takes it (S13, S14 of
    ``core.engine.averaged``).

    Attributes
    ----------
    sample_index : int
        The global sample index now: a whole number of loop periods.
    q, v : ndarray, shape (n,)
        Coordinates (m) and velocities (m/s), columns as :attr:`Simulator.coordinates`.
    loop : dict
        The loops' state after their last update (``DriveLoop.state``).
    nco_phase : float
        The NCO's phase now, rad.
    harmonics : ndarray of complex, shape (2,), or None
        The sense and drive amplifiers' first harmonics now, V (``volts = Re(V e^{i phi})``,
        phi the NCO's phase), from which the demodulator restarts; None from the full model
        (whose demodulator runs on, sample by sample).
    rebalance_state : ndarray
        The rebalance output's low-pass state (E14), as ``SenseElectronics`` holds it.
    latest_rate, latest_quadrature : float
        The last ``~/rate`` sample's rate and quadrature before the flicker, rad/s.
    die : thermal.DieTemperature
        The die, at the time of ``sample_index``.
    flicker : electronics.FlickerNoise or None
        The flicker bank's state (None: the simulator's own goes on).
    device_temperature : float or None
        The die temperature (K) the device's coefficients were last built at (T2-T6), so
        that the full model goes on with the same device; None: rebuilt by the die's rule.
    rate_knots : (ndarray, ndarray) or None
        The angular rate's profile in force from now on: knot times (s) and rates (rad/s);
        None: the configuration's.
    thermal_live : bool
        Whether the die is followed (a temperature profile or a set ambient, T2).
    die_reading : float or None
        The die temperature sensor's last reading, K (None: none yet).

    """

    sample_index: int
    q: np.ndarray
    v: np.ndarray
    loop: Dict[str, Any]
    nco_phase: float
    harmonics: np.ndarray
    rebalance_state: np.ndarray
    latest_rate: float
    latest_quadrature: float
    die: Any
    flicker: Any = None
    device_temperature: Optional[float] = None
    rate_knots: Optional[Tuple[np.ndarray, np.ndarray]] = None
    thermal_live: bool = False
    die_reading: Optional[float] = None


@dataclass(frozen=True)
class Samples:
    """
    Output samples of one stretch of simulation.

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s.
    q, v : ndarray, shape (K, n)
        Coordinates (m) and their velocities (m/s), columns as :attr:`Simulator.coordinates`.
    gap : ndarray, shape (K, E), or None
        Outer gap at each electrode centre, m. None: not computed (an averaged stretch whose
        run's sink keeps no channel: ``run.Sink.needs_channels``), nor are ``min_gap`` and
        ``capacitance``; :attr:`smallest_gap` is then the smallest of the samples' ``min_gap``.
    min_gap : ndarray, shape (K,), or None
        Smallest outer gap around the ring, m.
    capacitance : ndarray, shape (K, E), or None
        Capacitance of each outer electrode, F (untruncated parallel plate).
    drive_phase : ndarray, shape (K,) or None
        Phase of the drive force ``A cos(phase)`` at each sample time, rad (the reference of
        the sense electronics); None when the gyroscope is off.
    applied_rate : ndarray, shape (K,) or None
        Angular rate of the sensor frame at each sample time, rad/s (None: gyroscope off).
    control : ndarray, shape (K, len(control.CONTROL_CHANNELS)) or None
        The closed loop's state in force at each sample (``core.gyro.control``, C9); None open
        loop.
    demod : electronics.DemodSamples or None
        The sense chain's demodulator at every sample (``~/demodulator``); None: gyroscope
        off.
    rate_output : electronics.RateSamples or None
        The gyroscope's rate output (``~/rate``, at ``gyro.output_rate``); None: gyroscope
        off.
    die_temperature : float or None
        The die temperature at the last sample, K (core.thermal, T2).
    smallest_gap : float or None
        With the channels not computed (``gap`` None): the smallest of the samples' smallest
        gaps, m, the value ``min(min_gap)`` would have. :meth:`least_gap` gives it either way.

    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    gap: Optional[np.ndarray]
    min_gap: Optional[np.ndarray]
    capacitance: Optional[np.ndarray]
    drive_phase: Optional[np.ndarray] = None
    applied_rate: Optional[np.ndarray] = None
    control: Optional[np.ndarray] = None
    demod: Optional[electronics.DemodSamples] = None
    rate_output: Optional[electronics.RateSamples] = None
    die_temperature: Optional[float] = None
    smallest_gap: Optional[float] = None

    def __len__(self) -> int:
        return int(self.t.size)

    def least_gap(self) -> float:
        """Return the smallest of the samples' smallest gaps, m (inf without a sample)."""
        if self.min_gap is None:
            return math.inf if self.smallest_gap is None else self.smallest_gap
        return float(np.min(self.min_gap)) if self.min_gap.size else math.inf


@dataclass(frozen=True)
class Design:
    """
    What the gyroscope is, as the full model built it at a die temperature.

    What the averaged model is derived from (its force sums, its pick-off's, its loops'
    constants): read, never changed, by another engine.

    Attributes
    ----------
    config : SimConfig
        The configuration in force.
    model : forces.ForceModel
        The electrostatic force's model (eqs. 18-28) of the device at the die temperature.
    output_geometry : kernels.OutputGeometry
        The output channels' geometry: gaps, electrode panels, capacitance scale.
    pickoff : electronics.PickOff
        The pick-off amplifiers (the gains held by the loops).
    loop : control.DriveLoop
        The loops, for their constants (window, period, gains, ranges, set-point).
    low_pass : ndarray
        The output low-pass's second-order sections (E5).
    period_ns : int
        The output sample period, ns.
    device_temperature : float
        The die temperature the device's coefficients were built at, K.

    """

    config: SimConfig
    model: Any
    output_geometry: Any
    pickoff: Any
    loop: Any
    low_pass: np.ndarray
    period_ns: int
    device_temperature: float


class Engine(abc.ABC):
    """
    An engine of the gyroscope: the contract of the module docstring.

    ``core.engine.full.Simulator`` (the full model) and
    ``core.engine.averaged.AveragedEngine`` (the averaged model) keep it; ``run.Run`` holds
    one at a time and hands the state between them.
    """

    name: str = ''
    """The engine's name (``integrator.fidelity``, the run's hand-offs)."""

    @classmethod
    @abc.abstractmethod
    def refusal(cls, config: SimConfig) -> Optional[str]:
        """Return why this engine cannot run the gyroscope of ``config``; None: it can."""

    sample_index: int
    """The global index of the next sample (the samples simulated so far)."""
    period_ns: int
    """The output sample period, ns."""

    @property
    def time_ns(self) -> int:
        """Return the simulation time, ns."""
        return self.sample_index * self.period_ns

    @abc.abstractmethod
    def advance_samples(self, n_samples: int, between=None, channels: bool = True) -> Samples:
        """Advance by ``n_samples`` output samples; return them."""

    @abc.abstractmethod
    def next_scheduled_s(self) -> float:
        """Return when the next scheduled input acts, s (inf: none)."""

    @abc.abstractmethod
    def export_state(self) -> GyroState:
        """Return the gyroscope's state now, at a loop update."""

    @abc.abstractmethod
    def import_state(self, state: GyroState) -> None:
        """Go on from ``state``, another engine's at a loop update at or after now."""
