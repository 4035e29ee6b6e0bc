#!/usr/bin/env python3
"""
Write the built-in scenes of many bodies that are made from a seed, or check them.

    benchmarks/many_body_scenes.py            write config/scenes/debris_field.yaml and
                                              config/scenes/constellation.yaml
    benchmarks/many_body_scenes.py --check    exit 1 if either differs from what it writes

- debris_field: 100 tumbling bodies of random shapes (box, cylinder, ellipsoid), masses,
  sizes, orientations and spins, on a 5 x 5 x 4 grid 2 m apart, from the seed below;
- constellation: 1,000 identical 3U cubesats (the scene-wide body) on 10 rings of 100,
  each slowly tumbling from a random spin, for the many-body benchmark
  (benchmarks/many_bodies.py).

The files hold every value, so a body can be edited by hand; the test suite checks that
they are what this script writes (test/test_many_body_scenes.py).
"""

import argparse
import math
from pathlib import Path
import sys

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / 'config' / 'scenes'
SEED = 29


def _numbers(values, digits=4):
    return '[' + ', '.join(f'{float(value):.{digits}g}' for value in values) + ']'


def _unit_quaternion(rng):
    quaternion = rng.normal(size=4)
    quaternion /= np.linalg.norm(quaternion)
    if quaternion[3] < 0.0:
        quaternion = -quaternion
    # Written with 9 digits and normalised again by the reader within its 1e-6.
    return quaternion


def debris_field():
    """Return the text of debris_field.yaml."""
    rng = np.random.default_rng(SEED)
    lines = [
        '# 100 pieces of tumbling debris of random shapes, masses, sizes and spins, on a',
        '# 5 x 5 x 4 grid 2 m apart: written by benchmarks/many_body_scenes.py from its seed',
        f'# ({SEED}); edit a body by hand, or the script and run it again.  No effects: each',
        '# tumbles torque-free, each under error control with its own substeps.',
        'name: debris_field',
        'description: 100 tumbling pieces of debris of random shapes, torque-free, each under '
        'its own error control',
        'integrator: buss',
        'rate: 100',
        'tolerance: 1.0e-6',
        'bodies:',
    ]
    for index in range(100):
        shape = ('box', 'cylinder', 'ellipsoid')[rng.integers(3)]
        mass = rng.uniform(0.2, 5.0)
        extents = np.sort(rng.uniform(0.05, 0.6, 3))[::-1]
        if shape == 'box':
            body = f'{{mass: {mass:.3g}, shape: box, size: {_numbers(extents, 3)}}}'
        elif shape == 'cylinder':
            body = (f'{{mass: {mass:.3g}, shape: cylinder, radius: {extents[1] / 2:.3g}, '
                    f'height: {extents[0]:.3g}}}')
        else:
            body = (f'{{mass: {mass:.3g}, shape: ellipsoid, semi_axes: '
                    f'{_numbers(extents / 2, 3)}}}')
        column, row, layer = index % 5, (index // 5) % 5, index // 25
        position = (2.0 * column - 4.0, 2.0 * row - 4.0, 2.0 * layer)
        spin = rng.normal(0.0, 3.0, 3)
        orientation = _unit_quaternion(rng)
        color = rng.uniform(0.3, 0.9, 3)
        lines.append(f'  - name: debris_{index:03d}')
        lines.append(f'    body: {body}')
        lines.append(f'    initial: {{position: {_numbers(position)}, orientation: '
                     f'{_numbers(orientation, 9)}, angular_velocity_body: '
                     f'{_numbers(spin)}}}')
        lines.append(f'    draw: {{color: {_numbers(tuple(color) + (1.0,), 2)}}}')
    return '\n'.join(lines) + '\n'


def constellation():
    """Return the text of constellation.yaml."""
    rng = np.random.default_rng(SEED + 1)
    lines = [
        '# 1,000 identical 3U cubesats (4 kg, 0.1 x 0.1 x 0.34 m) on 10 rings of 100, each',
        "# slowly tumbling from a random spin: the many-body benchmark's scene",
        '# (benchmarks/many_bodies.py).  Written by benchmarks/many_body_scenes.py from its seed',
        f'# ({SEED + 1}).  No gravity field (the rings are where the satellites are, not',
        '# orbits): each rotates torque-free at a fixed step.',
        'name: constellation',
        'description: 1,000 cubesats on 10 rings, each tumbling torque-free (the many-body '
        'benchmark)',
        'integrator: buss',
        'rate: 100',
        'tolerance: 0',
        'body: {mass: 4.0, shape: box, size: [0.1, 0.1, 0.34]}',
        'draw: {color: [0.75, 0.75, 0.8, 1.0]}',
        'bodies:',
    ]
    for ring in range(10):
        inclination = math.radians(9.0 * ring)
        for slot in range(100):
            angle = 2.0 * math.pi * slot / 100
            radius = 100.0
            position = (radius * math.cos(angle),
                        radius * math.sin(angle) * math.cos(inclination),
                        radius * math.sin(angle) * math.sin(inclination))
            spin = rng.normal(0.0, 0.5, 3)
            orientation = _unit_quaternion(rng)
            lines.append(f'  - {{name: sat_{ring}_{slot:02d}, initial: {{position: '
                         f'{_numbers(position, 6)}, orientation: {_numbers(orientation, 9)}, '
                         f'angular_velocity_body: {_numbers(spin)}}}}}')
    return '\n'.join(lines) + '\n'


SCENE_TEXTS = {'debris_field': debris_field, 'constellation': constellation}


def main(argv=None):
    """Write the scenes, or with --check say which differ (exit 1)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 if a file differs from what it would be')
    arguments = parser.parse_args(argv)
    differ = []
    for name, make in SCENE_TEXTS.items():
        path = SCENES / f'{name}.yaml'
        text = make()
        if arguments.check:
            if not path.is_file() or path.read_text() != text:
                differ.append(str(path))
        else:
            path.write_text(text)
            print(f'wrote {path} ({len(text)} characters)')
    if differ:
        print('differ from what benchmarks/many_body_scenes.py writes: ' + ', '.join(differ))
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
