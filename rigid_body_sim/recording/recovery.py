"""
Turn a bag left by a killed writer into a complete bag.

A recorder killed with SIGKILL (or a machine that lost power) leaves its bag as it was at
the last flush: an MCAP file ending in a provisional footer without summary, or cut in the
middle of a record if the kill came while a chunk was being written; a sqlite3 file with
its committed messages; a ``metadata.yaml`` with the counts of the last flush, or none.

What can be read from such a file (tested):

- a provisionally ended MCAP: everything, by rosbags (``Reader``) and by ``mcap``
  (``make_reader``), both scanning it linearly;
- an MCAP cut anywhere: rosbags refuses it (no footer: "File end magic is invalid");
  ``mcap``'s seeking reader fails the same way, its stream reader yields every record
  up to the cut and then raises.  Every message of every complete chunk is there;
- a sqlite3 bag: every committed message.  It has two database files while it is written
  (:class:`rigid_body_sim.recording.bag_writer.BagWriter`), which rosbags reads as
  metadata.yaml says; the one with the most committed messages is recovered.  A database
  left with a journal (a transaction open at the kill, or a bag of an earlier writer) is
  read as SQLite rolls it back, from a copy: the original's bytes stay as they were.

:func:`recover_bag` reads every complete record that way and writes a new, complete bag
(chunks with their index, summary, statistics, ``metadata.yaml``) in the bag's place; the
damaged original is kept beside it, byte for byte, as ``<bag>.orig``.
"""

from dataclasses import dataclass
from pathlib import Path
import shutil
import sqlite3
import struct
import tempfile

from mcap.exceptions import McapError
from mcap.records import Channel
from mcap.records import Message
from mcap.records import Schema
from mcap.stream_reader import StreamReader
from rosbags.interfaces import Qos
from rosbags.interfaces import QosDurability
from rosbags.interfaces import QosHistory
from rosbags.interfaces import QosLiveliness
from rosbags.interfaces import QosReliability
from rosbags.interfaces import QosTime
from ruamel.yaml import YAML
from ruamel.yaml import YAMLError

from .bag_writer import BagWriter
from .bag_writer import typestore

__all__ = ['RecoverySummary', 'bag_is_complete', 'recover_bag']


@dataclass
class RecoverySummary:
    """What :func:`recover_bag` found: messages per topic, and whether the end was cut."""

    bag: Path
    original: Path
    counts: dict
    truncated: bool

    def __str__(self):
        end = ('the file was cut inside a record; everything before it is kept'
               if self.truncated else 'no record was cut')
        lines = [f'{self.bag}: recovered {sum(self.counts.values())} messages on '
                 f'{len(self.counts)} topics ({end}); the original is {self.original}']
        lines += [f'  {topic}: {count}' for topic, count in self.counts.items()]
        return '\n'.join(lines)


def _parse_qos(text):
    """
    Return the rosbags Qos profiles of an ``offered_qos_profiles`` text (a YAML list).

    Policies by name, as rosbag2 Jazzy writes them (metadata version 9, what
    :mod:`.bag_writer` writes), or by number (version 8 and older); an unknown policy is
    UNKNOWN, and text that is no such list gives no profiles: recovery keeps the messages.
    """
    def policy(kind, value):
        try:
            return kind(value) if isinstance(value, int) else kind[str(value).upper()]
        except (KeyError, ValueError):
            return kind.UNKNOWN

    def duration(value):
        return QosTime(int(value['sec']), int(value['nsec']))

    try:
        items = YAML(typ='safe').load(text) if text else None
        return [Qos(policy(QosHistory, item['history']), int(item['depth']),
                    policy(QosReliability, item['reliability']),
                    policy(QosDurability, item['durability']), duration(item['deadline']),
                    duration(item['lifespan']), policy(QosLiveliness, item['liveliness']),
                    duration(item['liveliness_lease_duration']),
                    bool(item['avoid_ros_namespace_conventions']))
                for item in items or ()]
    except (YAMLError, KeyError, TypeError, ValueError):
        return []


def _storage_files(path):
    """Return the bag's storage files: its .mcap file, or its one or two .db3 files."""
    mcap, sqlite3_files = sorted(path.glob('*.mcap')), sorted(path.glob('*.db3'))
    if len(mcap) + min(len(sqlite3_files), 1) != 1 or len(sqlite3_files) > 2:
        raise ValueError(f'{path} holds {len(mcap)} .mcap and {len(sqlite3_files)} .db3 '
                         'files; a bag to recover has one .mcap or one or two .db3 files')
    return mcap or sqlite3_files


def bag_is_complete(path):
    """Return True if the bag at `path` was closed properly (rosbags reads its index)."""
    from rosbags.rosbag2 import Reader

    path = Path(path)
    files = _storage_files(path)
    storage = files[0]
    if storage.suffix == '.mcap':
        with open(storage, 'rb') as stream:
            stream.seek(0, 2)
            if stream.tell() < 37:
                return False
            stream.seek(-37, 2)
            footer = stream.read()
        # Footer record (opcode 2) with a summary start, then the magic.
        if footer[-8:] != b'\x89MCAP0\r\n' or footer[0] != 0x02:
            return False
        if int.from_bytes(footer[9:17], 'little') == 0:
            return False
    elif len(files) > 1 or not _sqlite3_closed(storage):
        return False
    try:
        with Reader(path) as reader:
            return reader.message_count == sum(c.msgcount for c in reader.connections)
    except Exception:  # noqa: B902 (any failure to read means: not complete)
        return False


def _sqlite3_closed(storage):
    # Closing writes the bag's metadata into the database's metadata table (schema 4) and
    # leaves no journal.  Read as it is (immutable): nothing in the bag is changed.
    if Path(f'{storage}-journal').exists():
        return False
    try:
        connection = sqlite3.connect(f'file:{storage}?immutable=1', uri=True)
        try:
            return connection.execute('SELECT count(*) FROM metadata').fetchone()[0] > 0
        finally:
            connection.close()
    except sqlite3.Error:
        return False


class _McapRecords:
    """
    Iterate over the schemas, channels and messages of an MCAP file, up to its end or cut.

    A stream, not a list: the memory a recovery needs is one chunk's, whatever the bag's
    size (a list of every message held more than the whole bag in memory: docs/recording.md
    has the figures, from benchmarks/recover_memory.py).  After the
    iteration, `truncated` says whether the file ended inside a record: the stream reader
    raises EndOfFile (an McapError) at a record cut short, and struct.error at a footer cut
    short.
    """

    def __init__(self, storage):
        self.storage = storage
        self.truncated = False

    def __iter__(self):
        with open(self.storage, 'rb') as stream:
            try:
                for record in StreamReader(stream, skip_magic=False).records:
                    if isinstance(record, (Schema, Channel, Message)):
                        yield record
            except (McapError, struct.error):
                self.truncated = True


def _recover_mcap(storage, writer):
    records = _McapRecords(storage)
    schemas = {}
    connections = {}
    for record in records:
        # The summary section, when there is one, repeats the schemas and channels.
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            if record.id in connections:
                continue
            schema = schemas[record.schema_id]
            definition = schema.data.decode()
            type_hash = record.metadata.get('topic_type_hash', '')
            if not type_hash:
                type_hash = typestore().hash_rihs01(schema.name)
            offers = _parse_qos(record.metadata.get('offered_qos_profiles', ''))
            connections[record.id] = writer.add_topic(
                record.topic, schema.name, offers, message_definition=definition,
                type_hash=type_hash)
        else:
            writer.write(connections[record.channel_id], record.log_time, record.data,
                         publish_time=record.publish_time, sequence=record.sequence)
    return records.truncated


def _recover_sqlite3(files, writer):
    """Copy the committed messages of the bag's database that has most into `writer`."""
    bag = files[0].parent
    with tempfile.TemporaryDirectory(prefix='.recovering-', dir=bag.parent) as directory:
        # Opening a database with a journal rolls the journal back: done in copies.
        copies = [_copy_with_journal(file, Path(directory)) for file in files]
        counts = [_message_count(copy) for copy in copies]
        if max(counts) < 0:
            raise ValueError(f'{bag}: no database in it can be read')
        try:
            _copy_sqlite3(copies[counts.index(max(counts))], writer)
        except sqlite3.Error as error:
            raise ValueError(f'{bag}: cannot read its database: {error}') from None
    return False


def _copy_with_journal(file, directory):
    """Return a copy of a database in `directory`, with its journal if it has one."""
    copy = directory / file.name
    shutil.copyfile(file, copy)
    journal = Path(f'{file}-journal')
    if journal.exists():
        shutil.copyfile(journal, Path(f'{copy}-journal'))
    return copy


def _message_count(database):
    """Return the committed messages of a database (-1 if it cannot be read)."""
    try:
        connection = sqlite3.connect(str(database))
        try:
            return connection.execute('SELECT count(*) FROM messages').fetchone()[0]
        finally:
            connection.close()
    except sqlite3.Error:
        return -1


def _copy_sqlite3(storage, writer):
    connection = sqlite3.connect(str(storage))
    try:
        topics = connection.execute(
            'SELECT id, name, type, offered_qos_profiles, type_description_hash FROM topics '
            'ORDER BY id').fetchall()
        definitions = dict(connection.execute(
            'SELECT topic_type, encoded_message_definition FROM message_definitions'))
        connections = {}
        for topic_id, name, type_name, offers, type_hash in topics:
            connections[topic_id] = writer.add_topic(
                name, type_name, _parse_qos(offers), message_definition=definitions.get(
                    type_name), type_hash=type_hash or None)
        for topic_id, timestamp, data in connection.execute(
                'SELECT topic_id, timestamp, data FROM messages ORDER BY id'):
            writer.write(connections[topic_id], timestamp, data)
    finally:
        connection.close()
    return False


def recover_bag(path, force=False):
    """
    Rewrite the bag at `path` into a complete bag; return a :class:`RecoverySummary`.

    The bag directory is moved to ``<path>.orig`` and a new bag with every readable
    message (same topics, types, QoS, times, sequence numbers and custom data) is written
    at `path`, in the same storage format.  If that fails, the original is moved back.

    Raises
    ------
    ValueError
        If `path` is no bag directory, ``<path>.orig`` exists, or the bag is complete
        already (unless `force`).

    """
    path = Path(path)
    if not path.is_dir():
        raise ValueError(f'{path} is not a bag directory')
    files = _storage_files(path)
    if not force and bag_is_complete(path):
        raise ValueError(f'{path} is a complete bag already; nothing to recover')
    original = path.with_name(path.name + '.orig')
    if original.exists():
        raise ValueError(f'{original} exists already; move it away first')
    custom_data = _custom_data(path)
    path.rename(original)
    files = [original / file.name for file in files]
    try:
        kind = 'mcap' if files[0].suffix == '.mcap' else 'sqlite3'
        with BagWriter(path, kind) as writer:
            for key, value in custom_data.items():
                writer.set_custom_data(key, value)
            if kind == 'mcap':
                truncated = _recover_mcap(files[0], writer)
            else:
                truncated = _recover_sqlite3(files, writer)
            counts = dict(writer.message_counts)
    except BaseException:
        shutil.rmtree(path, ignore_errors=True)
        original.rename(path)
        raise
    return RecoverySummary(path, original, counts, truncated)


def _custom_data(path):
    """Return the custom data of the bag's metadata.yaml, if it has a readable one."""
    try:
        document = YAML(typ='safe').load((path / 'metadata.yaml').read_text())
        return dict(document['rosbag2_bagfile_information'].get('custom_data') or {})
    except Exception:  # noqa: B902 (missing or damaged: there is nothing to keep)
        return {}
