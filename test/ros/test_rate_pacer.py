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

"""Tests of ros/rate_pacer.py: timed messages sent when due, a few at a time, in order."""

from ring_gyro_sim.ros.rate_pacer import CATCH_UP, GROUP, RatePacer

PERIOD_S = 0.001


class Clock:
    """A wall clock the test moves by hand, s."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class Recorder:
    """A publisher that notes the clock's time of each message."""

    def __init__(self, clock):
        self.clock = clock
        self.sent = []

    def publish(self, msg):
        self.sent.append((self.clock.now, msg))


def pacer(clock, out, spacing=PERIOD_S):
    # Sample t_ns is due 20 ms after wall time 100 s + t (real time, two 10 ms blocks late).
    return RatePacer(out, lambda t_ns: 100.02 + t_ns * 1e-9, lambda: spacing, clock=clock)


def test_a_block_goes_out_at_its_sample_times_not_in_a_burst():
    clock = Clock()
    out = Recorder(clock)
    rate = pacer(clock, out)
    clock.now = 100.012  # the block of 0-10 ms, computed 2 ms after its end
    rate.publish([((k + 1) * 1_000_000, k) for k in range(10)])
    assert not out.sent and rate.pending == 10  # none due yet
    while clock.now < 100.035:
        clock.now += 0.00025  # the node calls every 0.25 ms here (ticks, stretches)
        rate.send_due()
    assert [m for _, m in out.sent] == list(range(10))
    for k, (t, _) in enumerate(out.sent):
        assert 100.021 + k * PERIOD_S <= t < 100.021 + k * PERIOD_S + 0.0003


def test_late_messages_drain_as_a_stream_of_small_groups():
    clock = Clock()
    out = Recorder(clock)
    rate = pacer(clock, out)
    clock.now = 100.08  # 30 messages 30-59 ms late (the node caught up after a stall)
    rate.publish([((k + 1) * 1_000_000, k) for k in range(30)])
    assert len(out.sent) == GROUP  # at once: a group, not all 30
    while rate.pending:
        clock.now += 0.001  # calls 1 ms apart
        rate.send_due()
    times = [t for t, _ in out.sent]
    assert [m for _, m in out.sent] == list(range(30))
    assert max(times.count(t) for t in set(times)) <= GROUP
    # at most CATCH_UP messages per period over time, after the first group
    assert (30 - GROUP) / (times[-1] - times[0]) <= CATCH_UP / PERIOD_S * 1.001


def test_unpaced_messages_go_out_with_their_block_and_flush_sends_all():
    clock = Clock()
    out = Recorder(clock)
    fast = pacer(clock, out, spacing=0.0)  # real_time_factor 0: as fast as possible
    fast.publish([(k, k) for k in range(10)])
    assert len(out.sent) == 10 and fast.pending == 0
    held = Recorder(clock)
    rate = pacer(clock, held)
    rate.publish([(k * 1_000_000, k) for k in range(5)])
    rate.flush()  # the end of a run
    assert [m for _, m in held.sent] == list(range(5)) and rate.pending == 0


def test_messages_later_than_max_late_go_out_at_once():
    from ring_gyro_sim.ros.rate_pacer import MAX_LATE_S
    clock = Clock()
    out = Recorder(clock)
    rate = pacer(clock, out)
    clock.now = 100.02 + MAX_LATE_S + 0.0305  # the first 30 of 40 are overdue
    rate.publish([(k * 1_000_000, k) for k in range(40)])
    assert [m for _, m in out.sent] == list(range(31))  # the overdue ones: 0 .. 30 ms
    clock.now += 0.5
    rate.send_due()
    assert rate.pending == 0 and [m for _, m in out.sent] == list(range(40))
