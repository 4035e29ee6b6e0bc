"""
Write rosbag2 bags (MCAP by default, or sqlite3) through public APIs only.

A bag is a directory with one storage file and ``metadata.yaml``, in rosbag2's format
version 9 (ROS 2 Jazzy), so ``ros2 bag info/play``, rosbags and the ``mcap`` tools read it.

Serialisation.  The messages arrive already serialised (CDR bytes): the offline simulation
writes the bytes of :class:`rigid_body_sim.messages.state.StateSerializer` and of rclpy's C
serializer (``rclpy.serialization.serialize_message``), the recorder the bytes it takes
from DDS.  Either way the bag holds byte for byte what the node puts on the wire; rosbags'
own pure-Python serializer would be a second CDR implementation to keep in step with the
node's and several times slower.  rosbags' ROS2_JAZZY typestore supplies only what a bag
needs beside the bytes: each type's message definition (the MCAP schema) and its RIHS01
type hash (equal to the installed interfaces' hashes; tested).

What writes the bytes.  Only documented, exported names of the libraries (a test checks
every import of this module and of :mod:`.recovery`), none of their private state:

- MCAP: the records of the MCAP specification (https://mcap.dev/spec), each built by the
  ``mcap`` library's public record classes (:mod:`mcap.records`: Header, Schema, Channel,
  Chunk, ChunkIndex, Metadata, MetadataIndex, Statistics, SummaryOffset, DataEnd, Footer,
  serialised by :class:`mcap.data_stream.RecordBuilder`), except the two kinds written per
  message, Message and MessageIndex, which are packed here from the specification with
  ``struct`` and numpy (a test compares them with the library's ``Message`` and
  ``MessageIndex`` records byte for byte).  Not :class:`mcap.writer.Writer`: it has no hook
  for a provisional end (below), nor for many messages at once, and its ``add_message``
  (a Message instance, six RecordBuilder writes, a MessageIndex entry each) made
  ``simulate`` write half as many messages per CPU second (docs/recording.md, "How
  `simulate` writes fast", has the figures).
- sqlite3: Python's :mod:`sqlite3`, in rosbag2 Jazzy's schema (version 4: tables schema,
  metadata, topics, message_definitions, messages).
- ``metadata.yaml``: written here (PyYAML, json).  From rosbags only its typestore and
  the QoS types of its interface (:mod:`rosbags.interfaces`: Qos, whose profiles
  :meth:`BagWriter.add_topic` takes and rosbags' Reader gives back).

QoS.  Each topic's ``offered_qos_profiles`` are written as rosbag2 Jazzy writes them:
metadata version 9, policies as lower-case names, in ``metadata.yaml`` as a YAML list and in
the MCAP channel's metadata as that list dumped to a string, next to ``topic_type_hash``.
``ros2 bag play`` offers a topic with the recorded reliability and durability, so a
reliable topic is republished reliably.  :func:`offered_qos` gives the profile DDS
discovery reports for a publisher (what ``ros2 bag record`` stores); the recorder stores
what discovery actually reported.

Durability.  :meth:`BagWriter.flush` makes everything written so far readable if the
process dies right after, even by SIGKILL: an MCAP file gets its pending chunk written and
a provisional end (DataEnd, a footer without summary, the closing magic), which the next
write overwrites; a sqlite3 bag commits its live database file and names it in
``metadata.yaml``, then writes on in its other file (:class:`_Sqlite3Storage`: the file
metadata.yaml names is never written, so it reads as counted whenever the process dies);
and ``metadata.yaml`` is rewritten with the counts so far (atomically, by rename), first
when the bag is created.  rosbags and ``mcap`` read such a bag as it is (a linear scan,
there being no summary); :func:`rigid_body_sim.recording.recovery.recover_bag` rewrites it
into a complete one with index and summary.  A write that fails (a full disk) is an
OSError naming the file, and the bag is left as at the last flush, as metadata.yaml says:
an MCAP file is cut back to that flush's provisional end.
"""

from collections import defaultdict
import errno
import json
import os
from pathlib import Path
import sqlite3
import struct
from typing import NamedTuple
import zlib

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import Channel
from mcap.records import Chunk
from mcap.records import ChunkIndex
from mcap.records import DataEnd
from mcap.records import Footer
from mcap.records import Header
from mcap.records import Metadata
from mcap.records import MetadataIndex
from mcap.records import Schema
from mcap.records import Statistics
from mcap.records import SummaryOffset
import numpy as np
from rosbags.interfaces import Qos
from rosbags.interfaces import QosDurability
from rosbags.interfaces import QosHistory
from rosbags.interfaces import QosLiveliness
from rosbags.interfaces import QosReliability
from rosbags.interfaces import QosTime
from rosbags.typesys import get_typestore
from rosbags.typesys import Stores
import yaml

__all__ = [
    'BAG_VERSION',
    'CUSTOM_DATA_PREFIX',
    'ROS_DISTRO',
    'STORAGES',
    'BagWriter',
    'INFINITE_DURATION',
    'fsync_file',
    'offered_qos',
    'qos_from_profile',
    'storage_file',
    'typestore',
]

BAG_VERSION = 9
"""The rosbag2 metadata version of ROS 2 Jazzy."""

ROS_DISTRO = 'jazzy'
"""The ``ros_distro`` of the bags' metadata, as rosbag2 Jazzy writes it."""

STORAGES = ('mcap', 'sqlite3')
"""Storage formats: MCAP (rosbag2's default since Iron) and sqlite3."""

CUSTOM_DATA_PREFIX = 'rigid_body_sim.'
"""The start of the package's keys in a bag's ``custom_data`` (the run's scene, integrator,
body and effects, which the node's messages do not carry; the plot reads them)."""

_SUFFIXES = {'mcap': '.mcap', 'sqlite3': '.db3'}

INFINITE_DURATION = QosTime(9223372036, 854775807)
"""RMW_DURATION_INFINITE (2^63 - 1 ns) as (sec, nsec): what discovery reports for 'none'."""

_TYPESTORE = None


def typestore():
    """Return the ROS 2 Jazzy type store of rosbags, loaded once."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


def _qos_time(duration_nanoseconds):
    seconds, nanoseconds = divmod(int(duration_nanoseconds), 1_000_000_000)
    return QosTime(seconds, nanoseconds)


def qos_from_profile(profile):
    """
    Return the rosbags Qos equal to an rclpy QoSProfile, policy by policy.

    Use it for profiles from the ROS graph (``Node.get_publishers_info_by_topic``), which
    already are in the form discovery reports; see :func:`offered_qos` for a profile a
    publisher was created with.
    """
    return Qos(QosHistory(int(profile.history)), int(profile.depth),
               QosReliability(int(profile.reliability)),
               QosDurability(int(profile.durability)),
               _qos_time(profile.deadline.nanoseconds), _qos_time(profile.lifespan.nanoseconds),
               QosLiveliness(int(profile.liveliness)),
               _qos_time(profile.liveliness_lease_duration.nanoseconds),
               bool(profile.avoid_ros_namespace_conventions))


def offered_qos(profile):
    """
    Return the Qos that DDS discovery reports for a publisher created with `profile`.

    This is what ``ros2 bag record`` stores as the topic's offered profile, and what
    ``ros2 bag play`` offers again.  With Fast DDS (rmw_fastrtps, Jazzy's default)
    discovery carries no history or depth (reported as unknown and 0), a duration left at
    its default (0: none) is reported infinite, and the system-default liveliness
    automatic; reliability and durability are reported as set.  A test compares this with
    what discovery reports for the running node.

    Parameters
    ----------
    profile : rclpy.qos.QoSProfile
        The profile the publisher was created with.

    """
    def duration(value):
        nanoseconds = value.nanoseconds
        return INFINITE_DURATION if nanoseconds == 0 else _qos_time(nanoseconds)

    liveliness = QosLiveliness(int(profile.liveliness))
    if liveliness == QosLiveliness.SYSTEM_DEFAULT:
        liveliness = QosLiveliness.AUTOMATIC
    return Qos(QosHistory.UNKNOWN, 0, QosReliability(int(profile.reliability)),
               QosDurability(int(profile.durability)), duration(profile.deadline),
               duration(profile.lifespan), liveliness,
               duration(profile.liveliness_lease_duration),
               bool(profile.avoid_ros_namespace_conventions))


def storage_file(path, storage):
    """Return the storage file of the bag directory `path`: ``<path>/<name>.mcap`` or .db3."""
    path = Path(path)
    return path / f'{path.name}{_SUFFIXES[storage]}'


# -- MCAP records (https://mcap.dev/spec)

_MAGIC = b'\x89MCAP0\r\n'
"""The magic that opens and closes an MCAP file (spec: Magic)."""

_NO_TIME = 2**63 - 1

# The two records written per message, packed here (the spec's layout, little-endian): a
# Message record is its opcode, its length (uint64), then channel id (uint16), sequence
# (uint32), log time and publish time (uint64, ns), then the data; a MessageIndex record is
# its opcode, its length, channel id (uint16), the byte length of its (log time, offset)
# pairs (uint32), then the pairs (uint64 each).
_MESSAGE = int(Opcode.MESSAGE)
_MESSAGE_INDEX = int(Opcode.MESSAGE_INDEX)
_MESSAGE_HEADER = struct.Struct('<BQHIQQ')
_MESSAGE_FIELDS_SIZE = 2 + 4 + 8 + 8
_MESSAGE_INDEX_HEADER = struct.Struct('<BQHI')

# Close the pending chunk at this size (1 MiB, as rosbags and the mcap library do).
_CHUNK_SIZE = 1 << 20

_LIBRARY = 'rigid_body_sim.recording.bag_writer'
"""The MCAP header's library field: who wrote the file."""


def _record_bytes(*records):
    """Return the bytes of MCAP records (mcap.records instances), one after the other."""
    builder = RecordBuilder()
    for record in records:
        record.write(builder)
    return builder.end()


# The provisional end of an MCAP file that is still being written: a DataEnd record (data
# section CRC 0: not computed), a Footer with no summary (summary start 0, summary offset
# start 0, CRC 0), and the closing magic.  Readers then scan the data section linearly.
_PROVISIONAL_END = _record_bytes(
    DataEnd(data_section_crc=0),
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0)) + _MAGIC


class _Connection(NamedTuple):
    """A topic of the bag, as :meth:`BagWriter.add_topic` returns it (id 1, 2, ...)."""

    id: int  # noqa: A003 (the name rosbags gives it, which callers use)
    topic: str
    msgtype: str
    definition: str
    encoding: str  # of the definition: 'ros2msg' or 'ros2idl'
    digest: str  # RIHS01 type hash
    serialization_format: str
    offered_qos_profiles: tuple


def _qos_dicts(profiles):
    """Return rosbags Qos profiles as rosbag2 Jazzy writes them (metadata version 9)."""
    def duration(value):
        return {'sec': value.sec, 'nsec': value.nsec}

    return [{'history': profile.history.name.lower(),
             'depth': profile.depth,
             'reliability': profile.reliability.name.lower(),
             'durability': profile.durability.name.lower(),
             'deadline': duration(profile.deadline),
             'lifespan': duration(profile.lifespan),
             'liveliness': profile.liveliness.name.lower(),
             'liveliness_lease_duration': duration(profile.liveliness_lease_duration),
             'avoid_ros_namespace_conventions': profile.avoid_ros_namespace_conventions}
            for profile in profiles]


def _safe_yaml(document):
    """Return `document` as block-style YAML text without the final newline."""
    return _block_yaml(document).strip()


# libyaml's emitter where PyYAML has it: the same text as the pure-Python one, many times
# faster (a bag of many bodies lists thousands of topics).
_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


def _block_yaml(document):
    """Return `document` as block-style YAML text, keys in their order, lines unfolded."""
    return yaml.dump(document, Dumper=_DUMPER, default_flow_style=False, width=4096,
                     sort_keys=False, allow_unicode=True)


# -- storages: an MCAP file and a pair of sqlite3 files, both with a durable flush()


class _McapStorage:
    """
    An MCAP file being written, in chunks of 1 MiB, with a provisional end at each flush.

    The data section is the Header, then Chunks, each followed by the MessageIndex records
    of its channels; a Schema (once per type) and a Channel record go into the chunk being
    filled when a topic is added, before its first message.  Closing writes the 'rosbag2'
    Metadata record, DataEnd, and the summary: Schemas, Channels, Statistics, ChunkIndexes,
    MetadataIndex, each group's SummaryOffset; then the Footer and the magic.  No
    compression; chunk CRCs are 0 (the spec's 'not computed'), the summary's is computed.
    """

    def __init__(self, path):
        self.path = path
        self.closed = False
        self.published = path
        self.file = open(path, 'xb')
        self.file.write(_MAGIC + _record_bytes(Header(profile='ros2', library=_LIBRARY)))
        self._schemas = {}  # message type -> Schema
        self._channels = []
        self._chunk_indexes = []
        self._counts = {}  # channel id -> messages
        self._message_start_time = _NO_TIME
        self._message_end_time = 0
        self._new_chunk()
        # Where the provisional end is (None: none now), and where the one that
        # metadata.yaml counts up to is (None: no flush yet).
        self._provisional_end_at = None
        self._published_end_at = None

    def _new_chunk(self):
        # The records of the pending chunk, as a list of bytes joined when it is written
        # (one copy, instead of a BytesIO's copies as it grows), and their total size.
        self._chunk = []
        self._chunk_size = 0
        self._chunk_start_time = _NO_TIME
        self._chunk_end_time = 0
        # Channel id -> its messages' (log time, offset) pairs in the chunk: tuples, or
        # (n, 2) arrays of them from write_rows.
        self._chunk_messages = defaultdict(list)

    def add_connection(self, connection, offered_qos_profiles):
        """Write the connection's Schema (the first of its type) and Channel records."""
        schema = self._schemas.get(connection.msgtype)
        records = []
        if schema is None:
            schema = Schema(id=len(self._schemas) + 1, name=connection.msgtype,
                            encoding=connection.encoding, data=connection.definition.encode())
            self._schemas[connection.msgtype] = schema
            records.append(schema)
        # With the topic_type_hash entry that rosbag2's MCAP plugin adds (keys in sorted
        # order, as its std::map has them).
        channel = Channel(id=connection.id, topic=connection.topic,
                          message_encoding=connection.serialization_format,
                          metadata={'offered_qos_profiles': offered_qos_profiles,
                                    'topic_type_hash': connection.digest},
                          schema_id=schema.id)
        records.append(channel)
        self._channels.append(channel)
        self._counts[connection.id] = 0
        self._append(_record_bytes(*records))

    def _append(self, records):
        self._chunk.append(records)
        self._chunk_size += len(records)

    def write(self, connection, timestamp, data, publish_time=None, sequence=0):
        """Write one Message record into the pending chunk."""
        if timestamp < self._chunk_start_time:
            self._chunk_start_time = timestamp
        if timestamp > self._chunk_end_time:
            self._chunk_end_time = timestamp
        channel_id = connection.id
        self._counts[channel_id] += 1
        if type(data) is not bytes:
            data = bytes(data)  # kept until the chunk is written: a copy the caller cannot change
        offset = self._chunk_size
        self._chunk_messages[channel_id].append((timestamp, offset))
        self._chunk += (_MESSAGE_HEADER.pack(
            _MESSAGE, _MESSAGE_FIELDS_SIZE + len(data), channel_id, sequence & 0xFFFFFFFF,
            timestamp, timestamp if publish_time is None else publish_time), data)
        self._chunk_size = offset = offset + _MESSAGE_HEADER.size + len(data)
        if offset > _CHUNK_SIZE:
            self.close_chunk()

    def write_rows(self, connections, datas, log_times):
        """Write, for each i, the message datas[j][i] of every connection j at log_times[i]."""
        records, offsets = _message_records(connections, datas, log_times)
        base = self._chunk_size
        self._chunk_start_time = min(self._chunk_start_time, int(log_times[0]))
        self._chunk_end_time = max(self._chunk_end_time, int(log_times[-1]))
        for connection, offset in zip(connections, offsets):
            index = np.empty((len(log_times), 2), dtype=np.uint64)
            index[:, 0] = log_times
            index[:, 1] = base + offset
            self._chunk_messages[connection.id].append(index)
            self._counts[connection.id] += len(log_times)
        self._append(records)
        if self._chunk_size > _CHUNK_SIZE:
            self.close_chunk()

    def close_chunk(self):
        """
        Write the pending chunk: its Chunk record and its channels' MessageIndex records.

        Once the bag has been flushed, a full chunk is followed at once by a new provisional
        end: else, between this chunk and the next flush (most of the time when a chunk
        fills many times per flush period, as simulate's do), a SIGKILL would leave a file
        without its end that no reader opens.
        """
        flushed = self._provisional_end_at is not None
        self._drop_provisional_end()
        records = b''.join(self._chunk)
        if self._chunk_messages:
            start, end = self._chunk_start_time, self._chunk_end_time
            self._message_start_time = min(self._message_start_time, start)
            self._message_end_time = max(self._message_end_time, end)
        else:
            start = end = 0  # the spec's times of a chunk without messages
        file = self.file
        chunk_start = file.tell()
        file.write(_record_bytes(Chunk(
            compression='', data=records, message_start_time=start, message_end_time=end,
            uncompressed_crc=0, uncompressed_size=len(records))))
        index_start = file.tell()
        index_offsets = {}
        for channel_id, entries in self._chunk_messages.items():
            index = _index_array(entries)
            index_offsets[channel_id] = file.tell()
            file.write(_MESSAGE_INDEX_HEADER.pack(_MESSAGE_INDEX, 2 + 4 + index.nbytes,
                                                  channel_id, index.nbytes))
            file.write(index.tobytes())
        self._chunk_indexes.append(ChunkIndex(
            message_start_time=start, message_end_time=end, chunk_start_offset=chunk_start,
            chunk_length=index_start - chunk_start, message_index_offsets=index_offsets,
            message_index_length=file.tell() - index_start, compression='',
            compressed_size=len(records), uncompressed_size=len(records)))
        self._new_chunk()
        if flushed:
            self._write_provisional_end()

    def _write_provisional_end(self):
        self._provisional_end_at = self.file.tell()
        self.file.write(_PROVISIONAL_END)
        self.file.flush()

    def _drop_provisional_end(self):
        # Whatever comes next (a chunk, the summary) is longer than the provisional end
        # and overwrites it completely.
        if self._provisional_end_at is not None:
            self.file.seek(self._provisional_end_at)
            self._provisional_end_at = None

    def flush(self, sync, publish):
        """Write the pending chunk and a provisional end (a valid MCAP), then ``publish``."""
        if self._chunk:
            self.close_chunk()
        self._drop_provisional_end()
        self._write_provisional_end()
        if sync:
            os.fsync(self.file.fileno())
        end = self._provisional_end_at
        publish(self.path)
        self._published_end_at = end

    def close(self, serialized_metadata):
        """Write the pending chunk, the 'rosbag2' metadata, the summary and the footer."""
        self._drop_provisional_end()
        if self._chunk:
            self.close_chunk()
        file = self.file
        metadata_start = file.tell()
        file.write(_record_bytes(Metadata(
            name='rosbag2', metadata={'serialized_metadata': serialized_metadata})))
        metadata_index = MetadataIndex(offset=metadata_start,
                                       length=file.tell() - metadata_start, name='rosbag2')
        file.write(_record_bytes(DataEnd(data_section_crc=0)))
        count = sum(self._counts.values())
        statistics = Statistics(
            message_count=count, schema_count=len(self._schemas),
            channel_count=len(self._channels), attachment_count=0, metadata_count=1,
            chunk_count=len(self._chunk_indexes),
            message_start_time=self._message_start_time if count else 0,
            message_end_time=self._message_end_time if count else 0,
            channel_message_counts=dict(sorted(self._counts.items())))
        summary_start = file.tell()
        builder = RecordBuilder()
        offsets = []
        for opcode, records in ((Opcode.SCHEMA, list(self._schemas.values())),
                                (Opcode.CHANNEL, self._channels),
                                (Opcode.STATISTICS, [statistics]),
                                (Opcode.CHUNK_INDEX, self._chunk_indexes),
                                (Opcode.METADATA_INDEX, [metadata_index])):
            if not records:
                continue
            group_start = builder.count
            for record in records:
                record.write(builder)
            offsets.append(SummaryOffset(group_opcode=opcode,
                                         group_start=summary_start + group_start,
                                         group_length=builder.count - group_start))
        summary_offset_start = summary_start + builder.count
        for offset in offsets:
            offset.write(builder)
        summary = builder.end()
        # The summary CRC covers the summary section and the footer up to the CRC itself.
        footer = _record_bytes(Footer(summary_start=summary_start,
                                      summary_offset_start=summary_offset_start, summary_crc=0))
        crc = zlib.crc32(footer[:-4], zlib.crc32(summary))
        file.write(summary)
        file.write(_record_bytes(Footer(summary_start=summary_start,
                                        summary_offset_start=summary_offset_start,
                                        summary_crc=crc)))
        file.write(_MAGIC)
        file.close()
        self.closed = True

    def abort(self):
        """
        Close after a failed write, the file ending as at the last flush.

        That is what metadata.yaml counts; what came after is cut off (on a full disk, that
        frees the space the end needs).
        """
        try:
            self.file.close()  # a buffer that cannot be written is dropped
        except OSError:
            pass
        if self._published_end_at is not None:
            with open(self.path, 'r+b') as stream:
                stream.truncate(self._published_end_at)
                stream.seek(self._published_end_at)
                stream.write(_PROVISIONAL_END)

    def finish(self, publish):
        """After close: nothing to do, the bag's one file is named in metadata.yaml."""

    def sync(self):
        """Fsync the file (what was flushed to the OS survives a power loss)."""
        try:
            descriptor = self.file.fileno()
        except ValueError:
            return  # closed meanwhile by the writing thread (abort after a failed write)
        os.fsync(descriptor)


# rosbag2 Jazzy's sqlite3 schema (schema_version 4, rosbag2_storage_sqlite3), with the
# distribution in its schema table as rosbag2 writes it.
_SQLITE3_SCHEMA = f"""
CREATE TABLE schema(
  schema_version INTEGER PRIMARY KEY,
  ros_distro TEXT NOT NULL
);
CREATE TABLE metadata(
  id INTEGER PRIMARY KEY,
  metadata_version INTEGER NOT NULL,
  metadata TEXT NOT NULL
);
CREATE TABLE topics(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL,
  type TEXT NOT NULL,
  serialization_format TEXT NOT NULL,
  offered_qos_profiles TEXT NOT NULL,
  type_description_hash TEXT NOT NULL
);
CREATE TABLE message_definitions(
  id INTEGER PRIMARY KEY,
  topic_type TEXT NOT NULL,
  encoding TEXT NOT NULL,
  encoded_message_definition TEXT NOT NULL,
  type_description_hash TEXT NOT NULL
);
CREATE TABLE messages(
  id INTEGER PRIMARY KEY,
  topic_id INTEGER NOT NULL,
  timestamp INTEGER NOT NULL,
  data BLOB NOT NULL
);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
INSERT INTO schema(schema_version, ros_distro) VALUES (4, '{ROS_DISTRO}');
"""

_INSERT_MESSAGE = 'INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)'


def _sqlite3_uri(path, mode=None):
    """Return the SQLite URI of a file (any characters in its path), opened in `mode`."""
    uri = Path(path).absolute().as_uri()
    return uri if mode is None else f'{uri}?mode={mode}'


class _Sqlite3Storage:
    """
    A sqlite3 bag, durable: two database files written in turn.

    rosbags reads a database with ``immutable=1``, ignoring any journal: a database that
    SQLite was writing when the process died reads as it is on disk, with the pages of the
    open transaction that SQLite had to write out (its page cache holds 2 MB) or half of a
    commit, malformed or with messages missing or added.  So the file metadata.yaml names is
    never written to.  Messages go into the live file; a flush commits it, has metadata.yaml
    name it (:meth:`flush` calls `publish`), and only then brings the other file up to it
    (its rows copied by SQLite) and makes that one live.  Both files hold the same rows
    with the same ids after each flush.  Closing leaves one file, ``<bag>.db3``.
    """

    def __init__(self, path):
        self.files = (path, path.with_name(f'{path.stem}_alternate.db3'))
        self._connections = []
        for file in self.files:
            connection = sqlite3.connect(_sqlite3_uri(file), uri=True)
            self._connections.append(connection)
            connection.executescript(_SQLITE3_SCHEMA)
        for connection, partner in zip(self._connections, reversed(self.files)):
            connection.execute('ATTACH DATABASE ? AS partner', (_sqlite3_uri(partner, 'ro'),))
            # No fsync at each commit: the file a SIGKILL could leave half-written is never
            # the one metadata.yaml names, and flush(sync=True) fsyncs the one it publishes.
            connection.execute('PRAGMA synchronous = OFF')
        self._live = 0
        self.conn = self._connections[0]
        self.cursor = self.conn.cursor()
        self.path = path
        self.published = None
        self.closed = False
        self._types = set()

    def add_connection(self, connection, offered_qos_profiles):
        """Insert the connection's topic, and its type's definition (the first of its type)."""
        if connection.msgtype not in self._types:
            self.cursor.execute(
                'INSERT INTO message_definitions (topic_type, encoding, '
                'encoded_message_definition, type_description_hash) VALUES(?, ?, ?, ?)',
                (connection.msgtype, connection.encoding, connection.definition,
                 connection.digest))
            self._types.add(connection.msgtype)
        self.cursor.execute('INSERT INTO topics VALUES(?, ?, ?, ?, ?, ?)',
                            (connection.id, connection.topic, connection.msgtype,
                             connection.serialization_format, offered_qos_profiles,
                             connection.digest))

    def write(self, connection, timestamp, data, publish_time=None, sequence=0):
        """Insert one message (publish time and sequence have no column in rosbag2's schema)."""
        self.cursor.execute(_INSERT_MESSAGE, (connection.id, timestamp, data))

    def write_rows(self, connections, datas, log_times):
        """Write, for each i, the message datas[j][i] of every connection j at log_times[i]."""
        self.cursor.executemany(
            _INSERT_MESSAGE,
            ((connection.id, int(log_time), data[i].tobytes())
             for i, log_time in enumerate(log_times)
             for connection, data in zip(connections, datas)))

    def flush(self, sync, publish):
        """Commit the live file, ``publish(file)`` it, then make the other file live."""
        self.conn.commit()
        published = self.files[self._live]
        if sync:
            fsync_file(published)
        publish(published)
        self.published = published
        self._live = 1 - self._live
        self.conn = self._connections[self._live]
        self.cursor = self.conn.cursor()
        self.path = self.files[self._live]
        # The rows the published file has and this one lacks: those of the last two flushes.
        for table in ('topics', 'message_definitions', 'messages'):
            self.conn.execute(f'INSERT INTO main.{table} SELECT * FROM partner.{table} '
                              f'WHERE id > (SELECT coalesce(max(id), 0) FROM main.{table})')
        self.conn.commit()

    def close(self, serialized_metadata):
        """Finish the live file (its metadata table) and close both files."""
        self.conn.commit()
        # Before PRAGMA optimize, which would analyse the read-only partner too.
        self.conn.execute('DETACH DATABASE partner')
        self.conn.execute('INSERT INTO metadata(metadata_version, metadata) VALUES(?, ?)',
                          (BAG_VERSION, serialized_metadata))
        self.conn.commit()
        self.conn.execute('PRAGMA optimize')
        self.conn.close()
        self._connections[1 - self._live].close()
        self.published = self.files[self._live]
        self.closed = True

    def abort(self):
        """Close both files without committing: the published one stays as it is."""
        for connection in self._connections:
            try:
                connection.rollback()
            except sqlite3.Error:
                pass
            connection.close()

    def finish(self, publish):
        """
        After close: leave the bag with its one file, ``<bag>.db3``, named in metadata.yaml.

        If the live file was the alternate, ``<bag>.db3`` becomes a second name of it (a
        hard link) before metadata.yaml names it and the alternate name goes: at every
        moment metadata.yaml names a complete file.
        """
        canonical, alternate = self.files
        if self.published == alternate:
            canonical.unlink()
            os.link(alternate, canonical)
            publish(canonical)
            self.published = canonical
        alternate.unlink()

    def sync(self):
        """Nothing to do: flush(sync=True) fsyncs the file it publishes."""


def fsync_file(path):
    """Flush a file's data to the disk (fsync(2)), by its path: what a kill cannot undo."""
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


_STORAGES = {'mcap': _McapStorage, 'sqlite3': _Sqlite3Storage}


def _message_records(connections, datas, log_times):
    """
    Return (bytes, offsets) of MCAP Message records, one per connection per log time.

    The records go row by row (time), within a row in the order of `connections`;
    offsets[j] is the byte offset of connection j's record in row 0, and rows are
    equally long.  Sequence 0 and publish time = log time.
    """
    fields = []
    prefixes = []
    for j, (connection, data) in enumerate(zip(connections, datas)):
        size = data.shape[1]
        prefixes.append(struct.pack('<BQHI', _MESSAGE, _MESSAGE_FIELDS_SIZE + size,
                                    connection.id, 0))
        fields += [(f'prefix{j}', 'V15'), (f'log{j}', '<u8'), (f'publish{j}', '<u8'),
                   (f'data{j}', 'u1', (size,))]
    dtype = np.dtype(fields)
    records = np.empty(len(log_times), dtype=dtype)
    for j, data in enumerate(datas):
        records[f'prefix{j}'] = np.void(prefixes[j])
        records[f'log{j}'] = log_times
        records[f'publish{j}'] = log_times
        records[f'data{j}'] = data
    offsets = [dtype.fields[f'prefix{j}'][1] for j in range(len(datas))]
    return records.tobytes(), offsets


def _index_array(entries):
    """Return the (n, 2) uint64 array of (log time, offset) pairs from tuples and arrays."""
    parts = []
    pairs = []
    for entry in entries:
        if isinstance(entry, tuple):
            pairs.append(entry)
        else:
            if pairs:
                parts.append(np.array(pairs, dtype=np.uint64))
                pairs = []
            parts.append(entry)
    if pairs:
        parts.append(np.array(pairs, dtype=np.uint64))
    index = np.concatenate(parts) if len(parts) > 1 else parts[0]
    return np.ascontiguousarray(index, dtype='<u8')


class BagWriter:
    """
    A rosbag2 bag being written: topics, serialised messages, custom data.

    Use it as a context manager: the bag is created on entry and closed (summary, index,
    final ``metadata.yaml``) on exit, also when an exception (Ctrl-C) ends the block, so an
    interrupted run leaves a complete bag of what was written.

    Parameters
    ----------
    path : str or Path
        The bag directory to create; it must not exist.
    storage : str
        'mcap' (default) or 'sqlite3'.

    Raises
    ------
    ValueError
        For an unknown storage or an existing path.
    OSError
        From any method, when the storage cannot be written (a full disk: ENOSPC), naming
        the file.  The bag is then left as at the last flush, as its metadata.yaml says, and
        the writer is closed.

    """

    def __init__(self, path, storage='mcap'):
        if storage not in STORAGES:
            raise ValueError(f'storage must be one of {", ".join(STORAGES)}; got {storage!r}')
        self.path = Path(path)
        if self.path.exists():
            raise ValueError(f'{self.path} exists already; a bag is written to a new directory')
        self.storage = storage
        self._storage = None
        self._connections = {}  # topic -> connection, in the order added (ids 1, 2, ...)
        self._qos_texts = {}  # QoS profiles as JSON -> their YAML text
        self._counts = {}  # connection id -> messages written
        self._custom_data = {}
        self._min_timestamp = _NO_TIME
        self._max_timestamp = 0
        self._closed = False
        # The messages metadata.yaml counts (None: there is no metadata.yaml yet).
        self._published_count = None

    def __enter__(self):
        self.create()
        return self

    def __exit__(self, exc_type, exc_value, traceback):
        self.close()
        return False

    def create(self):
        """
        Create the directory and the storage file (done on entering a with block).

        And flush: from the start the bag reads as its metadata.yaml says, empty, so that a
        disk full before the first flush of the run still leaves a bag that tells the truth.
        """
        try:
            self.path.mkdir(mode=0o755, parents=True)
            self._storage = _STORAGES[self.storage](self.storage_file)
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None
        self.flush(sync=False)

    @property
    def storage_file(self):
        """Return the storage file (``<path>/<name>.mcap`` or ``.db3``)."""
        return storage_file(self.path, self.storage)

    def add_topic(self, topic, message_type, offered_qos_profiles=(), message_definition=None,
                  type_hash=None):
        """
        Add a topic; return its connection, for :meth:`write`.

        Parameters
        ----------
        topic : str
            Absolute topic name, e.g. '/pose'.
        message_type : str
            ROS 2 type name, e.g. 'geometry_msgs/msg/PoseStamped'.
        offered_qos_profiles : sequence of rosbags Qos
            The profiles the topic's publishers offered (see :func:`offered_qos`).
        message_definition, type_hash : str, optional
            The type's definition (ros2msg text) and RIHS01 hash; default: from the Jazzy
            typestore, which knows the standard interfaces.

        """
        if topic in self._connections:
            raise ValueError(f'topic {topic} added twice')
        if self._storage is None:
            raise ValueError(f'{self.path}: the bag is not open for writing')
        if message_definition is None or type_hash is None:
            store = typestore()
            if message_type not in store.fielddefs:
                raise ValueError(f'unknown message type {message_type!r}: give its '
                                 'definition and hash')
            message_definition, _ = store.generate_msgdef(message_type, ros_version=2)
            type_hash = store.hash_rihs01(message_type)
        # An IDL definition starts as rosbag2 and rosbags write one, else it is ros2msg.
        encoding = 'ros2idl' if message_definition.startswith('=' * 80 + '\nIDL: ') \
            else 'ros2msg'
        connection = _Connection(
            id=len(self._connections) + 1, topic=topic, msgtype=message_type,
            definition=message_definition, encoding=encoding, digest=type_hash,
            serialization_format='cdr', offered_qos_profiles=tuple(offered_qos_profiles))
        try:
            # In the MCAP channel and the sqlite3 topics table: the list as YAML text.
            self._storage.add_connection(
                connection, self._qos_yaml(connection.offered_qos_profiles))
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None
        self._connections[topic] = connection
        self._counts[connection.id] = 0
        return connection

    def _qos_yaml(self, profiles):
        # A scene of many bodies offers the same QoS on hundreds of topics: YAML once each.
        dicts = _qos_dicts(profiles)
        key = json.dumps(dicts, sort_keys=True, default=str)
        text = self._qos_texts.get(key)
        if text is None:
            text = self._qos_texts[key] = _safe_yaml(dicts)
        return text

    def connection(self, topic):
        """Return the connection of an added topic (KeyError if there is none)."""
        return self._connections[topic]

    def set_custom_data(self, key, value):
        """
        Store a string in ``custom_data`` of ``metadata.yaml`` (rosbag2 Jazzy keeps it).

        The package's own keys start with :data:`CUSTOM_DATA_PREFIX`.
        """
        self._custom_data[str(key)] = str(value)

    def write(self, connection, log_time, data, publish_time=None, sequence=0):
        """
        Write one serialised message.

        Parameters
        ----------
        connection
            From :meth:`add_topic`.
        log_time : int
            The bag time in ns: receive time when recording, the stamp offline.
        data : bytes
            The CDR-serialised message.
        publish_time : int, optional
            Publication time in ns (MCAP only); default: log_time.
        sequence : int
            The publisher's sequence number (MCAP only; 0 if unknown).

        """
        try:
            self._storage.write(connection, log_time, data, publish_time, sequence)
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None
        self._counts[connection.id] += 1
        if log_time < self._min_timestamp:
            self._min_timestamp = log_time
        if log_time > self._max_timestamp:
            self._max_timestamp = log_time

    def write_rows(self, connections, datas, log_times):
        """
        Write many ticks of fixed-size messages at once.

        Parameters
        ----------
        connections : sequence
            From :meth:`add_topic`, one per topic.
        datas : sequence of ndarray (n, size_j) uint8
            datas[j][i] is the serialised message of connections[j] at tick i.
        log_times : ndarray (n,) of int
            The ticks' bag times in ns, non-decreasing; each tick's messages are written
            in the order of `connections`.

        """
        log_times = np.asarray(log_times, dtype=np.int64)
        if len(log_times) == 0:
            return
        try:
            self._storage.write_rows(connections, datas, log_times)
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None
        for connection in connections:
            self._counts[connection.id] += len(log_times)
        self._min_timestamp = min(self._min_timestamp, int(log_times[0]))
        self._max_timestamp = max(self._max_timestamp, int(log_times[-1]))

    @property
    def message_counts(self):
        """Topic -> number of messages written."""
        counts = self._counts
        return {topic: counts[connection.id] for topic, connection in self._connections.items()}

    def flush(self, sync=True):
        """
        Make everything written so far readable and durable.

        After this the bag survives the process being killed (SIGKILL) at any time up to
        the next flush: its storage file is valid and ``metadata.yaml`` lists the topics
        and counts written until now.  `sync` also fsyncs the storage file, against power
        loss (a killed process loses nothing the kernel has).
        """
        try:
            self._storage.flush(sync, self._write_metadata)
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None

    def sync_to_disk(self):
        """
        Fsync the storage file: what the last :meth:`flush` wrote survives a power loss.

        May run in another thread while this one writes on (the recorder does, so that a
        slow disk never stalls its takes); not after :meth:`close`.  After a failed write
        (the writer closed, the storage given up) there is nothing to sync.
        """
        storage = self._storage
        if storage is not None and not storage.closed:
            storage.sync()

    def close(self):
        """Finish the bag: summary and index, final ``metadata.yaml``.  Idempotent."""
        storage = self._storage
        if self._closed or storage is None:
            return
        self._closed = True
        try:
            # The metadata rosbag2 keeps in the storage too (the MCAP 'rosbag2' metadata
            # record, the sqlite3 metadata table): the final metadata.yaml's information.
            storage.close(_safe_yaml(self._information(self.storage_file.name)))
            self._write_metadata(storage.published, final=True)
            storage.finish(lambda file: self._write_metadata(file, final=True))
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error, storage) from None

    def _failure(self, error, storage=None):
        """
        Close the storage after `error`, leaving it as at the last flush; return the OSError.

        The OSError names the file (an OSError of a buffered write or SQLite's 'database or
        disk is full' name none): ENOSPC for a full disk, EIO for another SQLite error.
        """
        storage = storage or self._storage
        self._closed = True
        self._storage = None
        if storage is not None and not storage.closed:
            try:
                storage.abort()
            except (OSError, sqlite3.Error):
                pass  # the first error is the one to report
        file = str(storage.path) if storage is not None else str(self.path)
        if isinstance(error, sqlite3.Error):
            full = getattr(error, 'sqlite_errorname', '') == 'SQLITE_FULL'
            number, reason = (errno.ENOSPC, os.strerror(errno.ENOSPC)) if full else (
                errno.EIO, f'sqlite3: {error}')
        else:
            number, reason = error.errno, error.strerror or str(error)
            file = error.filename or file
        if self._published_count is not None:
            reason += (f'; the bag keeps the {self._published_count} messages of its last '
                       'flush, as its metadata.yaml says')
        return OSError(number, reason, file)

    def _information(self, name):
        """Return the bag's metadata (rosbag2_bagfile_information) with the counts so far."""
        counts = self._counts
        count = sum(counts.values())
        start = self._min_timestamp if count else 0
        duration = self._max_timestamp - start if count else 0
        # The keys in the order rosbag2 writes them.
        return {
            'version': BAG_VERSION,
            'storage_identifier': self.storage,
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {'topic_metadata': {
                    'name': connection.topic,
                    'type': connection.msgtype,
                    'serialization_format': connection.serialization_format,
                    'offered_qos_profiles': _qos_dicts(connection.offered_qos_profiles),
                    'type_description_hash': connection.digest},
                 'message_count': counts[connection.id]}
                for connection in self._connections.values()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [name],
            'files': [{'path': name, 'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration}, 'message_count': count}],
            'custom_data': dict(self._custom_data) or None,
            'ros_distro': ROS_DISTRO,
        }

    def _write_metadata(self, file, final=False):
        # metadata.yaml with the counts so far, naming the storage file `file`.  The final
        # one is block-style YAML without folded lines; at a flush, JSON (which is YAML
        # too): cheaper still, at four flushes a second.
        information = self._information(Path(file).name)
        document = {'rosbag2_bagfile_information': information}
        temporary = self.path / 'metadata.yaml.tmp'
        try:
            with open(temporary, 'w', encoding='utf-8') as stream:
                if final:
                    stream.write(_block_yaml(document))
                else:
                    json.dump(document, stream, indent=1)
                    stream.write('\n')
        except OSError as error:
            # The metadata.yaml of the last flush stays, true to what the storage holds.
            temporary.unlink(missing_ok=True)
            raise OSError(error.errno, error.strerror, str(self.path / 'metadata.yaml')) \
                from None
        os.replace(temporary, self.path / 'metadata.yaml')
        self._published_count = information['message_count']
