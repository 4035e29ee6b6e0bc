"""
Bags are written through the public APIs of rosbags and mcap only, and read back by both.

Every module of rigid_body_sim/recording/ and rigid_body_sim/tools/ may import from rosbags
and mcap only names their documented modules export (``__all__``, or defined in a module
the library documents), never a private or unexported module such as
``rosbags.rosbag2.storage_mcap`` or ``rosbags.rosbag2.errors``, nor read an attribute of a
rosbags Reader its class does not define publicly (``reader.storage``); no class of
bag_writer.py and recovery.py subclasses a library class: an upgrade of either library then
breaks recording only where its documented API changes, and these tests say where.

The bags read back byte for byte with rosbags' public Reader and with the mcap library's
readers (independent decoders), closed and as a flush leaves them (what SIGKILL leaves);
every record of an MCAP file, the Message and MessageIndex records packed by bag_writer
too, is byte for byte what mcap's record classes write for it.
"""

import ast
import contextlib
import errno
import importlib
from io import BytesIO
import os
from pathlib import Path
import shutil
import sqlite3
import zlib

from mcap.data_stream import RecordBuilder
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.reader import NonSeekingReader
from mcap.records import Chunk
from mcap.records import Footer
from mcap.stream_reader import StreamReader
import numpy as np
import pytest
from rigid_body_sim.recording import bag_writer
from rigid_body_sim.recording import recovery
from rigid_body_sim.recording.bag_writer import BagWriter
from rigid_body_sim.recording.bag_writer import INFINITE_DURATION
from rigid_body_sim.recording.recovery import recover_bag
from rosbags.interfaces import Qos
from rosbags.interfaces import QosDurability
from rosbags.interfaces import QosHistory
from rosbags.interfaces import QosLiveliness
from rosbags.interfaces import QosReliability
from rosbags.interfaces import QosTime
from rosbags.rosbag2 import Reader
import yaml

PACKAGE = Path(__file__).resolve().parent.parent / 'rigid_body_sim'
CHECKED_FILES = sorted((PACKAGE / 'recording').glob('*.py')) + sorted(
    (PACKAGE / 'tools').glob('*.py'))
LIBRARIES = ('rosbags', 'mcap')

# The modules of rosbags and mcap their documentation presents as API, with the page.
# rosbags.interfaces has no API page of its own: it defines the types of rosbags.rosbag2's
# documented signatures (Writer.add_connection(offered_qos_profiles: Sequence[Qos]),
# Reader.connections), and rosbags' documented examples import them from it.
DOCUMENTED_MODULES = {
    'rosbags.interfaces': 'https://ternaris.gitlab.io/rosbags/examples/edit_rosbags.html',
    'rosbags.rosbag2': 'https://ternaris.gitlab.io/rosbags/api/rosbags.rosbag2.html',
    'rosbags.typesys': 'https://ternaris.gitlab.io/rosbags/api/rosbags.typesys.html',
    'mcap.data_stream': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.exceptions': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.opcode': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.reader': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.records': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.stream_reader': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.well_known': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
    'mcap.writer': 'https://mcap.dev/docs/python/mcap-apidoc/mcap',
}

TYPE = 'std_msgs/msg/UInt8MultiArray'
OFFER = Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
            INFINITE_DURATION, QosTime(3, 500), QosLiveliness.AUTOMATIC, INFINITE_DURATION,
            False)


def _library_imports(path):
    """Return [(line, module, name or None)] of the file's imports from rosbags and mcap."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.split('.')[0] in LIBRARIES:
                found += [(node.lineno, node.module, alias.name) for alias in node.names]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, alias.name, None) for alias in node.names
                      if alias.name.split('.')[0] in LIBRARIES]
    return found


def _import_problem(module_name, name):
    """Return why importing `name` from `module_name` is not public API (None if it is)."""
    if any(part.startswith('_') for part in module_name.split('.')):
        return 'a private module'
    if module_name not in DOCUMENTED_MODULES:
        return 'a module the library does not document as API (see DOCUMENTED_MODULES)'
    if name is None:
        return None
    module = importlib.import_module(module_name)
    exported = getattr(module, '__all__', None)
    if exported is not None:
        return None if name in exported else f'not in {module_name}.__all__'
    if name.startswith('_'):
        return 'a private name'
    if not hasattr(module, name):
        return f'not defined in {module_name}'
    defined_in = getattr(getattr(module, name), '__module__', module_name)
    if defined_in != module_name:
        return f'defined in {defined_in}, only imported into {module_name}'
    return None


def _file_id(path):
    return str(path.relative_to(PACKAGE))


def test_the_checked_files_are_every_module_of_recording_and_tools():
    names = {_file_id(path) for path in CHECKED_FILES}
    assert {'recording/bag_writer.py', 'recording/recovery.py', 'recording/plot.py',
            'recording/animate.py', 'recording/state_batch.py', 'tools/plot.py'} <= names
    assert all(name.startswith(('recording/', 'tools/')) for name in names)


@pytest.mark.parametrize('path', CHECKED_FILES, ids=_file_id)
def test_every_rosbags_and_mcap_import_is_a_documented_exported_name(path):
    problems = []
    for line, module, name in _library_imports(path):
        problem = _import_problem(module, name)
        if problem is not None:
            library = module.split('.')[0]
            what = f'from {module} import {name}' if name else f'import {module}'
            problems.append(f'{path.name}:{line}: {what} ({library}): {problem}')
    assert not problems, '\n'.join(problems)
    assert not [m for _, m, _ in _library_imports(path) if m.startswith('rosbags.rosbag2.')]


def test_the_import_check_catches_the_imports_bag_writer_used_to_have():
    """The check above is no tautology: the old imports fail it, naming module and cause."""
    assert 'document' in _import_problem('rosbags.rosbag2.storage_mcap', 'McapWriter')
    assert 'document' in _import_problem('rosbags.rosbag2.metadata', 'dump_qos_v9')
    assert 'private' in _import_problem('mcap._chunk_builder', 'ChunkBuilder')
    assert '__all__' in _import_problem('mcap.writer', 'ChunkBuilder')
    assert 'only imported' in _import_problem('mcap.records', 'RecordBuilder')
    assert 'document' in _import_problem('rosbags.rosbag2.errors', 'ReaderError')
    assert _import_problem('rosbags.rosbag2', 'Reader') is None
    assert _import_problem('rosbags.rosbag2', 'ReaderError') is None
    assert _import_problem('mcap.records', 'Chunk') is None


def _reader_names(tree):
    """Return the names bound to a rosbags Reader: ``with Reader(...) as name``, ``name =``."""
    names = set()
    for node in ast.walk(tree):
        pairs = []
        if isinstance(node, (ast.With, ast.AsyncWith)):
            pairs = [(item.context_expr, item.optional_vars) for item in node.items]
        elif isinstance(node, ast.Assign) and len(node.targets) == 1:
            pairs = [(node.value, node.targets[0])]
        for value, target in pairs:
            if isinstance(value, ast.Call) and isinstance(value.func, ast.Name) and \
                    value.func.id == 'Reader' and isinstance(target, ast.Name):
                names.add(target.id)
    return names


def _reader_attribute_problems(source):
    """Return the attributes read of a Reader that its class does not define publicly."""
    public = {name for name in dir(Reader) if not name.startswith('_')}
    tree = ast.parse(source)
    readers = _reader_names(tree)
    return sorted(f'{node.value.id}.{node.attr}' for node in ast.walk(tree)
                  if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                  and node.value.id in readers and node.attr not in public)


@pytest.mark.parametrize('path', CHECKED_FILES, ids=_file_id)
def test_only_public_members_of_a_rosbags_reader_are_read(path):
    """Its class's properties and methods; not the instance's ``storage`` (a plugin)."""
    assert not _reader_attribute_problems(path.read_text())


def test_the_reader_check_catches_the_custom_data_plot_used_to_read():
    old = ('with Reader(bag) as reader:\n'
           '    custom = getattr(reader.storage.metadata, "custom", None)\n')
    assert _reader_attribute_problems(old) == ['reader.storage']
    assert not _reader_attribute_problems(
        'with Reader(bag) as reader:\n    n = reader.message_count, reader.connections\n')


@pytest.mark.parametrize('module', [bag_writer, recovery], ids=lambda module: module.__name__)
def test_no_class_subclasses_a_rosbags_or_mcap_class_and_no_private_attribute_is_read(module):
    """A subclass lives on its base's private state; so does reading a `_name` of theirs."""
    for name, value in vars(module).items():
        if isinstance(value, type) and value.__module__ == module.__name__:
            bases = [base for base in value.__mro__[1:]
                     if base.__module__.split('.')[0] in LIBRARIES]
            assert not bases, f'{module.__name__}.{name} subclasses {bases}'
    tree = ast.parse(Path(module.__file__).read_text())
    library_names = {alias.asname or alias.name for node in ast.walk(tree)
                     if isinstance(node, ast.ImportFrom) and node.module
                     and node.module.split('.')[0] in LIBRARIES for alias in node.names}
    touched = [f'{node.value.id}.{node.attr}' for node in ast.walk(tree)
               if isinstance(node, ast.Attribute) and node.attr.startswith('_')
               and isinstance(node.value, ast.Name) and node.value.id in library_names]
    assert not touched


def _write_bag(bag, storage, snapshot=None):
    """
    Write a bag through every path of BagWriter; return [(topic, time, data, publish, seq)].

    Single writes with publish times and sequence numbers, batches of rows, flushes, a
    topic added after a flush, chunks filled past 1 MiB; `snapshot` gets a copy of the
    bag as the last flush left it (what a SIGKILL then would leave).
    """
    rng = np.random.default_rng(3)
    written = []
    with BagWriter(bag, storage) as writer:
        writer.set_custom_data('rigid_body_sim.test', 'public api')
        first = writer.add_topic('/first', TYPE, [OFFER])
        second = writer.add_topic('/second', TYPE, [OFFER, OFFER])
        for index in range(300):
            data = rng.bytes(int(rng.integers(0, 700)))
            log_time = 1000 * index + 10
            writer.write(first, log_time, data, publish_time=log_time - 7, sequence=index + 1)
            written.append(('/first', log_time, data, log_time - 7, index + 1))
        writer.flush(sync=False)
        rows = [rng.integers(0, 256, size=(4000, size), dtype=np.uint8) for size in (40, 300)]
        times = 400_000 + 1000 * np.arange(4000)
        writer.write_rows([first, second], rows, times)
        for i, time in enumerate(times.tolist()):
            written += [('/first', time, rows[0][i].tobytes(), time, 0),
                        ('/second', time, rows[1][i].tobytes(), time, 0)]
        writer.flush(sync=True)
        third = writer.add_topic('/third', 'std_msgs/msg/String')
        writer.write(third, 5_000_000, b'\x00\x01\x00\x00\x04\x00\x00\x00abc\x00')
        written.append(('/third', 5_000_000, b'\x00\x01\x00\x00\x04\x00\x00\x00abc\x00',
                        5_000_000, 0))
        writer.flush(sync=False)
        if snapshot is not None:
            shutil.copytree(bag, snapshot)
    return written


def _read_rosbags(bag):
    with Reader(bag) as reader:
        messages = [(connection.topic, time, bytes(data))
                    for connection, time, data in reader.messages()]
        connections = {connection.topic: connection for connection in reader.connections}
        return messages, connections, reader.message_count


def _read_mcap(file, seeking=True):
    """Return [(topic, log time, data, publish time, sequence)] read by the mcap library."""
    with open(file, 'rb') as stream:
        reader = make_reader(stream) if seeking else NonSeekingReader(stream)
        messages = reader.iter_messages(log_time_order=False)
        return [(channel.topic, message.log_time, message.data, message.publish_time,
                 message.sequence) for _, channel, message in messages]


def _expected(written, with_publish=True):
    return [entry if with_publish else entry[:3] for entry in written]


@pytest.mark.parametrize('moment', ['closed', 'flushed'])
def test_an_mcap_bag_reads_back_byte_for_byte_with_rosbags_and_with_mcap(tmp_path, moment):
    snapshot = tmp_path / 'snapshot'
    written = _write_bag(tmp_path / 'bag', 'mcap', snapshot)
    bag = tmp_path / 'bag' if moment == 'closed' else snapshot
    file = bag / 'bag.mcap'
    messages, connections, count = _read_rosbags(bag)
    assert sorted(messages) == sorted(_expected(written, False))  # rosbags: in time order
    assert [time for _, time, _ in messages] == sorted(time for _, time, _ in messages)
    assert count == len(written)
    by_mcap = _read_mcap(file)
    assert by_mcap == written  # the order written, with publish times and sequences
    assert _read_mcap(file, seeking=False) == written
    assert connections['/second'].ext.offered_qos_profiles == [OFFER, OFFER]
    assert connections['/first'].digest == bag_writer.typestore().hash_rihs01(TYPE)
    with open(file, 'rb') as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        channels = {channel.topic: channel for channel in summary.channels.values()} \
            if summary else {}
    if moment == 'closed':
        assert summary.statistics.message_count == len(written)
        assert summary.statistics.channel_message_counts == {1: 4300, 2: 4000, 3: 1}
        assert channels['/first'].metadata['topic_type_hash'] == connections['/first'].digest
        assert yaml.safe_load(channels['/second'].metadata['offered_qos_profiles'])[0][
            'durability'] == 'transient_local'
        assert len(summary.chunk_indexes) > 2  # chunks closed at 1 MiB, and by flushes
    else:
        assert summary is None  # a provisional end: no summary, read by a linear scan


def _record_bytes(record):
    builder = RecordBuilder()
    record.write(builder)
    return builder.end()


def _chunk_records(chunk):
    records = []
    reader = StreamReader(BytesIO(chunk.data), skip_magic=True).records
    with contextlib.suppress(EndOfFile):
        records.extend(reader)
    return records


@pytest.mark.parametrize('moment', ['closed', 'flushed'])
def test_every_mcap_record_is_what_the_mcap_record_classes_write_for_it(tmp_path, moment):
    """Decoded by mcap's stream reader and written again by its record classes: same bytes."""
    snapshot = tmp_path / 'snapshot'
    _write_bag(tmp_path / 'bag', 'mcap', snapshot)
    file = (tmp_path / 'bag' if moment == 'closed' else snapshot) / 'bag.mcap'
    content = file.read_bytes()
    with open(file, 'rb') as stream:
        records = list(StreamReader(stream, emit_chunks=True, validate_crcs=True).records)
    magic = b'\x89MCAP0\r\n'
    assert magic + b''.join(_record_bytes(record) for record in records) + magic == content
    kinds = set()
    for chunk in (record for record in records if isinstance(record, Chunk)):
        inner = _chunk_records(chunk)
        kinds |= {type(record).__name__ for record in inner}
        assert b''.join(_record_bytes(record) for record in inner) == chunk.data
    assert {'Message', 'Schema', 'Channel'} <= kinds
    assert 'MessageIndex' in {type(record).__name__ for record in records}
    footer = records[-1]
    assert isinstance(footer, Footer)
    if moment == 'closed':
        # The summary CRC: the summary section and the footer up to the CRC field.
        covered = content[footer.summary_start:len(content) - len(magic) - 4]
        assert footer.summary_crc == zlib.crc32(covered)
    else:
        assert (footer.summary_start, footer.summary_offset_start) == (0, 0)


@pytest.mark.parametrize('moment', ['closed', 'flushed'])
def test_a_sqlite3_bag_reads_back_byte_for_byte_with_rosbags_and_with_sqlite3(tmp_path, moment):
    snapshot = tmp_path / 'snapshot'
    written = _write_bag(tmp_path / 'bag', 'sqlite3', snapshot)
    bag = tmp_path / 'bag' if moment == 'closed' else snapshot
    messages, connections, count = _read_rosbags(bag)
    assert messages == _expected(written, False) and count == len(written)
    assert connections['/second'].ext.offered_qos_profiles == [OFFER, OFFER]
    information = yaml.safe_load((bag / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    (database,) = information['relative_file_paths']
    with contextlib.closing(sqlite3.connect(bag / database)) as connection:
        topics = dict(connection.execute('SELECT id, name FROM topics'))
        rows = [(topics[topic_id], time, data) for topic_id, time, data in connection.execute(
            'SELECT topic_id, timestamp, data FROM messages ORDER BY id')]
        schema = connection.execute('SELECT schema_version, ros_distro FROM schema').fetchall()
        metadata = connection.execute('SELECT metadata_version, metadata FROM metadata').fetchall()
        columns = {table: [row[1] for row in connection.execute(f'PRAGMA table_info({table})')]
                   for table in ('topics', 'message_definitions', 'messages')}
    assert rows == _expected(written, False)
    assert schema == [(4, 'jazzy')]  # rosbag2 Jazzy's schema version and distribution
    assert columns == {
        'topics': ['id', 'name', 'type', 'serialization_format', 'offered_qos_profiles',
                   'type_description_hash'],
        'message_definitions': ['id', 'topic_type', 'encoding', 'encoded_message_definition',
                                'type_description_hash'],
        'messages': ['id', 'topic_id', 'timestamp', 'data']}
    if moment == 'closed':
        assert sorted(os.listdir(bag)) == ['bag.db3', 'metadata.yaml']
        ((version, text),) = metadata
        stored = yaml.safe_load(text)
        assert version == 9 and stored['ros_distro'] == 'jazzy'
        assert stored['message_count'] == len(written)
        assert stored['relative_file_paths'] == ['bag.db3']
        assert stored['custom_data'] == {'rigid_body_sim.test': 'public api'}
    else:
        assert metadata == []  # written when the bag is closed


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_an_empty_bag_reads_in_both_readers(tmp_path, storage):
    with BagWriter(tmp_path / 'empty', storage) as writer:
        writer.add_topic('/nothing', TYPE, [OFFER])
    messages, connections, count = _read_rosbags(tmp_path / 'empty')
    assert (messages, count, list(connections)) == ([], 0, ['/nothing'])
    if storage == 'mcap':
        assert _read_mcap(tmp_path / 'empty' / 'empty.mcap') == []


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_recovery_keeps_messages_and_offered_qos_profiles(tmp_path, storage):
    """A bag as a flush left it, recovered: the same messages, QoS, hashes and custom data."""
    snapshot = tmp_path / 'killed'
    written = _write_bag(tmp_path / 'bag', storage, snapshot)
    summary = recover_bag(snapshot)
    assert sum(summary.counts.values()) == len(written)
    messages, connections, _ = _read_rosbags(snapshot)
    assert sorted(messages) == sorted(_expected(written, False))
    assert connections['/second'].ext.offered_qos_profiles == [OFFER, OFFER]
    assert connections['/third'].digest == bag_writer.typestore().hash_rihs01(
        'std_msgs/msg/String')
    information = yaml.safe_load((snapshot / 'metadata.yaml').read_text())[
        'rosbag2_bagfile_information']
    assert information['custom_data'] == {'rigid_body_sim.test': 'public api'}
    if storage == 'mcap':
        assert _read_mcap(snapshot / 'killed.mcap') == written


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_failed_write_is_an_oserror_naming_the_file_and_the_bag_keeps_its_last_flush(
        tmp_path, storage, monkeypatch):
    """The storage refusing a write (as a full disk does): then sync and close do nothing."""
    bag = tmp_path / 'full'
    writer = BagWriter(bag, storage)
    writer.create()
    connection = writer.add_topic('/kept', TYPE)
    for index in range(10):
        writer.write(connection, index, b'kept %d' % index)
    writer.flush(sync=False)
    writer.write(connection, 10, b'after the flush')

    def refuse(*arguments):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(writer._storage, 'write', refuse)
    with pytest.raises(OSError) as raised:
        writer.write(connection, 11, b'refused')
    assert raised.value.errno == errno.ENOSPC
    assert raised.value.filename.startswith(str(bag / 'full'))
    assert raised.value.strerror.endswith(
        'the bag keeps the 10 messages of its last flush, as its metadata.yaml says')
    writer.sync_to_disk()  # the recorder's fsync thread may still ask: nothing to do
    writer.close()
    messages, _, count = _read_rosbags(bag)
    assert messages == [('/kept', index, b'kept %d' % index) for index in range(10)]
    assert count == 10
