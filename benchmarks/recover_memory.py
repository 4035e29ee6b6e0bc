"""
Peak memory of ``rigid-body-sim record --recover`` against the size of the bag it recovers.

For each size: `simulate` writes the default scene at 1 kHz for as long as it takes to fill
that many MB, the MCAP file is cut inside its last chunks (at 97 % of its length, as a kill
during a write leaves it) and its metadata.yaml removed, then `record --recover` runs in a
child process whose peak resident set size (ru_maxrss from wait4) is reported, beside the
peak of a child that only imports the same modules.  Memory independent of the bag's size
means: the recovery's peak minus the import's is the same for every size.

Usage:
  .venv/bin/python benchmarks/recover_memory.py                # 100 MB and 1000 MB
  .venv/bin/python benchmarks/recover_memory.py --sizes 20 100 --workdir /tmp/rec

Needs free disk of about twice the largest size (the original is kept as <bag>.orig).
"""

import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time

# MB of bag per simulated second of `default` at 1 kHz, from one bag's size over its duration:
# it only sizes the runs.
MB_PER_SIMULATED_SECOND = 1.315
CUT_FRACTION = 0.97
BIN = Path(sys.executable).parent


def _run_measured(command):
    """Run `command`; return (exit code, peak RSS in MB, wall seconds, stdout)."""
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    output = process.stdout.read().decode()
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    return process.returncode, usage.ru_maxrss / 1024, time.perf_counter() - start, output


def _make_cut_bag(path, size_mb):
    duration = max(1, round(size_mb / MB_PER_SIMULATED_SECOND))
    subprocess.run([str(BIN / 'rigid-body-sim'), 'simulate', '--scene', 'default',
                    '--rate', '1000', '--duration', str(duration), '--bag', str(path),
                    '--quiet'], check=True, stdout=subprocess.DEVNULL)
    storage = next(path.glob('*.mcap'))
    with open(storage, 'r+b') as stream:
        stream.truncate(int(storage.stat().st_size * CUT_FRACTION))
    (path / 'metadata.yaml').unlink()
    return storage.stat().st_size / 1e6


def main(argv=None):
    """Measure and print the table; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--sizes', type=float, nargs='+', default=[100, 1000], metavar='MB')
    parser.add_argument('--workdir', type=Path, default=None)
    args = parser.parse_args(argv)
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix='recover_memory_'))
    workdir.mkdir(parents=True, exist_ok=True)
    _, import_rss, _, _ = _run_measured([
        sys.executable, '-c', 'import rigid_body_sim.tools.record, '
        'rigid_body_sim.recording.recovery'])
    print(f'import only: peak RSS {import_rss:.0f} MB')
    print(f'{"bag MB":>8} {"messages":>10} {"peak RSS MB":>12} {"above import":>13} '
          f'{"seconds":>8}')
    for size in args.sizes:
        bag = workdir / f'cut_{size:g}MB'
        shutil.rmtree(bag, ignore_errors=True)
        shutil.rmtree(bag.with_name(bag.name + '.orig'), ignore_errors=True)
        cut_mb = _make_cut_bag(bag, size)
        code, rss, seconds, output = _run_measured(
            [str(BIN / 'rigid-body-sim'), 'record', '--recover', str(bag)])
        if code != 0:
            print(output)
            return 1
        messages = output.split('recovered ')[1].split(' ')[0]
        print(f'{cut_mb:8.0f} {messages:>10} {rss:12.0f} {rss - import_rss:13.0f} '
              f'{seconds:8.1f}')
        shutil.rmtree(bag)
        shutil.rmtree(bag.with_name(bag.name + '.orig'))
    if args.workdir is None:
        shutil.rmtree(workdir)
    return 0


if __name__ == '__main__':
    sys.exit(main())
