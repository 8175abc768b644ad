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
``doc/interface.md``. The simulation itself is a :class:`~ring_gyro_sim.run.Run` (the one run
path: when inputs act, refusals, statistics, diagnostics keys); this node adds only pacing and
ROS plumbing, and this docstring says how it keeps them.

Pacing
    A steady-clock timer advances the run in blocks of ``output.block_duration`` so that
    simulation time follows the wall clock times ``real_time_factor`` (0 = as fast as
    possible). A block is computed and published once its last sample time has been reached.
    When the computer cannot keep up, simulation time falls behind but no block is ever
    skipped: the lag and the achieved factor are on ``/diagnostics``. One timer callback works
    at most ``TICK_BUDGET_S`` of wall time, so inputs and services are served between blocks
    even when running as fast as possible; before each block the input messages waiting in the
    queues are taken (the executor alone takes one per subscription per wait, which starves
    inputs while the node lags). With the gyroscope, ``~/rate`` is paced
    (``ros/rate_pacer.py``): its messages go out at their sample times, ``RATE_LATENCY_BLOCKS``
    (2) blocks of simulated time after them, a pair at a time, so that a best-effort
    subscriber (``qos_profile_sensor_data``, keep last 5) that keeps up gets every one. Paced
    so, the timer ticks every ``MAX_TICK_PERIOD_S`` (100 ms) and a tick serves ``~/rate``
    until ``TICK_MARGIN_S`` before the next: it sleeps until each pair is due (no executor
    turn, no thread), computes each block as it falls due (sending what falls due meanwhile,
    after every loop update closed loop), and returns for the executor's turn, the only
    time no message goes out. Services and parameter changes wait for the end of a tick, at
    most 0.1 s (inputs are taken before every block and act at the next block either way);
    a turn builds rclpy's wait set in Python (about a millisecond of CPU), so the fewer
    turns the smaller the node's share of a core (doc/performance.md). ``duration`` > 0
    ends the run after that much simulated time; SIGINT or SIGTERM end it at the next block
    boundary. Either way: final diagnostics, a summary in the log (peak |q1|, smallest gap,
    q2 amplitude before the first shock and over the last 10 ms), the recording finalised,
    exit code 0. A signal before that, during start-up, ends the process at once, exit code
    0, without a traceback (see ``ring_gyro_sim.ros``). A bad parameter file or value, an
    unwritable ``record.path`` or a failed ``drive.start_on`` orbit: one FATAL line naming
    the parameter, exit code 1; so does another node of the same name in the graph
    ("Start-up").

    The node is spun with ``SingleThreadedExecutor.spin_once`` in a loop, not
    ``spin_until_future_complete``: rclpy (Jazzy) adds a done-callback to the future on
    every wake there (ros2/rclpy#1371), which grew the process by ~110 kB/s.

Start-up
    Another node of the same fully qualified name in the ROS graph is refused: two nodes of
    one name would publish on the same topics, interleaved, and record different runs with
    nothing to tell them apart, which a warning would not undo. Before it publishes anything
    the node looks once (after its parameters, start state and kernels: what discovery found
    meanwhile); then for its first ``NAMESAKE_WATCH_S`` (5 s) it looks again every
    ``NAMESAKE_CHECK_PERIOD_S`` (0.1 s), since discovery may take longer (up to 2.35 s under
    load). Found, the node stops: one FATAL line naming the name, its recording
    deleted, exit code 1; a namesake found late may have seen a few seconds of its blocks.
    Two nodes started within those seconds of each other both stop. Waiting for discovery
    before the first block instead (2.5 s) made every start 2.4 s longer. After its first
    seconds a node does not stop for a newcomer, but logs an ERROR once when one appears
    (every diagnostics period it looks). A node whose parameters are refused does not look.

Parameter handling
    Declared from the one table (``ros/parameters.py``), dynamically typed so that integer
    literals work for floats. Those a running simulation can take (voltages, Q factors,
    drive, ``shock.duration``, ``real_time_factor``, ``inputs.horizon``) are validated by
    rebuilding the whole configuration; a refusal gives the reason ('<name>: <reason>') and
    changes nothing, an accepted change acts at the current simulation time and is recorded.
    The others are read-only.

Inputs and the simulation time they act at
    See :mod:`ring_gyro_sim.run`: the current simulation time is the end of the last
    published block; ``~/shock``, ``~/base_acceleration``, ``~/angular_rate`` and
    ``~/temperature`` (sensor_msgs/Temperature, Celsius; the ambient, K in the run) act at their
    stamp (a zero stamp: now; up to one block late: now; older: refused; beyond
    ``inputs.horizon`` ahead: refused), ``~/drive/*``, ``~/reset`` and parameter changes now.
    ``~/angular_rate`` is always subscribed; without ``gyro.enabled`` the run refuses it
    (counted, and logged with the reason). Its ``vector.x`` and ``.y`` are not modelled: a
    non-zero value is ignored with one warning, as the z of ``~/shock``. Every refusal changes
    nothing, is counted on ``/diagnostics`` and logged with its reason (at most every 5 s per
    topic and kind). ``~/reset`` also discards everything pending.

QoS
    Block topics (``~/modal_displacement``, ``~/radial_gap``, ``~/sense_electrodes``):
    reliable, volatile, keep last 50. A subscriber with the default QoS (reliable, volatile,
    keep last 10) connects and receives every block as long as it keeps up with
    ``1 / output.block_duration`` messages per second; a best-effort subscriber connects too
    but may lose blocks. Inputs: reliable, keep last 1000 (``~/shock``,
    ``~/base_acceleration``) and 10 (drive), drained completely before every block: a flood
    is refused and counted by the run (pending limits), never stored without bound. Once the
    run refuses every shock until the next block (``run.MAX_SHOCKS_PER_BLOCK`` accepted), the
    shocks still waiting are taken undecoded and counted as refused: 10 000 shocks per second
    cost the node 1.1-1.5 times what they cost a process that only receives them and takes them
    raw (the middleware's reliable receive, tens of us each; doc/performance.md, "The node under
    a shock flood"), and the node keeps its pace through them (``test/ros/test_node.py``, the
    flood test).
    ``~/angular_rate`` has no such shortcut (a rate stamped before those held is always taken,
    so a refusal depends on each stamp), but each rate costs the run a bisection of the
    profile whatever is held (``run.MAX_PENDING_RATES``): 5 000 rates per second stamped ahead
    leave the node paced and every one accepted or refused and counted
    (``test/ros/test_node_gyro.py``, the rate flood test).
    ``/diagnostics`` and ``/clock``: reliable, keep last 10. The gyroscope (``gyro.enabled``;
    the publishers exist only then): ``~/demodulator`` as the block topics, ``~/rate``
    (sensor_msgs/Imu, one message per rate sample, paced: above) reliable, keep last 500;
    ``~/angular_rate`` reliable, keep last 1000; ``~/die_temperature`` (sensor_msgs/Temperature,
    one per block) reliable, keep last 10. ``~/temperature``: reliable, keep last 100. The
    closed loop
    (a closed ``control.mode``; the publisher exists only then): ``~/control``, the
    loops' updates (one row per update, at ``control.rate``), as the block topics
    (:mod:`ring_gyro_sim.ros.qos`).

Diagnostics (about 1 Hz)
    One status named ``<node>: simulator``, ``hardware_id`` ``ring_gyro_sim:<fully
    qualified node name>``, stamped with the node's clock (ROS time; the simulation time only
    with ``use_sim_time``). OK while running, WARN when more than ``LAG_WARN_S`` of wall time
    behind, ERROR in contact / pull-in (the message gives time and place; the node stays up and
    ``~/reset`` recovers, unless the contact came right after a reset: then the message, the
    log and the next ``~/reset`` answer name what is in force, ``Run.failure_text``). The keys
    are those of :meth:`ring_gyro_sim.run.Run.diagnostics`.
"""

# Google import order, as ament_flake8 checks it; ruff's default isort order differs.
# isort: off
import math
import re
import signal
import sys
import time
from typing import Optional

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import AccelStamped, Vector3Stamped
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks, UnsupportedEventTypeError
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from ring_gyro_sim import run as run_mod
from ring_gyro_sim.core.errors import InputError, ParameterError, RingGyroError
from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.kernels import cache
from ring_gyro_sim.paramfile import check_node_arguments
from ring_gyro_sim.recording.errors import RecordingError
from ring_gyro_sim.ros import conversions, EARLY_SIGNALS, parameters, qos
from ring_gyro_sim.ros.rate_pacer import GROUP, RatePacer
from ring_gyro_sim.ros.recorder import RunRecorder
from ring_gyro_sim.ros.sinks import Publishers, RosSink
from ring_gyro_sim.ros.throttle import ThrottledWarnings
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger
# isort: on

DIAGNOSTICS_PERIOD_S = 1.0
TICK_BUDGET_S = 0.05
"""Most wall time one timer callback spends on blocks before serving inputs and services."""
MAX_TICK_PERIOD_S = 0.1
"""Longest period of the node's timer, s: services and parameter changes wait for the end of
a tick (inputs are taken before every block and act at the next block either way). Each tick
ends in an executor turn, about a millisecond of CPU (doc/performance.md): the node ticks no
more often than that wait allows."""
TICK_MARGIN_S = 0.0005
"""A paced gyroscope's tick serves ``~/rate`` until this long before the next tick, s: the
executor's turn between them (its wait set built in Python, about a millisecond) is the only
time no message goes out."""
SPIN_TIMEOUT_S = 0.1
"""Longest wait of one executor turn (the stop flag is checked between turns)."""
LAG_WARN_S = 0.5
"""Wall seconds behind the real-time target from which /diagnostics says WARN."""
REJECT_LOG_PERIOD_S = 5.0
NAMESAKE_WATCH_S = 5.0
"""How long after its creation the node stops at once when another node of its name shows up,
s: discovery showed one after 0-2.35 s under load on two cores (Fast DDS announces a
participant 5 times in its first 0.5 s, then every 3 s; module doc, "Start-up")."""
NAMESAKE_CHECK_PERIOD_S = 0.1
"""How often the node looks at the graph for a namesake in its first ``NAMESAKE_WATCH_S``, s
(a graph query costs tens of us)."""
RATE_LATENCY_BLOCKS = 2
"""``~/rate`` goes out this many blocks of simulated time after its samples (module doc)."""
RATE_DRAIN_S = 1.0
"""Longest the node sends the ``~/rate`` messages still held, paced, at the end of a run, s
(two blocks and what ``rate_pacer.MAX_LATE_S`` lets fall behind: at most 0.27 s at the
defaults, drained at ``rate_pacer.CATCH_UP`` times the rate; then the rest at once). Flushed
at once, 100-130 of them were lost to a reliable subscriber as the node exited."""
_NUMBER = re.compile(r'[-+]?\d[\d.]*(e[-+]?\d+)?')


class RingGyroNode(parameters.CountedParameterRefusals, Node):
    """The simulator behind topics, parameters and a reset service (see the module doc)."""

    def __init__(self, node_name: str = 'ring_gyro', **kwargs) -> None:
        super().__init__(node_name, **kwargs)
        self._created_s = time.monotonic()
        self.run: Optional[run_mod.Run] = None
        self.rate_pacer: Optional[RatePacer] = None
        self.stop_requested: Optional[str] = None
        self.done = False
        self.result: Optional[str] = None
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
        fqn = self.get_fully_qualified_name()
        die_pub = None
        self.block_pubs = {name: self.create_publisher(Float64MultiArray, f'~/{name}',
                                                       qos.BLOCK_QOS)
                           for name in conversions.OUTPUT_TOPICS}
        if config.gyro.enabled:
            name = conversions.DEMODULATOR_TOPIC
            self.block_pubs[name] = self.create_publisher(Float64MultiArray, f'~/{name}',
                                                          qos.BLOCK_QOS)
            self.rate_pacer = RatePacer(
                self.create_publisher(Imu, f'~/{conversions.RATE_TOPIC}', qos.RATE_QOS),
                self._rate_due_s, self._rate_spacing_s)
            die_pub = self.create_publisher(Temperature,
                                            f'~/{conversions.DIE_TEMPERATURE_TOPIC}',
                                            qos.DIE_TEMPERATURE_QOS)
        if modes.of(config).closed:
            name = conversions.CONTROL_TOPIC
            self.block_pubs[name] = self.create_publisher(Float64MultiArray, f'~/{name}',
                                                          qos.BLOCK_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              qos.DIAGNOSTICS_QOS)
        clock_pub = (self.create_publisher(ClockMsg, '/clock', qos.CLOCK_QOS)
                     if config.run.publish_clock else None)
        names = run_mod.channel_names(config)
        recorder = None
        if config.run.record_path:
            # Opened (and so checked) before the start state is computed.
            try:
                recorder = RunRecorder(config.run.record_path, config, names, fqn,
                                       publish_clock=config.run.publish_clock)
            except OSError as exc:  # RingGyroErrors name the parameter themselves
                raise ParameterError(f'record.path: {exc}') from None
        self.sink = RosSink(names, fqn, recorder=recorder,
                            publishers=Publishers(self.block_pubs, self.diag_pub, clock_pub,
                                                  self.rate_pacer, die_pub),
                            stamp_ns=lambda: self.get_clock().now().nanoseconds,
                            frame_id=config.gyro.frame_id)
        block_samples = max(1, int(round(config.run.block_duration * config.run.output_rate)))
        self.run = run_mod.Run(config, sink=self.sink,
                               late_tolerance_ns=block_samples * config.run.output_period_ns,
                               log=log.info)
        if cache.cold_kernels():
            log.info(f'compiling the kernels before the clock starts (the first run of this '
                     f'version on this machine: ~{cache.COMPILE_CPU_S:.0f} s of CPU; the next '
                     f'runs load them)')
        run_mod.load_kernels(config)  # every model the run may use, before pacing
        self._refuse_a_namesake()
        self.block_samples = block_samples
        self.total_samples = (int(round(config.run.duration * config.run.output_rate))
                              if config.run.duration > 0.0 else 0)
        self._reject_log = ThrottledWarnings(lambda text: self.get_logger().warn(text),
                                             REJECT_LOG_PERIOD_S)
        self._ignored_z = set()
        self._contact_logged = False
        self._namesake_logged = False
        self._namesake_check_s = 0.0
        self._input_subs = [
            self._input(Vector3Stamped, 'shock', self._on_shock, qos.SHOCK_QOS),
            self._input(AccelStamped, 'base_acceleration', self._on_base_acceleration,
                        qos.BASE_ACCELERATION_QOS),
            self._input(Float64, 'drive/amplitude', self._on_drive_amplitude, qos.DRIVE_QOS),
            self._input(Float64, 'drive/frequency', self._on_drive_frequency, qos.DRIVE_QOS),
            self._input(Vector3Stamped, conversions.ANGULAR_RATE_TOPIC, self._on_angular_rate,
                        qos.ANGULAR_RATE_QOS),
            self._input(Temperature, conversions.TEMPERATURE_TOPIC, self._on_temperature,
                        qos.TEMPERATURE_QOS),
        ]
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.tick_timer = None
        self._pace_wall0: Optional[float] = None
        self._pace_sim0_ns = 0
        self._start_wall: Optional[float] = None
        self._start_cpu: Optional[float] = None
        self._start_sim_ns = self.run.time_ns
        self._diag_wall = time.monotonic()
        self._diag_sim_ns = self.run.time_ns
        self._restart_tick_timer()
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._on_diagnostics_timer, clock=self.steady)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        rc = config.run
        log.info(
            f'simulating {", ".join(self.run.full_model().coordinates)}, '
            f'output at {rc.output_rate:g} Hz in blocks of {self.block_samples} samples, '
            f'real_time_factor {rc.real_time_factor:g}, '
            f'duration {"unlimited" if not rc.duration else f"{rc.duration:g} s"}'
            + (f', recording to {rc.record_path}' if recorder is not None else ''))

    def _namesake_refusal(self) -> Optional[str]:
        """Return why the node refuses to run if another of its name is in the graph."""
        if self.get_node_names_and_namespaces().count((self.get_name(),
                                                       self.get_namespace())) < 2:
            return None
        return (f'another node named {self.get_fully_qualified_name()} is running: two nodes '
                f'of one name would publish on the same topics, with nothing to tell them '
                f'apart (ROS 2 node names must be unique); rename this one '
                f'(--ros-args -r __node:=NAME) or stop the other')

    def _refuse_a_namesake(self) -> None:
        """Refuse to start beside a namesake already discovered (module doc, "Start-up")."""
        refusal = self._namesake_refusal()
        if refusal is not None:
            self.sink.discard()
            raise RingGyroError(refusal)

    def _watch_for_a_namesake(self) -> None:
        """
        In the node's first ``NAMESAKE_WATCH_S``: stop at once if a namesake shows up.

        Every ``NAMESAKE_CHECK_PERIOD_S``; the recording is deleted and ``main`` logs the
        reason as FATAL and exits with code 1 (module doc, "Start-up").
        """
        now = time.monotonic()
        if now - self._created_s > NAMESAKE_WATCH_S or now < self._namesake_check_s:
            return
        self._namesake_check_s = now + NAMESAKE_CHECK_PERIOD_S
        refusal = self._namesake_refusal()
        if refusal is not None:
            self.done = True
            self.sink.discard()
            raise RingGyroError(f'{refusal} (seen {now - self._created_s:.1f} s after this '
                                f'node started; its recording is deleted)')

    def _input(self, msg_type, topic: str, handler, profile: QoSProfile):
        """Subscribe to an input topic; count the messages the middleware reports lost."""
        def lost(info) -> None:
            self.run.count_lost(topic, info.total_count_change)
            self.get_logger().warn(f'~/{topic}: the middleware lost '
                                   f'{info.total_count_change} messages',
                                   throttle_duration_sec=REJECT_LOG_PERIOD_S)
        try:
            sub = self.create_subscription(
                msg_type, f'~/{topic}', handler, profile,
                event_callbacks=SubscriptionEventCallbacks(message_lost=lost))
        except UnsupportedEventTypeError:  # an RMW without the event: nothing to count
            sub = self.create_subscription(msg_type, f'~/{topic}', handler, profile)
        return sub, handler, profile.depth

    @property
    def real_time_factor(self) -> float:
        """Return the pacing target in force."""
        return self.run.config.run.real_time_factor

    def _restart_tick_timer(self) -> None:
        if self.tick_timer is not None:
            self.destroy_timer(self.tick_timer)
        rtf = self.real_time_factor
        block_wall_s = self.block_samples * self.run.period_ns * 1e-9 / rtf if rtf > 0 else 0.0
        period = min(max(block_wall_s / 4.0, 0.001), MAX_TICK_PERIOD_S)
        if self.rate_pacer is not None and rtf > 0.0:
            # A tick serves ~/rate until the next and computes the blocks due meanwhile
            # (module doc, "Pacing"): few executor turns, each ~0.3 ms of rclpy's wait set.
            period = MAX_TICK_PERIOD_S
        self.tick_timer = self.create_timer(period, self._on_tick, clock=self.steady)

    # ------------------------------------------------------------------ pacing
    def _target_ns(self, now: float, rtf: Optional[float] = None) -> float:
        """Return the simulation time (ns) due at wall time ``now`` (inf: as fast as possible)."""
        rtf = self.real_time_factor if rtf is None else rtf
        if rtf <= 0.0 or self._pace_wall0 is None:
            return math.inf
        return self._pace_sim0_ns + (now - self._pace_wall0) * rtf * 1e9

    def _wall_at(self, t_ns: int) -> float:
        """Return the wall time (monotonic, s) simulation time ``t_ns`` is due at (inf: rtf 0)."""
        rtf = self.real_time_factor
        if rtf <= 0.0 or self._pace_wall0 is None:
            return math.inf
        return self._pace_wall0 + (t_ns - self._pace_sim0_ns) / (rtf * 1e9)

    def _rate_due_s(self, t_ns: int) -> float:
        """Return the wall time (monotonic, s) the ``~/rate`` sample of ``t_ns`` is due at."""
        rtf = self.real_time_factor
        if rtf <= 0.0 or self._pace_wall0 is None:
            return 0.0  # as fast as possible: at once
        latency_ns = RATE_LATENCY_BLOCKS * self.block_samples * self.run.period_ns
        return self._pace_wall0 + (t_ns + latency_ns - self._pace_sim0_ns) / (rtf * 1e9)

    def _rate_spacing_s(self) -> float:
        """Return the wall time between two ``~/rate`` samples at the pacing in force, s."""
        rtf = self.real_time_factor
        return 1.0 / (self.run.config.gyro.output_rate * rtf) if rtf > 0.0 else 0.0

    def _rebase_pacing(self, old_rtf: float) -> None:
        """Keep the target continuous (and so the lag) across a change of real_time_factor."""
        if self._pace_wall0 is None:
            return  # pacing starts with the first tick
        now = time.monotonic()
        target = self._target_ns(now, old_rtf)
        self._pace_sim0_ns = target if math.isfinite(target) else self.run.time_ns
        self._pace_wall0 = now

    def _on_tick(self) -> None:
        self._watch_for_a_namesake()
        next_block_s = self._tick_blocks()
        if self.rate_pacer is None or self.done:
            return
        # ~/rate until shortly before the next tick, and the blocks that fall due meanwhile
        left_ns = self.tick_timer.time_until_next_call()
        end = time.monotonic() + (left_ns or 0) * 1e-9 - TICK_MARGIN_S
        while not self.done:
            self._serve_rate(min(end, next_block_s))
            if next_block_s > end:
                return
            delay = next_block_s - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            next_block_s = self._tick_blocks()

    def _serve_rate(self, until: float) -> None:
        """
        Send ``~/rate`` on time until shortly before the next tick (module doc, "Pacing").

        Sleeps (no GIL, no executor turn) until each message is due; returns once the next
        one is due after ``until`` (wall s): ``TICK_MARGIN_S`` before the next tick, or the
        time the next block is due if sooner (never a block late for it).
        """
        pacer = self.rate_pacer
        pacer.send_due()
        while True:
            when = pacer.next_send_s(GROUP)  # two at a time: half the wake-ups
            if when > until:
                return
            delay = when - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            pacer.send_due()

    def _tick_blocks(self) -> float:
        """
        Compute the blocks that are due, for at most ``TICK_BUDGET_S`` of wall time.

        Returns the wall time (monotonic, s) the next block is due at: now or earlier when
        the node is behind, inf as fast as possible or once the run is over.
        """
        if self.done:
            return math.inf
        if self.stop_requested:
            self._finish(f'stopped ({self.stop_requested})')
            return math.inf
        now = time.monotonic()
        if self._pace_wall0 is None:
            self._pace_wall0 = self._start_wall = self._diag_wall = now
            self._start_cpu = time.process_time()
            self._pace_sim0_ns = self._start_sim_ns = self._diag_sim_ns = self.run.time_ns
        if self.rate_pacer is not None:
            self.rate_pacer.send_due()
        deadline = now + TICK_BUDGET_S
        period_ns = self.run.period_ns
        while True:
            n = self.block_samples
            if self.total_samples:
                n = min(n, self.total_samples - self.run.sample_index)
                if n <= 0:
                    self._finish('duration reached')
                    return math.inf
            end_ns = self.run.time_ns + n * period_ns
            if end_ns > self._target_ns(now):
                return self._wall_at(end_ns)
            self._drain_inputs()
            self._step(n)
            now = time.monotonic()
            if now >= deadline:
                return now  # behind: the next block is due already

    def _drain_inputs(self) -> None:
        """
        Take every input message waiting in the subscription queues, before a block.

        The executor takes one message per subscription per wait, and a node that lags
        keeps its timer ready at every wait: without this a backlog (after a flood) would
        drain at one message per tick, a later input would act seconds late, and the
        middleware would overwrite the oldest waiting messages, which nobody can count
        (no RMW reports a keep-last overwrite). Taken, every message is either applied or
        refused and counted by the run (``run.MAX_SHOCKS_PER_BLOCK`` shocks per block and
        ``run.MAX_PENDING_SHOCKS`` pending bound the work a flood can buy). The queues hold
        1000 shocks or samples: a flood loses messages in the middleware only beyond 1000
        between two blocks, and those the RMW reports lost are counted (``lost_inputs``).
        """
        for sub, handler, most in self._input_subs:
            is_shock = handler == self._on_shock
            undecoded = 0
            raw = False
            for _ in range(most):
                # A flood's excess: once the run refuses every shock until the next block,
                # the waiting ones are taken undecoded and counted as refused (the reason is
                # the same for all of them). Taking one raw costs the node's only thread about
                # a sixth of a decoded take (doc/performance.md, "The node under a shock
                # flood"): 10 000 per second do not starve the simulation. Once refused, a
                # shock stays refused until the next block (the drain does not advance it), so
                # the reason is asked only until then, not formatted for every message.
                raw = is_shock and (raw or self.run.shock_refusal() is not None)
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, raw or sub.raw)
                if taken is None:
                    break
                if raw:
                    undecoded += 1
                    continue
                handler(taken[0])
            if undecoded:
                self.run.refuse_shocks(undecoded)
                self._log_reject('shock', self.run.shock_refusal() or 'a flood')

    def _step(self, n: int) -> None:
        """Advance one block (the sink publishes and records it); report a contact at once."""
        if self.rate_pacer is None:
            self.run.advance(n)
        else:  # ~/rate due while the block is computed goes out meanwhile (closed loop: 1 ms)
            self.run.advance(n, self.rate_pacer.send_due)
        if not self.run.running and not self._contact_logged:
            self._contact_logged = True
            self.get_logger().error(self.run.failure_text())
            self._publish_diagnostics()

    def _finish(self, why: str) -> None:
        """End the run: final diagnostics and summary; main() then closes the recording."""
        self.done = True
        self._publish_diagnostics(finished=True)
        self.get_logger().info(f'{why}: {self.summary()}')
        if self.rate_pacer is not None:  # every ~/rate message of the run out, paced
            self._serve_rate(time.monotonic() + RATE_DRAIN_S)
            self.rate_pacer.flush()
        self.result = why

    def summary(self) -> str:
        """Return simulated and wall time and the run's numbers in one line."""
        wall = time.monotonic() - self._start_wall if self._start_wall is not None else 0.0
        sim_s = (self.run.time_ns - self._start_sim_ns) * 1e-9
        rate = f' (x{sim_s / wall:.3f} real time)' if wall > 0 else ''
        if wall > 0 and self._start_cpu is not None:  # the node's threads, every one
            rate += (f', {100.0 * (time.process_time() - self._start_cpu) / wall:.1f} % of a '
                     f'core')
        text = (f'{self.run.time_s:.6f} s simulated in {wall:.3f} s{rate}; '
                f'{self.run.summary_text()}')
        if self.run.config.run.record_path:
            text += f'; recorded to {self.run.config.run.record_path}'
        return text

    # ------------------------------------------------------------------ inputs
    def _apply(self, event) -> bool:
        """Apply an input to the run; log a refusal (the run counts it)."""
        try:
            self.run.apply(event)
        except (InputError, ParameterError) as exc:
            self._log_reject(event.topic, str(exc))
            return False
        return True

    def _log_reject(self, topic: str, reason: str) -> None:
        """Log a refused input, at most every few seconds per topic and kind of reason."""
        self._reject_log((topic, _NUMBER.sub('#', reason)), f'rejected ~/{topic}: {reason}')

    def _warn_z(self, topic: str, z: float) -> None:
        if z != 0.0 and math.isfinite(z) and topic not in self._ignored_z:
            self._ignored_z.add(topic)
            self.get_logger().warn(f'~/{topic}: the z component is ignored (in-plane ring)')

    def _warn_xy(self, topic: str, x: float, y: float) -> None:
        if (x != 0.0 or y != 0.0) and topic not in self._ignored_z:
            self._ignored_z.add(topic)
            self.get_logger().warn(f'~/{topic}: the x and y components are ignored (rotation '
                                   f'about the ring axis z only)')

    def _on_shock(self, msg: Vector3Stamped) -> None:
        s = conversions.shock_input(msg)
        if self._apply(run_mod.Shock(x=s.x, y=s.y, z=s.z, at_ns=s.at_ns)):
            self._warn_z('shock', s.z)

    def _on_base_acceleration(self, msg: AccelStamped) -> None:
        a = conversions.base_acceleration_input(msg)
        if self._apply(run_mod.BaseAcceleration(x=a.x, y=a.y, z=a.z, at_ns=a.at_ns)):
            self._warn_z('base_acceleration', a.z)

    def _on_angular_rate(self, msg: Vector3Stamped) -> None:
        r = conversions.angular_rate_input(msg)
        if self._apply(run_mod.AngularRate(z=r.z, x=r.x, y=r.y, at_ns=r.at_ns)):
            self._warn_xy(conversions.ANGULAR_RATE_TOPIC, r.x, r.y)

    def _on_temperature(self, msg: Temperature) -> None:
        t = conversions.temperature_input(msg)
        self._apply(run_mod.AmbientTemperature(kelvin=t.kelvin, at_ns=t.at_ns))

    def _on_drive_amplitude(self, msg: Float64) -> None:
        self._apply(run_mod.DriveAmplitude(float(msg.data)))

    def _on_drive_frequency(self, msg: Float64) -> None:
        self._apply(run_mod.DriveFrequency(float(msg.data)))

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response):
        t_ns = self.run.time_ns
        relapse = self.run.relapse()
        self.run.apply(run_mod.Reset())
        self._contact_logged = False
        response.success = True
        response.message = f'ring at rest at simulation time {t_ns * 1e-9:.9f} s'
        if relapse is not None:  # the reset does what it can: say why it may not last
            response.message += f'; the contact it clears came {relapse}'
        self.get_logger().info(response.message)
        return response

    def on_parameter_refusal(self, kind: str, name: str, reason: str) -> None:
        """Log a refused parameter change (the mixin) and count it on the run."""
        super().on_parameter_refusal(kind, name, reason)
        if kind != 'invalid' and self.run is not None:  # 'invalid': counted by the run
            self.run.count_rejected(run_mod.ParameterChange.topic, kind)

    def _on_set_parameters(self, params) -> SetParametersResult:
        # A refusal here is logged by the mixin (CountedParameterRefusals) as 'invalid'.
        old_rtf = self.real_time_factor
        try:
            _, changed = parameters.updated_config(self.run.config, params)
        except (ParameterError, InputError) as exc:
            self.run.count_rejected(run_mod.ParameterChange.topic)
            return SetParametersResult(successful=False, reason=str(exc))
        if changed:
            try:
                self.run.apply(run_mod.ParameterChange(changed))  # counts a refusal
            except (ParameterError, InputError) as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        if not changed:
            return SetParametersResult(successful=True)
        t_ns = self.run.time_ns
        if self.real_time_factor != old_rtf:
            self._rebase_pacing(old_rtf)
            self._restart_tick_timer()
        self.get_logger().info(f'parameters applied at simulation time {t_ns * 1e-9:.9f} s: '
                               + ', '.join(f'{k} = {v}' for k, v in changed.items()))
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ diagnostics
    def _on_diagnostics_timer(self) -> None:
        if not self.done:
            self._publish_diagnostics()
            self._warn_of_a_namesake()

    def _warn_of_a_namesake(self) -> None:
        """Log an ERROR once when another node of this name appears (after start-up)."""
        count = self.get_node_names_and_namespaces().count((self.get_name(),
                                                            self.get_namespace()))
        if count > 1 and not self._namesake_logged:
            self.get_logger().error(
                f'another node named {self.get_fully_qualified_name()} appeared: both publish '
                f'on the same topics, with nothing to tell them apart (ROS 2 node names must '
                f'be unique); rename one (--ros-args -r __node:=NAME)')
        self._namesake_logged = count > 1

    def _publish_diagnostics(self, finished: bool = False) -> None:
        now = time.monotonic()
        run = self.run
        rtf = self.real_time_factor
        target = self._target_ns(now)
        lag_s = max(0.0, (target - run.time_ns) * 1e-9) if math.isfinite(target) else 0.0
        wall = now - self._diag_wall
        achieved = (run.time_ns - self._diag_sim_ns) * 1e-9 / wall if wall > 0 else 0.0
        self._diag_wall, self._diag_sim_ns = now, run.time_ns
        total_wall = now - self._start_wall if self._start_wall is not None else 0.0
        average = ((run.time_ns - self._start_sim_ns) * 1e-9 / total_wall
                   if total_wall > 0 else 0.0)
        run.diagnostics(run_mod.Pacing(target=rtf, achieved=achieved, average=average,
                                       lag_s=lag_s,
                                       lag_warn=rtf > 0 and lag_s / rtf > LAG_WARN_S),
                        finished=finished)

    # ------------------------------------------------------------------ shutdown
    def close(self, summary: bool = True) -> None:
        """Finalise the recording (idempotent); log a summary if the run did not finish."""
        if summary and self.run is not None and not self.done:
            self.done = True
            print(f'[ring_gyro_node] stopped: {self.summary()}', file=sys.stderr)
        if self.rate_pacer is not None:
            try:
                self.rate_pacer.flush()  # (done already if the run finished)
            except Exception:  # noqa: B902 - the context shut down under it: nothing to send to
                pass
        try:
            if self.run is not None:
                self.run.close()
            elif getattr(self, 'sink', None) is not None:
                self.sink.discard()
        except RecordingError as exc:  # e.g. the disk filled up: one line, no traceback
            self.get_logger().fatal(f'recording: {exc}')
        self.sink = None


class _StopOnSignal:
    """
    SIGINT / SIGTERM handler: the first one asks the node to end its run cleanly.

    Only a flag, never an exception, for the first signal: while the node is being built
    (parameters, recorder, start state, kernels) it is noted and the run ends as soon as the
    node exists, with the usual summary; an exception raised at an arbitrary point of that
    construction could leave the process in a state it cannot report. A second signal
    raises KeyboardInterrupt at once.
    """

    def __init__(self) -> None:
        self.node: Optional[RingGyroNode] = None
        self.early: Optional[str] = None

    def __call__(self, signum, frame) -> None:
        name = signal.Signals(signum).name
        node = self.node
        if node is None:
            if self.early is not None:
                raise KeyboardInterrupt  # a second signal during start-up
            self.early = name
            return
        if node.stop_requested:
            raise KeyboardInterrupt  # a second signal
        # The next block (or timer callback) ends the run with the context still up, so the
        # final diagnostics and the summary are still published.
        node.stop_requested = name


USAGE = """\
usage: ring_gyro_node [-h] [--ros-args [--params-file FILE] [-r __node:=NAME] [-r __ns:=/NS]
                      [-p NAME:=VALUE] ...]

The vibrating-ring gyroscope as a ROS 2 node (default name ring_gyro): ~/rate (sensor_msgs/Imu),
the modal displacements, gaps and capacitances, /diagnostics; inputs ~/shock,
~/base_acceleration, ~/angular_rate, ~/drive/*; service ~/reset. It runs until Ctrl-C (or for
`duration` s) and records to `record.path` when set.

ROS arguments (after --ros-args):
  --params-file FILE   the parameters, e.g. config/default.yaml (every parameter at its
                       default: the gyroscope), config/demo.yaml, config/paper.yaml (the
                       paper's resonator); installed under
                       $(ros2 pkg prefix --share ring_gyro_sim)/config/
  -r __node:=NAME      rename the node (the shipped files apply to any name)
  -r __ns:=/NS         put it in a namespace
  -p NAME:=VALUE       one parameter, e.g. -p duration:=5.0 -p record.path:=out/run.mcap

  -h, --help           show this message and exit (the node does not start)

Exit status: 0 at the end of `duration` or on SIGINT / SIGTERM; 1 for a bad parameter file
or value (one FATAL line naming the parameter).
Documentation: doc/interface.md (topics, parameters, QoS), doc/gyroscope.md,
doc/recording.md; `ros2 param describe /ring_gyro NAME` on a running node; `ring_gyro --help`
for the offline tools.
"""
"""What ``ring_gyro_node -h`` prints."""


def asks_for_help(argv) -> bool:
    """Tell whether ``-h`` or ``--help`` is among the node's own arguments (not ROS's)."""
    in_ros = False
    for arg in list(argv)[1:]:
        if arg == '--ros-args':
            in_ros = True
        elif arg == '--' and in_ros:
            in_ros = False
        elif not in_ros and arg in ('-h', '--help'):
            return True
    return False


def main(args=None) -> int:
    """Entry point of ``ring_gyro_node``: exit code 0 on a clean end, 1 if it cannot start."""
    if asks_for_help(sys.argv if args is None else args):
        print(USAGE, end='')
        return 0
    try:  # one verdict on the params files with `ring_gyro run` (paramfile.py)
        check_node_arguments(sys.argv if args is None else args)
    except ParameterError as exc:
        print(f'[FATAL] [ring_gyro_node]: cannot start: {exc}', file=sys.stderr)
        return 1
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
    executor = None
    code = 0
    try:
        if EARLY_SIGNALS:  # during the imports or rclpy.init: end before starting
            name = signal.Signals(EARLY_SIGNALS[0]).name
            print(f'[INFO] [ring_gyro_node]: stopped ({name}) during start-up', file=sys.stderr)
            return 0
        node = RingGyroNode()
        stop.node = node
        node.stop_requested = node.stop_requested or stop.early
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not node.done and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RingGyroError as exc:
        code = 1
        if node is not None:  # start-up errors are logged by the node, naming the parameter
            node.get_logger().fatal(str(exc))
    finally:
        if node is not None:
            node.close()
            if executor is not None:
                executor.remove_node(node)
            node.destroy_node()
        if executor is not None:
            executor.shutdown()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return code


if __name__ == '__main__':
    sys.exit(main())
