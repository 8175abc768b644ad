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
``ring_gyro replay``: publish a recording into ROS topics with its original timing.

Messages are published in log-time order, already serialized (no decode / re-encode), each at
``wall_start + (log_time - first_log_time) / rate``. Publishers are reliable / volatile,
KeepLast(100): what the node offers, so estimators with default subscriptions connect.
With ``--clock`` the log time is also published on ``/clock`` before each message (for
subscribers that run on ``use_sim_time``).

Discovery: volatile publishers deliver only to subscribers they have matched, so the first
message waits ``DISCOVERY_WAIT_S``; on a loaded machine discovery can take longer and the
first messages then reach nobody. ``--wait-for-subscribers S`` waits instead until every
publisher has at least one subscriber (at most S seconds, then starts anyway and says so):
subscribers started before the replay then receive every message.
"""

import math
import sys
import time
from typing import Iterable, Optional

from ring_gyro_sim.core.errors import InputError

DISCOVERY_WAIT_S = 3.0
"""Time given to subscribers to discover the new publishers before the first message."""
MATCH_SETTLE_S = 1.0
"""
After every publisher has matched a subscriber: time for the subscribers to match the
publishers in turn (not visible from here; until then a reliable publisher's messages reach
them only later, in a burst: seen 0.3 s after the publisher's side on a loaded machine).
"""


def replay(path: str, rate: float = 1.0, clock: bool = False,
           topics: Optional[Iterable[str]] = None, discovery_wait_s: float = DISCOVERY_WAIT_S,
           node_name: str = 'ring_gyro_replay', wait_for_subscribers_s: float = 0.0) -> int:
    """
    Publish the messages of ``path``; returns how many were published.

    Parameters
    ----------
    path : str
        MCAP recording.
    rate : float
        Playback speed factor (2 = twice as fast), > 0.
    clock : bool
        Also publish /clock with the log times.
    topics : iterable of str, optional
        Only these topics.
    discovery_wait_s : float
        Wall time to wait after creating the publishers, so that subscribers discover them, s.
    node_name : str
        Name of the publishing node.
    wait_for_subscribers_s : float
        If > 0: instead of ``discovery_wait_s``, wait until every publisher has a subscriber,
        at most this long, s.

    """
    if not rate > 0.0:
        raise InputError(f'rate: must be > 0, got {rate!r}')
    if not (math.isfinite(wait_for_subscribers_s) and wait_for_subscribers_s >= 0.0):
        raise InputError(f'wait_for_subscribers: must be finite and >= 0, got '
                         f'{wait_for_subscribers_s!r}')
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from ring_gyro_sim.recording.reader import read_messages, read_topics
    from ring_gyro_sim.recording.schemas import message_class
    from ring_gyro_sim.ros.conversions import clock_message

    wanted = set(topics) if topics else None
    types = {t: name for t, name in read_topics(path).items() if wanted is None or t in wanted}
    messages = read_messages(path, topics=list(topics) if topics else None)
    rclpy.init()
    node = rclpy.create_node(node_name)
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    # Every publisher before the discovery wait, so that no topic's first message is lost.
    publishers = {t: node.create_publisher(message_class(name), t, qos)
                  for t, name in types.items()}
    clock_pub = node.create_publisher(message_class('rosgraph_msgs/msg/Clock'), '/clock',
                                      qos) if clock else None
    count = 0
    try:
        first = None
        start = None
        for m in messages:
            if m.topic not in publishers:
                publishers[m.topic] = node.create_publisher(message_class(m.type_name),
                                                            m.topic, qos)
            if first is None:
                if wait_for_subscribers_s > 0.0:
                    every = list(publishers.values()) + [p for p in (clock_pub,) if p]
                    _wait(node, wait_for_subscribers_s,
                          lambda: all(p.get_subscription_count() > 0 for p in every))
                    alone = sorted(p.topic_name for p in every if not p.get_subscription_count())
                    if alone:
                        print(f'replay: no subscriber after {wait_for_subscribers_s:g} s on '
                              f'{", ".join(alone)}; starting anyway', file=sys.stderr)
                    else:
                        _wait(node, MATCH_SETTLE_S)
                else:
                    _wait(node, discovery_wait_s)
                first = m.log_time_ns
                start = time.monotonic()
            due = start + (m.log_time_ns - first) * 1e-9 / rate
            delay = due - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            if clock_pub is not None:
                clock_pub.publish(clock_message(m.log_time_ns))
            publishers[m.topic].publish(m.data)
            count += 1
        _wait(node, 0.5)  # let reliable publishers deliver the tail
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return count


def _wait(node, seconds: float, done=lambda: False) -> None:
    import rclpy
    end = time.monotonic() + seconds
    while time.monotonic() < end and not done():
        rclpy.spin_once(node, timeout_sec=0.05)
