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
Recording of one run to a ROS 2 bag, shared by the node and the offline command line.

What a recording holds (doc/interface.md, "Recording (MCAP)"):

* the output blocks (``<ns>/modal_displacement``, ``radial_gap``, ``sense_electrodes``),
  ``/diagnostics`` and, when published, ``/clock``; log time = simulation time of the last
  sample of the block (when it is complete);
* every input that reached the simulator, at the simulation time it was applied:
  ``<ns>/shock``, ``<ns>/base_acceleration`` (stamps = application times),
  ``<ns>/drive/amplitude``, ``<ns>/drive/frequency``; and, so that a run can be re-simulated,
  ``<ns>/events/reset`` (std_msgs/Empty) and ``<ns>/events/parameters`` (std_msgs/String: a
  YAML mapping of the parameters changed at run time);
* with ``gyro.enabled`` (and only then: the node has these topics only then): the rate output
  ``<ns>/rate`` (sensor_msgs/Imu, one message per rate sample, log time = its sample time =
  its header stamp, so ``ring_gyro replay`` publishes them at their rate), the block topic
  ``<ns>/demodulator`` (as the other block topics), and the rotation input
  ``<ns>/angular_rate`` (Vector3Stamped, stamped and logged at the time it acted, in the
  sensor frame: ``header.frame_id`` = ``gyro.frame_id``, as ``~/rate``);
* with a closed ``control.mode`` (and only then): the block topic ``<ns>/control``, the
  loops' updates of each block (one row per update, ``t`` and
  ``core.gyro.control.CONTROL_CHANNELS``), logged at the block's end as the other block topics;
* a metadata record ``ring_gyro_sim`` with the full resolved parameters (YAML), the package
  version, the git revision, the namespace, the exact initial state (JSON, repr floats), and
  how the recording was cut: ``output_period_ns``, ``block_samples`` (samples per block of
  the run), ``record_decimation``, ``record_topics`` and ``block_topics`` (JSON lists of the
  topics it holds), ``compression``.

Messages are written in log-time order: an input stamped ahead (a scheduled shock at 0.5 s)
is held back until the outputs reach its time (one still pending when the run ends is written
at the end, so the recording keeps every input that was accepted).

Controls (parameters ``record.*``, read from the configuration):

``record.topics``
    The topics to record, as the node names them: ``modal_displacement``, ``radial_gap``,
    ``sense_electrodes``, ``demodulator``, ``control``, ``rate``, ``/diagnostics``,
    ``/clock``, and the inputs ``shock``, ``base_acceleration``, ``drive/amplitude``,
    ``drive/frequency``, ``events/reset``, ``events/parameters``, ``angular_rate`` (fully
    qualified names ``<ns>/modal_displacement`` work too). Empty = all. The inputs and events,
    and the metadata record, are always recorded whatever the list says: they are what a
    re-simulation needs (:data:`ALWAYS_RECORDED`). An unknown name is refused
    (``ParameterError`` naming ``record.topics``). The gyroscope's topics (:data:`GYRO_TOPICS`)
    are left out of a run without ``gyro.enabled``, the closed loop's (:data:`CONTROL_TOPICS`)
    out of a run without a closed ``control.mode``, as ``/clock`` is without
    ``publish_clock``, whatever the list says (one list serves every kind of run).
``record.decimation``
    N >= 1 (default 200: 1 kHz at the default 200 kHz output, the rate of ``rate`` and
    ``control``; doc/recording.md says why): the block topics keep the samples whose global
    sample index is a multiple of N (sample i is at t = i * output period, i = 1 for the first
    sample after the start), so what is kept does not depend on how the run is cut into
    blocks; every block message is still written, at the block's end time, with the same
    layout and fewer rows (possibly none). This holds for ``demodulator`` too (a block topic,
    at every output sample).
    ``control`` is not decimated (:data:`UNDECIMATED_BLOCK_TOPICS`): its rows are the loop
    updates, already at ``control.rate`` (1 kHz by default, every 200th output sample), not
    output samples; every update is kept, in every block message.
    ``rate`` is never decimated: it is already the gyroscope's own, slower output
    (``gyro.output_rate``) and what an estimator consumes; to record less of it, leave it out
    of ``record.topics``. ``/diagnostics``, ``/clock`` and the inputs are not decimated. The
    metadata says N; :func:`ring_gyro_sim.recording.reader.block_end_times_ns` returns the
    original block ends.
``record.compression``
    ``zstd`` (default), ``lz4`` (needs the ``lz4`` package) or ``none``: the MCAP chunk
    compression, as rosbag2's MCAP storage offers.
``record.overwrite``
    False (default): an existing file at the output path is refused, as rosbag2 refuses an
    existing output. True: an existing MCAP recording is replaced; a file that is not an MCAP
    file (a scenario given as the output by mistake) is never replaced.

The parent directories of the path are created; a path that cannot be written, an existing
file or a file another recorder is writing right now (each recorder holds a ``flock`` on its
file) is refused at construction with the reason, before anything is simulated.

A write error (a full disk) is raised once, by the next call or by ``close()``, as a
``RecordingError`` naming the file and the reason; the recorder then stops writing
(:attr:`RunRecorder.failed`), later calls do nothing and ``close()`` only releases the file,
which reads like a killed recording.

QoS: each topic is recorded with the profile the node uses live (:mod:`ring_gyro_sim.ros.qos`),
which is what ``ros2 bag play`` offers again.
"""

import ctypes
import functools
import heapq
import json
import os
import pathlib
import platform
import queue
import subprocess
import threading
from typing import Dict, FrozenSet, Iterable, Optional, Sequence

import numpy as np
from ring_gyro_sim import __version__
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.params import SimConfig, to_flat
from ring_gyro_sim.recording import cdr
from ring_gyro_sim.recording.errors import OutputExistsError, RecordingError
from ring_gyro_sim.recording.reader import HANDOFF_METADATA_NAME, RUN_METADATA_NAME
from ring_gyro_sim.recording.writer import BagWriter
from ring_gyro_sim.ros import conversions
from ring_gyro_sim.ros.qos import recorded_qos, TOPIC_QOS
from std_msgs.msg import Empty, Float64MultiArray, String
import yaml

METADATA_NAME = RUN_METADATA_NAME
BLOCK_TYPE = 'std_msgs/msg/Float64MultiArray'
INPUT_TOPICS = {
    'shock': 'geometry_msgs/msg/Vector3Stamped',
    'base_acceleration': 'geometry_msgs/msg/AccelStamped',
    'drive/amplitude': 'std_msgs/msg/Float64',
    'drive/frequency': 'std_msgs/msg/Float64',
    'events/reset': 'std_msgs/msg/Empty',
    'events/parameters': 'std_msgs/msg/String',
    conversions.ANGULAR_RATE_TOPIC: 'geometry_msgs/msg/Vector3Stamped',
    conversions.TEMPERATURE_TOPIC: 'sensor_msgs/msg/Temperature',
}
RATE_TYPE = 'sensor_msgs/msg/Imu'
#: Block topics, by the name ``record.topics`` takes (decimated by ``record.decimation``,
#: except :data:`UNDECIMATED_BLOCK_TOPICS`), one message per block, logged at its end.
BLOCK_TOPICS = conversions.OUTPUT_TOPICS + (conversions.DEMODULATOR_TOPIC,
                                            conversions.CONTROL_TOPIC)
#: Block topics whose rows are not output samples (the loop updates): never decimated.
UNDECIMATED_BLOCK_TOPICS = (conversions.CONTROL_TOPIC,)
OTHER_TOPICS = {
    conversions.RATE_TOPIC: RATE_TYPE,
    conversions.DIE_TEMPERATURE_TOPIC: 'sensor_msgs/msg/Temperature',
    '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
    '/clock': 'rosgraph_msgs/msg/Clock',
}
#: Every topic a recording can hold, by the name ``record.topics`` takes, with its type.
RECORDABLE_TOPICS = {**{name: BLOCK_TYPE for name in BLOCK_TOPICS},
                     **OTHER_TOPICS, **INPUT_TOPICS}
#: Recorded whatever ``record.topics`` says: what a re-simulation needs.
ALWAYS_RECORDED = tuple(INPUT_TOPICS)
#: The topics of the gyroscope: recorded only with ``gyro.enabled``.
GYRO_TOPICS = (conversions.DEMODULATOR_TOPIC, conversions.RATE_TOPIC,
               conversions.ANGULAR_RATE_TOPIC, conversions.DIE_TEMPERATURE_TOPIC)
#: The topics of the closed loop: recorded only with a closed ``control.mode``.
CONTROL_TOPICS = (conversions.CONTROL_TOPIC,)


def recorded_topic_names(record_topics: Iterable[str], namespace: str = '/ring_gyro',
                         publish_clock: bool = True, gyro: bool = False,
                         control: bool = False) -> list:
    """
    Return the names (as ``record.topics`` takes them) that a recording holds.

    ``record_topics`` empty means every topic; the inputs and events are always added.
    ``/clock`` is recorded only when it is published, the :data:`GYRO_TOPICS` only with
    ``gyro`` (``gyro.enabled``), the :data:`CONTROL_TOPICS` only with ``control``
    (a closed ``control.mode``).

    Raises
    ------
    ParameterError
        If a name is not a topic of the node (the message names ``record.topics``).

    """
    if isinstance(record_topics, str):
        record_topics = [record_topics]
    prefix = namespace.rstrip('/') + '/'
    wanted = set()
    for given in record_topics:
        name = given
        if isinstance(name, str):
            name = name[2:] if name.startswith('~/') else name
            if name.startswith(prefix) and name[len(prefix):] in RECORDABLE_TOPICS:
                name = name[len(prefix):]
        if name not in RECORDABLE_TOPICS:
            raise ParameterError(
                f'record.topics: {given!r} is not a topic of the node (topics: '
                f'{", ".join(RECORDABLE_TOPICS)})')
        wanted.add(name)
    if not wanted:
        wanted = set(RECORDABLE_TOPICS)
    wanted.update(ALWAYS_RECORDED)
    if not publish_clock:
        wanted.discard('/clock')
    if not gyro:
        wanted.difference_update(GYRO_TOPICS)
    if not control:
        wanted.difference_update(CONTROL_TOPICS)
    return [name for name in RECORDABLE_TOPICS if name in wanted]


def check_output_path(output, inputs: Iterable) -> None:
    """
    Refuse an output path that is one of the run's input files (even with overwrite).

    ``ring_gyro run X.yaml -o X.yaml`` or ``--from A.mcap -o A.mcap`` would destroy the run's
    own source.

    Raises
    ------
    OutputExistsError
        Naming ``record.path``, the file and the reason.

    """
    if not output:
        return
    out = pathlib.Path(output)
    for source in inputs:
        if not source:
            continue
        try:
            same = out.exists() and os.path.samefile(out, source)
        except OSError:
            same = False
        if same:
            raise OutputExistsError(
                f'record.path: {str(output)!r} is the input file {str(source)!r} of this run '
                f'(refusing to write over it, whatever record.overwrite says)')


_M_MMAP_THRESHOLD = -3
"""glibc's mallopt parameter number of the mmap threshold (malloc.h)."""
MMAP_THRESHOLD_BYTES = 128 * 1024
"""Allocations from this size on are mmapped and given back to the system when freed."""


def keep_large_buffers_out_of_the_heap() -> bool:
    """
    Fix glibc's mmap threshold at :data:`MMAP_THRESHOLD_BYTES` (once per process; True if set).

    A recording builds each 1 MiB chunk in a growing buffer, compresses it and frees it, many
    times a second. glibc's default *dynamic* threshold rises after the first such buffer is
    freed, so the later ones come from the heap, which then fragments: a paced, recording
    node grew by ~13 kB/s (4.2 MB in 10 min at 20 kHz), a non-recording one not at all
    (0.07 kB/s). With the threshold fixed, buffers of this size are mapped and unmapped and
    the growth left is the chunk indexes the MCAP summary needs (~300 B per chunk). Elsewhere
    than glibc nothing is changed.
    """
    global _heap_fixed
    if _heap_fixed is not None:
        return _heap_fixed
    _heap_fixed = False
    if platform.system() == 'Linux' and platform.libc_ver()[0] == 'glibc':
        try:
            libc = ctypes.CDLL(None)
            _heap_fixed = bool(libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES))
        except (OSError, AttributeError):
            _heap_fixed = False
    return _heap_fixed


_heap_fixed: Optional[bool] = None


@functools.lru_cache(maxsize=1)
def git_revision() -> str:
    """
    Git revision of the package source, or 'unknown' (installed without .git).

    Asked of git once per process (a subprocess, ~10 ms): the code a process runs does not
    change under it.
    """
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        out = subprocess.run(['git', '-C', here, 'rev-parse', 'HEAD'], capture_output=True,
                             text=True, timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return 'unknown'
    return out.stdout.strip() if out.returncode == 0 else 'unknown'


#: Batches queued for the writer thread at most: one batch per block, so 0.5 s of 10 ms blocks
#: (at most 22 MB of the gyroscope's messages recorded at the full 200 kHz).
WRITE_QUEUE_DEPTH = 50


def _parameters_message(text: str) -> String:
    return String(data=text)


class RunRecorder:
    """
    Writes one run to ``path`` (a context manager; the file is finalised on exit).

    The file is created, locked and checked at construction (see the module doc), so build the
    recorder before the expensive start-up (a start orbit); the metadata record is written with
    the first message, so the initial state may be given later with :meth:`set_initial_state`.

    Parameters
    ----------
    path : str
        The ``.mcap`` file (``record.path`` or ``ring_gyro run -o``).
    config : SimConfig
        Resolved configuration: goes to the metadata record; ``record.topics``,
        ``record.decimation``, ``record.compression`` and ``record.overwrite`` are taken from
        it.
    channel_names : dict
        ``Simulator.channel_names``.
    namespace : str
        Topic namespace of the node, e.g. '/ring_gyro'.
    initial_state : (ndarray, ndarray), optional
        Initial coordinates and velocities (m, m/s); zeros when None (and not set later).
    publish_clock : bool
        Also record ``/clock`` (if ``record.topics`` keeps it).
    threaded : bool
        Serialise, compress and write in a background thread (messages keep their order; a
        write error is raised by the next call or by :meth:`close`).

    Raises
    ------
    ParameterError
        A name in ``record.topics`` that is not a topic of the node.
    RecordingError
        The file cannot be created: it exists (``OutputExistsError``; with the hint to set
        ``record.overwrite``), another recorder writes it (``OutputBusyError``), or the path
        is not writable; the message starts with ``record.path:`` and gives the reason.

    """

    def __init__(self, path: str, config: SimConfig, channel_names: Dict[str, Sequence[str]],
                 namespace: str = '/ring_gyro', initial_state=None,
                 publish_clock: bool = False, threaded: bool = True) -> None:
        keep_large_buffers_out_of_the_heap()
        run = config.run
        self.namespace = namespace.rstrip('/') or ''
        self.channel_names = channel_names
        self.config = config
        self.publish_clock = publish_clock
        self.names = recorded_topic_names(run.record_topics, self.namespace or '/',
                                          publish_clock, config.gyro.enabled,
                                          modes.of(config).closed)
        self.decimation = int(run.record_decimation)
        self.period_ns = run.output_period_ns
        self.block_samples = max(1, int(round(run.block_duration / (self.period_ns * 1e-9))))
        try:
            self.writer = BagWriter(path, compression=run.record_compression,
                                    overwrite=run.record_overwrite)
        except RecordingError as exc:
            hint = (' (set record.overwrite: true to replace a recording)'
                    if isinstance(exc, OutputExistsError) and not run.record_overwrite else '')
            raise type(exc)(f'record.path: {exc}{hint}') from None
        self._topics = {name: self.topic(name) for name in self.names}
        try:
            for name in self.names:
                self.writer.add_topic(self._topics[name], RECORDABLE_TOPICS[name],
                                      **recorded_qos(TOPIC_QOS[name]))
        except BaseException:
            self.writer.finish()
            raise
        self._blocks = [name for name in BLOCK_TOPICS if name in self._topics]
        self._initial_state = initial_state
        self._calibration = None
        self._started = False
        self._now_ns = 0  # log time of the latest output written: inputs after it wait
        # Inputs acting after _now_ns, as a heap of (t_ns, order, name, build, args): compact,
        # the message is built when it is written (100 000 pending samples stay a few MB).
        self._pending = []
        self._order = 0
        # Serialising and compressing the messages is done by a writer thread while the
        # (GIL-free) kernel runs, on the second core. The messages go to it in one batch per
        # block (and per diagnostics snapshot, so that they go also when no block comes): a
        # hand-over per message (15 per block for the gyroscope) woke the thread each time,
        # and the main thread then waited for the GIL. The bounded queue keeps memory bounded.
        self._failure: Optional[BaseException] = None  # a write error not reported yet
        self._failed = False  # a write failed: nothing more is written
        self._batch: list = []  # (topic, message, t_ns) for the writer thread, in order
        self._queue: 'queue.Queue' = queue.Queue(maxsize=WRITE_QUEUE_DEPTH)
        self._thread: Optional[threading.Thread] = None
        if threaded:
            self._thread = threading.Thread(target=self._drain, name='ring_gyro_recorder',
                                            daemon=True)
            self._thread.start()

    def topic(self, name: str) -> str:
        """Full topic name of a node-relative name ('/diagnostics' and '/clock' stay)."""
        return name if name.startswith('/') else f'{self.namespace}/{name}'

    @property
    def path(self) -> pathlib.Path:
        """Return the path of the recording."""
        return self.writer.path

    def set_initial_state(self, q, v) -> None:
        """
        Set the initial coordinates and velocities (m, m/s) written to the metadata record.

        Raises
        ------
        RecordingError
            If the metadata record has been written already (a message was recorded).

        """
        if self._started:
            raise RecordingError(f'{str(self.path)!r}: the initial state must be set before '
                                 f'the first message is recorded')
        self._initial_state = (q, v)

    def set_calibration(self, calibration) -> None:
        """
        Set the rate output's held calibration written to the metadata record.

        ``calibration``: ``Calibration.to_dict()``, or None (``gyro.calibration.source:
        ideal``, or no gyroscope). Before the first message, as :meth:`set_initial_state`.
        """
        if self._started:
            raise RecordingError(f'{str(self.path)!r}: the calibration must be set before '
                                 f'the first message is recorded')
        self._calibration = calibration

    def start(self, initial_state) -> None:
        """Set the initial state (q, v) of the run (the :class:`~ring_gyro_sim.run.Sink` call)."""
        self.set_initial_state(*initial_state)

    def handoff(self, at_ns: int, model: str) -> None:
        """
        Record a change of model at ``at_ns``: a metadata record ``ring_gyro_sim.handoff``.

        ``{'t_ns', 'model'}`` (``averaged`` or ``full`` from then on), written at once, so
        that a cut recording keeps the hand-offs before the cut
        (``recording.reader.read_handoffs``).
        """
        self.writer.add_metadata(HANDOFF_METADATA_NAME, {'t_ns': str(int(at_ns)),
                                                         'model': str(model)})

    def discard(self) -> None:
        """Close and delete the file: the run never started (no metadata, no samples)."""
        path = self.path
        try:
            self.close()
        finally:
            try:
                os.remove(path)
            except OSError:
                pass

    def _start(self) -> None:
        """Write the metadata record (once, before the first message)."""
        if self._started:
            return
        self._started = True
        state = self._initial_state
        if state is None:
            n = len(self.channel_names['modal_displacement'])
            state = (np.zeros(n), np.zeros(n))
        self.writer.add_metadata(METADATA_NAME, {
            'parameters': yaml.safe_dump(to_flat(self.config), sort_keys=True),
            'version': __version__,
            'git_revision': git_revision(),
            'namespace': self.namespace,
            'initial_state': json.dumps({'q': [float(x) for x in state[0]],
                                         'v': [float(x) for x in state[1]]}),
            'output_period_ns': str(self.period_ns),
            'block_samples': str(self.block_samples),
            'record_decimation': str(self.decimation),
            'record_topics': json.dumps(list(self._topics.values())),
            'block_topics': json.dumps([self._topics[name] for name in self._blocks]),
            'compression': self.writer.compression,
            'calibration': json.dumps(self._calibration),
        })

    def __enter__(self) -> 'RunRecorder':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """
        Write the inputs still held back and what is queued, then finalise the file.

        Idempotent. A write error is raised once (here or by the call that met it first);
        after that, close() only releases the file.
        """
        try:
            if not self.writer.closed and not self._failed:
                self._start()
                self._release(None)
                self._hand_over()
        finally:
            if self._thread is not None:
                self._queue.put(None)
                self._thread.join()
                self._thread = None
            failure, self._failure = self._failure, None
            try:
                self.writer.finish()
            finally:
                if failure is not None:
                    raise failure

    @property
    def failed(self) -> bool:
        """Tell whether writing stopped on an error (raised once; nothing is written after)."""
        return self._failed

    def _put(self, topic: str, msg, t_ns: int) -> None:
        """Hand one message to the writer (thread, with the block's batch), in call order."""
        self._raise_failure()
        if self._failed:
            return
        if self._thread is None:
            try:
                self.writer.write(topic, msg, t_ns)
            except BaseException:
                self._failed = True
                raise
            return
        self._batch.append((topic, msg, t_ns))

    def _hand_over(self) -> None:
        """Queue the messages gathered since the last hand-over for the writer thread."""
        if self._batch:
            batch, self._batch = self._batch, []
            self._queue.put(batch)

    def _release(self, t_ns: Optional[int]) -> None:
        """Write the inputs held back that act at or before ``t_ns`` (None: all of them)."""
        while self._pending and (t_ns is None or self._pending[0][0] <= t_ns):
            at_ns, _, name, build, args = heapq.heappop(self._pending)
            self._put(self._topics[name], build(*args), at_ns)

    def _advance(self, t_ns: int) -> None:
        """Move the run's time to ``t_ns``: write the inputs held back up to it."""
        self._start()
        self._release(t_ns)
        self._now_ns = max(self._now_ns, t_ns)

    def _input(self, name: str, at_ns: int, build, *args) -> None:
        """Write the input ``build(*args)`` acting at ``at_ns``, now or when outputs reach it."""
        self._raise_failure()
        self._start()
        if at_ns <= self._now_ns:
            self._put(self._topics[name], build(*args), at_ns)
            return
        self._order += 1
        heapq.heappush(self._pending, (at_ns, self._order, name, build, args))

    def _write(self, topic: str, msg, t_ns: int) -> None:
        """Write one message of any topic now (no ordering, no decimation)."""
        self._start()
        self._put(topic, msg, t_ns)

    def _drain(self) -> None:
        """Writer thread: serialise, compress and write the queued batches in order."""
        while True:
            batch = self._queue.get()
            if batch is None:
                return
            for item in batch:
                if self._failed:
                    break  # keep draining so that producers never block forever
                try:
                    self.writer.write(*item)
                except BaseException as exc:  # reported to the caller's thread, once
                    self._failure = exc
                    self._failed = True

    def _raise_failure(self) -> None:
        if self._failure is not None:
            failure, self._failure = self._failure, None
            raise failure

    @property
    def block_topics(self) -> FrozenSet[str]:
        """Return the block topics this recording keeps (``record.topics``)."""
        return frozenset(self._blocks)

    def kept_rows(self, t_ns: int, rows: int) -> slice:
        """
        Return the rows a block of ``rows`` samples ending at ``t_ns`` keeps when decimated.

        Those whose global sample index is a multiple of N (``record.decimation``); all of
        them with N = 1.
        """
        if self.decimation == 1:
            return slice(None)
        end_index, rest = divmod(t_ns, self.period_ns)
        if rest:
            raise ValueError(f'block end {t_ns} ns is not on the {self.period_ns} ns grid')
        first_index = end_index - rows + 1
        return slice((-first_index) % self.decimation, None, self.decimation)

    def _decimated(self, msg: Float64MultiArray, t_ns: int) -> bytes:
        """
        Return the CDR of the block's rows whose global sample index is a multiple of N.

        Packed from the kept rows (``recording.cdr``), not built as a message for rclpy to
        serialise; the layout is the block's own (its labels as one string, ``data_offset``
        0 as every block has).
        """
        rows, columns = msg.layout.dim[0].size, msg.layout.dim[1].size
        data = np.frombuffer(msg.data, dtype=np.float64).reshape(rows, columns)
        return cdr.float64_multiarray(data[self.kept_rows(t_ns, rows)],
                                      [msg.layout.dim[1].label], msg.layout.dim[0].label)

    def outputs(self, blocks: Dict[str, object], t_ns: int, thinned: bool = False) -> None:
        """
        Record the block messages of one block, logged at its last sample time ``t_ns``.

        ``thinned``: the messages hold only the rows :meth:`kept_rows` keeps already (built
        so by ``RosSink`` when nothing publishes them); otherwise they are decimated here.
        """
        self._advance(t_ns)
        for name, msg in blocks.items():
            if name not in self._topics:
                continue
            if self.decimation > 1 and not thinned and name not in UNDECIMATED_BLOCK_TOPICS:
                msg = self._decimated(msg, t_ns)
            self._put(self._topics[name], msg, t_ns)
        self._hand_over()

    def rate(self, messages) -> None:
        """
        Record the ``~/rate`` messages ``[(t_ns, Imu)]`` of one block, each at its sample time.

        Call it before :meth:`outputs` of the same block: the inputs held back are written
        between the samples, so that the file stays in log-time order.
        """
        topic = self._topics.get(conversions.RATE_TOPIC)
        for t_ns, msg in messages:
            self._advance(t_ns)
            if topic is not None:
                self._put(topic, msg, t_ns)

    def diagnostics(self, msg, t_ns: int) -> None:
        """Record a /diagnostics message (and hand what waits over: also when no block comes)."""
        self._advance(t_ns)
        if '/diagnostics' in self._topics:
            self._put('/diagnostics', msg, t_ns)
        self._hand_over()

    def clock(self, t_ns: int) -> None:
        """Record /clock at ``t_ns`` (only when the run publishes it)."""
        self._advance(t_ns)
        if '/clock' in self._topics:
            self._put('/clock', conversions.clock_message(t_ns), t_ns)

    def shock(self, at_ns: int, x: float, y: float = 0.0) -> None:
        """Record a shock applied at ``at_ns``."""
        self._input('shock', at_ns, conversions.shock_message, at_ns, x, y)

    def base_acceleration(self, at_ns: int, x: float, y: float = 0.0) -> None:
        """Record a base-acceleration sample applied at ``at_ns``."""
        self._input('base_acceleration', at_ns, conversions.base_acceleration_message,
                    at_ns, x, y)

    def angular_rate(self, at_ns: int, z: float, x: float = 0.0, y: float = 0.0) -> None:
        """
        Record an angular rate that acts from ``at_ns`` on.

        Raises
        ------
        RecordingError
            If the recording has no ``angular_rate`` topic (the run is not a gyroscope: the
            rate cannot have acted).

        """
        if conversions.ANGULAR_RATE_TOPIC not in self._topics:
            raise RecordingError(f'{str(self.path)!r}: an angular rate acted in a run without '
                                 f'gyro.enabled (not recorded)')
        self._input(conversions.ANGULAR_RATE_TOPIC, at_ns, conversions.angular_rate_message,
                    at_ns, z, x, y, self.config.gyro.frame_id)

    def temperature(self, at_ns: int, kelvin: float) -> None:
        """Record the ambient, in K, that acts from ``at_ns`` on (``~/temperature``)."""
        self._input(conversions.TEMPERATURE_TOPIC, at_ns, conversions.temperature_message,
                    at_ns, kelvin)

    def die_temperature(self, msg, t_ns: int) -> None:
        """Record a ``~/die_temperature`` message at ``t_ns`` (gyroscope only)."""
        self._advance(t_ns)
        topic = self._topics.get(conversions.DIE_TEMPERATURE_TOPIC)
        if topic is not None:
            self._put(topic, msg, t_ns)

    def drive(self, at_ns: int, amplitude: Optional[float] = None,
              frequency_hz: Optional[float] = None) -> None:
        """Record a drive change applied at ``at_ns``."""
        if amplitude is not None:
            self._input('drive/amplitude', at_ns, conversions.float_message, amplitude)
        if frequency_hz is not None:
            self._input('drive/frequency', at_ns, conversions.float_message, frequency_hz)

    def reset(self, at_ns: int) -> None:
        """Record a reset applied at ``at_ns``."""
        self._input('events/reset', at_ns, Empty)

    def parameters(self, at_ns: int, changed: Dict[str, object]) -> None:
        """Record parameters changed at run time, applied at ``at_ns``."""
        self._input('events/parameters', at_ns, _parameters_message,
                    yaml.safe_dump(dict(changed), sort_keys=True))
