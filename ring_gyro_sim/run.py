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
The one run path: every way of running the simulator drives a :class:`Run`.

The node (``ros/node.py``), ``ring_gyro run`` and ``--from`` (``offline.py``), the paper
cases (``analysis/cases.py``) and the benchmark all do the same three things::

    run = Run(config, sink=...)                    # Simulator + start state + statistics
    run.apply(Shock(x=..., at_ns=...))             # any input, validated and timed here
    block = run.advance(n_samples)                 # samples of every channel

so there is one place that decides when an input acts and whether it is refused (and counts
it), one set of run statistics, one diagnostics builder (:meth:`Run.diagnostics`: the same
keys whichever way a run is made) and one sink interface (:class:`Sink`, with
:class:`NullSink` instead of ``if recorder is not None``). The node adds only pacing and ROS
plumbing; offline adds only a loop. This module imports only ``core``: a sink that publishes
or records ROS messages lives in ``ros/``.

When inputs act (``apply``)
    ``at_ns`` None means the current simulation time (the end of the last block). A stamp in
    the future acts at that time, exactly (a shock starts between samples if need be); one at
    most ``late_tolerance_ns`` in the past (a late arrival) acts now; an older one is refused.
    A stamp more than ``inputs.horizon`` ahead of the simulation time is refused, so that one
    message stamped in 2038 cannot lock a topic or hold a constant force for decades. At most
    :data:`MAX_PENDING_SHOCKS` shocks that have not ended and
    :data:`MAX_PENDING_BASE_ACCELERATION` future base-acceleration samples and
    :data:`MAX_PENDING_RATES` angular rates are held, and at most :data:`MAX_SHOCKS_PER_BLOCK`
    shocks are accepted between two blocks. A rate stamped before one already held replaces
    it (and everything held after it), so it is always taken; one stamped after them all is
    refused once the limit is reached. Each rate costs a bisection of the profile, whatever
    is held (``core.rate_profile``), so a flood costs the run a bounded time per message and
    every message is accepted or refused and counted. Drive,
    reset and parameter changes act at the current simulation time. A refused input changes
    nothing, is counted per topic (``rejected_<topic>`` on the diagnostics) and raises
    :class:`~ring_gyro_sim.core.errors.InputError` (or ``ParameterError``) with the reason.

Reset
    :class:`Reset` puts the ring at rest, clears a contact or a failure and discards
    everything pending: shocks not over, base-acceleration samples (so a later profile may
    start at any stamp), drive and parameter changes scheduled ahead, and the scheduled
    ``scenario.*`` shocks still to come. Not the angular rate: it is the motion of the case,
    not a state of the ring, so its profile (the scheduled knots and the streamed rates still
    to come) acts on after a reset. A reset cannot help while what drove the ring into
    contact is still in force (a drive too strong, the inputs that arrived after it): a
    contact or failure within :data:`RELAPSE_S` of a reset is a relapse, and its message
    (:meth:`Run.failure_text`: the diagnostics, the node's log and its next ``~/reset``
    answer) names what is in force instead of promising that a reset recovers.

Which model (``integrator.fidelity``)
    ``full``: the full model (``Simulator``) throughout. ``auto`` (the default) and
    ``averaged``: the averaged model (``core.engine.averaged.AveragedEngine``: the closed-loop
    gyroscope's slow flow, its blocks reconstructed from the envelopes) wherever it may run,
    the full model elsewhere. A run starts on the full model, which hands over at its first
    check if it may (its sense chain has then judged a sample). The averaged model hands
    over to the full one at the last loop update at or before anything scheduled that it
    does not integrate acts
    (``Simulator.next_scheduled_s``: a shock pulse, a base-acceleration sample, a parameter,
    drive or temperature change), and at once when an input other than an angular rate
    acts at the current time (a reset included); angular rates it integrates itself. The
    full model hands back at a hand-back check (every ``core.engine.handoff.CHECK_S`` of
    simulated time) that ``core.engine.handoff.may_hand_back`` allows (the one policy): the
    loops locked with force-to-rebalance and the drive at its set-point, the last ``~/rate``
    sample a measurement, nothing scheduled acting, the last input other than a rate
    ``CHECK_S`` ago or more, and the modes the averaged model leaves out rung down below
    ``HAND_BACK_THRESHOLD``. Never
    averaged: a gyroscope the averaged model does not run (``core.engine.handoff.refusal``:
    open loop, no rebalance, an environment, ``gyro.output_rate`` below ``control.rate``,
    ...). The rules read the state and the acting times of the inputs, never when an input
    arrived, so that a re-simulation (``--from``) makes the same hand-offs. ``averaged``
    differs from ``auto`` only in refusing, at the start, a gyroscope the averaged model
    cannot run. Each change of model goes to the sink (:meth:`Sink.handoff`: the
    recording's ``ring_gyro_sim.handoff`` metadata), the diagnostics (``model``,
    ``model_changes``) and the summary (``model_handoffs``).

Recording order
    The sink sees every accepted input when it acts, in simulation-time order, before the
    block that contains its time (:meth:`Sink.input`), so a recording is written in log-time
    order even for inputs accepted long before they act; an input discarded by a reset is
    never recorded, and so is an angular rate replaced before it acted (a rate replaces the
    profile after its time: the streamed rates and scheduled knots stamped later than it).
    Inputs are the inputs as they acted: their ``at_ns`` is the acting time.
"""

import collections
from dataclasses import asdict, dataclass, field, replace
import heapq
import json
import math
import time
from typing import Any, Callable, Deque, Dict, List, Mapping, Optional, Tuple, Union

import numpy as np

from ring_gyro_sim.core import thermal
from ring_gyro_sim.core.bench import factory
from ring_gyro_sim.core.engine import ENGINES, handoff
from ring_gyro_sim.core.engine.averaged import AveragedEngine
from ring_gyro_sim.core.engine.full import (channel_names, joined_samples, Samples, Simulator,
                                            Status)
from ring_gyro_sim.core.errors import InputError, ParameterError
from ring_gyro_sim.core.gyro import calibration as gyro_calibration, operating_point
from ring_gyro_sim.core.gyro.control import ControlSamples, update_rows
from ring_gyro_sim.core.gyro.electronics import DemodSamples, RateSamples
from ring_gyro_sim.core.gyro.stats import describe, DriveStats, RateStats
from ring_gyro_sim.core.params import SimConfig, TEMPERATURE_RANGE_K

__all__ = ['AmbientTemperature', 'AngularRate', 'BaseAcceleration', 'Block', 'Diagnostics',
           'DriveAmplitude', 'DriveFrequency', 'FINISHED',
           'Input', 'MAX_PENDING_BASE_ACCELERATION', 'MAX_PENDING_RATES', 'MAX_PENDING_SHOCKS',
           'MAX_SHOCKS_PER_BLOCK', 'NullSink',
           'PARAMETER_REFUSAL_KINDS',
           'Pacing', 'ParameterChange', 'Reset', 'Run', 'RunStats', 'RunSummary', 'Shock',
           'Sink', 'channel_names', 'format_number', 'load_kernels']

MAX_PENDING_SHOCKS = 1000
"""Shocks accepted and not over yet; beyond this a shock is refused."""
MAX_SHOCKS_PER_BLOCK = 10
"""Shocks accepted between two blocks; beyond this one is refused (each costs sub-steps:
a 10 000 /s flood must not buy unbounded work per block, nor vanish uncounted)."""
MAX_PENDING_BASE_ACCELERATION = 100_000
"""Base-acceleration samples stamped in the future; beyond this one is refused."""
MAX_PENDING_RATES = 1000
"""
Angular rates accepted that have not acted yet; beyond this a rate stamped after them all is
refused. A step profile streamed 1 s ahead at the 1 kHz of ``~/rate``: more ahead than that
belongs in ``scenario.rate_*``. Each holds two knots of the profile, which the simulator reads
once per block.
"""
RELAPSE_S = 0.1
"""A contact or failure within this simulated time (s) of a reset is a relapse (module doc)."""
SUMMARY_WINDOW_S = 0.01
"""Window (s) of the final amplitudes and of the q2 amplitude before the first shock."""
FINISHED = 'finished'
"""``RunSummary.status`` of a run that ended with the ring free (its simulator still
``running``): a summary describes a run that is over."""
PARAMETER_REFUSAL_KINDS = ('undeclared', 'read_only', 'range', 'invalid')
"""Kinds of refused parameter changes: the first three are refused by ROS before the run
sees them (``ros/parameters.py``), ``invalid`` by the run's validation."""
INPUT_TOPICS = ('shock', 'base_acceleration', 'drive/amplitude', 'drive/frequency',
                'events/reset', 'events/parameters', 'angular_rate', 'temperature')
"""Input topics (relative names) in the order the diagnostics list their counts."""


# ---------------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class Shock:
    """
    A half-sine shock (eq. 32): peak base acceleration (m/s^2) along x and y.

    ``z`` (out of plane) is not modelled: it must be finite and is otherwise ignored.
    """

    x: float
    y: float = 0.0
    at_ns: Optional[int] = None
    z: float = 0.0
    topic = 'shock'


@dataclass(frozen=True)
class BaseAcceleration:
    """One sample of a streamed base-acceleration profile, m/s^2, at ``at_ns`` (z as Shock)."""

    x: float
    y: float = 0.0
    at_ns: Optional[int] = None
    z: float = 0.0
    topic = 'base_acceleration'


@dataclass(frozen=True)
class DriveAmplitude:
    """Drive force on the 2theta mode per unit modal mass, m/s^2 (0 = off)."""

    value: float
    at_ns: Optional[int] = None
    topic = 'drive/amplitude'


@dataclass(frozen=True)
class DriveFrequency:
    """Drive frequency, Hz (the drive phase stays continuous)."""

    value_hz: float
    at_ns: Optional[int] = None
    topic = 'drive/frequency'


@dataclass(frozen=True)
class Reset:
    """The ring back at rest; everything pending discarded."""

    at_ns: Optional[int] = None
    topic = 'events/reset'


@dataclass(frozen=True)
class ParameterChange:
    """Parameters changed at run time, ``{dotted name: value}`` (validated when applied)."""

    changes: Mapping[str, Any]
    at_ns: Optional[int] = None
    topic = 'events/parameters'


@dataclass(frozen=True)
class AmbientTemperature:
    """
    The ambient temperature, K, from ``at_ns`` on: a step, held (``core.thermal``, T1).

    It replaces ``scenario.temperature_*`` after its time; the die follows it with
    ``thermal.time_constant``. ``~/temperature`` carries degrees Celsius (sensor_msgs), the
    run kelvin.
    """

    kelvin: float
    at_ns: Optional[int] = None
    topic = 'temperature'


@dataclass(frozen=True)
class AngularRate:
    """
    Angular rate of the sensor frame about z (the ring's axis), rad/s, REP-103 sign.

    It steps to ``z`` at ``at_ns`` and holds (needs ``gyro.enabled``). ``x`` and ``y`` (about
    in-plane axes) are not modelled: they must be finite and are otherwise ignored.
    """

    z: float
    at_ns: Optional[int] = None
    x: float = 0.0
    y: float = 0.0
    topic = 'angular_rate'


Input = Union[Shock, BaseAcceleration, DriveAmplitude, DriveFrequency, Reset, ParameterChange,
              AngularRate, AmbientTemperature]


# ---------------------------------------------------------------------------------- outputs
@dataclass(frozen=True)
class Block:
    """
    One advanced stretch of simulation.

    Attributes
    ----------
    samples : Samples
        Every channel at the new sample times.
    end_ns : int
        Simulation time of the last sample, ns (the block's log time).
    first_index : int
        Global index of the first sample (sample ``i`` is at ``(i + 1) * period``).
    rate, demod : RateSamples, DemodSamples or None
        With ``gyro.enabled``: the rate output (``~/rate``, at ``gyro.output_rate``) and the
        demodulator's channels at every sample (``~/demodulator``); None otherwise.
    control : ControlSamples or None
        With a closed ``control.mode``: the loops' updates in the block (``~/control``,
        at ``control.rate``; ``core.gyro.control.update_rows``); None otherwise.

    """

    samples: Samples
    end_ns: int
    first_index: int
    rate: Optional[RateSamples] = None
    demod: Optional[DemodSamples] = None
    control: Optional[ControlSamples] = None

    def __len__(self) -> int:
        return len(self.samples)


@dataclass(frozen=True)
class Pacing:
    """What the caller knows about wall-clock pacing (the node; offline: as fast as possible)."""

    target: float = 0.0
    achieved: float = 0.0
    average: float = 0.0
    lag_s: float = 0.0
    lag_warn: bool = False


@dataclass(frozen=True)
class Diagnostics:
    """
    A diagnostics snapshot: level ('OK', 'WARN', 'ERROR'), message and values.

    ``values`` always has the same keys in the same order (see :meth:`Run.diagnostics`).
    """

    t_ns: int
    level: str
    message: str
    values: Dict[str, Any]


class Sink:
    """
    Where a run's inputs, blocks and diagnostics go: a publisher, a recorder, a summary.

    The base class does nothing (it is the null sink); subclasses override what they need.
    Calls come in simulation-time order.
    """

    def start(self, state: Tuple[np.ndarray, np.ndarray]) -> None:
        """Take the start ``state`` = (q, v) (m, m/s): called once by :class:`Run`."""

    def set_calibration(self, calibration: Optional[Dict[str, Any]]) -> None:
        """Take the rate output's held calibration (``Calibration.to_dict``; None: ideal)."""

    def set_rate_variance(self, variance: float) -> None:
        """Take the predicted variance of the rate output, (rad/s)^2 (``gyro.enabled``)."""

    def input(self, event: Input) -> None:
        """Take an accepted event; it acts now (``event.at_ns``: its acting time, ns)."""

    @property
    def needs_channels(self) -> bool:
        """
        Tell whether the next block's samples must carry every channel (gaps, capacitances).

        True here (the block :meth:`Run.advance` returns has them). A sink that neither
        publishes nor records them says False: an averaged stretch then leaves them out
        (``Samples.gap`` None) and gives only their smallest gap, which the statistics take
        (``core.engine.averaged.AveragedEngine``).
        """
        return True

    def block(self, block: Block) -> None:
        """Take a simulated block; every sample in it is finite."""

    def diagnostics(self, diag: Diagnostics) -> None:
        """Take a diagnostics snapshot."""

    def handoff(self, at_ns: int, model: str) -> None:
        """Take a change of model at ``at_ns`` (``averaged`` or ``full`` from then on)."""

    def close(self) -> None:
        """End the run (finalise files)."""

    def discard(self) -> None:
        """Drop what was opened: the run never started (e.g. no start state)."""
        self.close()


class NullSink(Sink):
    """A sink that keeps nothing (no recorder, no publisher)."""


def load_kernels(config: SimConfig) -> None:
    """
    Run the models ``config`` may use for a moment, so that their kernels are compiled.

    For a paced run (the node), before its clock starts: numba compiles a kernel at its first
    call (or loads it from its disk cache), and a kernel first called inside the paced run
    would stall it for as long (tens of seconds of CPU on a first run). The full model runs a
    sample; when the averaged model may take over (``integrator.fidelity`` not ``full`` and
    the configuration not refused by ``core.engine.handoff``) the run goes on until it has,
    at most ``4 handoff.CHECK_S``, and one block further. A throwaway run without a sink:
    nothing is published or recorded, and the run that follows is not changed.
    """
    run = Run(config)
    block = max(1, int(round(config.run.block_duration * config.run.output_rate)))
    run.advance(block)
    if run.fidelity_reason is not None:
        return
    # whole blocks from 0, as the node advances: the averaged model runs whole loop periods
    limit = int(round(4.0 * handoff.CHECK_S * config.run.output_rate))
    while run.running and run.model != 'averaged' and run.sample_index < limit:
        run.advance(block)
    if run.running and run.model == 'averaged':
        run.advance(block)


def format_number(value: float, unit_scale: float = 1.0, digits: int = 4) -> str:
    """
    Format ``value * unit_scale`` with ``digits`` decimals, or in exponent form when huge.

    ``f'{1.7e308:.4f}'`` has 313 characters: a state blown up by a huge input must not print
    like that in a summary or a log line.
    """
    x = value * unit_scale
    if not math.isfinite(x) or abs(x) >= 1e9:
        return f'{x:.{digits}e}'
    return f'{x:.{digits}f}'


# ---------------------------------------------------------------------------------- statistics
class RunStats:
    """Peaks, smallest gaps and amplitude windows of a run (diagnostics and summaries)."""

    def __init__(self, names: List[str], period_ns: int, gap_m: float) -> None:
        self.names = list(names)
        self.period_ns = period_ns
        self.gap_m = gap_m
        self.peak = np.zeros(len(names))
        self.min_gap = math.inf
        self.interval_min_gap = math.inf
        self.last_min_gap = gap_m
        self.samples = 0
        self.keep = max(1, int(round(SUMMARY_WINDOW_S * 1e9 / period_ns)))
        self.tail_t = np.zeros(0, dtype=np.int64)
        self.tail_q = np.zeros((0, len(names)))
        self.first_shock_ns: Optional[int] = None
        self.before_shock: Optional[np.ndarray] = None

    def shock_at(self, at_ns: int) -> None:
        """Note a shock acting at ``at_ns`` (the first one sets the pre-shock window)."""
        if self.before_shock is None and (self.first_shock_ns is None
                                          or at_ns < self.first_shock_ns):
            self.first_shock_ns = int(at_ns)

    def add(self, s: Samples, end_index: int) -> None:
        """Add the samples of one block ending at global sample index ``end_index``."""
        if len(s) == 0:
            return
        self.samples += len(s)
        self.peak = np.maximum(self.peak, np.max(np.abs(s.q), axis=0))
        block_min = s.least_gap()
        self.min_gap = min(self.min_gap, block_min)
        self.interval_min_gap = min(self.interval_min_gap, block_min)
        self.last_min_gap = block_min
        t_ns = (np.arange(end_index - len(s), end_index) + 1) * self.period_ns
        all_t = np.concatenate([self.tail_t, t_ns[-self.keep:]])
        all_q = np.concatenate([self.tail_q, s.q[-self.keep:]])
        if (self.before_shock is None and self.first_shock_ns is not None
                and t_ns[-1] >= self.first_shock_ns):
            # The pulse starts at first_shock_ns: samples up to that time are unaffected.
            sel = t_ns <= self.first_shock_ns
            before = np.concatenate([self.tail_q[self.tail_t <= self.first_shock_ns],
                                     s.q[sel]])[-self.keep:]
            self.before_shock = (np.max(np.abs(before), axis=0) if len(before)
                                 else np.full(len(self.names), math.nan))
        self.tail_t = all_t[-self.keep:]
        self.tail_q = all_q[-self.keep:]

    def take_interval_min_gap(self) -> float:
        """Return the smallest gap (m) since the last call (the last block's if none since)."""
        value = (self.interval_min_gap if math.isfinite(self.interval_min_gap)
                 else self.last_min_gap)
        self.interval_min_gap = math.inf
        return value

    def final(self) -> Dict[str, float]:
        """Return max |q| per coordinate over the last :data:`SUMMARY_WINDOW_S`, m."""
        if len(self.tail_q) == 0:
            return {n: 0.0 for n in self.names}
        return {n: float(v) for n, v in zip(self.names, np.max(np.abs(self.tail_q), axis=0))}

    def text(self) -> str:
        """Return peak |q1|, smallest gap, q2 amplitude before the first shock and at the end."""
        if not math.isfinite(self.min_gap):
            return 'no block simulated'
        parts = [f'peak |q1| = {format_number(self.peak[0], 1e6)} um',
                 f'smallest gap = {format_number(self.min_gap, 1e6)} um '
                 f'({format_number(self.min_gap / self.gap_m, digits=3)} d_g)']
        if len(self.names) >= 2:
            window = f'{1e3 * SUMMARY_WINDOW_S:g} ms'
            if self.before_shock is not None and math.isfinite(self.before_shock[1]):
                parts.append(f'q2 amplitude {format_number(self.before_shock[1], 1e6)} um over '
                             f'the {window} before the first shock '
                             f'(t = {self.first_shock_ns * 1e-9:.6f} s)')
            elif self.first_shock_ns is None:
                parts.append('no shock')
            final = np.max(np.abs(self.tail_q), axis=0)
            parts.append(f'q2 amplitude {format_number(final[1], 1e6)} um over the last '
                         f'{window}')
        return ', '.join(parts)


@dataclass
class RunSummary:
    """
    Numbers of one run (SI units; ``*_m`` in metres), as ``ring_gyro run`` prints them.

    ``status`` is how the run ended: :data:`FINISHED` (the ring was free to the end),
    ``contact`` or ``failed`` (the simulator's status, with ``message``).
    """

    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    peak_abs_m: Dict[str, float]
    final_abs_m: Dict[str, float]
    min_gap_m: float
    contact: bool
    status: str
    message: str
    samples: int
    steps: int
    output: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> str:
        """
        Return one JSON object (a non-finite number, e.g. no gap seen yet, is null).

        The ``extra`` figures (the rate channel's, ``core.gyro.stats``) are top-level keys.
        """
        values = asdict(self)
        values.update(values.pop('extra'))
        return json.dumps(_finite_or_none(values), sort_keys=True, allow_nan=False)


def _finite_or_none(value):
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_or_none(v) for v in value]
    return value


# ---------------------------------------------------------------------------------- the run
class Run:
    """
    A Simulator with its start state, inputs, statistics, sink and diagnostics.

    Parameters
    ----------
    config : SimConfig
        Validated configuration (``scenario.*`` shocks are scheduled).
    start_state : (q, v), optional
        Initial coordinates (m) and velocities (m/s), for a run that continues a recorded
        one (``ring_gyro run --from``). None (the default): the run starts itself, at rest or
        on the drive's branch of ``drive.start_on``
        (``core.gyro.operating_point.start_state``: the orbit is computed once per device
        and drive and memoised).
    sink : Sink, optional
        Receives inputs as they act, blocks and diagnostics (default :class:`NullSink`).
    late_tolerance_ns : int
        How far in the past a stamp may be and still act now (the node: one block; offline:
        0, every input has its exact time).
    clock : callable
        Wall clock for the summary, s (``time.monotonic``).
    log : callable, optional
        Told what takes a while at construction (computing a start state, calibrating),
        one line each.
    calibration : Calibration, None or 'auto'
        The rate output's held calibration (``core.gyro.calibration``), for a run that
        continues a recorded one; ``'auto'`` (default): what ``gyro.calibration.source``
        asks for (``factory``: measured once per device and memoised).

    """

    def __init__(self, config: SimConfig, start_state=None, sink: Optional[Sink] = None,
                 late_tolerance_ns: int = 0,
                 clock: Callable[[], float] = time.monotonic,
                 log: Optional[Callable[[str], None]] = None,
                 calibration: Any = 'auto') -> None:
        if start_state is None:  # on the device at the die's start temperature (T2)
            start_state = operating_point.start_state(thermal.start_state_device(config), log)
        if isinstance(calibration, str) and calibration == 'auto':
            calibration = factory.for_config(config, log)
        self.calibration: Optional[gyro_calibration.Calibration] = calibration
        self._stretch: Optional[AveragedEngine] = None
        self._stale = False
        self._sim = Simulator(config, start_state, calibration=calibration)
        random = self.full_model().random_vibration
        if random is not None and log is not None:
            r = config.run
            log(f'random vibration: {random.rms_g:.4g} g rms, '
                f'{r.vibration_psd_frequencies[0]:g} .. {r.vibration_psd_frequencies[-1]:g} '
                f'Hz along {r.vibration_angle:g} deg, a multisine of {random.lines.size} '
                f'lines that repeats every {random.n / r.output_rate:.4g} s '
                f'(doc/environments.md)')
        self.start_state: Tuple[np.ndarray, np.ndarray] = (self.full_model().q.copy(),
                                                           self.full_model().v.copy())
        self.rate_stats: Optional[RateStats] = None
        if config.gyro.enabled:
            self.rate_stats = RateStats(config.gyro.output_rate)
        self.drive_stats: Optional[DriveStats] = (
            DriveStats(self.full_model().loop) if self.full_model().loop is not None else None)
        self.sink: Sink = sink if sink is not None else NullSink()
        if self.full_model().sense is not None:
            self.sink.set_rate_variance(self.full_model().sense.electronics.rate_variance())
            self.sink.set_calibration(None if calibration is None else calibration.to_dict())
        self.late_tolerance_ns = int(late_tolerance_ns)
        self.stats = RunStats(self._sim.coordinates, self._sim.period_ns, self._sim.model.gap)
        self.rejected: Dict[str, int] = {topic: 0 for topic in INPUT_TOPICS}
        self.accepted: Dict[str, int] = {topic: 0 for topic in INPUT_TOPICS}
        self.lost: Dict[str, int] = {}
        self.parameter_refusals: Dict[str, int] = {k: 0 for k in PARAMETER_REFUSAL_KINDS}
        self.blocks = 0
        self._clock = clock
        self._wall0: Optional[float] = None
        self._to_sink: List[Tuple[int, int, Input]] = []  # heap of (acting ns, seq, input)
        # The angular rates (streamed and scheduled knots) that have not acted yet, in
        # (acting ns, seq) order: a rate replaces those after its time, as in the profile.
        self._rates_to_sink: Deque[Tuple[int, int, AngularRate]] = collections.deque()
        self._seq = 0
        self._shock_ends: List[int] = []  # heap of end times of accepted shocks, ns
        self._shocks_this_block = 0
        self._future_profile: List[int] = []  # heap of future base-acceleration stamps, ns
        self._reset_ns: Optional[int] = None  # the last reset, ns
        for at_ns, x, y in config.run.scheduled_shocks():
            # The Simulator scheduled these itself; recorded on ~/shock as if they had arrived.
            self._accept_shock(Shock(x=x, y=y, at_ns=at_ns))
        for t_s, rate in zip(config.run.rate_times, config.run.rate_values):
            # The knots of the scheduled profile (the Simulator has them), recorded on
            # ~/angular_rate at their times: a linear profile's knots, not steps.
            self._accepted(AngularRate(z=float(rate), at_ns=int(round(t_s * 1e9))))
        self.sink.start(self.start_state)
        # the model of each stretch (integrator.fidelity, module docstring)
        self.fidelity = config.integrator.fidelity
        self.handoffs: List[Tuple[float, str]] = []
        self._last_input_ns = -(1 << 62)  # the latest acting time of an input not a rate
        self._check_samples = max(1, int(round(handoff.CHECK_S / self._sim.period_s)))
        self.fidelity_reason: Optional[str] = (
            'integrator.fidelity: full' if self.fidelity == 'full'
            else handoff.refusal(config))
        if self.fidelity == 'averaged' and self.fidelity_reason is not None:
            raise ParameterError(f'integrator.fidelity: averaged, but {self.fidelity_reason}')
        if self._may_hand_back():
            self._to_averaged()
        else:
            self._handoff('full')

    # ------------------------------------------------------------------ properties
    def full_model(self) -> Simulator:
        """
        Return the full model, holding the state now.

        After an averaged stretch the averaged model's state is handed to it first (S14),
        so that whatever reads or changes it sees the run's state now.
        """
        if self._stale:
            self._stretch.sync()
            self._stale = False
        return self._sim

    @property
    def model(self) -> str:
        """Return the model running now: ``averaged`` or ``full``."""
        return 'averaged' if self._stretch is not None else 'full'

    @property
    def config(self) -> SimConfig:
        """Return the configuration in force."""
        return self._sim.config

    @property
    def time_ns(self) -> int:
        """Return the simulation time, ns (the end of the last block)."""
        return self._sample_index() * self._sim.period_ns

    @property
    def time_s(self) -> float:
        """Return the simulation time, s."""
        return self._sample_index() * self._sim.period_s

    @property
    def sample_index(self) -> int:
        """Return the global index of the next sample (the samples simulated so far)."""
        return self._sample_index()

    @property
    def period_ns(self) -> int:
        """Return the sample period, ns (``output.rate``)."""
        return self._sim.period_ns

    def _sample_index(self) -> int:
        return (self._stretch.sample_index if self._stretch is not None
                else self._sim.sample_index)

    @property
    def channel_names(self) -> Dict[str, List[str]]:
        """Return the channel names of the block outputs (``Simulator.channel_names``)."""
        return self._sim.channel_names

    @property
    def running(self) -> bool:
        """Tell whether the ring is free (not in contact, not failed)."""
        return self._sim.status == Status.RUNNING

    @property
    def pending_shocks(self) -> int:
        """Return the number of accepted shocks that have not ended."""
        return len(self._shock_ends)

    @property
    def pending_inputs(self) -> int:
        """Return the number of accepted inputs stamped after the current simulation time."""
        now = self.full_model().time_ns
        return (sum(1 for t_ns, _, _ in self._to_sink if t_ns > now)
                + sum(1 for t_ns, _, _ in self._rates_to_sink if t_ns > now))

    # ------------------------------------------------------------------ inputs
    def apply(self, event: Input) -> int:
        """
        Validate an input, schedule it and return the simulation time (ns) it acts at.

        Raises
        ------
        InputError, ParameterError
            Refused (counted under ``event.topic``); nothing changed.

        """
        try:
            at_ns = self._apply(event)
        except (InputError, ParameterError):
            self.count_rejected(event.topic)
            raise
        if (self._stretch is not None and not isinstance(event, AngularRate)
                and at_ns <= self.time_ns):
            # it acted on the full model already (at the current time): it goes on from it
            self._to_full()
        return at_ns

    def _apply(self, event: Input) -> int:
        sim = self.full_model()
        if isinstance(event, (Shock, BaseAcceleration)) and not all(
                math.isfinite(v) for v in (event.x, event.y, event.z)):
            raise InputError(f'not finite: x = {event.x!r}, y = {event.y!r}, z = {event.z!r}')
        if isinstance(event, AngularRate) and not all(
                math.isfinite(v) for v in (event.x, event.y, event.z)):
            raise InputError(f'not finite: x = {event.x!r}, y = {event.y!r}, z = {event.z!r}')
        if isinstance(event, Shock):
            return self._accept_shock(event, schedule=True)
        if isinstance(event, BaseAcceleration):
            at_ns = self.acting_time(event.at_ns)
            if len(self._future_profile) >= MAX_PENDING_BASE_ACCELERATION:
                raise InputError(f'{MAX_PENDING_BASE_ACCELERATION} samples are already pending')
            sim.add_base_acceleration(at_ns, event.x, event.y)
            heapq.heappush(self._future_profile, at_ns)
            event = replace(event, z=0.0)
        elif isinstance(event, AngularRate):
            at_ns = self.acting_time(event.at_ns)
            pending = self._rates_to_sink
            if len(pending) >= MAX_PENDING_RATES and pending[-1][0] <= at_ns:
                raise InputError(f'{MAX_PENDING_RATES} angular rates are already pending '
                                 f'(stamped ahead, none after this one)')
            sim.set_rate(at_ns, float(event.z))
            # The profile dropped its knots after at_ns: the rates that held them never act,
            # so they are never recorded (a recording holds the inputs as they acted).
            while pending and pending[-1][0] > at_ns:
                pending.pop()
        elif isinstance(event, AmbientTemperature):
            kelvin = float(event.kelvin)
            low, high = TEMPERATURE_RANGE_K
            if not (math.isfinite(kelvin) and low <= kelvin <= high):
                raise InputError(f'temperature: must be within {low:g} .. {high:g} K '
                                 f'(the temperature laws of core.thermal), got {kelvin!r}')
            at_ns = self.acting_time(event.at_ns)
            sim.set_ambient(kelvin, at_ns=at_ns)
        elif isinstance(event, DriveAmplitude):
            at_ns = self._now_only(event.at_ns)
            sim.set_drive(amplitude=float(event.value), at_ns=at_ns)
        elif isinstance(event, DriveFrequency):
            at_ns = self._now_only(event.at_ns)
            sim.set_drive(frequency_hz=float(event.value_hz), at_ns=at_ns)
        elif isinstance(event, Reset):
            at_ns = self._now_only(event.at_ns)
            if at_ns != sim.time_ns:
                raise InputError('reset: acts at the current simulation time only')
            sim.reset()
            self._discard_pending()
            self._reset_ns = at_ns
        elif isinstance(event, ParameterChange):
            at_ns = self._now_only(event.at_ns)
            sim.update_parameters(event.changes, at_ns=at_ns)
            if self.fidelity != 'full':   # the averaged model may (no longer) run it
                self.fidelity_reason = handoff.refusal(sim.config)
        else:
            raise InputError(f'unknown input {event!r}')
        self._accepted(replace(event, at_ns=at_ns))
        return at_ns

    def acting_time(self, at_ns: Optional[int]) -> int:
        """
        Return the simulation time (ns) an input stamped ``at_ns`` acts at (None: now).

        Raises
        ------
        InputError
            Too far in the past (beyond ``late_tolerance_ns``) or beyond ``inputs.horizon``.

        """
        now = self.full_model().time_ns
        if at_ns is None:
            return now
        at_ns = int(at_ns)
        if at_ns >= now:
            horizon_ns = int(round(self.config.run.input_horizon * 1e9))
            if at_ns - now > horizon_ns:
                raise InputError(
                    f'stamp {at_ns * 1e-9:.9f} s is {(at_ns - now) * 1e-9:.6g} s ahead of the '
                    f'simulation time {now * 1e-9:.9f} s, beyond inputs.horizon '
                    f'({self.config.run.input_horizon:g} s)')
            return at_ns
        if now - at_ns <= self.late_tolerance_ns:
            return now
        raise InputError(f'stamp {at_ns * 1e-9:.9f} s is {(now - at_ns) * 1e-9:.6f} s in the '
                         f'past (simulation time {now * 1e-9:.9f} s, tolerance '
                         f'{self.late_tolerance_ns * 1e-9:g} s)')

    def _now_only(self, at_ns: Optional[int]) -> int:
        """Drive, reset and parameter changes act at a sample time at or after ``at_ns``."""
        t = self.acting_time(at_ns)
        period = self.full_model().period_ns
        return -(-t // period) * period

    def shock_refusal(self) -> Optional[str]:
        """
        Return why any shock would be refused now, whatever it holds (None: one may be accepted).

        :data:`MAX_PENDING_SHOCKS` are pending, or :data:`MAX_SHOCKS_PER_BLOCK` were accepted
        since the last block. A caller facing a flood may then refuse the waiting shocks
        without decoding them (:meth:`refuse_shocks`): the outcome is what :meth:`apply` would
        give each of them.
        """
        if len(self._shock_ends) >= MAX_PENDING_SHOCKS:
            return f'{MAX_PENDING_SHOCKS} shocks are already pending'
        if self._shocks_this_block >= MAX_SHOCKS_PER_BLOCK:
            return (f'{MAX_SHOCKS_PER_BLOCK} shocks were already accepted since the last block '
                    f'(a flood)')
        return None

    def refuse_shocks(self, count: int) -> None:
        """Count ``count`` shocks refused for :meth:`shock_refusal`'s reason, not decoded."""
        self.rejected[Shock.topic] = self.rejected.get(Shock.topic, 0) + int(count)

    def _accept_shock(self, event: Shock, schedule: bool = False) -> int:
        if schedule:
            at_ns = self.acting_time(event.at_ns)
            refusal = self.shock_refusal()
            if refusal is not None:
                raise InputError(refusal)
            self.full_model().shock(event.x, event.y, at_ns=at_ns)
            self._shocks_this_block += 1
        else:
            at_ns = int(event.at_ns)
        heapq.heappush(self._shock_ends,
                       at_ns + int(round(self.config.shock_duration_s * 1e9)))
        self.stats.shock_at(at_ns)
        if self.rate_stats is not None:
            self.rate_stats.shock_at(at_ns * 1e-9)
        if self.drive_stats is not None:
            self.drive_stats.shock_at(at_ns * 1e-9)
        self._accepted(replace(event, at_ns=at_ns, z=0.0))
        return at_ns

    def _accepted(self, event: Input) -> None:
        self.accepted[event.topic] = self.accepted.get(event.topic, 0) + 1
        if isinstance(event, AngularRate):
            self._rates_to_sink.append((int(event.at_ns), self._seq, event))  # in time order
        else:
            heapq.heappush(self._to_sink, (int(event.at_ns), self._seq, event))
        self._seq += 1

    def _discard_pending(self) -> None:
        """
        Forget what a reset discarded (the Simulator dropped it too).

        Not the angular rates: the sensor frame keeps turning (``Simulator.reset``), so the
        rates still to come act after the reset and are recorded when they do.
        """
        now = self.full_model().time_ns
        self._flush_inputs(now)
        self._to_sink = []
        self._shock_ends = []
        self._future_profile = []
        self.stats.first_shock_ns = (self.stats.first_shock_ns
                                     if self.stats.before_shock is not None else None)

    def _flush_inputs(self, up_to_ns: int) -> None:
        heap, rates = self._to_sink, self._rates_to_sink
        while True:
            if heap and heap[0][0] <= up_to_ns and (not rates or heap[0][:2] < rates[0][:2]):
                _, _, event = heapq.heappop(heap)
            elif rates and rates[0][0] <= up_to_ns:
                _, _, event = rates.popleft()
            else:
                return
            if not isinstance(event, AngularRate):
                self._last_input_ns = max(self._last_input_ns, int(event.at_ns))
            self.sink.input(event)

    def count_rejected(self, topic: str, kind: str = 'invalid') -> None:
        """
        Count a refused input of ``topic``; :meth:`apply` calls it, and so may the caller.

        The caller counts what is refused before it reaches :meth:`apply` (a ROS parameter
        refused by its descriptor: ``kind`` one of :data:`PARAMETER_REFUSAL_KINDS`).
        """
        self.rejected[topic] = self.rejected.get(topic, 0) + 1
        if topic == ParameterChange.topic:
            self.parameter_refusals[kind] = self.parameter_refusals.get(kind, 0) + 1

    def count_lost(self, topic: str, count: int) -> None:
        """Count ``count`` messages of ``topic`` that the middleware reports lost."""
        self.lost[topic] = self.lost.get(topic, 0) + int(count)

    # ------------------------------------------------------------------ advancing
    def advance_for(self, duration_s: float,
                    progress: Optional[Callable[[float], None]] = None) -> bool:
        """
        Advance by ``duration_s`` (whole output periods) in blocks; stop early at contact.

        ``progress`` is called with the simulated time (s) after each block. Returns whether
        the whole duration was simulated.
        """
        total = int(round(duration_s / (self.config.run.output_period_ns * 1e-9)))
        block = self.config.run.block_samples
        done = 0
        while done < total and self.running:
            count = min(block, total - done)
            self.advance(count)
            done += count
            if progress is not None:
                progress(self.time_s)
        return done >= total

    def advance(self, n_samples: int,
                between: Optional[Callable[[], None]] = None) -> Block:
        """
        Advance by ``n_samples`` output periods and hand the block to the sink.

        ``between`` is called while the block is computed, after every stretch
        (``Simulator.advance_samples``; the node sends the ``~/rate`` messages that are due).

        Every value of the block is finite: a non-finite one is a failure of the run, which
        the Simulator reports (``Status.FAILED``) and holds with finite values, so that the
        stream and the recording never have a hole.
        """
        if self._wall0 is None:
            self._wall0 = self._clock()
        sim = self._sim
        first = self._sample_index()
        self._shocks_this_block = 0
        samples = self._advance(int(n_samples), between)
        end_ns = self.time_ns
        self._flush_inputs(end_ns)
        while self._shock_ends and self._shock_ends[0] <= end_ns:
            heapq.heappop(self._shock_ends)
        while self._future_profile and self._future_profile[0] <= end_ns:
            heapq.heappop(self._future_profile)
        rate, demod = samples.rate_output, samples.demod
        self.stats.add(samples, self._sample_index())
        if rate is not None and self.rate_stats is not None:
            at = np.clip(np.searchsorted(samples.t, rate.t), 0, max(0, len(samples) - 1))
            self.rate_stats.add(rate, samples.applied_rate[at])
        if self.drive_stats is not None and samples.control is not None:
            self.drive_stats.add(samples.t, samples.control)
        updates = None
        if sim.loop is not None and samples.control is not None:
            updates = update_rows(first, samples.t, samples.control, sim.loop.window,
                                  sim.period_s)
        block = Block(samples=samples, end_ns=end_ns, first_index=first, rate=rate,
                      demod=demod, control=updates)
        self.blocks += 1
        self.sink.block(block)
        return block

    def _advance(self, count: int, between: Optional[Callable[[], None]]) -> Samples:
        """
        Advance by ``count`` samples on the model of each stretch (module docstring).

        Averaged up to the last loop update at or before the next scheduled input the full
        model must simulate, full from there; full up to the next hand-back check (every
        :data:`~ring_gyro_sim.core.engine.handoff.CHECK_S` of simulated time), averaged from a
        check that allows it.
        """
        sim = self._sim
        parts: List[Samples] = []
        while count > 0:
            stretch = self._stretch
            if stretch is not None:
                window = sim.loop.window
                now = stretch.sample_index
                limit = count - count % window
                fast = sim.next_scheduled_s()
                if not math.isinf(fast):
                    stop = int(math.floor(fast / sim.period_s + 1e-9)) // window * window
                    limit = min(limit, max(0, stop - now))
                if limit > 0:
                    parts.append(stretch.advance_samples(limit, channels=self.sink.needs_channels))
                    self._stale = True
                    count -= limit
                    if between is not None:
                        between()
                if count > 0:
                    self._to_full()
                continue
            step = count
            if self.fidelity_reason is None:   # the hand-back checks (CHECK_S)
                step = min(count, self._check_samples - sim.sample_index % self._check_samples)
            parts.append(sim.advance_samples(step, between))
            count -= step
            if sim.sample_index % self._check_samples == 0 and self._may_hand_back():
                self._to_averaged()
        if not parts:
            return sim.advance_samples(0)
        return parts[0] if len(parts) == 1 else joined_samples(parts)

    def _may_hand_back(self) -> bool:
        """
        Whether the full model may hand over to the averaged one now (``handoff``'s policy).

        At fidelity ``auto`` or ``averaged``, with the refusal of the configuration in force;
        the inputs that have acted are handed to the sink first, once the state allows it.
        """
        if self.fidelity == 'full':
            return False
        sim = self._sim
        loop = sim.loop
        if (sim.status == Status.RUNNING and not sim.in_stop_contact and loop is not None
                and sim.sample_index and sim.sample_index % loop.window == 0):
            self.fidelity_reason = handoff.refusal(sim.config)

        def last_input_ns() -> int:
            self._flush_inputs(sim.time_ns)
            return self._last_input_ns
        return handoff.may_hand_back(sim, self.fidelity_reason, last_input_ns,
                                     self._check_samples)

    def _to_averaged(self) -> None:
        self._stretch = ENGINES['averaged'](self._sim)
        self._stale = False
        self._handoff('averaged')

    def _to_full(self) -> None:
        self.full_model()   # the averaged model's state handed to the full model
        self._stretch = None
        self._handoff('full')

    def _handoff(self, model: str) -> None:
        at_ns = self._sim.time_ns
        self.handoffs.append((at_ns * 1e-9, model))
        self.sink.handoff(at_ns, model)

    # ------------------------------------------------------------------ reporting
    def diagnostics(self, pacing: Pacing = Pacing(), finished: bool = False) -> Diagnostics:
        """
        Take a diagnostics snapshot and hand it to the sink.

        Keys (always all of them, in this order): ``sim_time_s``, ``real_time_factor_target``,
        ``real_time_factor_achieved`` (over the last interval), ``real_time_factor_average``,
        ``lag_s``, ``steps``, ``blocks``, ``min_gap_m`` and ``min_gap_ratio`` (smallest outer
        gap since the last snapshot), ``min_gap_ratio_run``, ``contact``, ``status``,
        ``rejected_inputs`` and ``rejected_<topic>`` per input topic,
        ``rejected_parameter_changes`` and ``rejected_parameter_<kind>`` (kinds of
        :data:`PARAMETER_REFUSAL_KINDS`), ``rejected_angular_rate``, ``lost_inputs`` (messages
        the middleware reports lost), ``pending_shocks``, ``pending_inputs``, ``accepted_shocks``,
        ``accepted_angular_rate``, ``drive_amplitude``, ``drive_frequency_hz``,
        ``nonfinite_failures`` (``Simulator.nonfinite_failures``), ``stop_impacts`` (impacts
        on the mechanical stops, ``Simulator.impacts``: 0 without them), ``model`` (the model
        running now: ``averaged`` or ``full``) and ``model_changes`` (hand-offs so far).
        """
        sim = self.full_model()
        stats = self.stats
        self._flush_inputs(sim.time_ns)
        gap = stats.take_interval_min_gap()
        values: Dict[str, Any] = {
            'sim_time_s': sim.time_s,
            'real_time_factor_target': pacing.target,
            'real_time_factor_achieved': pacing.achieved,
            'real_time_factor_average': pacing.average,
            'lag_s': pacing.lag_s,
            'steps': sim.steps_taken,
            'blocks': self.blocks,
            'min_gap_m': gap,
            'min_gap_ratio': gap / stats.gap_m,
            'min_gap_ratio_run': (stats.min_gap / stats.gap_m
                                  if math.isfinite(stats.min_gap) else 1.0),
            'contact': not self.running,
            'status': str(sim.status),
            'rejected_inputs': sum(self.rejected.values()),
        }
        for topic in INPUT_TOPICS[:4]:
            values[f'rejected_{topic.replace("/", "_")}'] = self.rejected[topic]
        values['rejected_reset'] = self.rejected['events/reset']
        values['rejected_parameter_changes'] = self.rejected['events/parameters']
        for kind, count in self.parameter_refusals.items():
            values[f'rejected_parameter_{kind}'] = count
        values['rejected_angular_rate'] = self.rejected['angular_rate']
        values['rejected_temperature'] = self.rejected['temperature']
        values['lost_inputs'] = sum(self.lost.values())
        values['pending_shocks'] = self.pending_shocks
        values['pending_inputs'] = self.pending_inputs
        values['accepted_shocks'] = self.accepted['shock']
        values['accepted_angular_rate'] = self.accepted['angular_rate']
        drive = sim.config.drive
        values['drive_amplitude'] = drive.amplitude
        values['drive_frequency_hz'] = drive.frequency
        values['nonfinite_failures'] = sim.nonfinite_failures
        values['stop_impacts'] = sim.impacts
        values['model'] = self.model
        values['model_changes'] = len(self.handoffs) - 1
        values['die_temperature_k'] = float(sim.die.kelvin)
        values['ambient_temperature_k'] = float(sim.die.ambient.at(sim.time_s))
        gyro_warning = ''
        if sim.loop is not None:
            loop = sim.loop.diagnostics_values()
            values.update(loop)
            if not loop['pll_locked']:
                gyro_warning = (f'PLL out of lock since t = {sim.loop.unlocked_since_s:.6f} s '
                                f'(phase error {loop["pll_phase_error_rad"]:.3g} rad)')
        if self.full_model().sense is not None:
            gyro = self.full_model().sense.diagnostics_values()
            values.update(gyro)
            if not gyro['rate_valid'] and not gyro_warning:
                # The rate channel's own verdict (core.gyro.validity), from what the sensor
                # measures: not a measurement, or its variance inflated by a transient.
                reason = gyro['rate_invalid_reason'] or (
                    f'a transient: sigma {gyro["rate_sigma_rad_s"]:.3g} rad/s')
                gyro_warning = (f'~/rate is not a measurement: {reason} (drive pick-off at '
                                f'{gyro.get("drive_amplitude_ratio", math.nan):.3g} of its '
                                f'operating point)')
        if not self.running:
            level, message = 'ERROR', self.failure_text()
        elif gyro_warning:
            level, message = 'WARN', gyro_warning
        elif pacing.lag_warn:
            level = 'WARN'
            message = f'falling behind real time by {pacing.lag_s / pacing.target:.2f} s'
        else:
            level, message = 'OK', 'finished' if finished else 'running'
        diag = Diagnostics(t_ns=sim.time_ns, level=level, message=message, values=values)
        self.sink.diagnostics(diag)
        return diag

    def relapse(self) -> Optional[str]:
        """
        Return why a reset does not help, if the ring is in contact again right after one.

        None while running, or when the contact or failure came more than :data:`RELAPSE_S`
        after the last reset (or with no reset before it).
        """
        sim = self.full_model()
        if self.running or self._reset_ns is None or not math.isfinite(sim.contact_time_s):
            return None
        after_s = sim.contact_time_s - self._reset_ns * 1e-9
        if not 0.0 <= after_s <= RELAPSE_S:
            return None
        return (f'again {after_s * 1e3:.3g} ms after the reset at t = '
                f'{self._reset_ns * 1e-9:.6f} s: a reset does not help while what drives the '
                f'ring there is in force ({self.in_force()})')

    def in_force(self) -> str:
        """Return the inputs in force now that can drive the ring, in words."""
        sim = self.full_model()
        config = sim.config
        parts = []
        if sim.gyro:
            rate = float(sim.rates_at(np.array([sim.time_ns], dtype=np.int64))[0])
            parts.append(f'angular rate {rate:.6g} rad/s')
        if sim.loop is not None:
            parts.append(f'closed-loop drive, set-point {sim.loop.setpoint_m * 1e6:.4g} um')
        elif config.drive.amplitude != 0.0:
            parts.append(f'drive {config.drive.amplitude:.6g} m/s^2 at '
                         f'{config.drive.frequency:.6g} Hz')
        e = config.electrodes
        parts.append(f'electrodes.outer_voltage {e.outer_voltage:g} V'
                     + (f', electrodes.inner_voltage {e.inner_voltage:g} V'
                        if e.inner_voltage else ''))
        if self._shock_ends:
            parts.append(f'{len(self._shock_ends)} shocks not over')
        if self._future_profile:
            parts.append(f'{len(self._future_profile)} base-acceleration samples ahead')
        return ', '.join(parts)

    def failure_text(self) -> str:
        """
        Return the contact or failure in words, and what a reset will do about it.

        ``'<status>: <where and when> (~/reset recovers)'``, or after a relapse
        (:meth:`relapse`) what is in force instead of the promise; '' while running.
        """
        if self.running:
            return ''
        sim = self.full_model()
        relapse = self.relapse()
        return (f'{sim.status}: {sim.message}; {relapse}' if relapse is not None
                else f'{sim.status}: {sim.message} (~/reset recovers)')

    def wall_time_s(self) -> float:
        """Return the wall time since the first block, s."""
        return self._clock() - self._wall0 if self._wall0 is not None else 0.0

    def summary(self, output: Optional[str] = None) -> RunSummary:
        """Return the run's numbers (``ring_gyro run``); ``status`` as the run ended."""
        sim = self.full_model()
        wall = self.wall_time_s()
        return RunSummary(
            sim_time_s=sim.time_s, wall_time_s=wall,
            real_time_factor=sim.time_s / wall if wall > 0 else math.inf,
            peak_abs_m={n: float(v) for n, v in zip(sim.coordinates, self.stats.peak)},
            final_abs_m=self.stats.final(), min_gap_m=self.stats.min_gap,
            contact=not self.running,
            status=FINISHED if self.running else str(sim.status), message=sim.message,
            samples=self.stats.samples, steps=sim.steps_taken, output=output,
            extra=self._environment_figures())

    def _environment_figures(self) -> Dict[str, Any]:
        """
        Return :meth:`stop_figures`, :meth:`gyro_figures` and the random vibration's rms (g).

        The rms only if a random vibration is on.
        """
        out = {**self.stop_figures(), **self.gyro_figures(), **self.fidelity_figures()}
        if self.full_model().random_vibration is not None:
            out['random_vibration_rms_g'] = self.full_model().random_vibration.rms_g
        return out

    def fidelity_figures(self) -> Dict[str, Any]:
        """
        Return the models of the run: ``model_handoffs`` and why it is full throughout.

        ``model_handoffs``: ``[[t_s, model], ...]`` from the start (``averaged`` or ``full``
        from ``t_s`` on); ``fidelity_reason``: why the averaged model never ran, when it did
        not.
        """
        out: Dict[str, Any] = {'model_handoffs': [[t, model] for t, model in self.handoffs]}
        if all(model == 'full' for _, model in self.handoffs):
            out['fidelity_reason'] = self.fidelity_reason
        return out

    def stop_figures(self) -> Dict[str, Any]:
        """Return the mechanical stops' figures (``stop_impacts``), {} without stops."""
        if not self.full_model().config.stops.enabled:
            return {}
        return {'stop_impacts': self.full_model().impacts}

    def gyro_figures(self) -> Dict[str, Any]:
        """
        Return the rate channel's and the drive loop's figures, {} without either.

        ``core.gyro.stats.RateStats`` with the gyroscope on, ``DriveStats`` with the closed
        loop.
        """
        out: Dict[str, Any] = {}
        if self.drive_stats is not None:
            out.update(self.drive_stats.figures())
        if self.full_model().sense is None or self.rate_stats is None:
            return out
        out.update(self.rate_stats.figures())
        diag = self.full_model().sense.diagnostics_values()
        if self.calibration is not None:
            out.update({f'calibration_{k}': v for k, v in self.calibration.to_dict().items()})
        else:
            out['calibration_source'] = 'ideal'
        for key in ('rate_scale_factor_v_per_rad_s', 'scale_factor_valid',
                    'drive_amplitude_ratio', 'predicted_arw_deg_per_sqrt_h', 'bandwidth_hz'):
            if key in diag:
                out[key if key.startswith('rate_') else f'rate_{key}'] = diag[key]
        return out

    def summary_text(self) -> str:
        """Return the run's numbers in one line (the node's log), the gyroscope's included."""
        text = self.stats.text()
        if self.full_model().config.stops.enabled:
            text += f'; {self.full_model().impacts} impacts on the stops'
        gyro = describe(self.gyro_figures())
        if gyro:
            text += f'; {gyro}'
        if any(model == 'averaged' for _, model in self.handoffs):
            text += '; models: ' + ', '.join(f'{model} from {t:.6g} s'
                                             for t, model in self.handoffs)
        if not self.running:
            text += f'; {self.full_model().status}: {self.full_model().message}'
        return text

    def close(self) -> None:
        """Close the sink (finalise a recording). Idempotent through the sink."""
        self._flush_inputs(self.full_model().time_ns)
        sink, self.sink = self.sink, NullSink()
        sink.close()
