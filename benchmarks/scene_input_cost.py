"""
Time and peak memory of loading hostile scene files: what a file of any size or shape costs.

Each case writes one scene file and loads it with ``load_scene`` in a child process, which
reports the wall time of the load, its peak resident set size and how it ended (loaded, the
first 100 characters of the refusal, or the exception's type).  ``--before DIR`` loads the
same files with the ``rigid_body_sim`` package found in DIR as well (e.g. a checkout of main
extracted with ``git archive main rigid_body_sim config | tar -x -C /tmp/before``), so that
the two columns compare the same files on the same machine.

Usage:
  .venv/bin/python benchmarks/scene_input_cost.py
  .venv/bin/python benchmarks/scene_input_cost.py --before /tmp/before
"""

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile

HEAD = 'name: t\ndescription: '
BODY = '\nbody: {mass: 1, shape: sphere, radius: 1}\n'
CASES = {
    'string of 16 MB': lambda: HEAD + '"' + 'a' * 16_000_000 + '"' + BODY,
    'string of 256 KB': lambda: HEAD + '"' + 'a' * 262_000 + '"' + BODY,
    'list of 1M values': lambda: HEAD + 'd' + BODY + 'draw: {size: [' + '0, ' * 1_000_000
    + '0]}\n',
    'list of 87k values (256 KB)': lambda: HEAD + 'd' + BODY + 'draw: {size: ['
    + '0, ' * 87_000 + '0]}\n',
    '3000 levels of nesting': lambda: HEAD + 'd\nbody: ' + '[' * 3000 + ']' * 3000 + '\n',
    'integer of 400 digits': lambda: HEAD + 'd' + BODY.replace('mass: 1', 'mass: ' + '9' * 400),
}

CHILD = """
import json, resource, sys, time
from rigid_body_sim.scenes import load_scene
started = time.perf_counter()
try:
    load_scene(sys.argv[1])
    outcome = 'loaded'
except ValueError as error:
    outcome = str(error).split(': ', 1)[1][:100]
except Exception as error:
    outcome = type(error).__name__
print(json.dumps({'seconds': time.perf_counter() - started, 'outcome': outcome,
                  'peak_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def load(path, package_dir):
    """Load the scene at `path` in a child process; return its report."""
    environment = dict(os.environ)
    if package_dir is not None:
        environment['PYTHONPATH'] = str(package_dir)
    result = subprocess.run([sys.executable, '-c', CHILD, str(path)], capture_output=True,
                            text=True, env=environment, cwd=tempfile.gettempdir(), check=True)
    return json.loads(result.stdout)


def main():
    """Write each case, load it (and with --before), print a table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--before', type=Path, help='a directory holding rigid_body_sim')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as directory:
        for name, make in CASES.items():
            path = Path(directory) / 'scene.yaml'
            path.write_text(make())
            size = path.stat().st_size
            columns = [('now', None)] + ([('before', args.before)] if args.before else [])
            for label, package_dir in columns:
                report = load(path, package_dir)
                print(f'{name:28} {size / 1e6:7.2f} MB  {label:6}  {report["seconds"]:6.2f} s  '
                      f'peak {report["peak_mb"]:5.0f} MB  {report["outcome"]}', flush=True)


if __name__ == '__main__':
    main()
