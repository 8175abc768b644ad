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
Write a run as a ROS 2 bag in a single MCAP file, laid out as rosbag2 (Jazzy) writes it.

What rosbag2_storage_mcap (Jazzy) writes and this writer reproduces:

- header profile ``ros2``; one schema per type, named 'pkg/msg/Type', encoding ``ros2msg``, data
  = the full definition (:func:`ring_gyro_sim.recording.schemas.message_definition`); one
  channel per topic, message encoding ``cdr``, channel metadata ``offered_qos_profiles`` (the
  YAML of ``serialize_rclcpp_qos_vector``, version 9 string enums) and ``topic_type_hash``
  ('RIHS01_...', '' if unknown);
- on :meth:`BagWriter.finish`, one metadata record ``rosbag2`` with key ``serialized_metadata``
  = the YAML of the complete BagMetadata (version 9), then the summary: schemas, channels,
  statistics, chunk / metadata indexes and summary offsets; every chunk is followed by its
  message indexes.

Chunks are compressed with zstd (default), lz4 (needs the ``lz4`` package) or not at all, as
rosbag2's MCAP storage offers, and written straight to the file descriptor (no user-space
buffer), so after ``kill -9`` every completed chunk is on disk and readable with
:func:`ring_gyro_sim.recording.reader.read_messages`; the ``rosbag2`` record is then absent,
never partial, and :func:`ring_gyro_sim.recording.recover.recover` (``ring_gyro recover``)
writes a complete copy that every MCAP reader opens.

The output file:

- its parent directories are created;
- an existing file is refused (:class:`~ring_gyro_sim.recording.errors.OutputExistsError`,
  as rosbag2 refuses an existing output) unless ``overwrite=True``, and even then only an MCAP
  file (or an empty one) is replaced: a scenario file given as the output by mistake is never
  destroyed;
- the writer holds an advisory lock (``flock``) on it until :meth:`BagWriter.finish`: a second
  writer on the same file is refused
  (:class:`~ring_gyro_sim.recording.errors.OutputBusyError`) instead of corrupting it;
- a write error (a full disk) is raised once, as a :class:`RecordingError` naming the file and
  the reason; the writer then stops writing, and :meth:`BagWriter.finish` only closes the
  file (what was written before stays readable like a killed recording).

Memory: the summary needs one chunk index per chunk, so a writer grows with its file until
:meth:`BagWriter.finish`, and by nothing else. mcap's ``Writer`` keeps each index as a
``ChunkIndex`` object with a dict of the chunk's channels, ~1.5 kB for a chunk of 15 channels;
here (:class:`_ChunkIndexRecords`) it is kept as the record the summary will hold, 77 bytes and
10 per channel of the chunk (227 B for 15). What that makes per hour of recording is in
doc/recording.md ("Memory").
"""

import operator
import os
import pathlib
import stat
import threading

from mcap import __version__ as mcap_version
from mcap.data_stream import RecordBuilder
from mcap.exceptions import UnsupportedCompressionError
from mcap.writer import CompressionType, IndexType, Writer

from ring_gyro_sim import __version__
from ring_gyro_sim.recording import _rosbag2, cdr
from ring_gyro_sim.recording._filelock import is_being_written, lock_exclusive
from ring_gyro_sim.recording.errors import OutputBusyError, OutputExistsError, RecordingError
from ring_gyro_sim.recording.schemas import (
    message_definition,
    message_type_name,
    normalize_type_name,
    type_description_hash,
)

#: Default uncompressed chunk size in bytes (what a kill -9 can lose at most, per file).
DEFAULT_CHUNK_SIZE = 1024 * 1024

#: Name of the metadata record that rosbag2 reads (``serialized_metadata``); reserved.
ROSBAG2_METADATA_NAME = 'rosbag2'

#: Chunk compressions (the names of ``record.compression``), as rosbag2's MCAP storage offers.
COMPRESSIONS = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}

MCAP_MAGIC = b'\x89MCAP0\r\n'

_MAX_TIME_NS = 2**63 - 1  # rosbag2 timestamps are int64 ns


def _time_ns(value, name):
    try:
        value = operator.index(value)
    except TypeError:
        raise TypeError(f'{name} must be an integer number of ns, got {value!r}') from None
    if not 0 <= value <= _MAX_TIME_NS:
        raise ValueError(f'{name} must be in [0, 2**63 - 1] ns, got {value}')
    return value


def _string_map(data, what):
    if not isinstance(data, dict) or not all(
            isinstance(key, str) and isinstance(value, str) for key, value in data.items()):
        raise TypeError(f'{what} must be a dict[str, str]')
    return dict(data)


def _open_output(path, overwrite):
    """
    Create (or, with ``overwrite``, replace) ``path`` and lock it; return the descriptor.

    The lock is taken before the file is truncated, so a writer never empties a file that
    another writer is filling.
    """
    name = repr(str(path))
    parent = path.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise RecordingError(f'cannot create recording {name}: {str(parent)!r} exists and is '
                             f'not a directory') from None
    except OSError as exc:
        raise RecordingError(f'cannot create recording {name}: cannot create its directory '
                             f'{str(parent)!r}: {exc.strerror or exc}') from exc
    flags = os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | (0 if overwrite else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o666)
    except FileExistsError:
        if is_being_written(path):
            raise OutputBusyError(
                f'cannot create recording {name}: another recorder is writing it right now '
                f'(two recorders on one file would corrupt it)') from None
        kind = 'a directory' if path.is_dir() else 'a file'
        raise OutputExistsError(f'cannot create recording {name}: {kind} of that name exists '
                                f'(refusing to replace it)') from None
    except OSError as exc:
        raise RecordingError(
            f'cannot create recording {name}: {exc.strerror or exc}') from exc
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise OutputExistsError(f'cannot create recording {name}: it exists and is not a '
                                    f'regular file')
        if not lock_exclusive(fd):
            raise OutputBusyError(
                f'cannot create recording {name}: another recorder is writing it right now '
                f'(two recorders on one file would corrupt it)')
        if info.st_size > 0:
            head = os.pread(fd, len(MCAP_MAGIC), 0)
            if head != MCAP_MAGIC[:len(head)]:
                raise OutputExistsError(
                    f'cannot create recording {name}: the existing file is not an MCAP '
                    f'recording (refusing to replace it even with overwrite)')
            os.ftruncate(fd, 0)
    except OSError as exc:
        os.close(fd)
        raise RecordingError(f'cannot create recording {name}: {exc.strerror or exc}') from exc
    except BaseException:
        os.close(fd)
        raise
    return fd


class _FileSink:
    """Unbuffered binary output for mcap.writer.Writer: every write() reaches the kernel."""

    def __init__(self, path, overwrite):
        self.path = path
        self._fd = -1  # for __del__ if open fails
        self._fd = _open_output(path, overwrite)
        self._position = 0

    def write(self, data):
        view = memoryview(data).cast('B')
        while view:
            written = os.write(self._fd, view)
            view = view[written:]
            self._position += written
        return len(data)

    def tell(self):
        return self._position

    def flush(self):
        pass

    def close(self):
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            os.close(fd)  # releases the lock

    def __del__(self):
        # An unfinished writer that is garbage collected must not leak its descriptor; what it
        # wrote stays readable like a killed recording.
        try:
            self.close()
        except OSError:
            pass


class _RawRecords:
    """Records already serialised, written as they are (the summary's chunk index group)."""

    __slots__ = ('data',)

    def __init__(self, data):
        self.data = data

    def write(self, builder):
        builder.write(self.data)


class _ChunkIndexRecords:
    """
    Stands in for the list of ``ChunkIndex`` objects of mcap's ``Writer``: keeps their records.

    The writer appends the index of every chunk it writes and, on ``finish``, writes each item
    of the list into the summary; here each index is serialised when it is appended and the
    list yields one item that writes them all, byte for byte what mcap would have written.
    """

    def __init__(self):
        self._data = bytearray()
        self._count = 0

    def append(self, index):
        builder = RecordBuilder()
        index.write(builder)
        self._data += builder.end()
        self._count += 1

    def __len__(self):
        return self._count

    def __iter__(self):
        if self._count:
            yield _RawRecords(bytes(self._data))


def _keep_chunk_indexes_compact(writer):
    """
    Make mcap's ``writer`` keep its chunk indexes as records (True if it could).

    The list is a private attribute of ``mcap.writer.Writer``; should a version of mcap not
    have it, the writer is left as it is (it then keeps its ``ChunkIndex`` objects).
    """
    name = '_Writer__chunk_indices'
    if isinstance(getattr(writer, name, None), list) and not getattr(writer, name):
        setattr(writer, name, _ChunkIndexRecords())
        return True
    return False


class _NullSink:
    """Discards everything (to ask mcap whether a compression is available)."""

    def write(self, data):
        return len(data)

    def tell(self):
        return 0


class _Topic:
    __slots__ = ('name', 'type_name', 'channel_id', 'profile', 'type_hash', 'message_count')

    def __init__(self, name, type_name, channel_id, profile, type_hash):
        self.name = name
        self.type_name = type_name
        self.channel_id = channel_id
        self.profile = profile
        self.type_hash = type_hash
        self.message_count = 0


class BagWriter:
    """
    A ROS 2 bag (profile ros2, ros2msg schemas, cdr messages) in one MCAP file.

    Use as a context manager: :meth:`finish` runs on exit, also when the body raises, so the file
    is always finalised. The file is created (and locked) at construction.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file to write.
    chunk_size : int, optional
        Uncompressed size in bytes above which a chunk is compressed and written (default
        1 MiB). A killed process loses at most the chunk in progress.
    compression : {'zstd', 'lz4', 'none'}, optional
        Chunk compression (default 'zstd'; 'lz4' needs the ``lz4`` package).
    overwrite : bool, optional
        Replace an existing MCAP file at ``path`` (default False: refuse it). A file that is
        not an MCAP recording is never replaced.
    ros_distro : str, optional
        Value of ``ros_distro`` in the rosbag2 metadata (default 'jazzy'; the layout is
        Jazzy's, metadata version 9).
    custom_data : dict[str, str], optional
        ``custom_data`` of the rosbag2 metadata (rosbag2's ``--custom-data``).

    Raises
    ------
    OutputExistsError
        If the file exists and ``overwrite`` is False, or it is not an MCAP file.
    OutputBusyError
        If another writer (in any process) is writing the file.
    RecordingError
        If the file cannot be created; the message names the path and the reason.

    Examples
    --------
    >>> with BagWriter('run.mcap') as bag:  # doctest: +SKIP
    ...     bag.add_topic('/clock', 'rosgraph_msgs/msg/Clock')
    ...     bag.write('/clock', clock_msg, log_time_ns=1_000_000)

    """

    def __init__(self, path, *, chunk_size=DEFAULT_CHUNK_SIZE, compression='zstd',
                 overwrite=False, ros_distro='jazzy', custom_data=None):
        try:
            chunk_size = operator.index(chunk_size)
        except TypeError:
            raise TypeError(f'chunk_size must be an integer, got {chunk_size!r}') from None
        if chunk_size <= 0:
            raise ValueError(f'chunk_size must be positive, got {chunk_size} bytes')
        if not isinstance(ros_distro, str) or not ros_distro:
            raise ValueError(f'ros_distro must be a non-empty string, got {ros_distro!r}')
        if compression not in COMPRESSIONS:
            raise ValueError(f'compression must be one of {", ".join(COMPRESSIONS)}, '
                             f'got {compression!r}')
        self._custom_data = _string_map(custom_data or {}, 'custom_data')
        self._ros_distro = ros_distro
        self._path = pathlib.Path(path)
        self._lock = threading.Lock()
        self._topics = {}
        self._schema_ids = {}
        self._message_count = 0
        self._start_ns = None
        self._end_ns = None
        self._closed = False
        self._failure = None  # the first write error, raised once
        self._compression = compression
        try:
            # Checks that the compression library is there, before the file is created.
            Writer(_NullSink(), compression=COMPRESSIONS[compression])
        except UnsupportedCompressionError:
            package = 'lz4' if compression == 'lz4' else 'zstandard'
            raise RecordingError(
                f'cannot create recording {str(self._path)!r}: compression {compression} needs '
                f'the Python package {package} (pip install {package})') from None
        self._sink = _FileSink(self._path, bool(overwrite))
        try:
            self._writer = Writer(
                self._sink,
                chunk_size=chunk_size,
                compression=COMPRESSIONS[compression],
                index_types=IndexType.ALL,
                repeat_channels=True,
                repeat_schemas=True,
                use_chunking=True,
                use_statistics=True,
                use_summary_offsets=True,
                enable_crcs=True,
            )
            _keep_chunk_indexes_compact(self._writer)
            self._writer.start(
                profile='ros2', library=f'ring_gyro_sim/{__version__}; mcap-python/{mcap_version}')
        except OSError as exc:
            self._sink.close()
            self._closed = True
            raise self._io_error('write the header of', exc) from exc
        except BaseException:
            self._sink.close()
            self._closed = True
            raise

    @property
    def path(self) -> pathlib.Path:
        """Return the MCAP file being written."""
        return self._path

    @property
    def closed(self) -> bool:
        """Tell whether :meth:`finish` has run."""
        return self._closed

    @property
    def message_count(self) -> int:
        """Return the number of messages written so far."""
        return self._message_count

    @property
    def compression(self) -> str:
        """Return the chunk compression: 'zstd', 'lz4' or 'none'."""
        return self._compression

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc_value, traceback):
        self.finish()
        return False

    def _io_error(self, action, exc):
        return RecordingError(
            f'cannot {action} recording {str(self._path)!r}: {exc.strerror or exc}')

    def _failed(self, action, exc):
        """Note the first write error (the writer stops writing) and return it as raised."""
        error = self._io_error(action, exc)
        if self._failure is None:
            self._failure = error
            self._sink.close()  # what is on disk stays, like a killed recording
        return error

    def _check_open(self):
        if self._closed:
            raise RecordingError(f'recording {str(self._path)!r} is already finished')
        if self._failure is not None:
            raise RecordingError(f'recording {str(self._path)!r} stopped after a write error: '
                                 f'{self._failure}')

    def add_topic(self, topic, type_name, *, reliable=True, durability='volatile', depth=10):
        """
        Register a topic (its schema once per type, and a channel).

        Registering the same topic again with the same type and QoS does nothing.

        Parameters
        ----------
        topic : str
            Fully qualified topic name, e.g. '/ring_gyro/modal_displacement'.
        type_name : str
            'pkg/msg/Type' (or 'pkg/Type'), e.g. 'std_msgs/msg/Float64MultiArray'.
        reliable : bool, optional
            Offered reliability: reliable (default, so default subscriptions connect on
            ``ros2 bag play``) or best effort.
        durability : {'volatile', 'transient_local'}, optional
            Offered durability.
        depth : int, optional
            History depth (keep last) of the recorded publisher, in messages (>= 1).

        Raises
        ------
        RecordingError
            If the type is unknown, the topic is already registered differently, or the
            writer is finished.

        """
        if not isinstance(topic, str) or not topic.startswith('/') or len(topic) < 2:
            raise ValueError(f'topic must be a fully qualified name like /ns/name, got {topic!r}')
        if durability not in _rosbag2.DURABILITIES:
            raise ValueError(
                f'durability must be one of {_rosbag2.DURABILITIES}, got {durability!r}')
        try:
            depth = operator.index(depth)
        except TypeError:
            raise TypeError(f'depth must be an integer, got {depth!r}') from None
        if depth < 1:
            raise ValueError(f'depth must be >= 1 message, got {depth}')
        type_name = normalize_type_name(type_name)
        profile = _rosbag2.qos_profile(reliable=reliable, durability=durability, depth=depth)
        with self._lock:
            self._check_open()
            known = self._topics.get(topic)
            if known is not None:
                if known.type_name == type_name and known.profile == profile:
                    return
                raise RecordingError(
                    f'topic {topic!r} is already registered as {known.type_name} with other QoS'
                    if known.type_name == type_name else
                    f'topic {topic!r} is already registered as {known.type_name}, '
                    f'not {type_name}')
            definition = message_definition(type_name)
            type_hash = type_description_hash(type_name)
            try:
                schema_id = self._schema_ids.get(type_name)
                if schema_id is None:
                    schema_id = self._writer.register_schema(
                        name=type_name, encoding='ros2msg', data=definition.encode('utf-8'))
                    self._schema_ids[type_name] = schema_id
                channel_id = self._writer.register_channel(
                    topic=topic,
                    message_encoding='cdr',
                    schema_id=schema_id,
                    metadata={
                        'offered_qos_profiles': _rosbag2.dump([profile]),
                        'topic_type_hash': type_hash,
                    },
                )
            except OSError as exc:
                raise self._failed('write to', exc) from exc
            self._topics[topic] = _Topic(topic, type_name, channel_id, profile, type_hash)

    def write(self, topic, message, log_time_ns, publish_time_ns=None):
        """
        Write one message.

        Parameters
        ----------
        topic : str
            A topic registered with :meth:`add_topic`.
        message : rclpy message or bytes
            A message of the topic's type (serialized to CDR here) or its CDR bytes.
        log_time_ns : int
            Log (receive) time in ns, here the simulation time; in [0, 2**63 - 1].
        publish_time_ns : int, optional
            Publish (send) time in ns; defaults to ``log_time_ns``.

        Raises
        ------
        RecordingError
            If the topic is not registered, the writer is finished or the file cannot be
            written.
        TypeError
            If ``message`` is neither bytes nor a message of the topic's type.

        """
        log_time_ns = _time_ns(log_time_ns, 'log_time_ns')
        publish_time_ns = (log_time_ns if publish_time_ns is None
                           else _time_ns(publish_time_ns, 'publish_time_ns'))
        with self._lock:
            self._check_open()
            info = self._topics.get(topic)
            if info is None:
                raise RecordingError(
                    f'topic {topic!r} is not registered in {str(self._path)!r} '
                    f'(registered: {sorted(self._topics)})')
            if isinstance(message, (bytes, bytearray, memoryview)):
                data = bytes(message)
            else:
                actual = message_type_name(message)
                if actual != info.type_name:
                    raise TypeError(
                        f'topic {topic!r} records {info.type_name}, got a {actual} message')
                data = cdr.serialize(message)
            info.message_count += 1
            try:
                self._writer.add_message(
                    channel_id=info.channel_id,
                    log_time=log_time_ns,
                    data=data,
                    publish_time=publish_time_ns,
                    sequence=info.message_count & 0xFFFFFFFF,  # uint32 in MCAP
                )
            except OSError as exc:
                raise self._failed('write to', exc) from exc
            finally:
                # Counted as the mcap statistics count it, even if the chunk write failed.
                self._message_count += 1
                if self._start_ns is None:
                    self._start_ns = self._end_ns = log_time_ns
                else:
                    self._start_ns = min(self._start_ns, log_time_ns)
                    self._end_ns = max(self._end_ns, log_time_ns)

    def add_metadata(self, name, data):
        """
        Write a metadata record (name -> dict[str, str]) now, outside the chunks.

        Written immediately, so it survives a killed process. The name 'rosbag2' is reserved
        for the record :meth:`finish` writes.
        """
        if not isinstance(name, str) or not name:
            raise ValueError(f'metadata name must be a non-empty string, got {name!r}')
        if name == ROSBAG2_METADATA_NAME:
            raise ValueError(f'metadata name {name!r} is reserved for the rosbag2 bag metadata')
        data = _string_map(data, f'metadata {name!r}')
        with self._lock:
            self._check_open()
            try:
                self._writer.add_metadata(name, data)
            except OSError as exc:
                raise self._failed('write to', exc) from exc

    def flush(self):
        """Compress and write the chunk in progress now (less to lose on a kill, worse ratio)."""
        with self._lock:
            self._check_open()
            try:
                self._writer.flush()
            except OSError as exc:
                raise self._failed('write to', exc) from exc

    def _rosbag2_metadata(self):
        topics = [(t.name, t.type_name, t.profile, t.type_hash, t.message_count)
                  for t in self._topics.values()]
        start_ns = self._start_ns if self._start_ns is not None else 0
        end_ns = self._end_ns if self._end_ns is not None else 0
        return _rosbag2.dump(_rosbag2.bag_metadata(
            file_name=self._path.name, topics=topics, message_count=self._message_count,
            start_ns=start_ns, end_ns=end_ns, custom_data=self._custom_data,
            ros_distro=self._ros_distro))

    def finish(self):
        """
        Write the last chunk, the rosbag2 metadata and the summary, and close the file.

        Safe to call more than once; later calls do nothing. After a write error (raised
        already) it only closes the file.

        Raises
        ------
        RecordingError
            If the file cannot be written (it is closed anyway).

        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._failure is not None:
                self._sink.close()
                return
            try:
                # Last chunk first, so the rosbag2 record follows every message it counts.
                self._writer.flush()
                self._writer.add_metadata(
                    ROSBAG2_METADATA_NAME, {'serialized_metadata': self._rosbag2_metadata()})
                self._writer.finish()
            except OSError as exc:
                raise self._failed('finish', exc) from exc
            finally:
                self._sink.close()
