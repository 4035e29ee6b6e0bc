#!/usr/bin/env python3
"""
rk4 before (git b9ece38, world-frame formulation) and now (body-frame Euler equations).

For t_handle and tennis_racket at dt 0.01 and 0.001 s, prints the largest orientation error
over 30 s (samples every 1 s) against the committed extended-precision reference of the
tolerance sweep, for the old rk4, the current rk4 and MuJoCo's RK4 at the same step.  The
old module runs from a temporary git worktree of b9ece38 (removed afterwards).

Usage: ``.venv/bin/python benchmarks/rk4_before_after.py``
"""

import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile

ROOT = Path(__file__).resolve().parent.parent
BEFORE = 'b9ece38'
SCENES = ('t_handle', 'tennis_racket')
STEPS = (0.01, 0.001)
SPAN = 30


def rotations_of_checkout(checkout, scene, dt):
    """Return the rk4 rotations (1 s apart) of `scene` at `dt` run with the given checkout."""
    output = subprocess.run(
        [sys.executable, __file__, '--child', scene, repr(dt)], cwd=checkout, check=True,
        env=dict(os.environ, PYTHONPATH=str(checkout)), capture_output=True, text=True).stdout
    return json.loads(output)


def child(scene_name, dt):
    """Print the rk4 rotations of a scene every 1 s over SPAN s as JSON (one checkout)."""
    import inspect

    import numpy as np
    from rigid_body_sim.scenes import load_scene

    scene = load_scene(scene_name)
    keywords = {'integrator': 'rk4'}
    if 'tolerance' in inspect.signature(scene.simulator).parameters:
        keywords['tolerance'] = 0.0  # fixed steps (error control came after b9ece38)
    simulator = scene.simulator(**keywords)
    rotations = []
    for _ in range(SPAN):
        simulator.run(1.0, dt)
        rotations.append(np.asarray(simulator.state.rotation).tolist())
    print(json.dumps(rotations))


def main():
    """Print the table; return 0."""
    import numpy as np
    sys.path.insert(0, str(ROOT))
    from rigid_body_sim.work_precision.peer_mujoco import MujocoPeer
    from rigid_body_sim.work_precision.reference import rotation_angle
    from rigid_body_sim.work_precision.tolerance_sweep import case_reference
    from rigid_body_sim.work_precision.tolerance_sweep import scene_cases
    from rigid_body_sim.scenes import load_scene

    print('| scene | dt (s) | rk4 before | rk4 now | MuJoCo RK4 |')
    print('|---|---|---|---|---|')
    with tempfile.TemporaryDirectory() as directory:
        before = Path(directory) / 'before'
        subprocess.run(['git', 'worktree', 'add', '--detach', str(before), BEFORE], cwd=ROOT,
                       check=True, capture_output=True)
        try:
            for name in SCENES:
                case = scene_cases([name], float(SPAN))[0]
                rotations, _, _ = case_reference(case)
                per_second = int(round(1.0 / case.tick))
                reference = [rotations[k * per_second] for k in range(1, SPAN + 1)]
                scene = load_scene(name)
                for dt in STEPS:
                    peer = MujocoPeer(scene.body, scene.state, 'mujoco_rk4', dt)
                    mujoco = []
                    for _ in range(SPAN):
                        peer.step(int(round(1.0 / dt)))
                        mujoco.append(np.array(peer.rotation))
                    errors = [max(rotation_angle(np.array(a), b) for a, b in zip(run, reference))
                              for run in (rotations_of_checkout(before, name, dt),
                                          rotations_of_checkout(ROOT, name, dt), mujoco)]
                    print(f'| {name} | {dt:g} | ' + ' | '.join(f'{e:.2e}' for e in errors)
                          + ' |', flush=True)
        finally:
            subprocess.run(['git', 'worktree', 'remove', '--force', str(before)], cwd=ROOT,
                           check=False, capture_output=True)
    return 0


if __name__ == '__main__':
    if sys.argv[1:2] == ['--child']:
        child(sys.argv[2], float(sys.argv[3]))
        sys.exit(0)
    import argparse
    argparse.ArgumentParser(description=__doc__.strip().splitlines()[0],
                            epilog='No options: runs the old rk4 from a temporary git worktree '
                                   f'of {BEFORE} beside the current one.').parse_args()
    sys.exit(main())
