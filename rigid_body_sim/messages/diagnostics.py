"""
The /diagnostics status of a simulation, built in one place for the node and ``simulate``.

Both report the same keys in the same order (:data:`STATUS_KEYS`); the node from its live
ticks, ``rigid-body-sim simulate`` from an offline run (:mod:`rigid_body_sim.recording`).
:func:`status_values` turns what each knows into the (key, value) pairs and
:func:`diagnostic_array` into the message.
"""

from dataclasses import dataclass
import math

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from diagnostic_msgs.msg import KeyValue
import numpy as np

__all__ = ['NODE_NAME', 'STATUS_KEYS', 'TickFigures', 'diagnostic_array', 'status_name',
           'status_values', 'substep_diagnostics', 'substep_cap_reached']

NODE_NAME = 'rigid_body_sim'
"""Default name of the node, the name ``simulate`` reports under."""

STATUS_KEYS = (
    'scene', 'effects', 'integrator', 'requested rate [Hz]', 'real-time factor',
    'achieved rate [Hz]', 'achieved real-time factor', 'missed ticks',
    'tolerance [rad/s]', 'substeps', 'substeps min', 'substeps max', 'step [s]',
    'estimated error rate [rad/s]', 'estimated error rate max [rad/s]',
    'integration CPU per simulated s [s]',
    'step time p50 [ms]', 'step time max [ms]', 'tick duration p50 [ms]',
    'tick duration p99 [ms]', 'simulated time [s]', 'clock [s]', 'paused',
    'external wrench active', 'energy [J]', 'energy drift since last input', '|L| [kg m^2/s]',
    '|L| drift since last input', 'inputs rejected', 'inputs scaled down to the scene limits',
)
"""Every key of the status, in order."""


@dataclass(eq=False)
class TickFigures:
    """
    What one reporting window measured: the inputs of :func:`status_values`.

    achieved : float, ticks per wall-clock second.
    missed : int, ticks dropped (late by more than the node catches up).
    step_durations, tick_durations : arrays of s (wall), one per tick of the window.
    simulated : float, simulated s the window's steps advanced (0 after a reset: then
        ticks x period is used).
    """

    achieved: float
    missed: int
    step_durations: np.ndarray
    tick_durations: np.ndarray
    simulated: float

    def __post_init__(self):
        """Hold the durations as arrays."""
        self.step_durations = np.asarray(self.step_durations)
        self.tick_durations = np.asarray(self.tick_durations)


def status_name(node_name=NODE_NAME):
    """Return the status's name for a node of that name."""
    return f'{node_name}: simulation'


def substep_diagnostics(simulator, period, step_seconds, simulated_seconds):
    """
    Return the diagnostics (key, value) pairs of the substeps and error control.

    The simulator's figures since the last call (it starts a new period): tolerance (or
    'off'), substeps in use (the last tick's, and the least and most of the period), the
    step, the error rate estimated last and the largest of the period (rad/s, 'n/a' off),
    and the integration's CPU per simulated second: `step_seconds` (the wall time of the
    steps, pure computation in one thread: their CPU time unless it was preempted) over
    `simulated_seconds`.
    """
    figures = simulator.substep_statistics(reset=True)
    controlled = figures['tolerance'] is not None

    def rate(value):
        return f'{value:.3e}' if controlled and math.isfinite(value) else 'n/a'
    return [
        ('tolerance [rad/s]', f'{figures["tolerance"]:g}' if controlled else 'off'),
        ('substeps', str(figures['substeps'])),
        ('substeps min', str(figures['substeps_min'])),
        ('substeps max', str(figures['substeps_max'])),
        ('step [s]', f'{period / figures["substeps"]:.6g}'),
        ('estimated error rate [rad/s]', rate(figures['error_rate'])),
        ('estimated error rate max [rad/s]', rate(figures['error_rate_max'])),
        ('integration CPU per simulated s [s]',
         f'{step_seconds / simulated_seconds:.3e}' if simulated_seconds > 0.0 else 'n/a'),
    ]


def substep_cap_reached(values, cap):
    """Return whether the status (key -> value) shows error control at its substep cap."""
    try:
        return values['tolerance [rad/s]'] != 'off' and int(values['substeps max']) >= cap
    except (KeyError, ValueError):
        return False


def status_values(scene, simulator, rate, real_time_factor, figures, clock_seconds=None,
                  paused=False, wrench_active=False, reference_energy=0.0,
                  reference_momentum=0.0, rejected=0, limited=0):
    """
    Return the status's (key, value) pairs, in the order of :data:`STATUS_KEYS`.

    Parameters
    ----------
    scene : Scene
        What runs (its name and effects are reported).
    simulator : Simulator
        Its integrator, substep statistics (read and restarted), time, energy and momentum.
    rate : float
        Requested tick rate in Hz.
    real_time_factor : float or str
        The node's, or a text (offline: 'offline: as fast as possible').
    figures : TickFigures
        The window's measurements.
    clock_seconds : float, optional
        The /clock time published, if any.
    paused, wrench_active : bool
        Whether the simulation is paused, and whether an external wrench is held.
    reference_energy, reference_momentum : float
        Energy (J) and |L| (kg m^2/s) at the last input (or start, or reset).
    rejected, limited : int
        Inputs rejected, and scaled down to the scene's limits, so far.

    """
    step = figures.step_durations
    tick = figures.tick_durations
    simulated = figures.simulated if figures.simulated > 0.0 else tick.size / rate
    energy = simulator.energy()
    momentum = float(np.linalg.norm(simulator.state.angular_momentum))
    factor = real_time_factor if isinstance(real_time_factor, str) \
        else f'{real_time_factor:g}'
    values = [
        ('scene', scene.name),
        ('effects', ', '.join(scene.effect_names()) or 'none'),
        ('integrator', simulator.integrator),
        # compiled, or interpreted while the kernels compile (physics/kernels/interpreted.py)
        ('kernels', simulator.path),
        ('requested rate [Hz]', f'{rate:g}'),
        ('real-time factor', factor),
        # Ticks per wall-clock second: rate x real-time factor when the node keeps up.
        ('achieved rate [Hz]', f'{figures.achieved:.2f}'),
        ('achieved real-time factor', f'{figures.achieved / rate:.3f}'),
        ('missed ticks', str(figures.missed)),
        *substep_diagnostics(simulator, 1.0 / rate, float(step.sum()), simulated),
        ('step time p50 [ms]', _milliseconds(step, 50)),
        ('step time max [ms]', _milliseconds(step, 100)),
        ('tick duration p50 [ms]', _milliseconds(tick, 50)),
        ('tick duration p99 [ms]', _milliseconds(tick, 99)),
        ('simulated time [s]', f'{simulator.time:.6f}'),
        ('clock [s]', 'not published' if clock_seconds is None else f'{clock_seconds:.6f}'),
        ('paused', str(bool(paused))),
        ('external wrench active', str(bool(wrench_active))),
        # Kinetic plus the effects' potential energy (gravity): what is conserved.
        ('energy [J]', f'{energy:.12g}'),
        ('energy drift since last input', _relative(energy, reference_energy)),
        ('|L| [kg m^2/s]', f'{momentum:.12g}'),
        ('|L| drift since last input', _relative(momentum, reference_momentum)),
        ('inputs rejected', str(rejected)),
        ('inputs scaled down to the scene limits', str(limited)),
    ]
    return values


def diagnostic_array(name, hardware_id, level, message, values, stamp_nanoseconds):
    """Return a DiagnosticArray of one status, stamped (ns)."""
    status = DiagnosticStatus()
    status.name = name
    status.hardware_id = hardware_id
    status.level = level
    status.message = message
    status.values = [KeyValue(key=key, value=value) for key, value in values]
    array = DiagnosticArray()
    array.header.stamp.sec, array.header.stamp.nanosec = divmod(int(stamp_nanoseconds),
                                                                1_000_000_000)
    array.status = [status]
    return array


def _milliseconds(durations, percentile):
    if durations.size == 0:
        return 'n/a'
    return f'{1e3 * float(np.percentile(durations, percentile)):.4f}'


def _relative(value, reference):
    if reference == 0.0:
        return f'{value - reference:+.3e} (absolute)'
    return f'{(value - reference) / abs(reference):+.3e}'
