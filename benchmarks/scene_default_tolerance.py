#!/usr/bin/env python3
"""
Each built-in scene at its default tolerance: substeps, error over 60 s, CPU per tick.

For every built-in scene, error-controlled ``buss`` at the scene's own tolerance and rate
runs 60 s (the tolerance sweep's case and reference: work_precision/tolerance_sweep.py, the
extended-precision solve for torque-free scenes, a converged rk4 run otherwise), beside
fixed-step ``buss`` at one substep per tick.  Printed as a markdown table: tolerance,
substeps (least-most), steps per tick, the largest orientation error over 60 s (rad),
the CPU per tick (us, ``time.process_time``, median of 3) and its ratio to the one-substep
run measured in the same process.

Usage: ``.venv/bin/python benchmarks/scene_default_tolerance.py [--scenes NAME ...]``
"""

import argparse
from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rigid_body_sim.work_precision.tolerance_sweep import case_reference  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import measure_case_run  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import scene_cases  # noqa: E402
from rigid_body_sim.work_precision.tolerance_sweep import SWEEP_SPAN  # noqa: E402


def main(argv=None):
    """Print the table; return 0."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--scenes', nargs='+', default=None, help='default: every built-in')
    args = parser.parse_args(argv)
    print('| scene | rate (Hz) | tolerance (rad/s) | substeps | steps/tick | error over 60 s '
          '(rad) | CPU per tick (us) | CPU vs one fixed substep | one fixed substep: error |')
    print('|---|---|---|---|---|---|---|---|---|')
    for case in scene_cases(args.scenes, span=SWEEP_SPAN):
        reference, _, _ = case_reference(case)
        tolerance = case.scene.tolerance
        controlled = measure_case_run(case, reference, 'buss', tolerance)
        fixed = measure_case_run(case, reference, 'buss', None, 1)
        print(f'| {case.name} | {1.0 / case.tick:g} | {tolerance:g} | '
              f'{controlled["substeps_min"]}-{controlled["substeps_max"]} | '
              f'{controlled["steps_per_tick"]:.1f} | {controlled["error"]:.1e} | '
              f'{controlled["us_per_tick"]:.1f} | '
              f'{controlled["cpu_per_second"] / fixed["cpu_per_second"]:.1f}x | '
              f'{fixed["error"]:.1e} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
