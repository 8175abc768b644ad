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

"""Sample run data for the recording tests: real rclpy messages laid out as the node sends them."""

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped
from ring_gyro_sim.recording.writer import BagWriter
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

BLOCK_TOPIC = '/ring_gyro/modal_displacement'
SHOCK_TOPIC = '/ring_gyro/shock'
DIAGNOSTICS_TOPIC = '/diagnostics'
CLOCK_TOPIC = '/clock'
IDLE_TOPIC = '/ring_gyro/radial_gap'  # registered, never written

TOPIC_TYPES = {
    BLOCK_TOPIC: 'std_msgs/msg/Float64MultiArray',
    SHOCK_TOPIC: 'geometry_msgs/msg/Vector3Stamped',
    DIAGNOSTICS_TOPIC: 'diagnostic_msgs/msg/DiagnosticArray',
    CLOCK_TOPIC: 'rosgraph_msgs/msg/Clock',
    IDLE_TOPIC: 'std_msgs/msg/Float64MultiArray',
}

RUN_METADATA = {'version': '0.1.0', 'parameters': 'modes:\n  frequencies: [14000.0]\n'}
CUSTOM_DATA = {'scenario': 'unit test', 'seed': '7'}

SAMPLE_PERIOD_NS = 10_000  # 100 kHz output rate
SAMPLES_PER_BLOCK = 4
CHANNELS = ('t', 'q1', 'q2', 'q3')


def stamp(time_ns):
    """Return a builtin_interfaces/Time for a time in ns."""
    return Time(sec=time_ns // 1_000_000_000, nanosec=time_ns % 1_000_000_000)


def block_message(first_sample_ns):
    """Return a block as the contract lays it out: dim[0] samples, dim[1] channels."""
    message = Float64MultiArray()
    message.layout.dim = [
        MultiArrayDimension(label='sample', size=SAMPLES_PER_BLOCK,
                            stride=SAMPLES_PER_BLOCK * len(CHANNELS)),
        MultiArrayDimension(label=','.join(CHANNELS), size=len(CHANNELS), stride=len(CHANNELS)),
    ]
    data = []
    for k in range(SAMPLES_PER_BLOCK):
        t_s = (first_sample_ns + k * SAMPLE_PERIOD_NS) * 1e-9
        data += [t_s, 1e-9 * (k + 1), -2e-9 * k, 0.5e-9]
    message.data = data
    return message


def shock_message(time_ns, peak_m_s2):
    """Return a shock input (peak base acceleration in m/s^2 along x)."""
    message = Vector3Stamped()
    message.header.stamp = stamp(time_ns)
    message.header.frame_id = 'ring'
    message.vector.x = peak_m_s2
    return message


def diagnostics_message(time_ns, real_time_factor):
    """Return a /diagnostics message with one status."""
    message = DiagnosticArray()
    message.header.stamp = stamp(time_ns)
    message.status = [DiagnosticStatus(
        level=DiagnosticStatus.OK, name='ring_gyro: simulator', message='running',
        hardware_id='ring_gyro_sim',
        values=[KeyValue(key='real_time_factor', value=f'{real_time_factor:.3f}'),
                KeyValue(key='contact', value='false')])]
    return message


def clock_message(time_ns):
    """Return a /clock message."""
    return Clock(clock=stamp(time_ns))


def sample_messages(block_count=5):
    """Return [(topic, message, log_time_ns)] of a short run, in log-time order."""
    messages = [(SHOCK_TOPIC, shock_message(0, 981.0), 0)]
    block_period_ns = SAMPLES_PER_BLOCK * SAMPLE_PERIOD_NS
    for b in range(block_count):
        time_ns = b * block_period_ns
        messages.append((CLOCK_TOPIC, clock_message(time_ns), time_ns))
        messages.append((BLOCK_TOPIC, block_message(time_ns), time_ns))
    end_ns = block_count * block_period_ns
    messages.append((DIAGNOSTICS_TOPIC, diagnostics_message(end_ns, 12.5), end_ns))
    return messages


def write_sample_bag(path, messages, **writer_options):
    """Record ``messages`` to ``path`` with every sample topic registered."""
    with BagWriter(path, custom_data=CUSTOM_DATA, **writer_options) as bag:
        for topic, type_name in TOPIC_TYPES.items():
            bag.add_topic(topic, type_name, reliable=topic != DIAGNOSTICS_TOPIC)
        bag.add_metadata('ring_gyro_sim', RUN_METADATA)
        for topic, message, log_time_ns in messages:
            bag.write(topic, message, log_time_ns)
    return path
