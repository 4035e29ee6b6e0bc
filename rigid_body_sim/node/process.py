"""
The node's process: its start-up, its signals and its spin, in one module.

SIGINT (Ctrl-C) and SIGTERM are only noted, from the console script's first statement
(:mod:`.entry_point`) to the end: the code that runs checks :func:`signalled` where it can
stop (between the start-up's phases, and every :data:`STOP_LATENCY` s of the spin) and then
stops in order (the node destroyed, its summary logged, rclpy shut down, exit code 0).
rclpy is initialised without its own signal handlers, so nothing shuts the context down
from another thread under the node or the executor.  No KeyboardInterrupt is ever raised:
one raised inside numba's compiler, in a ctypes callback, was swallowed ("Exception ignored
on calling ctypes callback function ... KeyboardInterrupt") and the compilation went on
to its end; one raised inside the EventsExecutor's dispatch could leave it holding callbacks
of a node about to be destroyed.

Where the process cannot get to such a check (a numba compilation, a step of the
integration that runs for seconds), a watchdog thread armed by the first signal ends it:
if :data:`STOP_GRACE` s later the main thread has not noticed the signal, one line says so
and the process exits with code 0 at once (nothing is lost: the node publishes nothing
that needs finishing).  What no Python program can cover is the interpreter's own start
before the entry point's first statement: a signal then takes its default action.

This module imports nothing heavy at its top (the node and rclpy are imported by
:func:`run_node`), and it holds the signal state however the node is started
(``rigid_body_node``, or ``python -m rigid_body_sim.node.entry_point``, where the entry point
runs as ``__main__``).

The node is spun by rclpy's EventsExecutor (``rclpy.experimental``): timers, subscriptions
and services in one thread, at a fraction of the SingleThreadedExecutor's cost per
callback.

RIGID_BODY_SIM_TRACE_START_UP=1 prints a line to stderr as each phase of the start-up
begins (handlers, imports, rclpy.init, node, spin), so that a test can send a signal in
every phase by waiting for its line, whatever the machine's speed.
"""

import faulthandler
import io
import os
import signal
import sys
import threading

__all__ = ['EXIT_GRACE', 'STOP_GRACE', 'STOP_LATENCY', 'bound_the_shutdown',
           'install_signal_handlers', 'main', 'run_node',
           'signalled', 'spin', 'start_up_phase']

STOP_LATENCY = 0.1
"""Longest time (s) the spin waits before it looks for a noted signal."""
STOP_GRACE = 1.0
"""Time (s) the main thread has to notice a signal before the watchdog ends the process."""
EXIT_GRACE = 30.0
"""Longest time (s) the node's teardown (node, context, DDS participant) may take once the
node is done; see :func:`bound_the_shutdown`.  Far above what a teardown takes, so that
only a hung one meets it, on a machine under any load seen here."""

_TRACE = os.environ.get('RIGID_BODY_SIM_TRACE_START_UP') == '1'
# The signals that arrived.
_received = []
# Set once the main thread has seen a signal (or is stopping): the watchdog stands down.
_noticed = threading.Event()


def _note(signal_number, frame):
    _received.append(signal_number)
    if len(_received) == 1:
        threading.Thread(target=_watchdog, args=(signal_number,), name='stop watchdog',
                         daemon=True).start()


def _watchdog(signal_number):
    if _noticed.wait(STOP_GRACE):
        return
    name = signal.Signals(signal_number).name
    print(f'rigid_body_node: stopped by {name}: the process was busy for over '
          f'{STOP_GRACE:g} s (compiling or integrating) and could not stop in order',
          file=sys.stderr, flush=True)
    os._exit(0)


def install_signal_handlers():
    """Make SIGINT and SIGTERM noted (see the module docstring); main thread only."""
    if threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGTERM, _note)
    signal.signal(signal.SIGINT, _note)


def signalled():
    """
    Return whether SIGINT or SIGTERM has arrived since the handlers were installed.

    A True answer tells the watchdog that the main thread is stopping in order.
    """
    if _received:
        _noticed.set()
        return True
    return False


def bound_the_shutdown():
    """
    Make sure the process ends within :data:`EXIT_GRACE` s from now, whatever the middleware.

    Called once the node is done (stopped by a signal, a failed tick or an invalid
    configuration), before the node, the context and, at exit, the DDS participant are
    torn down.  That teardown is the middleware's: Fast DDS's was seen to hang once (a node
    that had logged its configuration error never exited; 1 run in several hundred, ten
    nodes starting and stopping together on a loaded machine; deadlocks of this kind are
    known upstream, eProsima/Fast-DDS#6193, #2500).  The deadline is faulthandler's, a
    thread of C that needs no GIL, so it fires even inside a middleware call that holds it:
    the process then writes where each thread was (to stderr, for the report upstream)
    and exits with code 1.
    """
    try:
        faulthandler.dump_traceback_later(EXIT_GRACE, exit=True, file=sys.stderr)
    except (AttributeError, ValueError, io.UnsupportedOperation):
        pass  # stderr is no file (closed, or replaced by one without a descriptor)


def start_up_phase(name):
    """Note that a phase of the start-up begins (printed only when tracing is asked for)."""
    if _TRACE:
        print(f'start-up phase: {name}', file=sys.stderr, flush=True)


def _asks_for_help(arguments):
    # Only before --ros-args: what follows it belongs to ROS.
    ours = arguments[1:arguments.index('--ros-args')] if '--ros-args' in arguments \
        else arguments[1:]
    return '-h' in ours or '--help' in ours


def main(args=None):
    """Run the node (see :func:`run_node`); return the exit code."""
    try:
        # A signal noted since the handlers were set (during the entry point's import)
        # ends the start-up here.
        if signalled():
            return 0
        if _asks_for_help(sys.argv if args is None else args):
            from .help_text import help_text
            print(help_text())
            return 0
        start_up_phase('imports')
        return run_node(args)
    except BaseException:
        # What a signal made of an import (numba's ImportError after an interrupted
        # extension module's initialisation): a clean stop.
        if signalled():
            return 0
        raise
    finally:
        _noticed.set()


def spin(node):
    """
    Serve the node (its timer, inputs, services) until the context shuts down or a signal.

    Returns whether it ended on its own (the context shut down by rclpy's signal handler or
    a failed tick) rather than on a signal.
    """
    import rclpy
    from rclpy.experimental import EventsExecutor
    executor = None
    try:
        executor = EventsExecutor(context=node.context)
        # The executor catches SIGINT and SIGTERM itself (asio's signal set) and acts on
        # them late, in its own way (a process killed by the signal's default action as
        # the context shut down, 1 stop in ~15): ours are put back in front of it.
        install_signal_handlers()
        executor.add_node(node)
        while node.context.ok() and not signalled():
            executor.spin_once(timeout_sec=STOP_LATENCY)
    except rclpy.executors.ExternalShutdownException:
        pass
    finally:
        if executor is not None:
            # The executor lets go of the node's callbacks before the node is destroyed.
            if node in executor.get_nodes():
                executor.remove_node(node)
            executor.shutdown()
            del executor
            install_signal_handlers()
    return not signalled()


def run_node(args=None):
    """
    Run the node until SIGINT or SIGTERM; return the exit code.

    0 after a clean shutdown; 1 if the configuration is invalid (one error is logged) or the
    simulation failed; 2 if the ROS arguments cannot be parsed.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    from .rigid_body_node import ConfigurationError
    from .world_node import node_for_scene

    if signalled():
        return 0
    start_up_phase('rclpy.init')
    # A context of our own, without rclpy's signal handlers: ours note the signal, the spin
    # ends on it.  (Shutting the default context down would also "restore" the handlers
    # rclpy never installed, the signals' default actions.)
    context = rclpy.Context()
    try:
        rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
    except (RuntimeError, ValueError) as error:
        print(f'rigid_body_node: error: {error}'.replace('\n', ' '), file=sys.stderr)
        return 2
    node = unconfigured = None
    code = 0
    try:
        if not signalled():
            start_up_phase('node')
            # The one-body node, or for a scene of bodies: the world's.
            node = node_for_scene(context)
        if not signalled():
            start_up_phase('spin')
            spin(node)
    except ConfigurationError as error:
        code = 1
        unconfigured = error.node
    except ExternalShutdownException:
        pass
    finally:
        _noticed.set()
        bound_the_shutdown()
        if node is not None:
            if node.tick_error is not None:
                code = 1
            summary = node.statistics()
            logger = node.get_logger()
            node.destroy_node()
            logger.info(summary)
        if unconfigured is not None:
            unconfigured.destroy_node()
        rclpy.try_shutdown(context=context)
    return code
