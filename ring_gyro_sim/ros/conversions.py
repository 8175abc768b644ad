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
Message conversion, in one pure module: ROS messages <-> core inputs and outputs.

No node, no publisher here: functions take and return messages and plain values, so the node,
the offline recorder and the tests share them. Times are integer ns (``*_ns``) everywhere;
``builtin_interfaces/Time`` appears only at this boundary.

Block layout (doc/interface.md): ``layout.dim[0] = {label: 'sample', size: K, stride: K * C}``,
``layout.dim[1] = {label: 't,<channels>', size: C, stride: C}``, ``data`` row-major.

The gyroscope's rate output ``~/rate`` is one ``sensor_msgs/msg/Imu`` per rate sample
(:func:`imu_message`), filled as REP-145 and the Imu message's own comments say:

* ``header.stamp``: the sample time (simulation time), ``header.frame_id``: ``gyro.frame_id``;
* ``angular_velocity.z``: the measured rate about the ring axis, rad/s (REP-103 sign);
  ``angular_velocity.x`` and ``.y``: 0.0, not measured (a z-axis gyroscope);
* ``angular_velocity_covariance``: with the rate variance unknown (0) all nine elements are
  0, REP-145's "covariance unknown"; with a known variance ``v`` (rad/s)^2 the diagonal is
  ``(N, N, v)`` with ``N`` = ``core.gyro.validity.NOT_MEASURED_VARIANCE`` = 1e6 (rad/s)^2:
  x and y are not measured (a z-axis gyroscope), which a huge but finite variance says
  (infinity made robot_localization's ``R C R^T`` NaN: 0 * inf), and ``v`` is the sample's
  own variance (``RateSamples.variance``: what the sample is worth, the same ``N`` when it
  is not a measurement, ``core.gyro.validity``). Element 0 cannot be -1 ("no estimate")
  here: that would tell readers to disregard z as well;
* ``orientation`` (identity quaternion) and ``linear_acceleration`` (zero) are not
  estimated: element 0 of their covariances is -1, the rest 0.
"""

import array
from dataclasses import dataclass
import math
from typing import Collection, Dict, List, Optional, Sequence, Tuple

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import AccelStamped, Vector3Stamped
import numpy as np
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.core.gyro.electronics import DEMOD_CHANNELS
from ring_gyro_sim.core.gyro.validity import NOT_MEASURED_VARIANCE
from ring_gyro_sim.recording import cdr
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, Temperature
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension

OUTPUT_TOPICS = ('modal_displacement', 'radial_gap', 'sense_electrodes')
"""Block topics, relative to the node's private namespace (``~/``)."""
DEMODULATOR_TOPIC = 'demodulator'
"""The gyroscope's block topic (``gyro.enabled``): ``t`` and the demodulator channels."""
CONTROL_TOPIC = 'control'
"""The closed loop's block topic (a closed ``control.mode``): ``t`` and the
``core.gyro.control.CONTROL_CHANNELS``, one row per loop update (at ``control.rate``)."""
RATE_TOPIC = 'rate'
"""The gyroscope's rate output (``gyro.enabled``): sensor_msgs/Imu, one per rate sample."""
ANGULAR_RATE_TOPIC = 'angular_rate'
"""The rotation input (geometry_msgs/Vector3Stamped, ``vector.z`` rad/s)."""
TEMPERATURE_TOPIC = 'temperature'
"""The ambient temperature input (sensor_msgs/Temperature, degrees Celsius)."""
DIE_TEMPERATURE_TOPIC = 'die_temperature'
"""The gyroscope's die temperature sensor (``gyro.enabled``): sensor_msgs/Temperature, one per
block, degrees Celsius."""
ZERO_CELSIUS_K = 273.15
"""
0 degrees Celsius in kelvin: sensor_msgs/Temperature carries Celsius, the run kelvin.

A temperature the run takes (``params.TEMPERATURE_RANGE_K``, 150-500 K) goes to Celsius and
back bit for bit: ``K - 273.15`` is exact for ``K`` within a factor 2 of 273.15 (Sterbenz's
lemma), so the sum back is exact too, and a recording re-simulates the ambient it recorded.
"""


def ns_to_stamp(t_ns: int) -> Time:
    """Integer ns -> builtin_interfaces/Time."""
    t_ns = int(t_ns)
    return Time(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)


def stamp_to_ns(stamp: Time) -> int:
    """builtin_interfaces/Time -> integer ns."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def block_message(columns: Sequence[np.ndarray], labels: Sequence[str]) -> Float64MultiArray:
    """Build a Float64MultiArray block from equal-length columns (first one is ``t``, s)."""
    data = np.ascontiguousarray(np.column_stack(columns), dtype=np.float64)
    n_samples, n_channels = data.shape
    msg = Float64MultiArray()
    msg.layout.dim = [
        MultiArrayDimension(label='sample', size=n_samples, stride=n_samples * n_channels),
        MultiArrayDimension(label=','.join(labels), size=n_channels, stride=n_channels),
    ]
    values = array.array('d')
    values.frombytes(data.tobytes())
    msg.data = values
    return msg


def block_cdr(columns: Sequence[np.ndarray], labels: Sequence[str]) -> bytes:
    """Return the CDR of :func:`block_message` of the same columns, without the message."""
    return cdr.float64_multiarray(np.column_stack(columns), labels)


def block_arrays(msg: Float64MultiArray) -> Tuple[List[str], np.ndarray]:
    """Labels and the (K, C) array of a block message (inverse of :func:`block_message`)."""
    labels = msg.layout.dim[1].label.split(',')
    shape = (msg.layout.dim[0].size, msg.layout.dim[1].size)
    data = np.asarray(msg.data, dtype=np.float64).reshape(shape)
    return labels, data


def output_blocks(samples, channel_names: Dict[str, List[str]], rows: slice = slice(None),
                  build=block_message,
                  topics: Optional[Collection[str]] = None) -> Dict[str, Float64MultiArray]:
    """
    Build the three block messages of a :class:`~ring_gyro_sim.core.engine.full.Samples`.

    ``rows`` selects the samples (rows) the messages hold: all of them by default; a
    recording's decimated rows (``RunRecorder.kept_rows``) when nothing publishes the blocks.
    ``build``: :func:`block_message` (messages) or :func:`block_cdr` (their CDR, to record).
    ``topics``: only those of the three named (default all).
    """
    columns = {
        'modal_displacement': lambda: [samples.q[rows]],
        'radial_gap': lambda: [samples.gap[rows], samples.min_gap[rows]],
        'sense_electrodes': lambda: [samples.capacitance[rows]],
    }
    t = samples.t[rows]
    return {name: build([t, *get()], ['t'] + channel_names[name])
            for name, get in columns.items() if topics is None or name in topics}


def demodulator_block(demod, rows: slice = slice(None),
                      build=block_message) -> Float64MultiArray:
    """Build the ``~/demodulator`` block of a ``core.gyro.electronics.DemodSamples`` (rows)."""
    values = np.asarray(demod.values, dtype=np.float64)
    if values.shape != (len(demod.t), len(DEMOD_CHANNELS)):
        raise ValueError(f'demodulator values have shape {values.shape}, expected '
                         f'({len(demod.t)}, {len(DEMOD_CHANNELS)})')
    return build([demod.t[rows], values[rows]], ('t',) + DEMOD_CHANNELS)


def control_block(control, build=block_message) -> Float64MultiArray:
    """
    Build the ``~/control`` block of a ``core.gyro.control.ControlSamples``.

    One row per loop update in the block (``t`` = the update time, then the
    ``CONTROL_CHANNELS``); a block without an update (shorter than a loop period) gives a
    message with no rows, laid out as the others.
    """
    values = np.asarray(control.values, dtype=np.float64)
    if values.shape != (len(control.t), len(CONTROL_CHANNELS)):
        raise ValueError(f'control values have shape {values.shape}, expected '
                         f'({len(control.t)}, {len(CONTROL_CHANNELS)})')
    return build([control.t, values], ('t',) + CONTROL_CHANNELS)


#: Covariance element 0 of an estimate the message does not carry (sensor_msgs/Imu comments).
NOT_ESTIMATED = -1.0
_NOT_ESTIMATED_COVARIANCE = np.array([NOT_ESTIMATED] + [0.0] * 8)


def rate_covariance(rate_variance: float) -> np.ndarray:
    """
    Return ``angular_velocity_covariance`` of ``~/rate`` (row-major 3x3, see the module doc).

    Raises
    ------
    ValueError
        If ``rate_variance`` is negative or not finite.

    """
    v = float(rate_variance)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f'rate_variance: must be finite and >= 0 (rad/s)^2, got {v!r}')
    if v == 0.0:
        return np.zeros(9)
    return np.diag([NOT_MEASURED_VARIANCE, NOT_MEASURED_VARIANCE, v]).ravel()


def imu_message(t_ns: int, rate_z: float, frame_id: str,
                covariance: Optional[np.ndarray] = None) -> Imu:
    """Build one ``~/rate`` message (see the module doc); ``covariance`` from rate_covariance."""
    msg = Imu()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.orientation_covariance = _NOT_ESTIMATED_COVARIANCE
    msg.angular_velocity.z = float(rate_z)
    if covariance is not None:
        msg.angular_velocity_covariance = covariance
    msg.linear_acceleration_covariance = _NOT_ESTIMATED_COVARIANCE
    return msg


def sample_times_ns(t_s: np.ndarray) -> List[int]:
    """
    Return the integer ns of simulation times in s (on the output grid).

    Exact for any run shorter than about 50 days: a sample time (i + 1) * period is within
    1e-16 relative of its ns value, far below half a ns.
    """
    return [int(t) for t in np.rint(np.asarray(t_s, dtype=np.float64) * 1e9)]


def rate_messages(rate, frame_id: str,
                  covariance: Optional[np.ndarray] = None) -> List[Tuple[int, Imu]]:
    """
    Return ``[(t_ns, Imu)]`` of a ``core.gyro.electronics.RateSamples`` (``~/rate``).

    Each message's covariance is that of its sample's own variance when the samples carry
    one (``RateSamples.variance``), else ``covariance`` (a constant one, or none).
    """
    times = sample_times_ns(rate.t)
    values = np.asarray(rate.rate).tolist()
    if getattr(rate, 'variance', None) is None:
        return [(t_ns, imu_message(t_ns, z, frame_id, covariance))
                for t_ns, z in zip(times, values)]
    return [(t_ns, imu_message(t_ns, z, frame_id, rate_covariance(v)))
            for t_ns, z, v in zip(times, values, np.asarray(rate.variance).tolist())]


def imu_stream(frame_id: str, covariance: Optional[np.ndarray] = None) -> cdr.ImuStream:
    """Return the packer of :func:`imu_message`'s CDR for any stamp and rate (no message)."""
    return cdr.ImuStream(frame_id, (0.0, 0.0, 0.0, 1.0), _NOT_ESTIMATED_COVARIANCE, (0.0, 0.0),
                         np.zeros(9) if covariance is None else covariance, (0.0, 0.0, 0.0),
                         _NOT_ESTIMATED_COVARIANCE)


def rate_cdr(rate, stream: cdr.ImuStream) -> List[Tuple[int, bytes]]:
    """
    Return ``[(t_ns, CDR)]`` of :func:`rate_messages` from an :func:`imu_stream`.

    As there, each message carries its sample's own variance when the samples have one
    (``RateSamples.variance``), else the stream's covariance.
    """
    times = sample_times_ns(rate.t)
    values = np.asarray(rate.rate).tolist()
    if getattr(rate, 'variance', None) is None:
        return [(t_ns, stream.message(t_ns, z)) for t_ns, z in zip(times, values)]
    return [(t_ns, stream.message(t_ns, z, rate_covariance(v)))
            for t_ns, z, v in zip(times, values, np.asarray(rate.variance).tolist())]


@dataclass(frozen=True)
class AccelerationInput:
    """
    An in-plane base acceleration from a message.

    Attributes
    ----------
    at_ns : int or None
        Stamp, ns (None when the stamp is zero: "now").
    x, y : float
        m/s^2 (x: theta = 0 -> q1, y: theta = 90 deg -> q1s).
    z : float
        Out-of-plane component, m/s^2: not modelled (in-plane ring), reported so the node can
        say it was ignored.

    """

    at_ns: Optional[int]
    x: float
    y: float
    z: float

    def finite(self) -> bool:
        """All components finite."""
        return all(math.isfinite(v) for v in (self.x, self.y, self.z))


def shock_input(msg: Vector3Stamped) -> AccelerationInput:
    """Peak base acceleration of a half-sine shock (``~/shock``)."""
    t = stamp_to_ns(msg.header.stamp)
    v = msg.vector
    return AccelerationInput(at_ns=t or None, x=float(v.x), y=float(v.y), z=float(v.z))


def base_acceleration_input(msg: AccelStamped) -> AccelerationInput:
    """One sample of a streamed base-acceleration profile (``~/base_acceleration``)."""
    t = stamp_to_ns(msg.header.stamp)
    a = msg.accel.linear
    return AccelerationInput(at_ns=t or None, x=float(a.x), y=float(a.y), z=float(a.z))


@dataclass(frozen=True)
class AngularRateInput:
    """
    An angular rate from a ``~/angular_rate`` message.

    Attributes
    ----------
    at_ns : int or None
        Stamp, ns (None when the stamp is zero: "now"), as ``~/shock``.
    z : float
        Rate about the ring axis, rad/s (REP-103 sign).
    x, y : float
        Rates about the in-plane axes, rad/s: not modelled, reported so that the node can say
        they were ignored.

    """

    at_ns: Optional[int]
    z: float
    x: float
    y: float


def angular_rate_input(msg: Vector3Stamped) -> AngularRateInput:
    """Return the angular rate of the sensor frame in a ``~/angular_rate`` message."""
    t = stamp_to_ns(msg.header.stamp)
    v = msg.vector
    return AngularRateInput(at_ns=t or None, z=float(v.z), x=float(v.x), y=float(v.y))


def angular_rate_message(at_ns: int, z: float, x: float = 0.0, y: float = 0.0,
                         frame_id: str = '') -> Vector3Stamped:
    """Build a ``~/angular_rate`` message (recording a rate as it acted)."""
    msg = Vector3Stamped()
    msg.header.stamp = ns_to_stamp(at_ns)
    msg.header.frame_id = frame_id
    msg.vector.x = float(x)
    msg.vector.y = float(y)
    msg.vector.z = float(z)
    return msg


def shock_message(at_ns: int, x: float, y: float = 0.0, frame_id: str = '') -> Vector3Stamped:
    """Build a ``~/shock`` message (used to record scheduled shocks as if they had arrived)."""
    msg = Vector3Stamped()
    msg.header.stamp = ns_to_stamp(at_ns)
    msg.header.frame_id = frame_id
    msg.vector.x = float(x)
    msg.vector.y = float(y)
    return msg


def base_acceleration_message(at_ns: int, x: float, y: float = 0.0,
                              frame_id: str = '') -> AccelStamped:
    """Build a ``~/base_acceleration`` message."""
    msg = AccelStamped()
    msg.header.stamp = ns_to_stamp(at_ns)
    msg.header.frame_id = frame_id
    msg.accel.linear.x = float(x)
    msg.accel.linear.y = float(y)
    return msg


@dataclass(frozen=True)
class TemperatureInput:
    """
    An ambient temperature from a ``~/temperature`` message.

    Attributes
    ----------
    at_ns : int or None
        Stamp, ns (None when the stamp is zero: "now"), as ``~/shock``.
    kelvin : float
        The temperature, K (the message's Celsius plus :data:`ZERO_CELSIUS_K`).

    """

    at_ns: Optional[int]
    kelvin: float


def temperature_input(msg: Temperature) -> TemperatureInput:
    """Return the ambient temperature of a ``~/temperature`` message (its variance unused)."""
    t = stamp_to_ns(msg.header.stamp)
    return TemperatureInput(at_ns=t or None, kelvin=float(msg.temperature) + ZERO_CELSIUS_K)


def temperature_message(t_ns: int, kelvin: float, frame_id: str = '') -> Temperature:
    """
    Build a sensor_msgs/Temperature at ``t_ns`` of a temperature in K (the message: Celsius).

    ``~/temperature`` as recorded (the ambient as it acted) and ``~/die_temperature`` (the
    die's sensor, which reads the model's die exactly). ``variance`` is 0: "unknown" by the
    message's definition; the model states no sensor error.
    """
    msg = Temperature()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.header.frame_id = frame_id
    msg.temperature = float(kelvin) - ZERO_CELSIUS_K
    msg.variance = 0.0
    return msg


def float_message(value: float) -> Float64:
    """std_msgs/Float64."""
    return Float64(data=float(value))


def clock_message(t_ns: int) -> Clock:
    """rosgraph_msgs/Clock at simulation time ``t_ns``."""
    return Clock(clock=ns_to_stamp(t_ns))


LEVELS = {'OK': DiagnosticStatus.OK, 'WARN': DiagnosticStatus.WARN,
          'ERROR': DiagnosticStatus.ERROR, 'STALE': DiagnosticStatus.STALE}


def diagnostics_message(t_ns: int, name: str, hardware_id: str, level: str, message: str,
                        values: Dict[str, object]) -> DiagnosticArray:
    """Build a /diagnostics array with one status; values are formatted with ``str``."""
    status = DiagnosticStatus(level=LEVELS[level], name=name, message=message,
                              hardware_id=hardware_id)
    status.values = [KeyValue(key=k, value=_format(v)) for k, v in values.items()]
    msg = DiagnosticArray()
    msg.header.stamp = ns_to_stamp(t_ns)
    msg.status = [status]
    return msg


def _format(value: object) -> str:
    if isinstance(value, float):
        return repr(value)
    return str(value)
