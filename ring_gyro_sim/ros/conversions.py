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

Block layout (interface.md): ``layout.dim[0] = {label: 'sample', size: K, stride: K * C}``,
``layout.dim[1] = {label: 't,<channels>', size: C, stride: C}``, ``data`` row-major.
"""

import array
from dataclasses import dataclass
import math
from typing import Dict, List, Optional, Sequence, Tuple

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import AccelStamped, Vector3Stamped
import numpy as np
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension

OUTPUT_TOPICS = ('modal_displacement', 'radial_gap', 'sense_electrodes')
"""Block topics, relative to the node's private namespace (``~/``)."""


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


def block_arrays(msg: Float64MultiArray) -> Tuple[List[str], np.ndarray]:
    """Labels and the (K, C) array of a block message (inverse of :func:`block_message`)."""
    labels = msg.layout.dim[1].label.split(',')
    shape = (msg.layout.dim[0].size, msg.layout.dim[1].size)
    data = np.asarray(msg.data, dtype=np.float64).reshape(shape)
    return labels, data


def output_blocks(samples, channel_names: Dict[str, List[str]]) -> Dict[str, Float64MultiArray]:
    """Build the three block messages of a :class:`~ring_gyro_sim.core.simulator.Samples`."""
    t = samples.t
    return {
        'modal_displacement': block_message([t, samples.q],
                                            ['t'] + channel_names['modal_displacement']),
        'radial_gap': block_message([t, samples.gap, samples.min_gap],
                                    ['t'] + channel_names['radial_gap']),
        'sense_electrodes': block_message([t, samples.capacitance],
                                          ['t'] + channel_names['sense_electrodes']),
    }


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
