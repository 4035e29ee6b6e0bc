"""
List the built-in scenes with a one-line description each, or check and describe one.

A scene is a YAML file naming a body, its initial state, the effects on it (gravity, a
pivot, drag, dissipation, external pushes), the default integrator and rate, and how to
draw it.  Give a built-in name or a path to check a scene and print what it holds; an
invalid file is reported with its key path and what is wrong (exit code 2).  A scene of
several bodies (``bodies:``) is described one line a body (the first 20; --body NAME
describes one in full).  --effects
lists every effect a scene may name, with its parameters and their defaults: read from the
effect registry, it is the complete list (the schema comment in config/scenes/default.yaml
documents the first few and points here), the installed effect plugins' effects included; a
plugin that fails to load is one line on stderr naming it, and the rest are listed.
"""

from __future__ import annotations

import argparse
import inspect
import sys
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from numpy.typing import NDArray

from ..paths import scenes_dir
from ..physics import RigidBody
from ..physics.effects import effect_parameters
from ..physics.effects import EFFECTS
from ..physics.effects.plugins import problems
from ..scenes import DEFAULT_SCENE
from ..scenes import load_scene
from ..scenes import Scene
from ..scenes import scene_names


# Relative size below which a component is round-off (about 5000 ulp of its scale).
_ROUND_OFF = 1e-12


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim scenes``."""
    parser.add_argument('scene', nargs='?',
                        help='a built-in scene name or a path to a .yaml file: check it and '
                             'print what it holds')
    parser.add_argument('--body', metavar='NAME',
                        help='in a scene of several bodies, describe the body NAME in full')
    parser.add_argument('--effects', action='store_true',
                        help='list the effects a scene may name, with their parameters')


def main(args: argparse.Namespace) -> int:
    """List the scenes (or effects), or describe one scene; return 0."""
    if args.effects:
        _print_effects()
    elif args.scene is not None:
        scene = load_scene(args.scene)
        if args.body is not None:
            _print_scene(_member(scene, args.body))
        elif scene.has_named_bodies:
            _print_bodies(scene)
        else:
            _print_scene(scene)
    else:
        _print_scenes()
    return 0


def _print_scenes() -> None:
    names = scene_names()
    width = max(len(name) for name in names)
    print(f'built-in scenes ({scenes_dir()}):')
    for name in names:
        marker = '*' if name == DEFAULT_SCENE else ' '
        scene = load_scene(name)
        count = f' ({len(scene.members)} bodies)' if scene.has_named_bodies else ''
        print(f' {marker}{name:<{width}}  {scene.description}{count}')
    print("* the node's default.  Details: rigid-body-sim scenes NAME; run one: "
          'ros2 run rigid_body_sim rigid_body_node --ros-args -p scene:=NAME')


_LISTED_BODIES = 20


def _member(scene: Scene, name: str) -> Scene:
    """Return the body `name` of a scene as a one-body scene (ValueError naming them)."""
    for member in scene.members:
        if member.name == name:
            return member
    names = [member.name for member in scene.members]
    shown = ', '.join(names[:_LISTED_BODIES]) + (', ...' if len(names) > _LISTED_BODIES else '')
    raise ValueError(f'{scene.source}: no body called {name!r}; its bodies: {shown}')


def _print_bodies(scene: Scene) -> None:
    """Print a scene of several bodies: what they share, then one line a body."""
    members = scene.members
    control = ('off' if scene.tolerance is None
               else f'{scene.tolerance:g} rad/s, each body its own substeps')
    print(f'{scene.name}: {scene.description}')
    print(f'  source:      {scene.source}')
    print(f'  integrator:  {scene.integrator} at {scene.rate:g} Hz (dt {scene.dt:g} s), '
          f'tolerance {control}')
    print(f'  bodies:      {len(members)}; topics <name>/pose, <name>/twist, ..., frames '
          '<name> and <name>/imu')
    width = max(len(member.name) for member in members[:_LISTED_BODIES])
    for member in members[:_LISTED_BODIES]:
        body, state = member.body, member.state
        omega = np.linalg.norm(state.angular_velocity_body(body))
        position = np.array2string(without_round_off(state.position), precision=4,
                                   separator=', ')
        effects = ', '.join(member.effect_names()) or 'torque-free'
        print(f'    {member.name:<{width}}  {body.mass:g} kg {member.drawing.shape}, at '
              f'{position} m, |omega| {omega:.3g} rad/s, {effects}')
    if len(members) > _LISTED_BODIES:
        print(f'    ... and {len(members) - _LISTED_BODIES} more')
    print(f'  one body in full: rigid-body-sim scenes {scene.name} --body {members[0].name}')


def _print_scene(scene: Scene) -> None:
    body, state = scene.body, scene.state

    def vector(values: ArrayLike, scale: float | np.floating[Any] | None = None) -> str:
        return np.array2string(without_round_off(values, scale), precision=6,
                               separator=', ')
    omega = state.angular_velocity_body(body)

    print(f'{scene.name}: {scene.description}')
    print(f'  source:      {scene.source}')
    print(f'  body:        mass {body.mass:g} kg, {moments(body)}')
    print(f'  orientation: {vector(state.quaternion)} (x, y, z, w)')
    print(f'  omega body:  {vector(omega)} rad/s')
    # A pivot's COM velocity is omega x r: its round-off is relative to |omega| |r|.
    speed = max(np.linalg.norm(state.velocity(body)),
                np.linalg.norm(omega) * np.linalg.norm(state.position))
    print(f'  position:    {vector(state.position)} m, velocity '
          f'{vector(state.velocity(body), speed)} m/s')
    effects = ', '.join(repr(effect) for effect in scene.effects) or 'none (torque-free)'
    print(f'  effects:     {effects}')
    control = ('off' if scene.tolerance is None
               else f'{scene.tolerance:g} rad/s (substeps per tick chosen by error control)')
    print(f'  integrator:  {scene.integrator} at {scene.rate:g} Hz (dt {scene.dt:g} s), '
          f'tolerance {control}')
    drawing = scene.drawing
    print(f'  drawing:     {drawing.shape} {vector(drawing.size)} m, color '
          f'{vector(drawing.color)}')
    print(f'  outside push (torque/wrench topics): '
          f'{"yes" if scene.accepts_external_wrench else "no"}')


def moments(body: RigidBody) -> str:
    """
    Return how the body's inertia reads: its moments about body x, y, z if diagonal.

    A diagonal inertia (a shape's, or the scene's three moments) is given about the body
    axes in their order (a cylinder's axis is z, whatever its moments' order); otherwise the
    principal moments in ascending order, with their axes in the body frame.
    """
    inertia = body.inertia
    if np.count_nonzero(inertia - np.diag(np.diag(inertia))) == 0:
        values = np.array2string(np.diag(inertia), precision=6, separator=', ')
        return f'moments about body x, y, z {values} kg m^2'
    values = np.array2string(body.principal_moments, precision=6, separator=', ')
    axes = np.array2string(without_round_off(body.principal_axes.T.ravel()).reshape(3, 3),
                           precision=4, separator=', ').replace('\n', '')
    return f'principal moments {values} kg m^2 about the body axes (rows) {axes}'


def without_round_off(values: ArrayLike,
                      scale: float | np.floating[Any] | None = None) -> NDArray[np.float64]:
    """
    Return `values` with the components below their round-off set to 0.

    A component smaller than 1e-12 of `scale` (default: the largest component's magnitude)
    is round-off of the computation that made the vector (a rotation of (0, 0, 150) rad/s
    leaves ~1e-14 in its zero components), not a value: it prints as 0.
    """
    values = np.array(values, dtype=float)
    if scale is None:
        scale = float(np.max(np.abs(values))) if values.size else 0.0
    values[np.abs(values) <= _ROUND_OFF * scale] = 0.0
    return values + 0.0  # -0.0 prints as 0


def _print_effects() -> None:
    names = sorted(EFFECTS)
    for line in problems():
        print(f'rigid-body-sim scenes: {line}', file=sys.stderr)
    for name in names:
        cls = EFFECTS[name]
        doc = inspect.getdoc(cls) or ''
        print(f'{name}: {doc.splitlines()[0] if doc else ""}')
        units = getattr(cls, 'units', None) or {}
        for key, default in effect_parameters(name).items():
            value = 'required' if default is inspect.Parameter.empty else f'default {default}'
            unit = units.get(key)
            print(f'    {key} ({unit}; {value})' if unit else f'    {key} ({value})')
