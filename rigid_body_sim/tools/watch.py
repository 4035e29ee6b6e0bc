"""
Watch a running rigid_body_node live: a window, or a terminal view without a display.

Finds the node over DDS by what it publishes (any name or namespace; --node and
--namespace choose among several), from this venv alone: no ROS installation, no rviz2.
The window draws the body as `rigid-body-sim animate` does (its shape, the body axes x, y,
z in red, green, blue, the direction of L dashed, a trail), strip charts of the body
angular velocity and of the drift of what the scene conserves, and the node's live cost
and state from /diagnostics.  Without a display (or with --terminal) a terminal view
refreshes in place: simulated time, omega, |L|, energy drift, flips since watch started
(about the middle principal axis, while no input acts), substeps, ticks per second.  Both
follow a reset, a pause and an integrator switch, and say so while no node is found.  Only
the watched node's own publishers are believed (another node of the same name is said);
a peer's numbers that are not finite or absurd are said to be so, its text is cut and
escaped.  Ctrl-C (or closing the window) ends it.

A node of several bodies (a scene with bodies:, e.g. rigid_body_node --ros-args -p
scene:=juggling_clubs): --body NAME shows that body as the view of a one-body node (named in
the title; the drift of what its effects conserve computed from its state).  Without
--body, the terminal view is a table of its bodies (|omega|, |L|, position, speed; as many
as the terminal has lines for, sorted by name, subscribed to those only), and the window
shows the first body: the keys n and p show the next and the previous.  A name the node
has no body of is said in one line with the bodies it has (exit 2), as is --body on a
one-body node.

Typical use (the node in another terminal: make run):
  rigid-body-sim watch                        the window, or the terminal view without one
  rigid-body-sim watch --terminal             the terminal view
  rigid-body-sim watch --namespace /robot1    the node in namespace /robot1
  rigid-body-sim watch --timeout 10           give up (exit 1) if no node shows in 10 s
  rigid-body-sim watch --terminal --body club_left
                                              one body of a node of bodies (juggling_clubs)
  rigid-body-sim watch --terminal             of a node of bodies: the table of its bodies
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import sys
import threading
import time
from types import FrameType
from typing import Literal
from typing import NoReturn
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # for the annotations: the command imports the watch (rclpy) when it runs
    from ..watch.listener import Listener
    from ..watch.live import LiveState
    from ..watch.live import Snapshot


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``rigid-body-sim watch``."""
    parser.add_argument('--node', help='the node to watch: its name or /namespace/name '
                                       '(default: the first found)')
    parser.add_argument('--namespace', help='only nodes in this namespace (default: any)')
    parser.add_argument('--body', metavar='NAME',
                        help='of a node of several bodies, the body to watch (default: the '
                             'table of them in the terminal view; in the window the first, '
                             'n / p for the next / previous)')
    parser.add_argument('--terminal', action='store_true',
                        help='the terminal view even where a window could open')
    parser.add_argument('--history', type=float, default=20.0, metavar='S',
                        help='simulated seconds the strip charts show (default 20)')
    parser.add_argument('--timeout', type=float, default=math.inf, metavar='S',
                        help='exit with 1 if no node is found within S s (default: keep '
                             'looking)')
    parser.add_argument('--interval', type=float, default=0.5, metavar='S',
                        help='seconds between refreshes of the terminal view (default 0.5)')
    parser.add_argument('--refresh', type=float, metavar='S',
                        help="seconds between the window's redraws, kept as given (default: "
                             '0.2, longer while a redraw takes over a fifth of a core or the '
                             'machine is busy)')


class _Stop:
    """SIGINT and SIGTERM end the watch cleanly (a window closes, the context shuts down)."""

    def __init__(self) -> None:
        self.signal: signal.Signals | None = None
        self.timed_out = False
        self.problem_said = False
        # Set by the signal: the terminal view's wait between refreshes ends at once.
        self.event = threading.Event()

    def __enter__(self) -> _Stop:
        self._previous = {number: signal.signal(number, self._handle)
                          for number in (signal.SIGINT, signal.SIGTERM)}
        return self

    def _handle(self, number: int, frame: FrameType | None) -> None:
        self.signal = signal.Signals(number)
        self.event.set()

    def __exit__(self, *exc: object) -> Literal[False]:
        for number, handler in self._previous.items():
            signal.signal(number, handler)
        return False

    def __call__(self) -> bool:
        return self.signal is not None or self.timed_out


def main(args: argparse.Namespace) -> int:
    """
    Watch until Ctrl-C, the window's closing or the timeout; return the exit code.

    After a signal (Ctrl-C, SIGTERM) the process ends here, once all is closed, with the
    code it returns otherwise (130 for Ctrl-C, 0 for SIGTERM).
    """
    for name in ('history', 'interval', 'refresh'):
        value = getattr(args, name)
        if name == 'refresh' and value is None:
            continue
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f'--{name} must be a number of s > 0; got {value:g}')
    if math.isnan(args.timeout) or args.timeout <= 0.0:
        raise ValueError(f'--timeout must be a number of s > 0; got {args.timeout:g}')
    from ..watch.listener import new_state_and_listener
    from ..watch.window import display_problem

    problem = None if args.terminal else display_problem()
    if problem is not None:
        print(f'rigid-body-sim watch: {problem}: the terminal view (--terminal says so '
              'without this note)', file=sys.stderr)
    from ..watch.terminal import TABLE_MARGIN
    terminal = args.terminal or problem is not None
    state, listener = new_state_and_listener(
        args.history, args.node, args.namespace, body=args.body,
        chooser='table' if terminal else 'switch',
        table_rows=shutil.get_terminal_size().lines - TABLE_MARGIN)
    with _Stop() as stop:
        listener.start()
        try:
            if terminal:
                _terminal(state, listener, args, stop)
            else:
                _window(state, listener, args, stop)
        finally:
            listener.close()
    if stop.timed_out:
        return 1
    if listener.problem is not None:
        return 2
    code = 0 if stop.signal in (None, signal.SIGTERM) else 128 + stop.signal
    if stop.signal is not None:
        _exit_now(f'rigid-body-sim watch: stopped ({stop.signal.name})', code)
    return code


def _exit_now(message: str, code: int) -> NoReturn:
    """
    Say `message` and end the process at once, with `code`.

    Everything watch holds is released by now (the window, the DDS participant); what is
    left is the interpreter's own exit, seconds on a busy machine (mostly LLVM's teardown,
    which the physics core's numba brings), while a signal asks for the prompt back now.
    """
    import logging
    print(message, file=sys.stderr, flush=True)
    sys.stdout.flush()
    logging.shutdown()
    os._exit(code)


def _cannot_go_on(listener: Listener, stop: _Stop) -> bool:
    """Say the listener's problem (a --body the node has not) and return True, if it has one."""
    if listener.problem is None:
        return False
    if not stop.problem_said:
        stop.problem_said = True
        print(f'rigid-body-sim watch: {listener.problem}', file=sys.stderr, flush=True)
    return True


def _no_node_for(listener: Listener, timeout: float, stop: _Stop) -> bool:
    """Note a timeout (and say so) if no node has shown for `timeout` s; return True then."""
    if listener.watched is not None or time.monotonic() - listener.searching_since < timeout:
        return False
    from ..watch.terminal import waiting_lines
    stop.timed_out = True
    print(waiting_lines(listener, timeout)[0].replace('still looking (Ctrl-C stops)',
                                                      'giving up (--timeout)'),
          file=sys.stderr)
    return True


def _terminal(state: LiveState, listener: Listener, args: argparse.Namespace,
              stop: _Stop) -> None:
    from ..watch.terminal import render_lines
    from ..watch.terminal import TABLE_MARGIN
    from ..watch.terminal import table_lines
    from ..watch.terminal import TerminalView
    from ..watch.terminal import waiting_lines

    view = TerminalView(sys.stdout, in_place=sys.stdout.isatty())
    while not stop():
        if _cannot_go_on(listener, stop) or _no_node_for(listener, args.timeout, stop):
            return
        snapshot = state.snapshot()
        if snapshot.node is None:
            waited = time.monotonic() - listener.searching_since
            # Whole seconds: the block is rewritten (or appended) once a second.
            view.show(waiting_lines(listener, math.floor(waited)))
        elif snapshot.bodies and snapshot.body is None:
            # The table follows the terminal's height: the rows shown are those subscribed.
            listener.set_table_rows(shutil.get_terminal_size().lines - TABLE_MARGIN)
            view.show(table_lines(snapshot, listener.table_rows(), listener.table_bodies))
        else:
            view.show(render_lines(snapshot))
        stop.event.wait(args.interval)


def _window(state: LiveState, listener: Listener, args: argparse.Namespace,
            stop: _Stop) -> None:
    from ..watch.window import WatchWindow

    def should_stop() -> bool:
        return stop() or _cannot_go_on(listener, stop) or _no_node_for(listener, args.timeout,
                                                                       stop)

    def drawn(snapshot: Snapshot) -> None:
        # One line each time a body and both charts are on screen (again after n / p):
        # scripts and the tests wait for it.
        print(f'rigid-body-sim watch: window shows {snapshot.watched}', flush=True)
    WatchWindow(state, listener, args.history, should_stop, on_drawn=drawn,
                refresh=args.refresh).run()
