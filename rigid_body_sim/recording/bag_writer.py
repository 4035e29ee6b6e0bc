"""
Write rosbag2 bags (MCAP by default, or sqlite3) with the ``rosbags`` library.

A bag is a directory with one storage file and ``metadata.yaml``, in rosbag2's format
version 9 (ROS 2 Jazzy), so ``ros2 bag info/play``, rosbags and the ``mcap`` tools read it.

Serialisation.  The messages arrive already serialised (CDR bytes): the offline simulation
writes the bytes of :class:`rigid_body_sim.ros.conversions.StateSerializer` and of rclpy's C
serializer (``rclpy.serialization.serialize_message``), the recorder the bytes it takes
from DDS.  Either way the bag holds byte for byte what the node puts on the wire; rosbags'
own pure-Python serializer would be a second CDR implementation to keep in step with the
node's and several times slower.  rosbags' ROS2_JAZZY typestore supplies only what a bag
needs beside the bytes: each type's message definition (the MCAP schema) and its RIHS01
type hash (equal to the installed interfaces' hashes; tested).

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
from io import BytesIO
from io import StringIO
import json
import os
from pathlib import Path
import sqlite3
import struct

import numpy as np
from rosbags.interfaces import Qos
from rosbags.interfaces import QosDurability
from rosbags.interfaces import QosHistory
from rosbags.interfaces import QosLiveliness
from rosbags.interfaces import QosReliability
from rosbags.interfaces import QosTime
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.rosbag2.storage_mcap import Channel
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_mcap import PendingChunk
from rosbags.rosbag2.storage_mcap import write_channel
from rosbags.rosbag2.storage_mcap import write_string
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys import get_typestore
from rosbags.typesys import Stores
from ruamel.yaml import YAML

__all__ = [
    'BAG_VERSION',
    'ROS_DISTRO',
    'STORAGES',
    'BagWriter',
    'INFINITE_DURATION',
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

_PLUGINS = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
_SUFFIXES = {'mcap': '.mcap', 'sqlite3': '.db3'}

INFINITE_DURATION = QosTime(9223372036, 854775807)
"""RMW_DURATION_INFINITE (2^63 - 1 ns) as (sec, nsec): what discovery reports for 'none'."""

# MCAP records (https://mcap.dev/spec), little-endian.  A Message record is opcode 0x05,
# its length, then channel id (uint16), sequence (uint32), log time and publish time
# (uint64, ns), then the data.
_MESSAGE_HEADER = struct.Struct('<BQHIQQ')
_MESSAGE_FIELDS_SIZE = 2 + 4 + 8 + 8
_MAGIC = b'\x89MCAP0\r\n'
# The provisional end of an MCAP file that is still being written: a DataEnd record (data
# section CRC 0: not computed), a Footer with no summary (summary start 0, summary offset
# start 0, CRC 0), and the closing magic.  Readers then scan the data section linearly.
_PROVISIONAL_END = (struct.pack('<BQI', 0x0F, 4, 0) + struct.pack('<BQQQI', 0x02, 20, 0, 0, 0)
                    + _MAGIC)
# Close the pending chunk at this size (rosbags' own threshold, 1 MiB).
_CHUNK_SIZE = 1 << 20

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


# -- storage plugins: rosbags' writers with a fast message write and flush()


class _McapStorage(McapWriter):
    """rosbags' MCAP writer, plus topic_type_hash, a fast write and a durable flush."""

    def __init__(self, path, compression):
        super().__init__(path, compression)
        self._provisional_end_at = None
        self.closed = False
        # Where the provisional end that metadata.yaml counts up to is (None: no flush yet).
        self._published_end_at = None
        self.published = self.path

    def add_connection(self, connection, offered_qos_profiles):
        # As rosbags writes a channel, with the topic_type_hash entry that rosbag2's MCAP
        # plugin adds (keys in sorted order, as its std::map has them).
        metadata = BytesIO()
        for key, value in (('offered_qos_profiles', offered_qos_profiles),
                           ('topic_type_hash', connection.digest)):
            write_string(metadata, key)
            write_string(metadata, value)
        channel = Channel(connection.id, connection.msgtype, connection.topic,
                          connection.ext.serialization_format, metadata.getvalue())
        self.channels.append(channel)
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, channel, self.schemas)

    def write(self, connection, timestamp, data, publish_time=None, sequence=0):
        # rosbags' write packs each field through a BytesIO of its own; one struct call
        # per message makes a 1 kHz bag several times cheaper to write.
        chunk = self.chunk
        if timestamp < chunk.message_start_time:
            chunk.message_start_time = timestamp
        if timestamp > chunk.message_end_time:
            chunk.message_end_time = timestamp
        if timestamp < self.message_start_time:
            self.message_start_time = timestamp
        if timestamp > self.message_end_time:
            self.message_end_time = timestamp
        channel_id = connection.id
        self.channel_stats[channel_id] += 1
        bio = chunk.bio
        chunk.msgs[channel_id].append((timestamp, bio.tell()))
        bio.write(_MESSAGE_HEADER.pack(
            0x05, _MESSAGE_FIELDS_SIZE + len(data), channel_id, sequence & 0xFFFFFFFF,
            timestamp, timestamp if publish_time is None else publish_time))
        bio.write(data)
        if bio.tell() > _CHUNK_SIZE:
            self.close_chunk()

    def write_rows(self, connections, datas, log_times):
        """Write, for each i, the message datas[j][i] of every connection j at log_times[i]."""
        records, offsets = _message_records(connections, datas, log_times)
        chunk = self.chunk
        base = chunk.bio.tell()
        first, last = int(log_times[0]), int(log_times[-1])
        chunk.message_start_time = min(chunk.message_start_time, first)
        chunk.message_end_time = max(chunk.message_end_time, last)
        self.message_start_time = min(self.message_start_time, first)
        self.message_end_time = max(self.message_end_time, last)
        for connection, offset in zip(connections, offsets):
            index = np.empty((len(log_times), 2), dtype=np.uint64)
            index[:, 0] = log_times
            index[:, 1] = base + offset
            chunk.msgs[connection.id].append(index)
            self.channel_stats[connection.id] += len(log_times)
        chunk.bio.write(records)
        if chunk.bio.tell() > _CHUNK_SIZE:
            self.close_chunk()

    def close_chunk(self):
        # rosbags' close_chunk, with each message index packed in one go (it writes two
        # integers per message through BytesIO calls); entries are (time, offset) pairs or
        # arrays of them.  Chunk CRC 0: not computed, as rosbag2 writes by default.
        # Once the bag has been flushed, a full chunk is followed at once by a new
        # provisional end: else, between this chunk and the next flush (most of the time
        # when a chunk fills many times per flush period, as simulate's do), a SIGKILL
        # would leave a file without its end that no reader opens.
        flushed = self._provisional_end_at is not None
        self._drop_provisional_end()
        chunk = self.chunk
        uncompressed = chunk.bio.getvalue()
        compressed = self.compressor(uncompressed)
        compression = self.compression.encode()
        chunk_start = self.bio.tell()
        body = (struct.pack('<QQQI', chunk.message_start_time, chunk.message_end_time,
                            len(uncompressed), 0)
                + struct.pack('<I', len(compression)) + compression
                + struct.pack('<Q', len(compressed)))
        self.bio.write(struct.pack('<BQ', 0x06, len(body) + len(compressed)))
        self.bio.write(body)
        self.bio.write(compressed)
        chunk_end = self.bio.tell()
        index_offsets = []
        for channel_id, entries in chunk.msgs.items():
            index = _index_array(entries)
            index_offsets.append(struct.pack('<HQ', channel_id, self.bio.tell()))
            self.bio.write(struct.pack('<BQHI', 0x07, 2 + 4 + index.nbytes, channel_id,
                                       index.nbytes))
            self.bio.write(index.tobytes())
        record = BytesIO()
        record.write(struct.pack('<QQQQI', chunk.message_start_time, chunk.message_end_time,
                                 chunk_start, chunk_end - chunk_start, 10 * len(index_offsets)))
        record.write(b''.join(index_offsets))
        record.write(struct.pack('<Q', self.bio.tell() - chunk_end))
        record.write(struct.pack('<I', len(compression)) + compression)
        record.write(struct.pack('<QQ', len(compressed), len(uncompressed)))
        self.chunks.append(record)
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))
        if flushed:
            self._write_provisional_end()

    def _write_provisional_end(self):
        self._provisional_end_at = self.bio.tell()
        self.bio.write(_PROVISIONAL_END)
        self.bio.flush()

    def flush(self, sync, publish):
        """Write the pending chunk and a provisional end (a valid MCAP), then ``publish``."""
        if self.chunk.bio.tell():
            self.close_chunk()
        self._drop_provisional_end()
        self._write_provisional_end()
        if sync:
            os.fsync(self.bio.fileno())
        end = self._provisional_end_at
        publish(self.path)
        self._published_end_at = end

    def abort(self):
        """
        Close after a failed write, the file ending as at the last flush.

        That is what metadata.yaml counts; what came after is cut off (on a full disk, that
        frees the space the end needs).
        """
        try:
            self.bio.close()  # a buffer that cannot be written is dropped
        except OSError:
            pass
        if self._published_end_at is not None:
            with open(self.path, 'r+b') as stream:
                stream.truncate(self._published_end_at)
                stream.seek(self._published_end_at)
                stream.write(_PROVISIONAL_END)

    def finish(self, publish):
        """After close: nothing to do, the bag's one file is named in metadata.yaml."""

    def close(self, version, metadata):
        self._drop_provisional_end()
        super().close(version, _as_jazzy(metadata))
        self.closed = True

    def _drop_provisional_end(self):
        # Whatever comes next (a chunk, the summary) is longer than the provisional end
        # and overwrites it completely.
        if self._provisional_end_at is not None:
            self.bio.seek(self._provisional_end_at)
            self._provisional_end_at = None


class _Sqlite3Storage(Sqlite3Writer):
    """
    rosbags' sqlite3 writer, durable: two database files written in turn.

    rosbags reads a database with ``immutable=1``, ignoring any journal: a database that
    SQLite was writing when the process died reads as it is on disk, with the pages of the
    open transaction that SQLite had to write out (its page cache holds 2 MB) or half of a
    commit, malformed or with messages missing or added.  So the file metadata.yaml names is
    never written to.  Messages go into the live file; a flush commits it, has metadata.yaml
    name it (:meth:`flush` calls `publish`), and only then brings the other file up to it
    (its rows copied by SQLite) and makes that one live.  Both files hold the same rows
    with the same ids after each flush.  Closing leaves one file, ``<bag>.db3``.
    """

    def __init__(self, path, compression):
        super().__init__(path, compression)
        canonical = self.path
        self.files = (canonical, canonical.with_name(f'{canonical.stem}_alternate.db3'))
        other = sqlite3.connect(f'file:{self.files[1]}', uri=True)
        other.executescript(self.SQLITE_SCHEMA)
        self._connections = (self.conn, other)
        for connection, partner in zip(self._connections, reversed(self.files)):
            connection.execute('ATTACH DATABASE ? AS partner', (f'file:{partner}?mode=ro',))
            # No fsync at each commit: the file a SIGKILL could leave half-written is never
            # the one metadata.yaml names, and flush(sync=True) fsyncs the one it publishes.
            connection.execute('PRAGMA synchronous = OFF')
        self._live = 0
        self.published = None
        self.closed = False

    def write(self, connection, timestamp, data, publish_time=None, sequence=0):
        self.cursor.execute('INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)',
                            (connection.id, timestamp, data))

    def write_rows(self, connections, datas, log_times):
        """Write, for each i, the message datas[j][i] of every connection j at log_times[i]."""
        self.cursor.executemany(
            'INSERT INTO messages (topic_id, timestamp, data) VALUES(?, ?, ?)',
            ((connection.id, int(log_time), data[i].tobytes())
             for i, log_time in enumerate(log_times)
             for connection, data in zip(connections, datas)))

    def flush(self, sync, publish):
        """Commit the live file, ``publish(file)`` it, then make the other file live."""
        self.conn.commit()
        published = self.files[self._live]
        if sync:
            _fsync(published)
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

    def close(self, version, metadata):
        """Finish the live file (its metadata table) and close both files."""
        self.conn.commit()
        # PRAGMA optimize (in rosbags' close) would analyse the read-only partner too.
        self.conn.execute('DETACH DATABASE partner')
        super().close(version, _as_jazzy(metadata))
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


def _fsync(path):
    descriptor = os.open(path, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _as_jazzy(metadata):
    """
    Return rosbags' serialised bag metadata (YAML) with ``ros_distro: jazzy``.

    rosbags' Writer.close writes ``ros_distro: rosbags`` into the metadata it hands the
    storage (the MCAP 'rosbag2' metadata record, the sqlite3 metadata table) and has no
    option for it; rosbag2 Jazzy writes its distribution, which the bags here are for.
    """
    document = YAML(typ='safe').load(metadata)
    document['ros_distro'] = ROS_DISTRO
    stream = StringIO()
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    yaml.dump(document, stream)
    return stream.getvalue().strip()


class _Writer(Writer):
    """rosbags' Writer with the storages above and a write that skips re-validation."""

    STORAGE_PLUGINS = {StoragePlugin.MCAP: _McapStorage, StoragePlugin.SQLITE3: _Sqlite3Storage}

    def write(self, connection, timestamp, data, publish_time=None, sequence=0):
        # The connection came from add_connection of this writer (BagWriter ensures it).
        self.storage.write(connection, timestamp, data, publish_time, sequence)
        self.counts[connection.id] += 1
        if timestamp < self.min_timestamp:
            self.min_timestamp = timestamp
        if timestamp > self.max_timestamp:
            self.max_timestamp = timestamp

    def write_rows(self, connections, datas, log_times):
        """Write one message per connection per log time (see BagWriter.write_rows)."""
        if len(log_times) == 0:
            return
        self.storage.write_rows(connections, datas, log_times)
        for connection in connections:
            self.counts[connection.id] += len(log_times)
        self.min_timestamp = min(self.min_timestamp, int(log_times[0]))
        self.max_timestamp = max(self.max_timestamp, int(log_times[-1]))


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
        prefixes.append(struct.pack('<BQHI', 0x05, _MESSAGE_FIELDS_SIZE + size,
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
        self._writer = _Writer(self.path, version=BAG_VERSION, storage_plugin=_PLUGINS[storage])
        self._connections = {}
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
            self._writer.open()
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
        if message_definition is None or type_hash is None:
            store = typestore()
            if message_type not in store.fielddefs:
                raise ValueError(f'unknown message type {message_type!r}: give its '
                                 'definition and hash')
            message_definition, _ = store.generate_msgdef(message_type, ros_version=2)
            type_hash = store.hash_rihs01(message_type)
        try:
            connection = self._writer.add_connection(
                topic, message_type, msgdef=message_definition, rihs01=type_hash,
                offered_qos_profiles=list(offered_qos_profiles))
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None
        self._connections[topic] = connection
        return connection

    def connection(self, topic):
        """Return the connection of an added topic (KeyError if there is none)."""
        return self._connections[topic]

    def set_custom_data(self, key, value):
        """Store a string in ``custom_data`` of ``metadata.yaml`` (rosbag2 Jazzy keeps it)."""
        self._writer.set_custom_data(key, str(value))

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
            self._writer.write(connection, log_time, data, publish_time, sequence)
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None

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
        try:
            self._writer.write_rows(connections, datas, np.asarray(log_times, dtype=np.int64))
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None

    @property
    def message_counts(self):
        """Topic -> number of messages written."""
        counts = self._writer.counts
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
            self._writer.storage.flush(sync, self._write_metadata)
        except (OSError, sqlite3.Error) as error:
            raise self._failure(error) from None

    def sync_to_disk(self):
        """
        Fsync the storage file: what the last :meth:`flush` wrote survives a power loss.

        May run in another thread while this one writes on (the recorder does, so that a
        slow disk never stalls its takes); not after :meth:`close`.
        """
        storage = self._writer.storage
        if isinstance(storage, _McapStorage):
            os.fsync(storage.bio.fileno())

    def close(self):
        """Finish the bag: summary and index, final ``metadata.yaml``.  Idempotent."""
        storage = self._writer.storage
        if self._closed or storage is None:
            return
        self._closed = True
        try:
            self._writer.close()
            # Rewritten in rosbag2's key order, without rosbags' line folding.
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
        storage = storage or self._writer.storage
        self._closed = True
        self._writer.storage = None
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

    def _write_metadata(self, file, final=False):
        # The metadata.yaml of rosbags' Writer.close(), with the counts so far, its keys in
        # the order rosbag2 writes them.  The final one is block-style YAML without folded
        # lines; at a flush, JSON (which is YAML too): ruamel's pure-Python emitter would
        # cost a fifth of a core at four flushes a second.
        writer = self._writer
        count = sum(writer.counts.values())
        start = writer.min_timestamp if count else 0
        duration = writer.max_timestamp - start if count else 0
        name = Path(file).name
        information = {
            'version': BAG_VERSION,
            'storage_identifier': self.storage,
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {'topic_metadata': {
                    'name': connection.topic,
                    'type': connection.msgtype,
                    'serialization_format': connection.ext.serialization_format,
                    'offered_qos_profiles': dump_qos_v9(connection.ext.offered_qos_profiles),
                    'type_description_hash': connection.digest},
                 'message_count': writer.counts[connection.id]}
                for connection in writer.connections],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [name],
            'files': [{'path': name, 'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration}, 'message_count': count}],
            'custom_data': dict(writer.custom_data) or None,
            'ros_distro': ROS_DISTRO,
        }
        document = {'rosbag2_bagfile_information': information}
        temporary = self.path / 'metadata.yaml.tmp'
        try:
            with open(temporary, 'w', encoding='utf-8') as stream:
                if final:
                    yaml = YAML()
                    yaml.default_flow_style = False
                    yaml.width = 4096
                    yaml.dump(document, stream)
                else:
                    json.dump(document, stream, indent=1)
                    stream.write('\n')
        except OSError as error:
            # The metadata.yaml of the last flush stays, true to what the storage holds.
            temporary.unlink(missing_ok=True)
            raise OSError(error.errno, error.strerror, str(self.path / 'metadata.yaml')) \
                from None
        os.replace(temporary, self.path / 'metadata.yaml')
        self._published_count = count
