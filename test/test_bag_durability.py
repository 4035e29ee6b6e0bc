"""
A bag left by a killed writer or a full disk reads as its metadata.yaml says.

sqlite3: killed (SIGKILL) at any moment after its first flush, the bag opens in rosbags
(which reads the database with immutable=1, ignoring any journal) and yields exactly the
messages metadata.yaml counts.  A full disk is one line naming the file, and the bag left
reads as its metadata says, MCAP and sqlite3 alike.  ``record --recover`` leaves the original
bytes as they were.
"""

import hashlib
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time

from node_harness import PACKAGE_ROOT
import pytest
from rigid_body_sim.cli import main as cli_main
from rigid_body_sim.recording.bag_writer import BagWriter
from rigid_body_sim.recording.recovery import recover_bag
from rosbags.rosbag2 import Reader
import yaml

TOPIC_TYPE = 'std_msgs/msg/UInt8MultiArray'


def _metadata(bag):
    """Return metadata.yaml's information (None if there is none yet)."""
    path = Path(bag) / 'metadata.yaml'
    if not path.exists():
        return None
    return yaml.safe_load(path.read_text())['rosbag2_bagfile_information']


def _read_as_left(bag, copy):
    """
    Copy the bag as it is now (what a SIGKILL now would leave) and read the copy.

    Return (metadata counts per topic, [(topic, log time, data)] rosbags reads).
    """
    shutil.copytree(bag, copy)
    information = _metadata(copy)
    counted = {entry['topic_metadata']['name']: entry['message_count']
               for entry in information['topics_with_message_count']}
    with Reader(copy) as reader:
        read = [(connection.topic, time, bytes(data))
                for connection, time, data in reader.messages()]
    shutil.rmtree(copy)
    return counted, read


def _counts(messages, topics):
    """Return topic -> number of `messages` ((topic, log time, data)), every one of `topics`."""
    counts = dict.fromkeys(topics, 0)
    for topic, _, _ in messages:
        counts[topic] = counts.get(topic, 0) + 1
    return counts


def test_a_sqlite3_bag_reads_as_its_metadata_says_at_every_write_after_its_first_flush(
        tmp_path):
    """
    Snapshots of the bag between writes are what SIGKILL would leave at those moments.

    4 MB between flushes: more than SQLite's page cache (2 MB), which then writes pages of
    the open transaction into the database file; rosbags reads that file as it is.  Before,
    such a snapshot read as 'database disk image is malformed' or with messages missing.
    """
    bag = tmp_path / 'bag'
    written = []
    with BagWriter(bag, 'sqlite3') as writer:
        connections = [writer.add_topic(f'/topic{j}', TOPIC_TYPE) for j in range(2)]
        snapshot = 0
        for flush in range(4):
            for index in range(20000):
                connection = connections[index % 2]
                message = (connection.topic, 1000 * len(written), os.urandom(200))
                writer.write(connection, message[1], message[2])
                written.append(message)
                if flush > 0 and index % 2500 == 0:
                    snapshot += 1
                    counted, read = _read_as_left(bag, tmp_path / f'snapshot{snapshot}')
                    assert _counts(read, counted) == counted, snapshot
                    assert read == written[:len(read)], snapshot
            writer.flush()
            counted, read = _read_as_left(bag, tmp_path / f'flushed{flush}')
            assert read == written
    with Reader(bag) as reader:
        assert [(c.topic, t, bytes(d)) for c, t, d in reader.messages()] == written
    assert sorted(path.name for path in bag.iterdir()) == ['bag.db3', 'metadata.yaml']


def _bag_files(bag):
    return {path.name: hashlib.sha256(path.read_bytes()).hexdigest()
            for path in sorted(Path(bag).iterdir())}


def _database_sizes(bag):
    return {path.name: path.stat().st_size for path in Path(bag).glob('*.db3')}


@pytest.mark.parametrize('flushes, moment', [(1, 'flush'), (1, 'growth'), (2, 'growth'),
                                             (3, 'flush'), (3, 'growth')])
def test_simulate_sqlite3_killed_by_sigkill_opens_in_rosbags_with_the_counts_of_its_metadata(
        tmp_path, flushes, moment):
    """
    Kill -9 a sqlite3 simulate: rosbags reads the bag as it is, with no recovery.

    Killed right after a flush, or once a database file has grown since (SQLite writing
    pages of the open transaction: a second of simulate at 1 kHz is more than its 2 MB page
    cache).  Before: such a bag read as 'database disk image is malformed' or with more or
    fewer messages than counted.  Then ``--recover`` rewrites it into a closed bag and
    leaves the original's bytes as they were (it rolled the journal back inside DIR.orig).
    """
    bag = tmp_path / 'killed'
    process = subprocess.Popen(
        [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 't_handle',
         '--duration', '100000', '--rate', '1000', '--bag', str(bag), '--quiet',
         '--storage', 'sqlite3'],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=PACKAGE_ROOT)
    try:
        deadline = time.monotonic() + 300.0
        seen, last, sizes = 0, None, None

        def wait(event):
            while not event():
                assert process.poll() is None, process.communicate()
                assert time.monotonic() < deadline, f'{seen} flushes seen'
                time.sleep(0.002)  # waits-for: poll interval of the loop waiting for the event

        def flushed():
            nonlocal seen, last, sizes
            information = _metadata(bag)
            count = None if information is None else information['message_count']
            if count and count != last:  # the bag's first flush, at its creation, counts 0
                seen, last, sizes = seen + 1, count, _database_sizes(bag)
            return seen >= flushes

        wait(flushed)
        if moment == 'growth':
            wait(lambda: any(size > sizes.get(name, 0)
                             for name, size in _database_sizes(bag).items()))
    finally:
        process.send_signal(signal.SIGKILL)
        process.communicate()
    counted, read = _read_as_left(bag, tmp_path / 'copy')
    assert sum(counted.values()) >= last > 0
    assert _counts(read, counted) == counted
    original = _bag_files(bag)
    summary = recover_bag(bag)
    assert _bag_files(summary.original) == original
    assert sum(summary.counts.values()) >= sum(counted.values())


def _private_tmpfs_command(directory, size, command):
    """Return argv running `command` with a `size` tmpfs at `directory`, seen by it alone."""
    script = (f'mount -t tmpfs -o size={size} tmpfs {directory} && cd {PACKAGE_ROOT} && '
              f'{command}')
    return ['unshare', '--mount', '--propagation', 'private', 'sh', '-c', script]


def _can_mount_a_private_tmpfs(tmp_path):
    directory = tmp_path / 'probe'
    directory.mkdir()
    try:
        result = subprocess.run(_private_tmpfs_command(directory, '64k', 'true'),
                                capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return result.returncode == 0


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_a_full_disk_is_one_line_naming_the_file_and_the_bag_reads_as_its_metadata_says(
        tmp_path, storage):
    """
    Simulate onto a 2 MB tmpfs (mounted in a private mount namespace) until it is full.

    Before: sqlite3 was a sqlite3.OperationalError traceback that left a metadata.yaml
    counting 12,002 messages over a database of 0 rows; MCAP's error named no file.
    """
    if not _can_mount_a_private_tmpfs(tmp_path):
        pytest.skip('cannot mount a tmpfs in a private mount namespace here (unshare, mount)')
    disk = tmp_path / 'disk'
    disk.mkdir()
    kept = tmp_path / 'kept'
    simulate = (f'{sys.executable} -m rigid_body_sim.cli simulate --scene t_handle '
                f'--duration 1000 --rate 1000 --storage {storage} --quiet '
                f'--flush-period 0.01 --bag {disk}/full')
    # The bag is copied out of the tmpfs, which goes with the namespace.
    command = f'{simulate}; status=$?; cp -a {disk}/full {kept}; exit $status'
    result = subprocess.run(_private_tmpfs_command(disk, '2m', command), capture_output=True,
                            text=True, timeout=600)
    assert result.returncode == 1, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    suffix = '.db3' if storage == 'sqlite3' else '.mcap'
    assert lines[0].startswith(f'rigid-body-sim simulate: error: {disk}/full/'), lines[0]
    assert f'{suffix}: No space left on device; the bag keeps the ' in lines[0], lines[0]
    counted, read = _read_as_left(kept, tmp_path / 'copy')
    assert lines[0].endswith(f' keeps the {sum(counted.values())} messages of its last flush, '
                             'as its metadata.yaml says'), lines[0]
    assert sum(counted.values()) > 0
    assert _counts(read, counted) == counted


@pytest.mark.parametrize('storage, reason', [('sqlite3', 'sqlite3: disk I/O error'),
                                             ('mcap', 'File too large')])
def test_a_write_refused_by_a_file_size_limit_is_one_line_and_the_bag_reads_as_it_says(
        tmp_path, storage, reason):
    """
    The same as a full disk where no tmpfs can be mounted: RLIMIT_FSIZE makes writes fail.

    The writes beyond 2 MB fail (EFBIG) at the file layer, as on a full disk (ENOSPC).
    """
    bag = tmp_path / 'limited'
    child = (
        'import resource, signal, sys\n'
        'signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n'
        'resource.setrlimit(resource.RLIMIT_FSIZE, (2000000, 2000000))\n'
        'from rigid_body_sim.cli import main\n'
        'sys.exit(main(sys.argv[1:]))\n')
    result = subprocess.run(
        [sys.executable, '-c', child, 'simulate', '--scene', 't_handle', '--duration', '1000',
         '--rate', '1000', '--storage', storage, '--quiet', '--flush-period', '0.01',
         '--bag', str(bag)], capture_output=True, text=True, timeout=600, cwd=PACKAGE_ROOT)
    assert result.returncode == 1, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith(f'rigid-body-sim simulate: error: {bag}/limited'), lines[0]
    assert f': {reason}; the bag keeps the ' in lines[0], lines[0]
    counted, read = _read_as_left(bag, tmp_path / 'copy')
    assert sum(counted.values()) > 0
    assert _counts(read, counted) == counted


def test_recover_keeps_the_original_bytes_of_a_sqlite3_bag_with_a_leftover_journal(tmp_path):
    """A hot journal stays in DIR.orig as it was, and the recovered bag has what it protects."""
    source = tmp_path / 'source'
    with BagWriter(source, 'sqlite3') as writer:
        connection = writer.add_topic('/topic', TOPIC_TYPE)
        for index in range(100):
            writer.write(connection, index, b'committed %d' % index)
    # A leftover journal (the process killed with a transaction open): made by a writer in
    # a child process killed after SQLite spilled pages of its transaction into the file.
    bag = tmp_path / 'bag'
    shutil.copytree(source, bag)
    database = next(bag.glob('*.db3'))
    child = (
        'import os, sqlite3, sys\n'
        'connection = sqlite3.connect(sys.argv[1])\n'
        'connection.execute("PRAGMA cache_size = 10")\n'
        'connection.executemany("INSERT INTO messages (topic_id, timestamp, data) '
        'VALUES (1, 1000, ?)", [(os.urandom(4000),) for _ in range(500)])\n'
        'os.kill(os.getpid(), 9)\n')
    subprocess.run([sys.executable, '-c', child, str(database)], check=False, timeout=120)
    assert Path(f'{database}-journal').exists()
    original = _bag_files(bag)
    assert cli_main(['record', '--recover', str(bag)]) == 0
    assert _bag_files(tmp_path / 'bag.orig') == original
    with Reader(bag) as reader:
        assert [bytes(d) for _, _, d in reader.messages()] == [
            b'committed %d' % index for index in range(100)]
