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
Make a killed (or damaged) recording complete for every MCAP reader: ``ring_gyro recover``.

A recorder killed with SIGKILL leaves its completed chunks on disk but no summary, and
``mcap.reader.make_reader``, ``mcap_ros2`` and rosbags then read nothing. :func:`recover`
reads such a file linearly, as ``mcap recover`` (foxglove/mcap) does, and writes a new one
with the mcap library's writer: the header profile, every schema and channel, every message
of every chunk that is complete and passes its CRC, every attachment and metadata record
(the run's ``ring_gyro_sim`` record included), then statistics, chunk, message and metadata
indexes and the summary. For a ROS 2 bag (profile ``ros2``) it also writes the ``rosbag2``
record (``serialized_metadata``) that :class:`~ring_gyro_sim.recording.writer.BagWriter`
writes on a clean finish, computed from what was recovered (topics, QoS, type hashes and
counts; ``ros_distro`` and ``custom_data`` from the original record if the file had one).

Reading stops at the first record that is incomplete or fails its checks, like the project's
reader (:func:`ring_gyro_sim.recording.reader.read_messages`): both see the same messages.
The output is written to a temporary file beside the target and moved into place at the end,
so a failed recovery leaves no partial output; an existing output is never replaced, a file
that holds no record after its header (nothing to recover) is refused rather than copied into
an empty MCAP, and a file that a recorder is still writing is refused.
"""

import dataclasses
import os
import pathlib
from typing import Dict, Optional

from mcap import __version__ as mcap_version
from mcap.reader import SeekingReader
from mcap.records import Attachment, Channel, Chunk, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, IndexType, Writer
from ring_gyro_sim import __version__
from ring_gyro_sim.recording import _rosbag2
from ring_gyro_sim.recording._filelock import is_being_written
from ring_gyro_sim.recording.errors import OutputBusyError, OutputExistsError, RecordingError
from ring_gyro_sim.recording.reader import _linear_records, _summary, _TRUNCATION_ERRORS
from ring_gyro_sim.recording.writer import (
    DEFAULT_CHUNK_SIZE,
    MCAP_MAGIC,
    ROSBAG2_METADATA_NAME,
)
import yaml

__all__ = ['default_output', 'recover', 'Recovery']

_COMPRESSION = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                '': CompressionType.NONE}


@dataclasses.dataclass(frozen=True)
class Recovery:
    """
    What :func:`recover` wrote.

    Attributes
    ----------
    source, output : pathlib.Path
        The damaged file and the complete copy.
    message_count : int
        Messages copied (all topics).
    topics : dict[str, int]
        Messages copied per topic (every channel of the source, 0 for an idle one).
    chunk_count : int
        Complete chunks of the source whose messages were copied.
    metadata_count : int
        Metadata records copied (without the rosbag2 record, which is written anew).
    was_complete : bool
        The source had a valid summary already (it did not need recovering).
    stopped_at : int or None
        Byte offset of the first record that could not be read, None if read to its end.
    reason : str
        Why reading stopped there ('' if it did not).
    source_size : int
        Size of the source in bytes.

    """

    source: pathlib.Path
    output: pathlib.Path
    message_count: int
    topics: Dict[str, int]
    chunk_count: int
    metadata_count: int
    was_complete: bool
    stopped_at: Optional[int]
    reason: str
    source_size: int

    def describe(self) -> str:
        """Return what was recovered, in one or two lines."""
        text = (f'{_count(self.message_count, "message")} on '
                f'{_count(len(self.topics), "topic")} ({_count(self.chunk_count, "chunk")}, '
                f'{_count(self.metadata_count, "metadata record")}) from '
                f'{str(self.source)!r} written to {str(self.output)!r}')
        if self.was_complete:
            text += ' (the source was complete already)'
        if self.stopped_at is not None:
            text += (f'\nreading stopped at byte {self.stopped_at} of {self.source_size} '
                     f'({self.reason}); what follows is lost')
        return text


def _count(number, what):
    return f'{number} {what}' + ('' if number == 1 else 's')


def default_output(path) -> pathlib.Path:
    """Return where ``ring_gyro recover FILE`` writes by default: ``FILE.recovered.mcap``."""
    path = pathlib.Path(path)
    stem = path.name[:-len('.mcap')] if path.name.endswith('.mcap') else path.name
    return path.with_name(f'{stem}.recovered.mcap')


class _Copy:
    """The state of one recovery: the writer and the id maps from the source."""

    def __init__(self, stream, profile, library, compression):
        self.writer = Writer(stream, chunk_size=DEFAULT_CHUNK_SIZE, compression=compression,
                             index_types=IndexType.ALL, repeat_channels=True,
                             repeat_schemas=True, use_chunking=True, use_statistics=True,
                             use_summary_offsets=True, enable_crcs=True)
        self.profile = profile
        recovered = f'ring_gyro_sim/{__version__} recover; mcap-python/{mcap_version}'
        self.writer.start(profile=profile,
                          library=f'{recovered}; from: {library}' if library else recovered)
        self.schemas = {}  # source id -> (new id, Schema)
        self.channels = {}  # source id -> (new id, Channel)
        self.counts = {}  # new channel id -> messages
        self.message_count = 0
        self.attachment_count = 0
        self.start_ns = None
        self.end_ns = None

    def schema(self, record: Schema) -> None:
        if record.id in self.schemas or record.id == 0:
            return
        new = self.writer.register_schema(name=record.name, encoding=record.encoding,
                                          data=record.data)
        self.schemas[record.id] = (new, record)

    def channel(self, record: Channel) -> None:
        if record.id in self.channels:
            return
        if record.schema_id and record.schema_id not in self.schemas:
            return  # its schema did not survive: the messages cannot be decoded
        schema_id = self.schemas[record.schema_id][0] if record.schema_id else 0
        new = self.writer.register_channel(topic=record.topic,
                                           message_encoding=record.message_encoding,
                                           schema_id=schema_id, metadata=dict(record.metadata))
        self.channels[record.id] = (new, record)
        self.counts[new] = 0

    def message(self, record: Message) -> None:
        known = self.channels.get(record.channel_id)
        if known is None:
            return  # as the project's reader: a message without its channel is not readable
        self.writer.add_message(channel_id=known[0], log_time=record.log_time,
                                data=record.data, publish_time=record.publish_time,
                                sequence=record.sequence)
        self.counts[known[0]] += 1
        self.message_count += 1
        t = record.log_time
        self.start_ns = t if self.start_ns is None else min(self.start_ns, t)
        self.end_ns = t if self.end_ns is None else max(self.end_ns, t)

    def rosbag2_metadata(self, file_name, original) -> str:
        topics = []
        for new, channel in self.channels.values():
            schema = self.schemas.get(channel.schema_id)
            qos = channel.metadata.get('offered_qos_profiles', '')
            try:
                profiles = yaml.safe_load(qos) if qos else []
            except yaml.YAMLError:
                profiles = []
            topics.append((channel.topic, schema[1].name if schema else '',
                           profiles if isinstance(profiles, list) else [],
                           channel.metadata.get('topic_type_hash', ''), self.counts[new]))
        custom = original.get('custom_data') if isinstance(original, dict) else None
        distro = original.get('ros_distro') if isinstance(original, dict) else None
        return _rosbag2.dump(_rosbag2.bag_metadata(
            file_name=file_name, topics=topics, message_count=self.message_count,
            start_ns=self.start_ns or 0, end_ns=self.end_ns or 0,
            custom_data={str(k): str(v) for k, v in custom.items()}
            if isinstance(custom, dict) else None,
            ros_distro=distro if isinstance(distro, str) and distro else 'jazzy'))


def _check_source(path):
    try:
        size = os.path.getsize(path)
        with open(path, 'rb') as stream:
            magic = stream.read(len(MCAP_MAGIC))
    except OSError as exc:
        raise RecordingError(f'cannot read recording {str(path)!r}: '
                             f'{exc.strerror or exc}') from exc
    if magic != MCAP_MAGIC:
        if len(magic) < len(MCAP_MAGIC) and MCAP_MAGIC.startswith(magic):
            raise RecordingError(f'{str(path)!r} holds nothing to recover: its recorder '
                                 f'stopped before it wrote the MCAP header ({size} bytes)')
        raise RecordingError(f'{str(path)!r} is not an MCAP file')
    if is_being_written(path):
        raise OutputBusyError(f'{str(path)!r} is being recorded right now: recover it once its '
                              f'recorder has stopped')
    return size


def _compression_of(path):
    """Return the compression of the first chunk of ``path`` (zstd if it has none)."""
    with open(path, 'rb') as stream:
        try:
            for record in StreamReader(stream, emit_chunks=True).records:
                if isinstance(record, Chunk):
                    return _COMPRESSION.get(record.compression, CompressionType.ZSTD)
        except _TRUNCATION_ERRORS:
            pass
    return CompressionType.ZSTD


def _temporary(output):
    """Create a new file beside ``output`` (mode 0666 less the umask); return its path."""
    for attempt in range(100):
        path = output.with_name(f'.{output.name}.{os.getpid()}.{attempt}.tmp')
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:  # a read-only file system, a directory without write access
            raise RecordingError(f'cannot write {str(output)!r}: cannot create a file in '
                                 f'{str(output.parent)!r}: {exc.strerror or exc}') from exc
        os.close(fd)
        return path
    raise RecordingError(f'cannot create a temporary file beside {str(output)!r}')


def _move_into_place(temporary, output):
    """Give ``temporary`` the name ``output``, never replacing an existing file."""
    try:
        os.link(temporary, output)
    except FileExistsError:
        raise OutputExistsError(f'{str(output)!r} exists (refusing to replace it)') from None
    except OSError:
        # A file system without hard links: a rename, after checking (not atomic).
        if output.exists():
            raise OutputExistsError(
                f'{str(output)!r} exists (refusing to replace it)') from None
        os.rename(temporary, output)
        return
    os.unlink(temporary)


def recover(path, output=None) -> Recovery:
    """
    Write a complete copy of a killed or damaged recording (see the module doc).

    Parameters
    ----------
    path : str or os.PathLike
        The recording, e.g. one whose recorder was killed (no summary).
    output : str or os.PathLike, optional
        The complete copy to write (default :func:`default_output`: ``FILE.recovered.mcap``).
        Its parent directories are created; an existing file is refused.

    Returns
    -------
    Recovery

    Raises
    ------
    OutputExistsError
        If ``output`` exists (or is the source).
    OutputBusyError
        If a recorder is still writing ``path``.
    RecordingError
        If ``path`` cannot be read, is not an MCAP file or holds no record after its header
        (nothing to recover: no output is written), or the output cannot be written.

    """
    source = pathlib.Path(path)
    output = default_output(source) if output is None else pathlib.Path(output)
    size = _check_source(source)
    if output.exists():
        raise OutputExistsError(f'{str(output)!r} exists (refusing to replace it)')
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RecordingError(f'cannot create {str(output)!r}: cannot create its directory: '
                             f'{exc.strerror or exc}') from exc
    with open(source, 'rb') as stream:
        was_complete = _summary(SeekingReader(stream)) is not None
    compression = _compression_of(source)
    temporary = _temporary(output)
    try:
        with open(temporary, 'wb') as sink, open(source, 'rb') as stream:
            result = _copy(stream, sink, compression, output.name)
            _check_recovered(source, size, result)
            sink.flush()
            os.fsync(sink.fileno())
        _move_into_place(temporary, output)
    except OSError as exc:
        raise RecordingError(f'cannot write {str(output)!r}: {exc.strerror or exc}') from exc
    finally:
        if temporary.exists():
            temporary.unlink()
    copy, chunks, metadata_count, stop = result
    return Recovery(
        source=source, output=output, message_count=copy.message_count,
        topics={channel.topic: copy.counts[new] for new, channel in copy.channels.values()},
        chunk_count=chunks, metadata_count=metadata_count, was_complete=was_complete,
        stopped_at=stop[0] if stop else None, reason=stop[1] if stop else '',
        source_size=size)


def _check_recovered(source, size, result) -> None:
    """Refuse a recovery that read no record beyond the header: an empty MCAP is no copy."""
    copy, _, metadata_count, stop = result
    if copy.schemas or copy.channels or copy.message_count or metadata_count or \
            copy.attachment_count:
        return
    where = f'; reading stopped at byte {stop[0]} ({stop[1]})' if stop else ''
    raise RecordingError(f'{str(source)!r} holds nothing to recover: no schema, channel, '
                         f'message or metadata record after its header ({size} bytes'
                         f'{where})')


def _copy(stream, sink, compression, file_name):
    """
    Copy the readable records of ``stream`` to a new MCAP on ``sink``.

    The records come from the reader's linear read (:func:`_linear_records`), which stops at
    the first damaged or incomplete record: mcap's StreamReader, used here before, skipped a
    record whose opcode was damaged (a whole chunk) and went on with the next.
    """
    copy = None
    metadata_count = 0
    original_rosbag2 = None
    stops, counts = [], {}
    for item in _linear_records(stream, stops, counts):
        if isinstance(item, Header):
            copy = _Copy(sink, item.profile, item.library, compression)
            continue
        if copy is None:
            copy = _Copy(sink, '', '', compression)  # a file with its header damaged
        if isinstance(item, Schema):
            copy.schema(item)
        elif isinstance(item, Channel):
            copy.channel(item)
        elif isinstance(item, Message):
            copy.message(item)
        elif isinstance(item, Metadata):
            if item.name == ROSBAG2_METADATA_NAME:
                original_rosbag2 = item.metadata.get('serialized_metadata', '')
                continue
            copy.writer.add_metadata(item.name, dict(item.metadata))
            metadata_count += 1
        elif isinstance(item, Attachment):
            copy.writer.add_attachment(item.create_time, item.log_time, item.name,
                                       item.media_type, item.data)
            copy.attachment_count += 1
    chunks = counts.get('chunks', 0)
    stop = stops[0] if stops else None
    if copy is None:
        copy = _Copy(sink, '', '', compression)
    copy.writer.flush()  # the last chunk before the rosbag2 record, as BagWriter does
    if copy.profile == 'ros2':
        try:
            original = yaml.safe_load(original_rosbag2) if original_rosbag2 else None
        except yaml.YAMLError:
            original = None
        copy.writer.add_metadata(ROSBAG2_METADATA_NAME, {
            'serialized_metadata': copy.rosbag2_metadata(file_name, original)})
    copy.writer.finish()
    return copy, chunks, metadata_count, stop
