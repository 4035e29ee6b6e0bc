#!/usr/bin/env python3
"""
Recompute the committed extended-precision references, the benchmark's package data.

Two sets, each a JSON file in rigid_body_sim/work_precision/data/ that the benchmark reads
(``extended_reference.committed_references``):

- bodies, reference_values.json: every benchmark body (work_precision/bodies.py) after each N
  steps of dt that the full and the quick sweep of ``rigid-body-sim bench`` score
  (work_precision/measure.py), quaternions in all 42 digits;
- scenes, scene_reference_values.json: every torque-free built-in scene every 0.5 s over
  60 s at its tick (the tolerance sweep, work_precision/tolerance_sweep.py), quaternions rounded
  to 24 significant digits (they resolve 1e-24 rad, far below any double).

Each value is the Taylor solve in decimal arithmetic of work_precision/extended_reference.py
(42 digits, checked against a 34-digit solve: their angle is the stored uncertainty), from
the exact doubles of the body and its initial state, at exactly N x dt s.  A problem is
keyed by those doubles, so a changed body or scene finds no committed value (the benchmark
then solves it at run time and caches it): regenerate its set and commit the files.

Time: pure-Python decimal arithmetic on one core; each problem's line says the CPU seconds
it took, so a run with ``--only`` one problem shows what the rest will take.  ``--only``
takes the named ones and keeps the rest of the file.
"""

import argparse
import decimal
from decimal import Decimal
import json
import os
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rigid_body_sim.work_precision.bodies import benchmark_cases  # noqa: E402
from rigid_body_sim.work_precision.bodies import CASE_NAMES  # noqa: E402
from rigid_body_sim.work_precision.extended_reference import exact_time  # noqa: E402
from rigid_body_sim.work_precision.extended_reference import extended_reference  # noqa: E402
from rigid_body_sim.work_precision.extended_reference import key_string  # noqa: E402
from rigid_body_sim.work_precision.extended_reference import problem_fingerprint  # noqa: E402
from rigid_body_sim.work_precision.extended_reference import REFERENCE_SETS  # noqa: E402
from rigid_body_sim.work_precision.measure import FULL  # noqa: E402
from rigid_body_sim.work_precision.measure import QUICK  # noqa: E402
from rigid_body_sim.work_precision.measure import reference_keys  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import case_reference_keys  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import is_torque_free  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import scene_cases  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import SWEEP_SPAN  # noqa: E402

DATA_DIRECTORY = Path(__file__).resolve().parent.parent / 'rigid_body_sim/work_precision/data'
ABOUT = {
    'bodies': 'Extended-precision reference orientations of the benchmark bodies at every '
              '(N, dt) of the full and the quick sweep.',
    'scenes': 'Extended-precision references of the torque-free built-in scenes, every 0.5 s '
              "over 60 s at each scene's tick; quaternions to 24 significant digits.",
}
# Significant digits kept of each quaternion component (None: all 42).
DIGITS = {'bodies': None, 'scenes': 24}
FORMAT = ('problems: keyed by the exact doubles of the inertia tensor (body frame), the '
          'quaternion (x, y, z, w) and the world angular momentum, as hex; values: keyed by '
          "'N x dt', the unit quaternion (x, y, z, w), body to world, at exactly N x dt s as "
          'decimal strings, then the angle (rad) between the two solves; drift: the largest '
          'relative drift of |M| and 2T over the solves.')


def body_problems():
    """Yield (name, body, state, keys) of every benchmark body: the (N, dt) both sweeps need."""
    for case in benchmark_cases(CASE_NAMES):
        keys = set()
        for config in (FULL, QUICK):
            if case.name in config.cases:
                keys |= set(reference_keys(config))
        yield case.name, case.body, case.state, sorted(keys)


def scene_problems():
    """Yield (name, body, state, keys) of every torque-free built-in scene: its samples."""
    for case in scene_cases(span=SWEEP_SPAN):
        if is_torque_free(case):
            yield case.name, case.scene.body, case.scene.state, case_reference_keys(case)


PROBLEMS = {'bodies': body_problems, 'scenes': scene_problems}


def _significant(text, digits):
    """Return the decimal string `text` rounded to `digits` significant digits."""
    with decimal.localcontext() as context:
        context.prec = digits
        return str(+Decimal(text))


def solve(name, body, state, keys, digits=None):
    """Return the entry of one problem: its extended solve at every (N, dt)."""
    times = {key: exact_time(*key) for key in keys}
    values, drift = extended_reference(body.inertia, state.quaternion, state.angular_momentum,
                                       times.values())
    rounded = {}
    for key in sorted(keys, key=lambda key: (key[1], key[0])):
        quaternion, uncertainty = values[times[key]]
        if digits is not None:
            quaternion = [_significant(component, digits) for component in quaternion]
        rounded[key_string(*key)] = [*quaternion, uncertainty]
    return {'name': name, 'drift': drift, 'values': rounded}


def json_text(value, indent=''):
    """Return JSON of `value`: an object a member per line, an array on one line."""
    if not isinstance(value, dict):
        return json.dumps(value, allow_nan=False)
    inner = indent + ' '
    members = ',\n'.join(f'{inner}{json.dumps(key)}: {json_text(item, inner)}'
                         for key, item in value.items())
    return '{\n' + members + '\n' + indent + '}'


def write_set(path, which, problems):
    """Write the reference set `which` ({fingerprint: entry}) to `path`, replacing it whole."""
    content = {'about': ABOUT[which],
               'generated_by': 'benchmarks/regenerate_references.py --set ' + which,
               'format': FORMAT, 'problems': problems}
    temporary = path.with_name(f'{path.name}.{os.getpid()}.tmp')
    temporary.write_text(json_text(content) + '\n', encoding='utf-8')
    os.replace(temporary, path)


def regenerate(which, names, directory):
    """Recompute the set `which` (only `names` if given, keeping the file's others); write it."""
    path = directory / REFERENCE_SETS[which]
    problems = {}
    if names is not None and path.exists():
        try:
            problems = {fingerprint: entry for fingerprint, entry in
                        json.loads(path.read_text(encoding='utf-8'))['problems'].items()
                        if entry['name'] not in names}
        except (ValueError, KeyError, TypeError) as error:
            sys.exit(f'{path} is not a reference set ({error!r}): regenerate it whole, '
                     'without --only')
    for name, body, state, keys in PROBLEMS[which]():
        if names is not None and name not in names:
            continue
        fingerprint = problem_fingerprint(body, state)
        if fingerprint in problems:  # another name for the same problem (scenes may repeat)
            print(f'{which}: {name} is the problem of {problems[fingerprint]["name"]}',
                  file=sys.stderr)
            continue
        started = time.process_time()
        problems[fingerprint] = solve(name, body, state, keys, DIGITS[which])
        print(f'{which}: {name}, {len(keys)} times, {time.process_time() - started:.1f} CPU s',
              file=sys.stderr, flush=True)
    write_set(path, which, problems)
    print(f'wrote {path}', file=sys.stderr)


def main(argv=None):
    """Parse the command line, recompute the chosen sets and write them; return 0."""
    known = {which: [problem[0] for problem in problems()]
             for which, problems in PROBLEMS.items()}
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--set', choices=('bodies', 'scenes', 'all'), default='all',
                        help='which reference set to recompute (default: all)')
    parser.add_argument('--only', nargs='+', metavar='NAME',
                        help='recompute only these problems of the set, keep the others; '
                             + '; '.join(f'{which}: {", ".join(names)}'
                                         for which, names in known.items()))
    parser.add_argument('--output-dir', type=Path, default=DATA_DIRECTORY, metavar='DIR',
                        help='where to write the JSON files (default: the package data, '
                             'rigid_body_sim/work_precision/data)')
    args = parser.parse_args(argv)
    sets = list(PROBLEMS) if args.set == 'all' else [args.set]
    if args.only is not None:
        unknown = set(args.only).difference(*(known[which] for which in sets))
        if unknown:
            parser.error(f'--only: no {" or ".join(sets)} named {", ".join(sorted(unknown))}; '
                         + '; '.join(f'{which}: {", ".join(known[which])}' for which in sets))
        sets = [which for which in sets if set(known[which]) & set(args.only)]
    if not args.output_dir.is_dir():
        parser.error(f'--output-dir: {args.output_dir} is not a directory')
    for which in sets:
        regenerate(which, args.only and set(args.only), args.output_dir)
    return 0


if __name__ == '__main__':
    sys.exit(main())
