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
Read ROS 2 bags (MCAP), including what a killed recorder left behind.

A finished file is read through its summary and indexes (seeking, in log-time order). A file
without a valid summary, such as one truncated by ``kill -9``, is read linearly from the start:
everything up to the first incomplete or corrupt record (in practice: every completed chunk and
every metadata record before it) is returned, and the rest is silently ignored.
"""

import dataclasses
import io
import pathlib
import struct

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from rclpy.serialization import deserialize_message

from ring_gyro_sim.recording.errors import RecordingError
from ring_gyro_sim.recording.schemas import message_class

try:
    from zstandard import ZstdError
except ImportError:  # pragma: no cover - mcap needs zstandard to read our chunks anyway
    ZstdError = McapError

_MAGIC = b'\x89MCAP0\r\n'

# What reading a cut-off or partly written file can raise (CRCValidationError is a ValueError).
_TRUNCATION_ERRORS = (McapError, ValueError, struct.error, EOFError, ZstdError)


@dataclasses.dataclass(frozen=True, slots=True)
class BagMessage:
    """
    One recorded message.

    Attributes
    ----------
    topic : str
        Topic name, e.g. '/ring_gyro/modal_displacement'.
    type_name : str
        'pkg/msg/Type' (the schema name), '' if the channel has no schema.
    data : bytes
        The CDR-serialized message.
    log_time_ns : int
        Log (receive) time in ns.
    publish_time_ns : int
        Publish (send) time in ns.
    sequence : int
        Per-channel sequence number as written (0 if the writer did not set one).

    """

    topic: str
    type_name: str
    data: bytes
    log_time_ns: int
    publish_time_ns: int
    sequence: int = 0


def _checked_path(path):
    """Return the path of a readable MCAP file; RecordingError naming the path otherwise."""
    path = pathlib.Path(path)
    try:
        with open(path, 'rb') as stream:
            magic = stream.read(len(_MAGIC))
    except OSError as exc:
        raise RecordingError(
            f'cannot read recording {str(path)!r}: {exc.strerror or exc}') from exc
    # A shorter file is a recording killed before its header reached the disk: it is empty.
    if len(magic) == len(_MAGIC) and magic != _MAGIC:
        raise RecordingError(f'{str(path)!r} is not an MCAP file')
    return path


def _topic_set(topics):
    if topics is None:
        return None
    if isinstance(topics, str):
        return frozenset((topics,))
    return frozenset(topics)


def _summary(reader):
    """Return the summary of a complete file, or None if it has none or it cannot be read."""
    try:
        return reader.get_summary()
    except (*_TRUNCATION_ERRORS, OSError):
        # OSError: a file shorter than a footer cannot be seeked from its end.
        return None


def _linear_records(stream):
    """Yield the records of a possibly truncated file until the first unreadable one."""
    records = StreamReader(stream, validate_crcs=True).records
    while True:
        try:
            record = next(records)
        except StopIteration:
            return
        except _TRUNCATION_ERRORS:
            return
        yield record


def _bag_message(schema, channel, message):
    return BagMessage(
        topic=channel.topic,
        type_name=schema.name if schema is not None else '',
        data=bytes(message.data),
        log_time_ns=message.log_time,
        publish_time_ns=message.publish_time,
        sequence=message.sequence,
    )


def _iter_messages(path, topics):
    with open(path, 'rb') as stream:
        if len(stream.read(len(_MAGIC))) < len(_MAGIC):
            return
        stream.seek(0, io.SEEK_SET)
        reader = SeekingReader(stream)
        summary = _summary(reader)
        if summary is not None and summary.chunk_indexes:
            for schema, channel, message in reader.iter_messages(
                    topics=topics, log_time_order=True):
                yield _bag_message(schema, channel, message)
            return
        stream.seek(0, io.SEEK_SET)
        schemas, channels, found = {}, {}, []
        for record in _linear_records(stream):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or (topics is not None and channel.topic not in topics):
                    continue
                found.append(_bag_message(schemas.get(channel.schema_id), channel, record))
        # Without the index, log-time order needs every message in memory (stable: ties keep
        # file order, as the indexed read does).
        found.sort(key=lambda message: message.log_time_ns)
        yield from found


def read_topics(path):
    """
    Return ``{topic: type name}`` of a recording (from its summary, else by a linear scan).

    Raises
    ------
    RecordingError
        The file cannot be read or is not an MCAP file.

    """
    path = _checked_path(path)
    with open(path, 'rb') as stream:
        if len(stream.read(len(_MAGIC))) < len(_MAGIC):
            return {}
        stream.seek(0, io.SEEK_SET)
        summary = _summary(SeekingReader(stream))
        if summary is not None:
            schemas, channels = summary.schemas, summary.channels.values()
        else:
            stream.seek(0, io.SEEK_SET)
            schemas, channels = {}, []
            for record in _linear_records(stream):
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels.append(record)
        return {c.topic: schemas[c.schema_id].name for c in channels if c.schema_id in schemas}


def read_messages(path, topics=None):
    """
    Iterate over the messages of a bag in log-time order.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file. A truncated file (killed recorder) yields the messages of its
        complete chunks, without raising.
    topics : str or iterable of str, optional
        Only these topics (default: all).

    Returns
    -------
    iterator of BagMessage
        Messages sorted by ``log_time_ns``; equal times keep file order.

    Raises
    ------
    RecordingError
        Immediately, if the file cannot be opened or is not an MCAP file.

    """
    return _iter_messages(_checked_path(path), _topic_set(topics))


def read_metadata(path, name):
    """
    Return the metadata record ``name`` of a bag as a dict[str, str].

    Works on truncated files too (metadata records written before the cut are kept). If
    several records have this name, the last one is returned.

    Raises
    ------
    RecordingError
        If the file cannot be read or holds no metadata record of that name.

    """
    path = _checked_path(path)
    records = []
    with open(path, 'rb') as stream:
        if len(stream.read(len(_MAGIC))) == len(_MAGIC):
            stream.seek(0, io.SEEK_SET)
            reader = SeekingReader(stream)
            summary = _summary(reader)
            indexed = summary is not None and (
                summary.statistics is None
                or summary.statistics.metadata_count <= len(summary.metadata_indexes))
            if indexed:
                records = [record for record in reader.iter_metadata() if record.name == name]
            else:
                stream.seek(0, io.SEEK_SET)
                records = [record for record in _linear_records(stream)
                           if isinstance(record, Metadata) and record.name == name]
    if not records:
        raise RecordingError(f'recording {str(path)!r} has no metadata record {name!r}')
    return dict(records[-1].metadata)


def decode(message: BagMessage):
    """
    Deserialize a :class:`BagMessage` into an instance of its rclpy message class.

    Raises
    ------
    RecordingError
        If the type cannot be imported or the data is not a valid message of that type.

    """
    if not message.type_name:
        raise RecordingError(f'message on {message.topic!r} has no schema to decode it with')
    cls = message_class(message.type_name)
    try:
        return deserialize_message(message.data, cls)
    except RuntimeError as exc:
        raise RecordingError(
            f'cannot decode a {message.type_name} message on {message.topic!r} '
            f'at {message.log_time_ns} ns: {exc}') from exc
