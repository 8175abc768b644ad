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

A finished file is read through its summary and indexes (seeking, in log-time order), once
the summary matches the CRC in the footer. A file without a valid summary, such as one
truncated by ``kill -9`` or one whose summary is damaged, is read linearly from the start:
everything up to the first incomplete, corrupt or implausible record (in practice: every
completed chunk and every metadata record before it) is returned and nothing after it, so the
messages are a prefix of those written, never a later chunk after a damaged record; one
warning line (logger ``ring_gyro_sim.recording.reader``, once per file and process) says
where the reading stopped and that ``ring_gyro recover FILE`` writes a complete copy that
every MCAP reader opens. The linear read (:func:`_linear_records`) is stricter than mcap's
``StreamReader``, which skips records of unknown types for forward compatibility: here a
record type it does not know (a newer writer's, a private one) ends it too. The messages are
guarded by the chunk CRCs (``BagWriter`` always writes them); metadata records carry no CRC
of their own, so a damaged byte inside a metadata value of a killed file can go unnoticed.

A corrupt record found through the index of a finished file (a file written by two recorders
at once, a damaged disk) raises a :class:`~ring_gyro_sim.recording.errors.RecordingError`
naming the file and the reason; nothing else escapes the reader.

:func:`block_end_times_ns` returns where the blocks of a run recorded by
:class:`ring_gyro_sim.ros.recorder.RunRecorder` ended, which a re-simulation needs to cut the
run the same way (the block messages of a decimated recording hold fewer samples).

Series of a run, as arrays: :func:`read_block_topic` (any block topic, e.g. ``demodulator`` or
``control``: the blocks stacked), :func:`read_rate` (the gyroscope's ``rate``: stamps, rate
about z, frame) and :func:`read_angular_rate` (the rotation inputs as they acted).
"""

import dataclasses
import io
import json
import logging
import os
import pathlib
import struct
import zlib

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import (
    Attachment, Channel, Chunk, DataEnd, Header, Message, MessageIndex, Metadata, Schema)
from mcap.stream_reader import CRCValidationError, get_chunk_data_stream
import numpy as np
from rclpy.serialization import deserialize_message

from ring_gyro_sim.recording._filelock import is_being_written
from ring_gyro_sim.recording.errors import RecordingError
from ring_gyro_sim.recording.schemas import message_class
import yaml

try:
    from zstandard import ZstdError
except ImportError:  # pragma: no cover - mcap needs zstandard to read our chunks anyway
    ZstdError = McapError

_MAGIC = b'\x89MCAP0\r\n'

# What reading a cut-off, partly written or corrupt file can raise: CRCValidationError and
# UnicodeDecodeError are ValueErrors; lz4 raises RuntimeError; a damaged index points to a
# channel that does not exist (KeyError) or to a length beyond the data.
_TRUNCATION_ERRORS = (McapError, ValueError, struct.error, EOFError, ZstdError, KeyError,
                      IndexError, RuntimeError, OverflowError, MemoryError)
# Reading through the index also: a damaged chunk offset that the file cannot seek to (EINVAL).
_INDEXED_READ_ERRORS = (*_TRUNCATION_ERRORS, OSError)

#: Name of the metadata record of a run (written by ``ring_gyro_sim.ros.recorder``).
RUN_METADATA_NAME = 'ring_gyro_sim'
#: Name of the metadata records of the run's changes of model (``integrator.fidelity``).
HANDOFF_METADATA_NAME = 'ring_gyro_sim.handoff'

_log = logging.getLogger(__name__)
_hinted = set()


def _reason(exc):
    """Return why a record could not be read, in a few words."""
    if isinstance(exc, (EOFError, struct.error)) or type(exc).__name__ == 'EndOfFile':
        return 'the file ends inside a record'
    text = str(exc)
    return f'{type(exc).__name__}: {text}' if text else type(exc).__name__


def _size(stream):
    """Return the size of the file open as ``stream``."""
    return os.fstat(stream.fileno()).st_size


def _corrupt(path, exc):
    return RecordingError(
        f'recording {str(path)!r} is corrupt ({_reason(exc)}); was it written by two '
        f'recorders at once? `ring_gyro recover {path}` saves the records before the damage')


def _hint_incomplete(path, stop):
    """Say once per file (and size) that a file without a summary can be completed."""
    try:
        info = os.stat(path)
        key = (os.path.realpath(path), info.st_size, info.st_mtime_ns)
    except OSError:
        return
    if key in _hinted:
        return
    _hinted.add(key)
    where = f'; read up to byte {stop[0]} of {info.st_size} ({stop[1]})' if stop else ''
    busy = ' (it is being recorded right now)' if is_being_written(path) else ''
    what = 'has no summary'
    try:
        with open(path, 'rb') as stream:
            if _summary(SeekingReader(stream)) is not None:  # there, but not intact
                what = 'has a summary that fails its CRC (not used; read linearly)'
    except (*_TRUNCATION_ERRORS, OSError):  # no magic at its start: a summary is no question
        pass
    _log.warning(f'recording {str(path)!r} {what}{busy}{where}: '
                 f'`ring_gyro recover {path}` writes a complete copy that every MCAP reader '
                 f'opens')


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


_FOOTER = struct.Struct('<BQQQI')  # opcode, length, summary start, summary offsets start, CRC


def _summary_crc_matches(stream):
    """
    Tell whether the summary section and footer of a finished file match the footer's CRC.

    mcap does not check it, and takes what a damaged summary leaves (it skips a chunk index
    whose opcode is damaged; a damaged start time reorders the messages). True if the footer
    gives no CRC (0) or cannot be read (the summary is not used then).
    """
    size = _size(stream)
    footer_start = size - len(_MAGIC) - _FOOTER.size
    if footer_start < len(_MAGIC):
        return True
    stream.seek(footer_start, io.SEEK_SET)
    footer = stream.read(_FOOTER.size)
    _, _, summary_start, _, expected = _FOOTER.unpack(footer)
    if expected == 0:
        return True
    if not len(_MAGIC) <= summary_start <= footer_start:
        return False
    # From the summary's start up to the footer's CRC field.
    stream.seek(summary_start, io.SEEK_SET)
    crc, left = 0, footer_start + _FOOTER.size - 4 - summary_start
    while left > 0:
        data = stream.read(min(left, 1 << 20))
        if not data:
            return False
        crc, left = zlib.crc32(data, crc), left - len(data)
    return crc == expected


def _intact_summary(reader, stream):
    """Return the summary of a complete file, or None if it has none, or a damaged one."""
    summary = _summary(reader)
    if summary is None or not _summary_crc_matches(stream):
        return None
    return summary


class _DamagedRecord(McapError):
    """A record whose bytes are not what its opcode and length announce."""


# The records a linear read accepts: the header first, then only what a data section holds,
# and inside chunks only schemas, channels and messages. Anything else ends the read (see
# _linear_records).
_HEADER_RECORDS = {Opcode.HEADER: Header}
_DATA_RECORDS = {
    Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.MESSAGE: Message,
    Opcode.CHUNK: Chunk, Opcode.MESSAGE_INDEX: MessageIndex, Opcode.ATTACHMENT: Attachment,
    Opcode.METADATA: Metadata, Opcode.DATA_END: DataEnd,
}
_CHUNK_RECORDS = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.MESSAGE: Message}
_CHUNK_COMPRESSIONS = ('', 'zstd', 'lz4')
# Where a file keeps its messages, by the record that tells: all in chunks or none outside
# them, as every MCAP writer does.
_STORAGE = {Chunk: 'in chunks', MessageIndex: 'in chunks', Message: 'outside chunks'}
_RECORD_HEAD = struct.Struct('<BQ')  # opcode, length of the fields


class _RecordFields(ReadDataStream):
    """The fields of one record: reading past them is damage, not the end of the file."""

    def __init__(self, body):
        super().__init__(io.BytesIO(body))
        self._length = len(body)

    def read(self, length):
        if length < 0 or self.count + length > self._length:
            raise _DamagedRecord('its fields run past its length')
        return super().read(length)


def _record(opcode, body, kinds):
    """Return the record of ``opcode`` read with mcap's parser; its fields must fill ``body``."""
    kind = kinds.get(opcode)
    if kind is None:
        raise _DamagedRecord(f'unexpected record opcode 0x{opcode:02x}')
    fields = _RecordFields(body)
    record = kind.read(fields, len(body)) if kind is Message else kind.read(fields)
    if fields.count != len(body):
        raise _DamagedRecord(f'a {kind.__name__} record of {len(body)} bytes whose fields '
                             f'take {fields.count}')
    return record


def _chunk_records(chunk):
    """Return the records of ``chunk`` once its size and CRC are checked."""
    if chunk.compression not in _CHUNK_COMPRESSIONS:
        # mcap would take the compressed bytes as records.
        raise _DamagedRecord(f'a chunk compressed with unknown {chunk.compression!r}')
    stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    if size != chunk.uncompressed_size:
        raise _DamagedRecord(f'a chunk of {size} bytes announced as {chunk.uncompressed_size}')
    data = stream.read(size)
    records, offset = [], 0
    while offset < size:
        if size - offset < _RECORD_HEAD.size:
            raise _DamagedRecord('a chunk that ends inside a record')
        opcode, length = _RECORD_HEAD.unpack_from(data, offset)
        offset += _RECORD_HEAD.size
        if length > size - offset:
            raise _DamagedRecord('a chunk that ends inside a record')
        records.append(_record(opcode, data[offset:offset + length], _CHUNK_RECORDS))
        offset += length
    return records


def _storage(record, storage):
    """
    Return where the file keeps its messages (None: not known yet), ``record`` included.

    A message record among chunks is another record damaged into one (one flipped bit makes a
    message index a message, whose fields then fill its length), and a message index comes
    after its chunk.
    """
    where = _STORAGE.get(type(record))
    if where is None:
        return storage
    if storage is None and isinstance(record, MessageIndex):
        raise _DamagedRecord('a message index before any chunk')
    if storage not in (None, where):
        raise _DamagedRecord(f'a {type(record).__name__} record in a file whose messages are '
                             f'{storage}')
    return where


def _linear_records(stream, stop=None, counts=None):
    """
    Yield the records of a possibly truncated file until the first unreadable one.

    The records of a chunk come only once the whole chunk has been read and checked. Reading
    ends at the data section's end (DataEnd: the summary only repeats what came before) or
    at the first record that is incomplete or fails a check: an opcode that does not belong
    there, fields that do not fill the record's length exactly, a message record among
    chunks, a chunk's size, compression or CRC, the data section's CRC. It never goes on
    after such a record. mcap's StreamReader does: it skips records of unknown opcodes (room
    for record types added later) and ignores lengths that disagree with the fields, so one
    damaged opcode made it skip a whole chunk and go on with the next. If ``stop`` is a list,
    (byte offset of the first unreadable record, reason) is appended to it when reading stops
    before the end of the file. If ``counts`` is a dict, ``counts['chunks']`` counts the
    chunks read whole.
    """
    size = _size(stream)
    good = stream.tell()
    kinds, storage = _HEADER_RECORDS, None
    try:
        magic = stream.read(len(_MAGIC))
        if magic != _MAGIC:
            raise _DamagedRecord('no MCAP magic at its start')
    except _TRUNCATION_ERRORS as exc:
        if stop is not None:
            stop.append((good, _reason(exc)))
        return
    crc = zlib.crc32(magic)
    while True:
        good = stream.tell()
        head = stream.read(_RECORD_HEAD.size)
        if not head:
            return
        try:
            if len(head) < _RECORD_HEAD.size:
                raise EndOfFile()
            opcode, length = _RECORD_HEAD.unpack(head)
            if length > size - stream.tell():
                raise EndOfFile()
            body = stream.read(length)
            if len(body) < length:
                raise EndOfFile()
            record = _record(opcode, body, kinds)
            if isinstance(record, DataEnd):
                if record.data_section_crc not in (0, crc):
                    raise CRCValidationError(record.data_section_crc, crc, record)
                return
            storage = _storage(record, storage)
            records = _chunk_records(record) if isinstance(record, Chunk) else (record,)
        except _TRUNCATION_ERRORS as exc:
            if stop is not None:
                stop.append((good, _reason(exc)))
            return
        crc = zlib.crc32(body, zlib.crc32(head, crc))
        kinds = _DATA_RECORDS
        if counts is not None and isinstance(record, Chunk):
            counts['chunks'] = counts.get('chunks', 0) + 1
        yield from records


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
            _hint_incomplete(path, None)
            return
        stream.seek(0, io.SEEK_SET)
        reader = SeekingReader(stream, validate_crcs=True)
        summary = _intact_summary(reader, stream)
        if summary is not None and summary.chunk_indexes:
            try:
                for schema, channel, message in reader.iter_messages(
                        topics=topics, log_time_order=True):
                    yield _bag_message(schema, channel, message)
            except _INDEXED_READ_ERRORS as exc:
                raise _corrupt(path, exc) from exc
            return
        stream.seek(0, io.SEEK_SET)
        schemas, channels, found, stop = {}, {}, [], []
        for record in _linear_records(stream, stop):
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or (topics is not None and channel.topic not in topics):
                    continue
                found.append(_bag_message(schemas.get(channel.schema_id), channel, record))
        if summary is None:
            _hint_incomplete(path, stop[0] if stop else None)
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
        summary = _intact_summary(SeekingReader(stream), stream)
        if summary is not None:
            schemas, channels = summary.schemas, summary.channels.values()
        else:
            stream.seek(0, io.SEEK_SET)
            schemas, channels, stop = {}, [], []
            for record in _linear_records(stream, stop):
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels.append(record)
            _hint_incomplete(path, stop[0] if stop else None)
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
    records = _metadata_records(path, name)
    if not records:
        raise RecordingError(f'recording {str(path)!r} has no metadata record {name!r}')
    return records[-1]


def read_handoffs(path):
    """
    Return a run's changes of model: ``[(t_ns, model), ...]`` in time order.

    ``model`` is ``averaged`` or ``full`` from ``t_ns`` on (``integrator.fidelity``, one
    metadata record :data:`HANDOFF_METADATA_NAME` each, the first at the start); empty for a
    recording made before the records existed.
    """
    out = [(int(r['t_ns']), r['model']) for r in _metadata_records(path, HANDOFF_METADATA_NAME)]
    return sorted(out, key=lambda item: item[0])


def _metadata_records(path, name):
    """Return every metadata record ``name`` of a bag, in file order, as dicts."""
    path = _checked_path(path)
    records = []
    with open(path, 'rb') as stream:
        if len(stream.read(len(_MAGIC))) == len(_MAGIC):
            stream.seek(0, io.SEEK_SET)
            reader = SeekingReader(stream, validate_crcs=True)
            summary = _intact_summary(reader, stream)
            indexed = summary is not None and (
                summary.statistics is None
                or summary.statistics.metadata_count <= len(summary.metadata_indexes))
            if indexed:
                try:
                    records = [record for record in reader.iter_metadata()
                               if record.name == name]
                except _INDEXED_READ_ERRORS as exc:
                    raise _corrupt(path, exc) from exc
            else:
                stream.seek(0, io.SEEK_SET)
                stop = []
                records = [record for record in _linear_records(stream, stop)
                           if isinstance(record, Metadata) and record.name == name]
                if summary is None:
                    _hint_incomplete(path, stop[0] if stop else None)
    return [dict(record.metadata) for record in records]


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


# The block topics of a run, relative to the node (recordings made before the metadata
# listed them hold these three).
_BLOCK_NAMES = ('modal_displacement', 'radial_gap', 'sense_electrodes')


def _run_metadata(path):
    return read_metadata(path, RUN_METADATA_NAME)


def _output_period_ns(path, meta):
    if 'output_period_ns' in meta:
        return int(meta['output_period_ns'])
    # Recordings made before the metadata held the period: from the parameters.
    try:
        rate = float(yaml.safe_load(meta['parameters'])['output.rate'])
    except (KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise RecordingError(f'recording {str(path)!r}: the {RUN_METADATA_NAME} metadata gives '
                             f'no output period ({exc})') from None
    return int(round(1e9 / rate))


def block_end_times_ns(path):
    """
    Return the simulation times (ns) at which the blocks of a recorded run ended, in order.

    A run starts at 0 ns and is cut into blocks of ``output.block_duration`` (the last one of a
    run with a ``duration`` may be shorter); every block message is logged at the time of the
    block's last sample, also in a decimated recording, where it holds fewer samples (or none).
    The ends are taken from, in this order: the log times of the block topics the recording
    holds (all of them, so a block whose first message survived a kill counts); the ``/clock``
    messages (one per block); or, when ``record.topics`` kept neither, the regular cut of
    ``block_samples`` samples (metadata) up to the last ``/diagnostics`` message (always
    published at a block end).

    Raises
    ------
    RecordingError
        If the file is not a run recording, or it holds none of these topics.

    """
    meta = _run_metadata(path)
    namespace = meta.get('namespace', '/ring_gyro')
    if 'block_topics' in meta:
        block_topics = json.loads(meta['block_topics'])
    else:
        block_topics = [f'{namespace}/{name}' for name in _BLOCK_NAMES]
    blocks, clock, diagnostics = set(), set(), []
    for message in read_messages(path, topics=block_topics + ['/clock', '/diagnostics']):
        if message.topic == '/clock':
            clock.add(message.log_time_ns)
        elif message.topic == '/diagnostics':
            diagnostics.append(message.log_time_ns)
        else:
            blocks.add(message.log_time_ns)
    if blocks or clock:
        return sorted(blocks or clock)
    if not diagnostics or 'block_samples' not in meta:
        raise RecordingError(
            f'recording {str(path)!r} tells no block ends: it holds no block topic, no /clock '
            f'and no /diagnostics (record.topics)')
    step = int(meta['block_samples']) * _output_period_ns(path, meta)
    end = max(diagnostics)
    ends = list(range(step, end, step))
    return ends + [end] if end > 0 else []


def block_sample_counts(path):
    """
    Return the number of samples of every block of a recorded run (see block_end_times_ns).

    Raises
    ------
    RecordingError
        As :func:`block_end_times_ns`, or if a block end is not on the output sample grid.

    """
    period = _output_period_ns(path, _run_metadata(path))
    counts, previous = [], 0
    for end in block_end_times_ns(path):
        samples, rest = divmod(end - previous, period)
        if rest or samples <= 0:
            raise RecordingError(f'recording {str(path)!r}: a block ends at {end} ns, not '
                                 f'on the {period} ns output grid after {previous} ns')
        counts.append(samples)
        previous = end
    return counts


def _run_topic(path, name):
    """Full topic name of a node-relative ``name`` in a run recording (its namespace)."""
    if name.startswith('/'):
        return name
    namespace = _run_metadata(path).get('namespace', '/ring_gyro').rstrip('/')
    return f'{namespace}/{name}'


@dataclasses.dataclass(frozen=True)
class BlockSeries:
    """
    The blocks of one block topic, stacked.

    Attributes
    ----------
    labels : list of str
        Channel names, ``t`` first (from the layout).
    data : ndarray, shape (K, C)
        Every recorded sample (of a decimated recording: the kept ones), in order.
    end_ns : list of int
        Log time of each block message (the block's last sample time).

    """

    labels: list
    data: np.ndarray
    end_ns: list


def read_block_topic(path, name):
    """
    Return the :class:`BlockSeries` of a block topic of a run recording.

    Parameters
    ----------
    path : str or os.PathLike
        A run recording (with the ``ring_gyro_sim`` metadata record).
    name : str
        Relative to the run's namespace (``demodulator``, ``modal_displacement``...) or a full
        topic name.

    Raises
    ------
    RecordingError
        The file is not a run recording or has no message on that topic.

    """
    topic = _run_topic(path, name)
    labels, rows, ends = None, [], []
    for message in read_messages(path, topics=[topic]):
        msg = decode(message)
        shape = (msg.layout.dim[0].size, msg.layout.dim[1].size)
        labels = msg.layout.dim[1].label.split(',')
        rows.append(np.asarray(msg.data, dtype=np.float64).reshape(shape))
        ends.append(message.log_time_ns)
    if labels is None:
        raise RecordingError(f'recording {str(path)!r} has no message on {topic}')
    return BlockSeries(labels=labels, data=np.concatenate(rows), end_ns=ends)


@dataclasses.dataclass(frozen=True)
class RateSeries:
    """
    The gyroscope's rate output of a recording (``<ns>/rate``, sensor_msgs/Imu).

    Attributes
    ----------
    t_ns : ndarray of int64, shape (M,)
        Header stamps (the sample times), ns.
    rate : ndarray, shape (M,)
        ``angular_velocity.z``, rad/s.
    frame_id : str
        ``header.frame_id`` ('' when there is no sample).
    covariance : ndarray, shape (M, 9)
        ``angular_velocity_covariance`` of each sample.

    """

    t_ns: np.ndarray
    rate: np.ndarray
    frame_id: str
    covariance: np.ndarray


def read_rate(path, name='rate'):
    """
    Return the :class:`RateSeries` of a run recording (empty arrays if it holds none).

    Raises
    ------
    RecordingError
        The file is not a run recording.

    """
    topic = _run_topic(path, name)
    t, rate, cov, frame = [], [], [], ''
    for message in read_messages(path, topics=[topic]):
        msg = decode(message)
        t.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        rate.append(msg.angular_velocity.z)
        cov.append(np.asarray(msg.angular_velocity_covariance, dtype=np.float64))
        frame = frame or msg.header.frame_id
    return RateSeries(t_ns=np.array(t, dtype=np.int64), rate=np.array(rate, dtype=np.float64),
                      frame_id=frame,
                      covariance=np.array(cov, dtype=np.float64).reshape(len(cov), 9))


def read_angular_rate(path, name='angular_rate'):
    """
    Return the angular rates that acted in a run: ``(t_ns, z)`` arrays (int64 ns, rad/s).

    Each is the time the rate acted from (the log time and stamp) and the rate about z.

    Raises
    ------
    RecordingError
        The file is not a run recording.

    """
    topic = _run_topic(path, name)
    t, z = [], []
    for message in read_messages(path, topics=[topic]):
        t.append(message.log_time_ns)
        z.append(decode(message).vector.z)
    return np.array(t, dtype=np.int64), np.array(z, dtype=np.float64)
