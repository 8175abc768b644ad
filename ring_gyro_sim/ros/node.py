# Copyright 2025 ring_gyro_sim developers
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
``ring_gyro_node``: the vibrating-ring gyroscope as a ROS 2 node (default name ``ring_gyro``).

Run it with ``ring_gyro_node --ros-args --params-file config/default.yaml`` (or
``python -m ring_gyro_sim.ros.node ...``). The topics, parameters and services are those of
``interface.md``; this docstring says how the node keeps them.

Pacing
    A steady-clock timer advances the :class:`~ring_gyro_sim.core.simulator.Simulator` in
    blocks of ``output.block_duration`` so that simulation time follows the wall clock times
    ``real_time_factor`` (0 = as fast as possible). A block is computed and published once its
    last sample time has been reached. When the computer cannot keep up, simulation time falls
    behind but no block is ever skipped: the lag and the achieved factor are on
    ``/diagnostics``. One timer callback works at most ``TICK_BUDGET_S`` of wall time, so
    inputs and services are served between blocks even when running as fast as possible;
    before each block the input messages waiting in the queues are taken, at most
    ``SHOCK_DRAIN_PER_BLOCK`` shocks (the executor alone takes one per subscription per wait,
    which starves inputs while the node lags).
    ``duration`` > 0 ends the run after that much simulated time; SIGINT or SIGTERM end it
    at the next block boundary. Either way: final diagnostics, a summary in the log (peak
    |q1|, smallest gap, q2 amplitude before the first shock and over the last 10 ms), the
    recording finalised, exit code 0. A signal before that, during start-up, ends the
    process at once, exit code 0, without a traceback (see ``ring_gyro_sim.ros``). A bad
    parameter file or value, an unwritable ``record.path`` or a failed ``drive.start_on``
    orbit: one FATAL line naming the parameter, exit code 1.

Parameter handling
    Declared from the one table (``ros/parameters.py``), dynamically typed so that integer
    literals work for floats. Those a running simulation can take (voltages, Q factors,
    drive, ``shock.duration``, ``real_time_factor``) are validated by rebuilding the whole
    configuration; a refusal gives the reason ('<name>: <reason>') and changes nothing, an
    accepted change acts at the current simulation time and is recorded. The others are
    read-only.

Inputs and the simulation time they act at
    The current simulation time is the end of the last published block. ``~/shock`` and
    ``~/base_acceleration`` act at their stamp when it is in the future; a zero stamp, or a
    stamp at most one block in the past (a late arrival), means the current simulation time;
    an older stamp is rejected. ``~/drive/amplitude``, ``~/drive/frequency``, ``~/reset`` and
    parameter changes act at the current simulation time. Every accepted input is recorded at
    the time it acts; every rejected one (non-finite value, negative frequency, stamp too far
    in the past, too many pending shocks, ...) changes nothing, is counted on
    ``/diagnostics`` and logged with its reason (at most every 5 s per topic and kind).

QoS
    Block topics (``~/modal_displacement``, ``~/radial_gap``, ``~/sense_electrodes``):
    reliable, volatile, keep last 50. A subscriber with the default QoS (reliable, volatile,
    keep last 10) connects and receives every block as long as it keeps up with
    ``1 / output.block_duration`` messages per second; a best-effort subscriber connects too
    but may lose blocks. Inputs: reliable, keep last 100 (``~/shock``), 1000
    (``~/base_acceleration``) and 10 (drive): a flood is dropped by the middleware queue,
    never stored without bound. ``/diagnostics`` and ``/clock``: reliable, keep last 10.

Diagnostics (about 1 Hz, one status named ``<node name>: simulator``, stamped with the
simulation time)
    OK while running, WARN when more than ``LAG_WARN_S`` of wall time behind, ERROR in contact
    / pull-in (the message gives time and place; the node stays up and ``~/reset``
    recovers). Keys: ``sim_time_s``, ``real_time_factor_target``,
    ``real_time_factor_achieved`` (over the last interval), ``real_time_factor_average``
    (since the start), ``lag_s`` (simulated seconds behind the wall-clock target), ``steps``,
    ``blocks``, ``min_gap_m`` and ``min_gap_ratio`` (smallest outer gap since the last
    message, absolute and per d_g), ``min_gap_ratio_run`` (since the start), ``contact``,
    ``status``, ``rejected_inputs`` (all topics) and ``rejected_<topic>``,
    ``rejected_parameter_changes``, ``pending_shocks``, ``accepted_shocks``, ``drive_amplitude``,
    ``drive_frequency_hz``.
"""

# Google import order, as ament_flake8 checks it (style.md); ruff's default isort order differs.
# isort: off
import collections
import heapq
import math
import re
import signal
import sys
import time
from typing import Dict, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import AccelStamped, Vector3Stamped
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from ring_gyro_sim.core.errors import InputError, ParameterError, RingGyroError
from ring_gyro_sim.core.simulator import Samples, Simulator
from ring_gyro_sim.ros import conversions, EARLY_SIGNALS, parameters
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
# isort: on

BLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
SHOCK_QUEUE_DEPTH = 100
BASE_ACCELERATION_QUEUE_DEPTH = 1000
DRIVE_QUEUE_DEPTH = 10
MAX_PENDING_SHOCKS = 1000
# Shocks taken from the queue per block besides the executor's one per wait: every shock
# costs sub-steps (T_s / 16), so a flood must not buy unbounded work per block.
SHOCK_DRAIN_PER_BLOCK = 10
"""Shocks accepted but not over yet; beyond this a shock is rejected."""
MAX_PENDING_BASE_ACCELERATION = 100_000
"""Base-acceleration samples stamped in the future; beyond this one is rejected."""
DIAGNOSTICS_PERIOD_S = 1.0
TICK_BUDGET_S = 0.05
"""Most wall time one timer callback spends on blocks before serving inputs and services."""
LAG_WARN_S = 0.5
"""Wall seconds behind the real-time target from which /diagnostics says WARN."""
REJECT_LOG_PERIOD_S = 5.0
SUMMARY_WINDOW_S = 0.01
"""Window (s) of the q2 amplitudes in the summary: before the first shock and at the end."""
HARDWARE_ID = 'ring_gyro_sim'
_NUMBER = re.compile(r'[-+]?\d[\d.]*(e[-+]?\d+)?')


class RunStats:
    """Peaks, smallest gap and amplitudes for the diagnostics and the end-of-run summary."""

    def __init__(self, names: List[str], period_ns: int, gap_m: float) -> None:
        self.names = names
        self.period_ns = period_ns
        self.gap_m = gap_m
        self.peak = np.zeros(len(names))
        self.min_gap = math.inf
        self.interval_min_gap = math.inf
        self.last_min_gap = gap_m
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
        """Add the samples of one block ending at sample ``end_index``."""
        if len(s) == 0:
            return
        self.peak = np.maximum(self.peak, np.max(np.abs(s.q), axis=0))
        block_min = float(np.min(s.min_gap))
        self.min_gap = min(self.min_gap, block_min)
        self.interval_min_gap = min(self.interval_min_gap, block_min)
        self.last_min_gap = block_min
        t_ns = (np.arange(end_index - len(s), end_index) + 1) * self.period_ns
        all_t = np.concatenate([self.tail_t, t_ns])
        all_q = np.concatenate([self.tail_q, s.q])
        if (self.before_shock is None and self.first_shock_ns is not None
                and t_ns[-1] >= self.first_shock_ns):
            # The pulse starts at first_shock_ns: samples up to that time are unaffected.
            before = all_q[all_t <= self.first_shock_ns][-self.keep:]
            self.before_shock = (np.max(np.abs(before), axis=0) if len(before)
                                 else np.full(len(self.names), math.nan))
        self.tail_t = all_t[-self.keep:]
        self.tail_q = all_q[-self.keep:]

    def take_interval_min_gap(self) -> float:
        """Return the smallest gap (m) since the last call (the last block's if none since)."""
        value = self.interval_min_gap if math.isfinite(self.interval_min_gap) \
            else self.last_min_gap
        self.interval_min_gap = math.inf
        return value

    def summary(self) -> str:
        """Return peak |q1|, smallest gap, q2 amplitude before the first shock and at the end."""
        if not math.isfinite(self.min_gap):
            return 'no block simulated'
        parts = [f'peak |q1| = {1e6 * self.peak[0]:.4f} um',
                 f'smallest gap = {1e6 * self.min_gap:.4f} um '
                 f'({self.min_gap / self.gap_m:.3f} d_g)']
        if len(self.names) >= 2:
            window = f'{1e3 * SUMMARY_WINDOW_S:g} ms'
            if self.before_shock is not None and math.isfinite(self.before_shock[1]):
                parts.append(f'q2 amplitude {1e6 * self.before_shock[1]:.4f} um over the '
                             f'{window} before the first shock '
                             f'(t = {self.first_shock_ns * 1e-9:.6f} s)')
            elif self.first_shock_ns is None:
                parts.append('no shock')
            final = np.max(np.abs(self.tail_q), axis=0)
            parts.append(f'q2 amplitude {1e6 * final[1]:.4f} um over the last {window}')
        return ', '.join(parts)


class RingGyroNode(Node):
    """The simulator behind topics, parameters and a reset service (see the module doc)."""

    def __init__(self, node_name: str = 'ring_gyro', **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        self.recorder = None
        self.stop_requested: Optional[str] = None
        try:
            self._start()
        except RingGyroError as exc:
            self.get_logger().fatal(f'cannot start: {exc}')
            self.close(summary=False)
            raise
        except BaseException:  # e.g. a signal during start-up: leave no open recording
            self.close(summary=False)
            raise

    # ------------------------------------------------------------------ start-up
    def _start(self) -> None:
        log = self.get_logger()
        config = parameters.declare_parameters(self)
        for name in parameters.unknown_overrides(self):
            log.warn(f'ignoring {name!r}: not a parameter of ring_gyro_sim')
        self.sim = Simulator(config)
        Simulator(config).advance_samples(1)  # load the compiled kernels before pacing
        self.initial_state = None
        if config.drive.start_on != 'rest':
            from ring_gyro_sim.analysis.nnm import drive_initial_state
            log.info(f'computing the start state ({config.drive.start_on} of the drive at '
                     f'{config.drive.frequency} Hz)')
            self.initial_state = drive_initial_state(config)
        if self.initial_state is not None:
            self.sim.set_state(*self.initial_state)
        self.channels = self.sim.channel_names
        self.stats = RunStats(self.sim.coordinates, self.sim.period_ns, self.sim.model.gap)
        self.block_samples = max(1, int(round(config.run.block_duration / self.sim.period_s)))
        self.tolerance_ns = self.block_samples * self.sim.period_ns
        self.total_samples = (int(round(config.run.duration / self.sim.period_s))
                              if config.run.duration > 0.0 else 0)
        self.finished = Future()
        self._done = False
        self._pending_shocks: List[int] = []  # heap of end times, ns
        self._accepted_shocks = 0
        self._pending_profile: collections.deque = collections.deque()
        self._rejected: Dict[str, int] = {}
        self._reject_log: Dict[Tuple[str, str], Tuple[float, int]] = {}
        self._rejected_parameters = 0
        self._ignored_z = set()
        self._contact_logged = False
        self._nonfinite_blocks = 0
        self.blocks = 0
        if config.run.record_path:
            from ring_gyro_sim.ros.recorder import RunRecorder
            try:
                self.recorder = RunRecorder(
                    config.run.record_path, config, self.channels,
                    self.get_fully_qualified_name(), self.initial_state,
                    config.run.publish_clock)
            except (OSError, RingGyroError) as exc:
                raise ParameterError(f'record.path: {exc}') from None
        for t_s, peak in zip(config.run.shock_times, config.run.shock_peaks):
            at_ns = int(round(t_s * 1e9))  # the Simulator scheduled these itself
            self.stats.shock_at(at_ns)
            heapq.heappush(self._pending_shocks,
                           at_ns + int(round(config.shock_duration_s * 1e9)))
            if self.recorder is not None:
                self.recorder.shock(at_ns, peak, 0.0)

        self.block_pubs = {name: self.create_publisher(Float64MultiArray, f'~/{name}',
                                                       BLOCK_QOS)
                           for name in conversions.OUTPUT_TOPICS}
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.clock_pub = (self.create_publisher(ClockMsg, '/clock', 10)
                          if config.run.publish_clock else None)
        self._input_subs = [
            (self.create_subscription(Vector3Stamped, '~/shock', self._on_shock,
                                      SHOCK_QUEUE_DEPTH), self._on_shock, SHOCK_DRAIN_PER_BLOCK),
            (self.create_subscription(AccelStamped, '~/base_acceleration',
                                      self._on_base_acceleration,
                                      BASE_ACCELERATION_QUEUE_DEPTH),
             self._on_base_acceleration, BASE_ACCELERATION_QUEUE_DEPTH),
            (self.create_subscription(Float64, '~/drive/amplitude', self._on_drive_amplitude,
                                      DRIVE_QUEUE_DEPTH), self._on_drive_amplitude,
             DRIVE_QUEUE_DEPTH),
            (self.create_subscription(Float64, '~/drive/frequency', self._on_drive_frequency,
                                      DRIVE_QUEUE_DEPTH), self._on_drive_frequency,
             DRIVE_QUEUE_DEPTH),
        ]
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.tick_timer = None
        self._pace_wall0: Optional[float] = None
        self._pace_sim0_ns = 0
        self._start_wall: Optional[float] = None
        self._start_sim_ns = self.sim.time_ns
        self._diag_wall = time.monotonic()
        self._diag_sim_ns = self.sim.time_ns
        self._restart_tick_timer()
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._on_diagnostics_timer, clock=self.steady)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        run = config.run
        log.info(
            f'simulating {", ".join(self.sim.coordinates)}, '
            f'output at {run.output_rate:g} Hz in blocks of {self.block_samples} samples, '
            f'real_time_factor {run.real_time_factor:g}, '
            f'duration {"unlimited" if not run.duration else f"{run.duration:g} s"}'
            + (f', recording to {run.record_path}' if self.recorder is not None else ''))

    @property
    def real_time_factor(self) -> float:
        """The pacing target in force."""
        return self.sim.config.run.real_time_factor

    def _restart_tick_timer(self) -> None:
        if self.tick_timer is not None:
            self.destroy_timer(self.tick_timer)
        rtf = self.real_time_factor
        block_wall_s = self.block_samples * self.sim.period_s / rtf if rtf > 0 else 0.0
        period = min(max(block_wall_s / 4.0, 0.001), 0.02)
        self.tick_timer = self.create_timer(period, self._on_tick, clock=self.steady)

    # ------------------------------------------------------------------ pacing
    def _target_ns(self, now: float, rtf: Optional[float] = None) -> float:
        """Return the simulation time (ns) due at wall time ``now`` (inf: as fast as possible)."""
        rtf = self.real_time_factor if rtf is None else rtf
        if rtf <= 0.0 or self._pace_wall0 is None:
            return math.inf
        return self._pace_sim0_ns + (now - self._pace_wall0) * rtf * 1e9

    def _rebase_pacing(self, old_rtf: float) -> None:
        """Keep the target continuous (and so the lag) across a change of real_time_factor."""
        if self._pace_wall0 is None:
            return  # pacing starts with the first tick
        now = time.monotonic()
        target = self._target_ns(now, old_rtf)
        self._pace_sim0_ns = target if math.isfinite(target) else self.sim.time_ns
        self._pace_wall0 = now

    def _on_tick(self) -> None:
        if self._done:
            return
        if self.stop_requested:
            self._finish(f'stopped ({self.stop_requested})')
            return
        now = time.monotonic()
        if self._pace_wall0 is None:
            self._pace_wall0 = self._start_wall = self._diag_wall = now
            self._pace_sim0_ns = self._start_sim_ns = self._diag_sim_ns = self.sim.time_ns
        deadline = now + TICK_BUDGET_S
        while True:
            n = self.block_samples
            if self.total_samples:
                n = min(n, self.total_samples - self.sim.sample_index)
                if n <= 0:
                    self._finish('duration reached')
                    return
            if self.sim.time_ns + n * self.sim.period_ns > self._target_ns(now):
                return
            self._drain_inputs()
            self._step(n)
            now = time.monotonic()
            if now >= deadline:
                return

    def _drain_inputs(self) -> None:
        """
        Take the input messages waiting in the subscription queues, before a block.

        All of them, but at most ``SHOCK_DRAIN_PER_BLOCK`` shocks (each costs sub-steps).

        The executor takes one message per subscription per wait, and a node that lags
        keeps its timer ready at every wait: without this a backlog (after a flood) would
        drain at one message per tick and a later input would act seconds late.
        """
        for sub, handler, most in self._input_subs:
            for _ in range(most):
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                handler(taken[0])

    def _step(self, n: int) -> None:
        """Advance one block, publish and record it."""
        samples = self.sim.advance_samples(n)
        t_ns = self.sim.time_ns
        self.stats.add(samples, self.sim.sample_index)
        if self.sim.status != 'running' and not self._contact_logged:
            self._contact_logged = True
            self.get_logger().error(f'{self.sim.message} (call ~/reset to recover)')
            self._publish_diagnostics()
        if not all(np.all(np.isfinite(a)) for a in
                   (samples.q, samples.gap, samples.min_gap, samples.capacitance)):
            self._nonfinite_blocks += 1  # never published; the Simulator should prevent it
            self.get_logger().error(f'non-finite output at t = {t_ns * 1e-9:.9f} s withheld',
                                    throttle_duration_sec=REJECT_LOG_PERIOD_S)
            return
        blocks = conversions.output_blocks(samples, self.channels)
        for name, msg in blocks.items():
            self.block_pubs[name].publish(msg)
        if self.clock_pub is not None:
            self.clock_pub.publish(conversions.clock_message(t_ns))
        if self.recorder is not None:
            self.recorder.outputs(blocks, t_ns)
            self.recorder.clock(t_ns)
        self.blocks += 1
        while self._pending_shocks and self._pending_shocks[0] <= t_ns:
            heapq.heappop(self._pending_shocks)
        while self._pending_profile and self._pending_profile[0] <= t_ns:
            self._pending_profile.popleft()

    def _finish(self, why: str) -> None:
        """End the run: final diagnostics and summary; main() then closes the recording."""
        self._done = True
        self._publish_diagnostics()
        self.get_logger().info(f'{why}: {self.summary()}')
        self.finished.set_result(why)

    def summary(self) -> str:
        """Return simulated and wall time and the run's numbers in one line."""
        wall = time.monotonic() - self._start_wall if self._start_wall is not None else 0.0
        sim_s = (self.sim.time_ns - self._start_sim_ns) * 1e-9
        rate = f' (x{sim_s / wall:.3f} real time)' if wall > 0 else ''
        text = f'{self.sim.time_s:.6f} s simulated in {wall:.3f} s{rate}; {self.stats.summary()}'
        if self.sim.status != 'running':
            text += f'; {self.sim.status}: {self.sim.message}'
        if self.recorder is not None:
            text += f'; recorded to {self.sim.config.run.record_path}'
        return text

    # ------------------------------------------------------------------ inputs
    def _input_time(self, at_ns: Optional[int]) -> int:
        """Return the simulation time (ns) an input stamped ``at_ns`` acts at (None: now)."""
        now = self.sim.time_ns
        if at_ns is None or at_ns >= now:
            return now if at_ns is None else int(at_ns)
        if now - at_ns <= self.tolerance_ns:
            return now
        raise InputError(f'stamp {at_ns * 1e-9:.9f} s is {(now - at_ns) * 1e-9:.6f} s in the '
                         f'past (simulation time {now * 1e-9:.9f} s, tolerance '
                         f'{self.tolerance_ns * 1e-9:g} s)')

    def _reject(self, topic: str, reason: str) -> None:
        """Count a rejected input; log it, at most every few seconds per topic and kind."""
        self._rejected[topic] = self._rejected.get(topic, 0) + 1
        kind = (topic, _NUMBER.sub('#', reason))
        now = time.monotonic()
        last, suppressed = self._reject_log.get(kind, (-math.inf, 0))
        if now - last < REJECT_LOG_PERIOD_S:
            self._reject_log[kind] = (last, suppressed + 1)
            return
        more = f' ({suppressed} more like it since the last message)' if suppressed else ''
        self.get_logger().warn(f'rejected ~/{topic}: {reason}{more}')
        self._reject_log[kind] = (now, 0)

    def _check_in_plane(self, topic: str, value: conversions.AccelerationInput) -> None:
        if not value.finite():
            raise InputError(f'not finite: x = {value.x!r}, y = {value.y!r}, z = {value.z!r}')
        if value.z != 0.0 and topic not in self._ignored_z:
            self._ignored_z.add(topic)
            self.get_logger().warn(f'~/{topic}: the z component is ignored (in-plane ring)')

    def _on_shock(self, msg: Vector3Stamped) -> None:
        s = conversions.shock_input(msg)
        try:
            self._check_in_plane('shock', s)
            at_ns = self._input_time(s.at_ns)
            if len(self._pending_shocks) >= MAX_PENDING_SHOCKS:
                raise InputError(f'{MAX_PENDING_SHOCKS} shocks are already pending')
            self.sim.shock(s.x, s.y, at_ns=at_ns)
        except InputError as exc:
            self._reject('shock', str(exc))
            return
        end_ns = at_ns + int(round(self.sim.config.shock_duration_s * 1e9))
        heapq.heappush(self._pending_shocks, end_ns)
        self._accepted_shocks += 1
        self.stats.shock_at(at_ns)
        if self.recorder is not None:
            self.recorder.shock(at_ns, s.x, s.y)

    def _on_base_acceleration(self, msg: AccelStamped) -> None:
        a = conversions.base_acceleration_input(msg)
        try:
            self._check_in_plane('base_acceleration', a)
            at_ns = self._input_time(a.at_ns)
            if len(self._pending_profile) >= MAX_PENDING_BASE_ACCELERATION:
                raise InputError(f'{MAX_PENDING_BASE_ACCELERATION} samples are already pending')
            self.sim.add_base_acceleration(at_ns, a.x, a.y)
        except InputError as exc:
            self._reject('base_acceleration', str(exc))
            return
        self._pending_profile.append(at_ns)
        if self.recorder is not None:
            self.recorder.base_acceleration(at_ns, a.x, a.y)

    def _on_drive_amplitude(self, msg: Float64) -> None:
        self._set_drive('drive/amplitude', amplitude=float(msg.data))

    def _on_drive_frequency(self, msg: Float64) -> None:
        self._set_drive('drive/frequency', frequency_hz=float(msg.data))

    def _set_drive(self, topic: str, **change) -> None:
        try:
            self.sim.set_drive(**change)
        except InputError as exc:
            self._reject(topic, str(exc))
            return
        if self.recorder is not None:
            self.recorder.drive(self.sim.time_ns, **change)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response):
        t_ns = self.sim.time_ns
        self.sim.reset()
        self._contact_logged = False
        if self.recorder is not None:
            self.recorder.reset(t_ns)
        response.success = True
        response.message = f'ring at rest at simulation time {t_ns * 1e-9:.9f} s'
        self.get_logger().info(response.message)
        return response

    def _on_set_parameters(self, params) -> SetParametersResult:
        old_rtf = self.real_time_factor
        try:
            config, changed = parameters.updated_config(self.sim.config, params)
            if changed:
                self.sim.reconfigure(config)
        except (ParameterError, InputError) as exc:
            self._rejected_parameters += 1
            self.get_logger().warn(f'parameter change refused: {exc}')
            return SetParametersResult(successful=False, reason=str(exc))
        if not changed:
            return SetParametersResult(successful=True)
        t_ns = self.sim.time_ns
        if self.recorder is not None:
            self.recorder.parameters(t_ns, changed)
        if self.real_time_factor != old_rtf:
            self._rebase_pacing(old_rtf)
            self._restart_tick_timer()
        self.get_logger().info(f'parameters applied at simulation time {t_ns * 1e-9:.9f} s: '
                               + ', '.join(f'{k} = {v}' for k, v in changed.items()))
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ diagnostics
    def _on_diagnostics_timer(self) -> None:
        if not self._done:
            self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        sim = self.sim
        rtf = self.real_time_factor
        target = self._target_ns(now)
        lag_s = max(0.0, (target - sim.time_ns) * 1e-9) if math.isfinite(target) else 0.0
        wall = now - self._diag_wall
        achieved = (sim.time_ns - self._diag_sim_ns) * 1e-9 / wall if wall > 0 else 0.0
        self._diag_wall, self._diag_sim_ns = now, sim.time_ns
        total_wall = now - self._start_wall if self._start_wall is not None else 0.0
        average = ((sim.time_ns - self._start_sim_ns) * 1e-9 / total_wall
                   if total_wall > 0 else 0.0)
        gap = self.stats.take_interval_min_gap()
        values = {
            'sim_time_s': sim.time_s,
            'real_time_factor_target': rtf,
            'real_time_factor_achieved': achieved,
            'real_time_factor_average': average,
            'lag_s': lag_s,
            'steps': sim.steps_taken,
            'blocks': self.blocks,
            'min_gap_m': gap,
            'min_gap_ratio': gap / self.stats.gap_m,
            'min_gap_ratio_run': (self.stats.min_gap / self.stats.gap_m
                                  if math.isfinite(self.stats.min_gap) else 1.0),
            'contact': sim.status != 'running',
            'status': sim.status,
            'rejected_inputs': sum(self._rejected.values()),
        }
        for topic in ('shock', 'base_acceleration', 'drive/amplitude', 'drive/frequency'):
            values[f'rejected_{topic.replace("/", "_")}'] = self._rejected.get(topic, 0)
        values['rejected_parameter_changes'] = self._rejected_parameters
        values['pending_shocks'] = len(self._pending_shocks)
        values['accepted_shocks'] = self._accepted_shocks
        drive = sim.config.drive
        values['drive_amplitude'] = drive.amplitude
        values['drive_frequency_hz'] = drive.frequency
        if self._nonfinite_blocks:
            values['withheld_nonfinite_blocks'] = self._nonfinite_blocks
        if sim.status != 'running':
            level, message = 'ERROR', f'{sim.status}: {sim.message} (~/reset recovers)'
        elif rtf > 0 and lag_s / rtf > LAG_WARN_S:
            level, message = 'WARN', f'falling behind real time by {lag_s / rtf:.2f} s'
        else:
            level, message = 'OK', 'finished' if self._done else 'running'
        msg = conversions.diagnostics_message(sim.time_ns, f'{self.get_name()}: simulator',
                                              HARDWARE_ID, level, message, values)
        self.diag_pub.publish(msg)
        if self.recorder is not None:
            self.recorder.diagnostics(msg, sim.time_ns)

    # ------------------------------------------------------------------ shutdown
    def close(self, summary: bool = True) -> None:
        """Finalise the recording (idempotent); log a summary if the run did not finish."""
        if summary and not getattr(self, '_done', True):
            self._done = True
            print(f'[ring_gyro_node] stopped: {self.summary()}', file=sys.stderr)
        recorder, self.recorder = self.recorder, None
        if recorder is not None:
            recorder.close()


class _StopOnSignal:
    """SIGINT / SIGTERM handler: the first one asks the node to end its run cleanly."""

    def __init__(self) -> None:
        self.node: Optional[RingGyroNode] = None

    def __call__(self, signum, frame) -> None:
        node = self.node
        if node is None or node.stop_requested:
            raise KeyboardInterrupt  # before the node exists, or a second signal
        # Only a flag here: the next timer callback (<= 20 ms) ends the run with the context
        # still up, so the final diagnostics and the summary are still published.
        node.stop_requested = signal.Signals(signum).name


def main(args=None) -> int:
    """Entry point of ``ring_gyro_node``: exit code 0 on a clean end, 1 if it cannot start."""
    try:
        # The node handles SIGINT and SIGTERM itself (below) instead of rclpy's handlers,
        # which would shut the context down before the summary and diagnostics go out.
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # noqa: B902 - rcl reports a bad params file as RCLError
        print(f'[FATAL] [ring_gyro_node]: cannot start: {exc}', file=sys.stderr)
        return 1
    stop = _StopOnSignal()
    previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    code = 0
    try:
        if EARLY_SIGNALS:  # during the imports or rclpy.init: end before starting
            name = signal.Signals(EARLY_SIGNALS[0]).name
            print(f'[INFO] [ring_gyro_node]: stopped ({name}) during start-up', file=sys.stderr)
            return 0
        node = RingGyroNode()
        stop.node = node
        rclpy.spin_until_future_complete(node, node.finished)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RingGyroError as exc:
        code = 1
        if node is not None:  # start-up errors are logged by the node, naming the parameter
            node.get_logger().fatal(str(exc))
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return code


if __name__ == '__main__':
    sys.exit(main())
