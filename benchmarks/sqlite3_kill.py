"""
Kill -9 ``simulate --storage sqlite3`` at spread-out moments: does the bag read as it says.

Trial k of N kills the run 0.1 + 0.9 k / N s after its first flush with messages (the
default flush period is 1 s, so the kills land anywhere in a flush period, most of them
while SQLite is writing a transaction that outgrew its page cache), then opens the bag
with rosbags as it was left and prints what it reads beside what metadata.yaml counts.
``--before DIR`` runs the ``rigid_body_sim`` package found in DIR instead (e.g. main
extracted with ``git archive main rigid_body_sim config | tar -x -C /tmp/before``).

Usage:
  .venv/bin/python benchmarks/sqlite3_kill.py --trials 8
  .venv/bin/python benchmarks/sqlite3_kill.py --trials 8 --before /tmp/before
"""

import argparse
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from rosbags.rosbag2 import Reader
import yaml


def counted(bag):
    """Return the message count of the bag's metadata.yaml (0: none yet, or mid-write)."""
    try:
        text = (bag / 'metadata.yaml').read_text()
        return int(yaml.safe_load(text)['rosbag2_bagfile_information']['message_count'])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError):
        return 0


def main():
    """Run the trials and print one line each, then the tally."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--trials', type=int, default=8)
    parser.add_argument('--before', type=Path, help='a directory holding rigid_body_sim')
    args = parser.parse_args()
    environment = dict(os.environ)
    if args.before is not None:
        environment['PYTHONPATH'] = str(args.before)
    exact = 0
    with tempfile.TemporaryDirectory() as directory:
        for trial in range(args.trials):
            bag = Path(directory) / f'bag{trial}'
            process = subprocess.Popen(
                [sys.executable, '-m', 'rigid_body_sim.cli', 'simulate', '--scene', 't_handle',
                 '--duration', '100000', '--rate', '1000', '--storage', 'sqlite3', '--quiet',
                 '--bag', str(bag)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                env=environment, cwd=directory)
            while not counted(bag):
                time.sleep(0.001)  # poll for the first flush
            time.sleep(0.1 + 0.9 * trial / args.trials)
            process.kill()
            process.wait()
            try:
                with Reader(bag) as reader:
                    read = sum(1 for _ in reader.messages())
            except Exception as error:  # noqa: B902 (any failure to read is the finding)
                read = f'{type(error).__name__}: {error}'[:80]
            exact += read == counted(bag)
            print(f'trial {trial}: metadata.yaml counts {counted(bag)}, rosbags reads {read}',
                  flush=True)
    print(f'{exact} of {args.trials} bags read exactly as their metadata.yaml counts')


if __name__ == '__main__':
    main()
