"""
Animate the body in a bag: its shape turning, its axes, L and a trail, as a GIF or MP4.

Reads the node's odom, angular_momentum and marker topics (any bag of the node:
`rigid-body-sim simulate`, `rigid-body-sim record`, `ros2 bag record`) and draws, viewed
from the COM, the body's shape (the marker's; without a marker, the inertia-equivalent box
of an offline bag's mass and inertia), the body axes x, y, z (red, green, blue), the
direction of the world angular momentum L (dashed black) and a fading trail of the tip of
the body axis that moves most.  Frames are taken every SPEED / FPS simulated seconds.
A GIF (Pillow) is kept within --max-size by scaling its frames down; MP4 needs ffmpeg.

A bag of several bodies (a scene of `bodies:`) is drawn in one 3-D scene: every body its
shape and colour from the bag's marker array, at its pose, with a fading trail of its COM,
the axes fitted to all of them (up to 10 bodies named in the legend; more than 200, such as
a constellation of 1,000, as coloured points).  --body NAME animates that one body alone,
as a bag of one body is animated.

Typical use:
  rigid-body-sim simulate --scene default --duration 30 --bag flip
  rigid-body-sim animate flip                          writes flip.gif beside the bag
  rigid-body-sim animate flip --out flip.gif --fps 10 --speed 2
  rigid-body-sim simulate --scene tennis_racket --duration 10 --animate racket.gif
  rigid-body-sim simulate --scene juggling_clubs --duration 1 --bag clubs
  rigid-body-sim animate clubs                         all three clubs: clubs.gif
  rigid-body-sim animate clubs --body club_left        one club: clubs_club_left.gif
"""

from __future__ import annotations

import argparse
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim animate``."""
    parser.add_argument('bag', help='bag directory')
    add_animation_options(parser, out_help='GIF or MP4 file to write (default: <bag>.gif '
                                           'beside the bag)')
    parser.add_argument('--namespace', default='',
                        help="the node's namespace in the bag (default: none)")
    parser.add_argument('--body', metavar='NAME',
                        help='in a bag of several bodies, animate this one alone, viewed '
                             'from its COM (default: all, in one scene)')


def add_animation_options(parser: argparse.ArgumentParser, out_help: str | None = None,
                          prefix: str = '') -> None:
    """Add --fps, --speed, --max-size (and --out unless out_help is None) to a parser."""
    from ..recording.animate import DEFAULT_FPS
    from ..recording.animate import DEFAULT_MAX_BYTES
    from ..recording.animate import DEFAULT_SPEED
    if out_help is not None:
        parser.add_argument('--out', help=out_help)
    parser.add_argument(f'--{prefix}fps', type=float, default=DEFAULT_FPS,
                        help=f'frames per second of the animation (default {DEFAULT_FPS:g})')
    parser.add_argument(f'--{prefix}speed', type=float, default=DEFAULT_SPEED,
                        help='simulated seconds per second of the animation (default '
                             f'{DEFAULT_SPEED:g}: real time)')
    parser.add_argument(f'--{prefix}max-size', type=float,
                        default=DEFAULT_MAX_BYTES / 2 ** 20, metavar='MB',
                        help='size budget of a GIF in MiB: its frames are scaled down to fit '
                             f'(default {DEFAULT_MAX_BYTES / 2 ** 20:g})')


def render(bag: str, out: str | None, fps: float, speed: float, max_size: float,
           namespace: str = '', quiet: bool = False, body: str | None = None) -> int:
    """Animate `bag` into `out` with a progress bar; print what was written; return 0."""
    import math
    import time

    from ..recording.animate import prepare_animation
    from ..recording.animate import render_animation

    if not (math.isfinite(max_size) and max_size > 0.0):
        raise ValueError(f'--max-size must be a number of MiB > 0; got {max_size:g}')
    started = time.perf_counter()
    # Every check (options, bag, shape) before the progress bar: an error is one line.
    animation = prepare_animation(bag, out, fps=fps, speed=speed, namespace=namespace,
                                  max_bytes=int(max_size * 2 ** 20), body=body)
    plan = animation.plan
    bar = None
    if not quiet:
        from tqdm import tqdm
        bar = tqdm(total=plan.frames, desc='animate', unit='frame', file=sys.stderr,
                   dynamic_ncols=True)
    try:
        size = render_animation(animation,
                                progress=None if bar is None else (lambda done: bar.update(1)))
    finally:
        if bar is not None:
            bar.close()
    print(f'{animation.out}: {plan.frames} frames at {plan.fps:g} fps ({plan.duration:.1f} s, '
          f'{plan.speed:g}x simulated time), {size / 2 ** 20:.2f} MiB, rendered in '
          f'{time.perf_counter() - started:.1f} s')
    return 0


def main(args: argparse.Namespace) -> int:
    """Animate the bag; return 0."""
    return render(args.bag, args.out, args.fps, args.speed, args.max_size, args.namespace,
                  body=args.body)
