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
Sinks of a :class:`~ring_gyro_sim.run.Run` that speak ROS messages: publish and/or record.

:class:`RosSink` turns each block into its three ``Float64MultiArray`` messages once and
hands them to the node's publishers and to the recorder (either may be absent: a null
target stands in, so no caller tests for ``None``). Inputs are recorded as they act, under
the node's input topics (``<ns>/shock`` ... ``<ns>/angular_rate``), diagnostics as
``/diagnostics``.

The gyroscope (a block with ``rate`` / ``demod``, i.e. ``gyro.enabled``): the block's rate
samples become one ``sensor_msgs/Imu`` each on ``~/rate`` (:func:`conversions.imu_message`:
stamp = sample time, ``frame_id``, covariance from :attr:`RosSink.rate_variance`), handed to
the rate outlet before the block messages go out (the node publishes each at its sample
time: ``ros/rate_pacer.py``) and recorded at their sample times; the demodulator channels
become the block topic ``~/demodulator`` next to the other three.

The closed loop (a block with ``control``, i.e. a closed ``control.mode``): the loops'
updates in the block become the block topic ``~/control`` (:func:`conversions.control_block`:
one row per update, ``t`` and ``core.gyro.control.CONTROL_CHANNELS``; no rows in a block shorter
than a loop period), published and recorded with the other block messages, at the block's
end time.

Diagnostics: one status named ``<node>: simulator`` (the node's fully qualified name without
the leading slash, e.g. ``ring_gyro: simulator`` or ``left/gyro: simulator``) and
``hardware_id`` ``ring_gyro_sim:<fully qualified name>``, so two instances are told apart.
The header is stamped by ``stamp_ns`` (the node: its ROS clock, i.e. wall time, or the
simulation time only with ``use_sim_time``); without one (offline) by the simulation time.
"""

from typing import Callable, Dict, List, Mapping, Optional

from ring_gyro_sim import run as run_mod
from ring_gyro_sim.ros import conversions

__all__ = ['NullPublishers', 'NullRecorder', 'Publishers', 'RosSink', 'diagnostics_names']

CHANNEL_TOPICS = frozenset(('radial_gap', 'sense_electrodes'))
"""The block topics of the samples' channels (gaps, capacitances: ``Samples.gap``)."""


def diagnostics_names(fully_qualified_name: str):
    """Return ``(status name, hardware_id)`` of a node's diagnostics."""
    fqn = '/' + fully_qualified_name.strip('/')
    return f'{fqn.lstrip("/")}: simulator', f'ring_gyro_sim:{fqn}'


class NullRecorder:
    """Stands in for a :class:`~ring_gyro_sim.ros.recorder.RunRecorder` when not recording."""

    block_topics = frozenset()
    """No block topic is recorded."""

    def kept_rows(self, t_ns: int, rows: int) -> slice:
        """Return no row: nothing is recorded."""
        return slice(0, 0)

    def outputs(self, blocks, t_ns: int, thinned: bool = False) -> None:
        """Do nothing."""

    def clock(self, t_ns: int) -> None:
        """Do nothing."""

    def diagnostics(self, msg, t_ns: int) -> None:
        """Do nothing."""

    def shock(self, at_ns: int, x: float, y: float = 0.0) -> None:
        """Do nothing."""

    def base_acceleration(self, at_ns: int, x: float, y: float = 0.0) -> None:
        """Do nothing."""

    def angular_rate(self, at_ns: int, z: float, x: float = 0.0, y: float = 0.0) -> None:
        """Do nothing."""

    def rate(self, messages) -> None:
        """Do nothing."""

    def temperature(self, at_ns: int, kelvin: float) -> None:
        """Do nothing."""

    def die_temperature(self, msg, t_ns: int) -> None:
        """Do nothing."""

    def drive(self, at_ns: int, amplitude=None, frequency_hz=None) -> None:
        """Do nothing."""

    def reset(self, at_ns: int) -> None:
        """Do nothing."""

    def parameters(self, at_ns: int, changed) -> None:
        """Do nothing."""

    def start(self, initial_state) -> None:
        """Do nothing."""

    def set_calibration(self, calibration) -> None:
        """Do nothing."""

    def handoff(self, at_ns: int, model: str) -> None:
        """Do nothing."""

    def close(self) -> None:
        """Do nothing."""

    def discard(self) -> None:
        """Do nothing."""


class Publishers:
    """
    The node's output publishers: block topics, ``/clock``, ``/diagnostics``, ``~/rate``.

    ``blocks`` maps every block topic the node has (the gyroscope's ``demodulator`` and the
    closed loop's ``control`` only when it has them) to its publisher; ``rate`` is the outlet
    of ``~/rate``, which takes a block's messages with their sample times
    (``ros.rate_pacer.RatePacer``).
    """

    def __init__(self, blocks: Mapping[str, object], diagnostics, clock=None,
                 rate=None, die_temperature=None) -> None:
        self._blocks = dict(blocks)
        self._diagnostics = diagnostics
        self._clock = clock
        self._rate = rate
        self._die_temperature = die_temperature

    @property
    def publishes_blocks(self) -> bool:
        """
        Tell whether a subscriber is matched on any block topic.

        Only then does :class:`RosSink` build the block messages with every sample and
        publish them: nobody subscribed, a 200 kHz block costs the node its conversion to
        messages and their serialisation for no one (the recording keeps its rows either
        way).
        """
        return any(pub.get_subscription_count() > 0 for pub in self._blocks.values())

    def die_temperature(self, msg) -> None:
        """Publish ``~/die_temperature`` (gyroscope only)."""
        if self._die_temperature is not None:
            self._die_temperature.publish(msg)

    def rate(self, messages) -> None:
        """
        Hand the ``~/rate`` messages ``[(t_ns, Imu)]`` of one block to the rate outlet.

        The outlet (``rate``: the node's ``ros.rate_pacer.RatePacer``, gyroscope only) takes
        the whole list and publishes each message at its sample time.
        """
        if self._rate is not None:
            self._rate.publish(messages)

    def blocks(self, msgs: Mapping[str, object]) -> None:
        """Publish the block messages of one block."""
        for name, msg in msgs.items():
            self._blocks[name].publish(msg)

    def clock(self, msg) -> None:
        """Publish ``/clock`` (only when the node publishes it)."""
        if self._clock is not None:
            self._clock.publish(msg)

    def diagnostics(self, msg) -> None:
        """Publish ``/diagnostics``."""
        self._diagnostics.publish(msg)


class NullPublishers:
    """Stands in for :class:`Publishers` offline."""

    #: Nothing is published: :class:`RosSink` builds the blocks with the recorded rows only.
    publishes_blocks = False

    def blocks(self, msgs) -> None:
        """Do nothing."""

    def rate(self, messages) -> None:
        """Do nothing."""

    def die_temperature(self, msg) -> None:
        """Do nothing."""

    def clock(self, msg) -> None:
        """Do nothing."""

    def diagnostics(self, msg) -> None:
        """Do nothing."""


class RosSink(run_mod.Sink):
    """
    Publish and/or record a run.

    Parameters
    ----------
    channel_names : dict
        ``Run.channel_names``.
    fully_qualified_name : str
        The node's name with its namespace (offline: the namespace recorded, '/ring_gyro').
    recorder : RunRecorder, optional
        Records everything (default: nothing).
    publishers : Publishers, optional
        Publishes blocks, ``/clock`` and ``/diagnostics`` (default: nothing).
    stamp_ns : callable, optional
        Header stamp of the diagnostics, ns (default: the simulation time).
    frame_id : str
        ``header.frame_id`` of ``~/rate`` (``gyro.frame_id``).
    rate_variance : float
        Variance of one ``~/rate`` sample, (rad/s)^2, for its covariance; 0 = unknown
        (REP-145: all-zero covariance). An attribute: it may be set later, e.g. once the
        electronics know their noise.

    """

    def __init__(self, channel_names: Dict[str, List[str]], fully_qualified_name: str,
                 recorder=None, publishers=None,
                 stamp_ns: Optional[Callable[[], int]] = None, frame_id: str = '',
                 rate_variance: float = 0.0) -> None:
        self.channel_names = channel_names
        self.recorder = recorder if recorder is not None else NullRecorder()
        self.publishers = publishers if publishers is not None else NullPublishers()
        self.stamp_ns = stamp_ns
        self.frame_id = frame_id
        self._imu_stream = None  # ((frame_id, rate_variance), cdr.ImuStream) of rate_cdr
        self.rate_variance = rate_variance
        self.status_name, self.hardware_id = diagnostics_names(fully_qualified_name)

    @property
    def rate_variance(self) -> float:
        """Return the variance of one ``~/rate`` sample, (rad/s)^2 (0 = unknown)."""
        return self._rate_variance

    @rate_variance.setter
    def rate_variance(self, value: float) -> None:
        self._rate_covariance = conversions.rate_covariance(value)  # checks the value
        self._rate_variance = float(value)

    def set_rate_variance(self, variance: float) -> None:
        """Take the electronics' predicted variance of ``~/rate`` (``Run`` calls it)."""
        self.rate_variance = variance

    def set_calibration(self, calibration) -> None:
        """Take the rate output's held calibration for the recording (``Run`` calls it)."""
        self.recorder.set_calibration(calibration)

    def start(self, state) -> None:
        """Write the recording's metadata with the start state."""
        self.recorder.start(state)

    def handoff(self, at_ns: int, model: str) -> None:
        """Record a change of model (``integrator.fidelity``)."""
        self.recorder.handoff(at_ns, model)

    def input(self, event) -> None:
        """Record an input as it acts."""
        rec = self.recorder
        t = int(event.at_ns)
        if isinstance(event, run_mod.Shock):
            rec.shock(t, event.x, event.y)
        elif isinstance(event, run_mod.BaseAcceleration):
            rec.base_acceleration(t, event.x, event.y)
        elif isinstance(event, run_mod.DriveAmplitude):
            rec.drive(t, amplitude=event.value)
        elif isinstance(event, run_mod.DriveFrequency):
            rec.drive(t, frequency_hz=event.value_hz)
        elif isinstance(event, run_mod.Reset):
            rec.reset(t)
        elif isinstance(event, run_mod.ParameterChange):
            rec.parameters(t, event.changes)
        elif isinstance(event, run_mod.AngularRate):
            rec.angular_rate(t, event.z, event.x, event.y)
        elif isinstance(event, run_mod.AmbientTemperature):
            rec.temperature(t, event.kelvin)

    def rate_messages(self, rate):
        """Return ``[(t_ns, Imu)]`` of a block's rate samples (``~/rate``)."""
        return conversions.rate_messages(rate, self.frame_id, self._rate_covariance)

    def rate_cdr(self, rate):
        """Return ``[(t_ns, CDR)]`` of :meth:`rate_messages`, packed without the messages."""
        key = (self.frame_id, self._rate_variance)
        if self._imu_stream is None or self._imu_stream[0] != key:
            self._imu_stream = key, conversions.imu_stream(self.frame_id, self._rate_covariance)
        return conversions.rate_cdr(rate, self._imu_stream[1])

    @property
    def needs_channels(self) -> bool:
        """
        Tell whether the next block must carry its gaps and capacitances (``Run``).

        Only when a subscriber is matched on a block topic or the recording keeps
        ``radial_gap`` or ``sense_electrodes``: otherwise nothing reads them, and an averaged
        stretch leaves them out (``core.engine.averaged.AveragedEngine``, R5).
        """
        return (self.publishers.publishes_blocks
                or not CHANNEL_TOPICS.isdisjoint(self.recorder.block_topics))

    def block(self, block) -> None:
        """
        Convert a block to messages once; publish and record them, and ``/clock``.

        Published (a subscriber is matched on a block topic: ``Publishers.publishes_blocks``),
        the block messages hold every sample (the recorder decimates its copy); otherwise,
        and offline, nothing needs the message objects: the block topics and ``~/rate`` go to the
        recorder as their CDR, packed from the rows the recording keeps
        (``record.decimation``), so a recording does not pay for building every 200 kHz sample
        into a message, nor for rclpy's conversion of the messages back to CDR; and a block
        topic nothing records (``record.topics``, or no recording) is not built at all.
        """
        # A block computed without its channels (nobody subscribed then: needs_channels) is
        # not published to a subscriber matched meanwhile: its first block is the next one.
        thinned = not self.publishers.publishes_blocks or block.samples.gap is None
        if thinned:
            rows = self.recorder.kept_rows(block.end_ns, len(block.samples.t))
            build, topics = conversions.block_cdr, self.recorder.block_topics
        else:
            rows, build, topics = slice(None), conversions.block_message, None
        msgs = conversions.output_blocks(block.samples, self.channel_names, rows, build, topics)
        if block.rate is not None:
            rate = self.rate_cdr(block.rate) if thinned else self.rate_messages(block.rate)
            self.publishers.rate(rate)
            self.recorder.rate(rate)
            if block.samples.die_temperature is not None:  # the die's sensor, at the end
                die = conversions.temperature_message(block.end_ns,
                                                      block.samples.die_temperature,
                                                      self.frame_id)
                self.publishers.die_temperature(die)
                self.recorder.die_temperature(die, block.end_ns)
        if block.demod is not None and (topics is None
                                        or conversions.DEMODULATOR_TOPIC in topics):
            msgs[conversions.DEMODULATOR_TOPIC] = conversions.demodulator_block(block.demod,
                                                                                rows, build)
        if block.control is not None and (topics is None or conversions.CONTROL_TOPIC in topics):
            msgs[conversions.CONTROL_TOPIC] = conversions.control_block(block.control, build)
        if not thinned:
            self.publishers.blocks(msgs)
        clock = conversions.clock_message(block.end_ns)
        self.publishers.clock(clock)
        self.recorder.outputs(msgs, block.end_ns, thinned=thinned)
        self.recorder.clock(block.end_ns)

    def diagnostics_message(self, diag):
        """Return the ``/diagnostics`` message of a snapshot."""
        stamp = self.stamp_ns() if self.stamp_ns is not None else diag.t_ns
        return conversions.diagnostics_message(stamp, self.status_name, self.hardware_id,
                                               diag.level, diag.message, diag.values)

    def diagnostics(self, diag) -> None:
        """Publish and record a diagnostics snapshot (log time: the simulation time)."""
        msg = self.diagnostics_message(diag)
        self.publishers.diagnostics(msg)
        self.recorder.diagnostics(msg, diag.t_ns)

    def close(self) -> None:
        """Finalise the recording."""
        recorder, self.recorder = self.recorder, NullRecorder()
        recorder.close()

    def discard(self) -> None:
        """Delete the recording of a run that never started."""
        recorder, self.recorder = self.recorder, NullRecorder()
        recorder.discard()
