"""
The ``rigid-body-sim`` command: one entry point, one subcommand per tool.

Each tool is a module in :mod:`rigid_body_sim.tools` with ``add_arguments(parser)`` and
``main(args) -> int`` and a docstring whose first line is its one-line help.  Adding a tool
is one module and one line in :data:`TOOLS`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import importlib
import os
import signal
import sys

from .physics.simulator import DivergedError

# Subcommand name -> module in rigid_body_sim.tools.
TOOLS = {
    'run': 'summary',
    'watch': 'watch',
    'bench': 'bench',
    'scenes': 'scenes',
    'simulate': 'simulate',
    'record': 'record',
    'plot': 'plot',
    'animate': 'animate',
    'compile': 'compile',
    'sweep': 'sweep',
}

_EPILOG = """\
examples:
  rigid-body-sim run                        simulate the default tumbling body, print a summary
  rigid-body-sim watch                      a live view of the running node (make run)
  rigid-body-sim run --integrator rk4 --dt 0.01 --duration 60
  rigid-body-sim COMMAND --help             what each command does and takes
"""


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every tool's subcommand."""
    parser = argparse.ArgumentParser(
        prog='rigid-body-sim',
        description="Simulate a rigid body with geometric integrators (Buss's augmented "
                    'second-order method and its rivals): offline runs and reports beside '
                    'the ROS 2 node rigid_body_node.',
        epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    subparsers = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name, module_name in TOOLS.items():
        module = importlib.import_module(f'rigid_body_sim.tools.{module_name}')
        doc = (module.__doc__ or '').strip()
        summary = doc.splitlines()[0] if doc else ''
        sub = subparsers.add_parser(
            name, help=summary, description=doc,
            formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(sub)
        sub.set_defaults(tool=module)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run the command line; return the exit code.

    0 success, 1 failure (a path that cannot be written or read, a simulation that turned
    non-finite), 2 bad input, 130 Ctrl-C,
    141 when the reader of the output went away (``| head``);
    a tool stopped by signal n cleanly (``simulate``) returns 128 + n.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return int(args.tool.main(args) or 0)
    except DivergedError as error:
        # The simulation went non-finite: what was written ends at the last finite state.
        print(f'rigid-body-sim {args.command}: error: {error}', file=sys.stderr)
        return 1
    except ValueError as error:
        print(f'rigid-body-sim {args.command}: error: {error}', file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader went away (`rigid-body-sim scenes | head`): end quietly, as a program
        # killed by SIGPIPE would, without a second error on the closed stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except OSError as error:
        # A bag or PNG path that cannot be written (under a file, no permission, disk full).
        where = f'{error.filename}: ' if error.filename else ''
        reason = error.strerror or str(error)
        print(f'rigid-body-sim {args.command}: error: {where}{reason}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'rigid-body-sim {args.command}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
