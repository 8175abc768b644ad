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

Timing
    Every message has an absolute deadline on the monotonic clock, computed from the first
    message's start, never from the previous publication: no message is published before its
    deadline, and the small delay of each wake-up does not add up over a replay. A stall of
    the host (a loaded machine that does not run the replay for a while) delays the messages
    due during it; when the replay runs again it publishes those at once and is back on
    schedule with the next one: a stall costs lateness once, it does not shift what follows.
    Nothing is dropped to catch up. :attr:`ReplayResult.max_lag_s` (and the closing note)
    says how far behind its deadline the latest message was published.

Discovery
    Volatile publishers deliver only to subscribers they have matched, so the first message
    waits ``DISCOVERY_WAIT_S``; on a loaded machine discovery can take longer and the first
    messages then reach nobody. ``--wait-for-subscribers S`` waits instead until every
    publisher has at least one subscriber (at most S seconds, then starts anyway and says so),
    then :data:`MATCH_SETTLE_S` for the subscribers' side of the match: subscribers started
    before the replay then receive every message.

Gaps
    A gap between two consecutive log times longer than ``max_gap_s`` (``--max-gap``,
    default :data:`MAX_GAP_S`; ``inf`` keeps every gap) is shortened to ``max_gap_s``, with a
    warning naming where: an input stamped years ahead (a 2038 stamp) does not make replay
    wait for years. The later messages keep their spacing.

Signals
    SIGINT (Ctrl-C) and SIGTERM stop the replay within :data:`SIGNAL_LATENCY_S` (also during
    the discovery wait and any gap), the node is destroyed and rclpy shut down:
    :attr:`ReplayResult.stopped_by` names the signal and ``ring_gyro replay`` exits with code 0,
    saying how many messages were published. A second signal stops at once.

Files
    The recording is checked before ROS starts: an empty (0-byte) file, a file that is not
    MCAP, an incomplete one (no summary: a killed recorder or a cut-off copy), one whose
    chunks cannot be read, or a selection with no messages is refused with a
    :class:`~ring_gyro_sim.recording.errors.RecordingError` naming the file and the reason
    (exit code 1).
"""

from dataclasses import dataclass
import math
import signal
import sys
import threading
import time
from typing import Callable, Iterable, List, Optional

from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.recording.errors import RecordingError

__all__: List[str] = ['DISCOVERY_WAIT_S', 'MATCH_SETTLE_S', 'MAX_GAP_S', 'ReplayResult',
                      'check_recording', 'replay']

DISCOVERY_WAIT_S = 3.0
"""Time given to subscribers to discover the new publishers before the first message."""
MATCH_SETTLE_S = 1.0
"""
After every publisher has matched a subscriber: time for the subscribers to match the
publishers in turn (not visible from here; until then a reliable publisher's messages reach
them only later, in a burst: seen 0.3 s after the publisher's side on a loaded machine).
"""
MAX_GAP_S = 1.0
"""Longest gap between consecutive log times that replay keeps, s (of log time). Gaps in a
recording of the node or of ``ring_gyro run`` are one block (10 ms by default); a scheduled
shock or an input may come later, but hardly a second after the last block."""
SIGNAL_LATENCY_S = 0.05
"""Longest single sleep, s: how soon a signal is acted on."""
MAX_GAP_WARNINGS = 5
"""Gap warnings printed in one replay (the rest are only counted)."""
_MCAP_MAGIC = b'\x89MCAP0\r\n'


@dataclass
class ReplayResult:
    """
    What one replay did.

    Attributes
    ----------
    published : int
        Messages published (without /clock).
    total : int
        Messages selected for replay.
    stopped_by : str or None
        'SIGINT' or 'SIGTERM' if a signal stopped the replay, else None.
    shortened_gaps : int
        Gaps longer than ``max_gap_s`` that were shortened.
    skipped_s : float
        Log time skipped by shortening them, s.
    max_lag_s : float
        Largest delay between a message's deadline and its publication, s (monotonic clock of
        the replaying process).
    max_lag_log_time_ns : int or None
        Log time of that message, ns.

    """

    published: int
    total: int
    stopped_by: Optional[str] = None
    shortened_gaps: int = 0
    skipped_s: float = 0.0
    max_lag_s: float = 0.0
    max_lag_log_time_ns: Optional[int] = None

    def describe(self) -> str:
        """Return the one-line note ``ring_gyro replay`` prints at the end."""
        if self.stopped_by:
            text = (f'stopped by {self.stopped_by}: replayed {self.published} of '
                    f'{self.total} messages')
        else:
            text = f'replayed {self.published} messages'
        if self.shortened_gaps:
            text += (f' ({self.shortened_gaps} gap(s) shortened, {self.skipped_s:.6g} s of '
                     'log time skipped)')
        if self.published:
            text += (f'; latest publication {self.max_lag_s * 1e3:.3g} ms after its '
                     f'deadline (log time {self.max_lag_log_time_ns * 1e-9:.9g} s)')
        return text


def check_recording(path, topics: Optional[Iterable[str]] = None) -> int:
    """
    Check that ``path`` is a complete MCAP recording with messages to replay.

    Parameters
    ----------
    path : str or path-like
        The recording.
    topics : iterable of str, optional
        Only these topics (each must be in the recording).

    Returns
    -------
    int
        The number of messages selected.

    Raises
    ------
    RecordingError
        The file is missing, empty, not MCAP, incomplete (no summary) or has no messages to
        replay; the message names the file and the reason.

    """
    from mcap.reader import SeekingReader
    name = repr(str(path))
    try:
        with open(path, 'rb') as stream:
            magic = stream.read(len(_MCAP_MAGIC))
            size = stream.seek(0, 2)
            if size == 0:
                raise RecordingError(f'recording {name} is empty (0 bytes)')
            if magic != _MCAP_MAGIC:
                raise RecordingError(f'{name} is not an MCAP file ({size} bytes, no MCAP '
                                     'magic at the start)')
            stream.seek(0)
            try:
                summary = SeekingReader(stream).get_summary()
            except Exception:  # noqa: B902 - whatever a cut-off file makes mcap raise
                summary = None
    except OSError as exc:
        raise RecordingError(f'cannot read recording {name}: {exc.strerror or exc}') from exc
    if summary is None or summary.statistics is None:
        raise RecordingError(
            f'recording {name} is incomplete: it has no summary (the recorder was killed or '
            'the file was cut off); replay needs a complete file')
    counts = summary.statistics.channel_message_counts
    by_topic = {}
    for channel_id, channel in summary.channels.items():
        by_topic[channel.topic] = by_topic.get(channel.topic, 0) + counts.get(channel_id, 0)
    if topics:
        unknown = sorted(set(topics) - set(by_topic))
        if unknown:
            raise RecordingError(f'--topics: {", ".join(unknown)} not in recording {name} '
                                 f'(it has {", ".join(sorted(by_topic)) or "no topics"})')
        by_topic = {t: n for t, n in by_topic.items() if t in set(topics)}
    total = sum(by_topic.values())
    if total == 0:
        raise RecordingError(f'recording {name} holds no messages'
                             + (' on the selected topics' if topics else ''))
    return total


class _Stop:
    """SIGINT / SIGTERM handler: note the first signal, raise KeyboardInterrupt on the second."""

    def __init__(self) -> None:
        self.signal: Optional[str] = None

    def __call__(self, signum, frame) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signal.Signals(signum).name


def replay(path: str, rate: float = 1.0, clock: bool = False,
           topics: Optional[Iterable[str]] = None, discovery_wait_s: float = DISCOVERY_WAIT_S,
           node_name: str = 'ring_gyro_replay', max_gap_s: float = MAX_GAP_S,
           warn: Optional[Callable[[str], None]] = None,
           wait_for_subscribers_s: float = 0.0) -> ReplayResult:
    """
    Publish the messages of ``path``; see the module docstring.

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
    max_gap_s : float
        Longest gap between consecutive log times kept, s (``inf``: all), > 0.
    warn : callable, optional
        Called with each warning line (default: printed on stderr).
    wait_for_subscribers_s : float
        If > 0: instead of ``discovery_wait_s``, wait until every publisher has a subscriber,
        at most this long, s.

    Returns
    -------
    ReplayResult
        How many messages were published and whether a signal stopped the replay.

    Raises
    ------
    InputError
        A bad ``rate`` or ``max_gap_s``.
    RecordingError
        The file cannot be replayed (see :func:`check_recording`) or a chunk cannot be read.

    """
    if not rate > 0.0 or not math.isfinite(rate):
        raise InputError(f'rate: must be a finite number > 0, got {rate!r}')
    if not max_gap_s > 0.0:
        raise InputError(f'max_gap: must be > 0 s (inf keeps every gap), got {max_gap_s!r}')
    if not (math.isfinite(wait_for_subscribers_s) and wait_for_subscribers_s >= 0.0):
        raise InputError(f'wait_for_subscribers: must be finite and >= 0, got '
                         f'{wait_for_subscribers_s!r}')
    topics = list(topics) if topics else None
    if warn is None:
        def warn(line):
            print(f'ring_gyro replay: warning: {line}', file=sys.stderr)
    total = check_recording(path, topics)
    stop = _Stop()
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        return _publish(path, rate, clock, topics, discovery_wait_s, node_name, max_gap_s,
                        warn, total, stop, wait_for_subscribers_s)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _publish(path, rate, clock, topics, discovery_wait_s, node_name, max_gap_s, warn, total,
             stop, wait_for_subscribers_s) -> ReplayResult:
    result = ReplayResult(published=0, total=total)
    try:
        import rclpy
        from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rclpy.signals import SignalHandlerOptions

        from ring_gyro_sim.recording.reader import read_messages, read_topics
        from ring_gyro_sim.recording.schemas import message_class
        from ring_gyro_sim.ros.conversions import clock_message
    except KeyboardInterrupt:  # a second signal during the imports
        result.stopped_by = stop.signal
        return result
    if stop.signal:
        result.stopped_by = stop.signal
        return result
    wanted = set(topics) if topics else None
    types = {t: name for t, name in read_topics(path).items() if wanted is None or t in wanted}
    # Our own handlers (above), not rclpy's: those would shut the context down under a publish.
    # A context of its own: a process that already runs ROS (a test, an application calling
    # replay()) keeps its global context untouched.
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = rclpy.create_node(node_name, context=context)
        executor = SingleThreadedExecutor(context=context)  # node.executor is a weak reference
        executor.add_node(node)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        # Every publisher before the discovery wait, so that no topic's first message is lost.
        publishers = {t: node.create_publisher(message_class(name), t, qos)
                      for t, name in types.items()}
        clock_pub = node.create_publisher(message_class('rosgraph_msgs/msg/Clock'), '/clock',
                                          qos) if clock else None
        messages = _checked(read_messages(path, topics=topics), path)
        first = previous = None
        start = 0.0
        skipped_ns = 0
        max_gap_ns = max_gap_s * 1e9
        for m in messages:
            if stop.signal:
                break
            if m.topic not in publishers:
                publishers[m.topic] = node.create_publisher(message_class(m.type_name),
                                                            m.topic, qos)
            if first is None:
                if not _discover(node, list(publishers.values()) + [p for p in (clock_pub,) if p],
                                 discovery_wait_s, wait_for_subscribers_s, stop, warn):
                    break
                first = previous = m.log_time_ns
                start = time.monotonic()
            gap_ns = m.log_time_ns - previous
            if gap_ns > max_gap_ns:
                skipped_ns += gap_ns - max_gap_ns
                result.shortened_gaps += 1
                result.skipped_s = skipped_ns * 1e-9
                if result.shortened_gaps <= MAX_GAP_WARNINGS:
                    warn(f'a gap of {gap_ns * 1e-9:.6g} s in the log times before the message '
                         f'on {m.topic} at {m.log_time_ns * 1e-9:.6g} s: shortened to '
                         f'{max_gap_s:g} s (--max-gap)')
            previous = m.log_time_ns
            due = start + (m.log_time_ns - first - skipped_ns) * 1e-9 / rate
            if not _sleep_until(due, stop):
                break
            lag_s = time.monotonic() - due
            if result.max_lag_log_time_ns is None or lag_s > result.max_lag_s:
                result.max_lag_s, result.max_lag_log_time_ns = lag_s, m.log_time_ns
            if clock_pub is not None:
                clock_pub.publish(clock_message(m.log_time_ns))
            publishers[m.topic].publish(m.data)
            result.published += 1
        else:
            _spin_for(node, 0.5, stop)  # let reliable publishers deliver the tail
    except (KeyboardInterrupt, ExternalShutdownException):
        pass  # a second signal, or the context shut down from outside
    finally:
        if node is not None:
            node.destroy_node()
        context.try_shutdown()
    result.stopped_by = stop.signal
    return result


def _checked(messages, path):
    """Yield ``messages``; a chunk that cannot be read raises RecordingError naming ``path``."""
    iterator = iter(messages)
    count = 0
    while True:
        try:
            m = next(iterator)
        except StopIteration:
            return
        except RecordingError:
            raise
        except Exception as exc:  # noqa: B902 - mcap, zstd, CRC errors of a damaged chunk
            raise RecordingError(f'recording {str(path)!r} is damaged after {count} messages: '
                                 f'{type(exc).__name__}: {exc}') from exc
        count += 1
        yield m


def _sleep_until(due: float, stop) -> bool:
    """Sleep until monotonic time ``due`` in short slices; False if a signal came first."""
    while not stop.signal:
        delay = due - time.monotonic()
        if delay <= 0.0:
            return True
        time.sleep(min(delay, SIGNAL_LATENCY_S))
    return False


def _discover(node, publishers, discovery_wait_s: float, wait_for_subscribers_s: float,
              stop, warn) -> bool:
    """Wait for the subscribers (see the module docstring); False if a signal came first."""
    if wait_for_subscribers_s <= 0.0:
        return _spin_for(node, discovery_wait_s, stop)
    if not _spin_for(node, wait_for_subscribers_s, stop,
                     lambda: all(p.get_subscription_count() > 0 for p in publishers)):
        return False
    alone = sorted(p.topic_name for p in publishers if not p.get_subscription_count())
    if alone:
        warn(f'no subscriber after {wait_for_subscribers_s:g} s on {", ".join(alone)}; '
             'starting anyway')
        return True
    return _spin_for(node, MATCH_SETTLE_S, stop)


def _spin_for(node, seconds: float, stop, done=lambda: False) -> bool:
    """Serve the node's events for ``seconds`` or until ``done()``; False on a signal."""
    end = time.monotonic() + seconds
    while time.monotonic() < end and not done():
        if stop.signal:
            return False
        node.executor.spin_once(timeout_sec=min(SIGNAL_LATENCY_S,
                                                max(end - time.monotonic(), 0.0)))
    return not stop.signal
