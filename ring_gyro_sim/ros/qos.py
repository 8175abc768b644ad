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
The QoS of every topic of the node: the one source for the live node and the recorder.

A recording stores, per topic, the QoS its publisher offered (``offered_qos_profiles``), which
is what ``ros2 bag play`` offers again; the node creates its publishers and subscriptions with
these same profiles, so what a recording says is what a live subscriber met.

============================  ==========================================================
topic (relative to the node)  QoS
============================  ==========================================================
``modal_displacement``,       :data:`BLOCK_QOS`: reliable, volatile, keep last 50 (a
``radial_gap``,               default subscriber, keep last 10, connects and gets every
``sense_electrodes``          block while it keeps up)
``/diagnostics``              :data:`DIAGNOSTICS_QOS`: reliable, volatile, keep last 10
``/clock``                    :data:`CLOCK_QOS`: reliable, volatile, keep last 10
``shock``                     :data:`SHOCK_QOS`: reliable, volatile, keep last 1000
``base_acceleration``         :data:`BASE_ACCELERATION_QOS`: reliable, volatile, keep last
                              1000
``drive/amplitude``,          :data:`DRIVE_QOS`: reliable, volatile, keep last 10
``drive/frequency``
``events/reset``,             :data:`EVENTS_QOS`: reliable, volatile, keep last 10 (topics
``events/parameters``         of recordings only: a service call and parameter changes
                              live, recorded so that a run can be re-simulated)
``demodulator``               :data:`BLOCK_QOS` (a block topic; with ``gyro.enabled``)
``rate``                      :data:`RATE_QOS`: reliable, volatile, keep last 500 (one
                              sensor_msgs/Imu per rate sample: the same 50 blocks as
                              :data:`BLOCK_QOS` at the default 10 rate samples per block;
                              with ``gyro.enabled``)
``angular_rate``              :data:`ANGULAR_RATE_QOS`: reliable, volatile, keep last 1000
                              (a streamed rate profile comes in bursts, as
                              ``base_acceleration``)
``control``                   :data:`BLOCK_QOS` (a block topic; with a closed
                              ``control.mode``)
============================  ==========================================================

The inputs are subscriptions in the node; their recorded profile is the subscription's (a
publisher offering it on ``ros2 bag play`` is compatible with the node's subscription).
"""

from typing import Dict

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = [
    'ANGULAR_RATE_QOS', 'BASE_ACCELERATION_QOS', 'BLOCK_QOS', 'CLOCK_QOS', 'DIAGNOSTICS_QOS',
    'DIE_TEMPERATURE_QOS', 'DRIVE_QOS', 'EVENTS_QOS', 'RATE_QOS', 'SHOCK_QOS',
    'TEMPERATURE_QOS', 'TOPIC_QOS', 'recorded_qos',
]


def _reliable_keep_last(depth: int) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


#: Block topics (``~/modal_displacement``, ``~/radial_gap``, ``~/sense_electrodes``; also
#: ``~/demodulator`` and ``~/control``).
BLOCK_QOS = _reliable_keep_last(50)
#: ``/diagnostics``.
DIAGNOSTICS_QOS = _reliable_keep_last(10)
#: ``/clock`` (published when ``publish_clock`` is true).
CLOCK_QOS = _reliable_keep_last(10)
#: ``~/shock`` subscription: a flood is dropped by the middleware queue, never stored unbounded.
SHOCK_QOS = _reliable_keep_last(1000)
#: ``~/base_acceleration`` subscription (samples come in bursts).
BASE_ACCELERATION_QOS = _reliable_keep_last(1000)
#: ``~/drive/amplitude`` and ``~/drive/frequency`` subscriptions.
DRIVE_QOS = _reliable_keep_last(10)
#: ``~/events/reset`` and ``~/events/parameters`` (recordings only).
EVENTS_QOS = _reliable_keep_last(10)
#: ``~/rate`` (sensor_msgs/Imu, one message per rate sample, paced: ``ros/rate_pacer.py``).
RATE_QOS = _reliable_keep_last(500)
#: ``~/angular_rate`` subscription (a streamed profile comes in bursts).
ANGULAR_RATE_QOS = _reliable_keep_last(1000)
#: ``~/temperature`` subscription (an ambient profile may come in bursts).
TEMPERATURE_QOS = _reliable_keep_last(100)
#: ``~/die_temperature`` (sensor_msgs/Temperature, one message per block).
DIE_TEMPERATURE_QOS = _reliable_keep_last(10)

#: QoS of every topic, by the name the node uses (relative to its namespace, or absolute).
TOPIC_QOS: Dict[str, QoSProfile] = {
    'modal_displacement': BLOCK_QOS,
    'radial_gap': BLOCK_QOS,
    'sense_electrodes': BLOCK_QOS,
    '/diagnostics': DIAGNOSTICS_QOS,
    '/clock': CLOCK_QOS,
    'shock': SHOCK_QOS,
    'base_acceleration': BASE_ACCELERATION_QOS,
    'drive/amplitude': DRIVE_QOS,
    'drive/frequency': DRIVE_QOS,
    'events/reset': EVENTS_QOS,
    'events/parameters': EVENTS_QOS,
    'demodulator': BLOCK_QOS,
    'rate': RATE_QOS,
    'angular_rate': ANGULAR_RATE_QOS,
    'control': BLOCK_QOS,
    'temperature': TEMPERATURE_QOS,
    'die_temperature': DIE_TEMPERATURE_QOS,
}


def recorded_qos(profile: QoSProfile) -> Dict[str, object]:
    """
    Return the keyword arguments of ``BagWriter.add_topic`` that record ``profile``.

    Raises
    ------
    ValueError
        If the profile is not keep-last (the only history the recorder writes).

    """
    if profile.history != HistoryPolicy.KEEP_LAST:
        raise ValueError(f'only keep-last QoS profiles are recorded, got {profile.history!r}')
    durability = {DurabilityPolicy.VOLATILE: 'volatile',
                  DurabilityPolicy.TRANSIENT_LOCAL: 'transient_local'}[profile.durability]
    return {'reliable': profile.reliability == ReliabilityPolicy.RELIABLE,
            'durability': durability, 'depth': int(profile.depth)}
