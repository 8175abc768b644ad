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
``~/rate`` paced: each message goes out at its sample time, not in a burst with its block.

The node computes a block once its last sample is due and publishes its block messages at
once, but the rate output is one ``sensor_msgs/Imu`` per rate sample (10 per 10 ms block at
the defaults): published with its block, the 10 went out in a burst, and a subscriber with
rclpy's ``qos_profile_sensor_data`` (best effort, keep last 5: what a sensor-fusion node
uses) kept the last 5 of each burst it had not taken yet: 79-80 % of the messages. A real
gyroscope sends one sample per output period; so does the node now, two at a time at most.

:class:`RatePacer` holds the messages of the blocks computed (:meth:`RatePacer.publish`) and
sends those that are due whenever the node calls :meth:`RatePacer.send_due`. The node, which
has one thread, calls it at every tick of its timer, after every stretch of a block it
computes (``Simulator.advance_samples``, ``between``: every loop update, 1 ms, closed loop)
and, through each tick, sleeps until the next pair is due (:meth:`RatePacer.next_send_s`;
``ros/node.py``, "Pacing"). A message is due at the wall time the node gives: its sample
time delayed by a fixed latency, so that a block's messages are ready before the first of
them is due (two blocks, while the node keeps its pace), mapped to the wall clock by the
node's pacing. A token bucket sends at most :data:`GROUP` together and at most
:data:`CATCH_UP` times the rate over time, so messages that are late (the node behind and
catching up, or a long stretch) drain as a stream a subscriber can follow, not as a burst;
only those more than :data:`MAX_LATE_S` late go out at once.
As fast as possible (``real_time_factor`` 0) nothing is paced: the messages go out with their
block. The order is kept; :meth:`RatePacer.flush` sends what is held (the end of a run).

Not a thread that sleeps until each message is due: it wakes once per message and takes the
GIL from the simulation each time, which costs the simulation CPU time and, with a short
switch interval, speed; single-threaded, the pacing costs nothing measurable
(doc/performance.md, "``~/rate`` paced", has the figures).
"""

import collections
import math
import time
from typing import Callable, Deque, Sequence, Tuple

__all__ = ['CATCH_UP', 'GROUP', 'MAX_LATE_S', 'RatePacer']

GROUP = 2
"""
Most messages sent together (the bucket's tokens): late ones, those due during a long stretch,
and on time the node sends them in pairs (half the wake-ups); a keep-last-5 subscriber takes a
pair before the next.
"""
CATCH_UP = 1.5
"""
Most messages sent per rate period over time, when they are late (a token bucket).

Barely faster than the rate: a subscriber that keeps up with the rate keeps up with a backlog
(rclpy's executor takes 100-200 us per message under load: at 4 times the rate a
``qos_profile_sensor_data`` subscriber lost 4 % of them); a backlog of N messages drains in
N / (CATCH_UP - 1) periods.
"""


MAX_LATE_S = 0.25
"""
Latest a message waits for a token, s: one later than this goes out at once.

After a lag (the host busy elsewhere, the node behind and catching up as fast as it can) the
messages come late faster than ``CATCH_UP`` drains them: unbounded, they fell up to 1.3 s
behind the blocks under load on two cores, and the flush at the end of the run sent them all
at once, more than ``~/rate``'s reliable history of 500 holds for a subscriber that has not
acknowledged them. Bounded, a stall of the node shorter than this (80-100 ms were common
under that load, also at nice -10) drains as a stream; a longer one makes a burst of the
excess, as a node that cannot keep real time does, and nothing more.
"""


class RatePacer:
    """
    Send timed messages when they are due, a few at a time (module doc); not thread-safe.

    Parameters
    ----------
    publisher
        Has ``publish(msg)`` (an rclpy publisher).
    due_s : callable
        ``due_s(t_ns)``: the wall time (``clock``, s) at which the message of sample time
        ``t_ns`` is due.
    spacing_s : callable
        ``spacing_s()``: the wall time between two samples at the current pacing, s; 0: no
        pacing (every message goes out as soon as it is handed over).
    clock : callable
        Monotonic wall clock, s.

    """

    def __init__(self, publisher, due_s: Callable[[int], float],
                 spacing_s: Callable[[], float],
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._publisher = publisher
        self._due_s = due_s
        self._spacing_s = spacing_s
        self._clock = clock
        self._queue: Deque[Tuple[float, object]] = collections.deque()
        self._tokens = float(GROUP)
        self._filled_s = clock()
        self.published = 0

    @property
    def pending(self) -> int:
        """Return the number of messages held, not sent yet."""
        return len(self._queue)

    def publish(self, messages: Sequence[Tuple[int, object]]) -> None:
        """Hold ``[(t_ns, msg)]`` (in time order) until each is due; send those due now."""
        for t_ns, msg in messages:
            self._queue.append((self._due_s(int(t_ns)), msg))
        self.send_due()

    def send_due(self) -> None:
        """Send the messages that are due, at most the tokens of the bucket (module doc)."""
        queue = self._queue
        if not queue:
            return
        spacing = self._spacing_s()
        if spacing <= 0.0:
            self.flush()  # not paced
            return
        now = self._clock()
        period = spacing / CATCH_UP
        self._tokens = min(float(GROUP), self._tokens + (now - self._filled_s) / period)
        self._filled_s = now
        while queue and queue[0][0] <= now:
            if self._tokens >= 1.0:
                self._tokens -= 1.0
            elif queue[0][0] > now - MAX_LATE_S:
                break  # late, paced: it waits for a token
            self._publisher.publish(queue.popleft()[1])  # (overdue: at once, token or not)
            self.published += 1

    def next_send_s(self, count: int = 1) -> float:
        """
        Return the wall time (s) the next ``count`` messages may go out (inf: none held).

        When they are due and the bucket holds their tokens; with fewer held, when those held
        may. Unpaced: now.
        """
        queue = self._queue
        if not queue:
            return math.inf
        spacing = self._spacing_s()
        if spacing <= 0.0:
            return self._clock()
        count = min(count, len(queue), GROUP)
        token_s = self._filled_s + max(0.0, count - self._tokens) * spacing / CATCH_UP
        return max(queue[count - 1][0], token_s)

    def flush(self) -> None:
        """Send every message held, now."""
        queue = self._queue
        while queue:
            self._publisher.publish(queue.popleft()[1])
            self.published += 1
