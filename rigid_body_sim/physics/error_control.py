"""
Error control: each outer step (a node's tick) split into as many equal substeps as needed.

The accuracy target is a tolerance on the orientation error added per simulated second
(rad/s).  Each tick of T s is taken as n equal substeps of h = T / n by the integrator's
compiled run (one call), and n is chosen from an estimate of the error rate; the lower bound
n_min is the node's ``substeps``.  Nothing else changes: the state, the integrator, the
effects and the kicks are exactly those of a fixed-step run at h.

The estimate: step doubling (Richardson).  A method of order q makes a local error
e(h) = C h^(q+1) + O(h^(q+2)) per step, C a vector fixed by the state.  From one state,

    two steps of h:    2 C h^(q+1)           one step of 2 h:    C (2 h)^(q+1) = 2^(q+1) C h^(q+1)

so the two results differ by (2^(q+1) - 2) C h^(q+1), and the error of one step of h is

    e(h) ~ |difference| / (2^(q+1) - 2)        (buss, q = 2: / 6; rk4, q = 4: / 30).

The tick's last two substeps are that pair (they are taken anyway), and one extra step of 2 h
from the state before them is the companion: the estimate costs one step.  A tick of one
substep is compared instead with two half steps from its start: its own error is
e(h) = |difference| / (1 - 2^-q), at the price of two extra (half) steps.  The error rate is
r = e(h) / h (rad/s), the orientation error the substeps add per simulated second, and
behaves as r(h) = C' h^q.

|difference| (rad): the rotation angle between the two orientations, plus h |I_b^-1 R^T dL|
(dL the difference of the two angular momenta): the orientation error the momentum
discrepancy makes within one step.  Torque-free, Buss, the splittings and the exact flow
leave L untouched and the term is zero; under a torque a momentum error turns into an
orientation error later, and this counts its first step of that.

Where the count is set.  Error per step is what the estimate measures, but not what a long
run's error follows: measured on the built-in scenes, a count that followed the local error
along the orbit (n ~ sqrt(r), the textbook controller) was several times dearer than a fixed
step at the same error after 60 s, for two reasons.  Near the separatrix (the T-handle, the
tennis racket, van Zon's body) an error made next to the unstable axis, where Buss's local
error all but vanishes, is amplified most: it shifts every later flip.  And a geometric
integrator's errors stay small over long runs at a constant step, while a varying one lets
them drift (the heavy top, whose local error varies several-fold over each nutation: more
error than a fixed step at the same mean count).  So the count is held at what the worst
point of the motion needs, and changed seldom:

- torque-free (no torque, no dissipation: :func:`set_torque_free`), the error constant
  C = r / h^q is also estimated at the turning points of the body's polhode
  (:func:`turning_points`, virtual states stepped like the real one, every ORBIT_EVERY
  estimates), so that from the first tick the count covers the whole orbit, the flips
  included, not just where the body is.  Under a torque or a flow the polhode is not the
  body's future, and only the body's own estimates count (measured on flat_spin: its
  polhode widens as it dissipates, and the turning points asked for substeps that
  bought nothing, the error being made before the separatrix crossing);
- the decision uses the largest C seen, decaying with the time constant HOLD (simulated s):
  C_held = max(C, C_held exp(-dt / HOLD)), and the count n* = T (C_held / (SAFETY tol))^(1/q)
  that makes r = SAFETY x tolerance at it.

The decision (:func:`next_substeps`):

- r > tolerance (at the body or a turning point): n jumps at once to max(n + 1, ceil(n*))
  and the tick is taken again from its start (rejected);
- ceil(n*) <= DECREASE_FRACTION x n: n goes down to ceil(n*);
- otherwise n stays.  After any change r <= SAFETY x tolerance, a factor 2 below the
  threshold of the next increase: n cannot alternate tick to tick on a smooth trajectory.

Amortised: an estimate is made every few ticks, so that its work (its extra steps and
ESTIMATE_WORK) costs at most OVERHEAD of the substeps taken (one in 64 ticks at n = 1, one
in 16 at n = 3, every tick from n = 48), at least once per MAX_TURN rad the body turns, and
at once after anything changes (the wrench, the state, the integrator, the tolerance or the
lower bound: :func:`changed`).  The ticks between two estimates are one call of the run.

The state of the controller lives in one float array (see :func:`new_control`), which the
compiled kernel updates in place.  :data:`controlled` is that kernel: compiled once, it takes
any integrator's run kernel as a first-class function (kernels/loop.py's RUN_SIGNATURE), so
that no integrator compiles a controller of its own.  The run reaches it inside a
:class:`Controller` (a compiled structure holding it), built once per integrator by
:func:`new_controller`: numba unboxes a compiled function passed from Python as an argument
on every call (typing it, then resolving its address), a cost many times that of the tick's
physics, where a structure that holds it is unboxed by reading one pointer
(benchmarks/controlled_call_cost.py measures both).
"""

from __future__ import annotations

import collections
import math
from typing import Any
from typing import Callable

from numba import types
from numba.experimental import structref
import numpy as np
import numpy.typing as npt

from .kernels import helper
from .kernels import LazyKernel
from .kernels.algebra import conjugate
from .kernels.algebra import quaternion_product
from .kernels.algebra import rotate_back
from .kernels.interpreted import stand_in
from .kernels.layout import BODY_AXES
from .kernels.layout import BODY_KIND
from .kernels.layout import BODY_MOMENTS
from .kernels.layout import inverse_inertia_times
from .kernels.layout import STATE_SIZE
from .kernels.loop import METHOD_TYPE
from .kernels.loop import RUN_SIGNATURE
from .kernels.model import Array
from .kernels.model import Model
from .kernels.model import MODEL_TYPE

__all__ = ['new_control', 'controlled_ticks', 'controlled', 'CONTROLLED_SIGNATURE',
           'Controller', 'CONTROLLER_TYPE', 'new_controller', 'controller_of',
           'CONTROLLER_KERNELS',
           'next_substeps', 'step_difference',
           'set_tolerance', 'set_order', 'set_bounds', 'set_torque_free', 'changed', 'statistics',
           'reset_statistics', 'turning_points',
           'SAFETY', 'HOLD', 'DECREASE_FRACTION', 'OVERHEAD', 'MAX_TURN', 'MAX_SUBSTEPS',
           'ORBIT_EVERY', 'ESTIMATE_WORK']

# Slots of the control array.
(TOLERANCE, ORDER, MIN_SUBSTEPS, CAP, SUBSTEPS, COUNTDOWN, HELD, SINCE, RATE,
 LAST, LOWEST, HIGHEST, STEPS, TICKS, ESTIMATES, REJECTED, HIGHEST_RATE, ORBIT_CONSTANT,
 ORBIT_COUNTDOWN, TORQUE_FREE, TAKEN, CONTROL_SIZE) = range(22)

SAFETY = 0.5
"""The fraction of the tolerance a new substep count aims at (the dead band's width)."""
HOLD = 10.0
"""Time constant (simulated s) of the decay of the largest error constant seen."""
DECREASE_FRACTION = 0.75
"""n goes down only to at most this fraction of itself: few, large changes."""
OVERHEAD = 1.0 / 16.0
"""Most of the substeps' cost spent on estimates (one extra step per estimate, two at n=1)."""
ESTIMATE_WORK = 2.0
"""An estimate's work besides its extra steps, in steps: its two more calls of the
integrator's run (each about what a compiled Buss step costs), the difference and
the decision.  Counted with the extra steps against OVERHEAD."""
MAX_TURN = 1.0
"""Longest turn of the body (rad) between two estimates: the error rate follows the state."""
MAX_SUBSTEPS = 100_000
"""Most substeps per tick: below the round-off floor a tolerance cannot be met."""
ORBIT_EVERY = 64
"""Estimates between two estimates on the polhode's turning points (and after any change
or a new substep count).  Torque-free, the polhode and so its error constant are fixed: the
estimate is renewed only because it is taken at the step in use."""
# Step counts passed to the run kernel as int64 values, not literals: numba compiles a
# kernel once per literal argument it is called with (a run for 1, one for 2, one for any n),
# which tripled the run kernel's compile time.
_ONE = np.int64(1)
_TWO = np.int64(2)
# Retakes of one tick after a rejection (the second has the count the first one measured).
_RETAKES = 2


def new_control(order: int, substeps: int = 1,
                tolerance: float = 0.0) -> npt.NDArray[np.float64]:
    """
    Return a new control array for a method of order `order` (see the module docstring).

    tolerance in rad/s (0: no control, fixed `substeps`); substeps: the lower bound n_min.
    """
    control = np.zeros(CONTROL_SIZE)
    control[TOLERANCE] = tolerance
    control[ORDER] = order
    control[MIN_SUBSTEPS] = control[SUBSTEPS] = substeps
    control[CAP] = max(MAX_SUBSTEPS, substeps)
    control[RATE] = np.nan
    reset_statistics(control)
    return control


def changed(control: npt.NDArray[np.float64], forget: bool = False) -> None:
    """
    Say that something changed: estimate at the next tick, the turning points too.

    forget=True also drops the held error constant: after a new state (a reset) or
    integrator the motion's history says nothing; a new wrench keeps it.
    """
    control[COUNTDOWN] = control[ORBIT_COUNTDOWN] = 0.0
    if forget:
        control[HELD] = 0.0


def set_torque_free(control: npt.NDArray[np.float64], torque_free: bool) -> None:
    """Say whether the motion is torque-free (the turning points are then estimated too)."""
    control[TORQUE_FREE] = 1.0 if torque_free else 0.0
    control[ORBIT_CONSTANT] = 0.0
    control[ORBIT_COUNTDOWN] = 0.0


def set_tolerance(control: npt.NDArray[np.float64], tolerance: float) -> None:
    """Set the tolerance (rad/s, > 0) and estimate at the next tick."""
    control[TOLERANCE] = tolerance
    changed(control)


def set_order(control: npt.NDArray[np.float64], order: int) -> None:
    """Set the order of the method now in use and estimate at the next tick."""
    control[ORDER] = order
    changed(control, forget=True)


def set_bounds(control: npt.NDArray[np.float64], substeps: int) -> None:
    """Set the lower bound n_min (int >= 1); n is raised to it at once."""
    control[MIN_SUBSTEPS] = substeps
    control[CAP] = max(MAX_SUBSTEPS, substeps)
    control[SUBSTEPS] = max(control[SUBSTEPS], substeps)
    changed(control)


def reset_statistics(control: npt.NDArray[np.float64]) -> None:
    """Start a new statistics period (substeps min/max, steps, ticks, estimates)."""
    control[LOWEST] = np.inf
    control[HIGHEST] = 0.0
    control[STEPS] = control[TICKS] = control[ESTIMATES] = control[REJECTED] = 0.0
    control[TAKEN] = 0.0
    control[HIGHEST_RATE] = np.nan


def statistics(control: npt.NDArray[np.float64]) -> dict[str, Any]:
    """
    Return the controller's figures as a dict.

    substeps: n of the last tick; substeps_min / substeps_max / substeps_mean: over the
    period (since reset_statistics); error_rate: the last estimate (rad/s, nan before the first);
    error_rate_max: the largest accepted estimate of the period; steps: integrator steps
    taken in the period, estimates and retaken ticks included; ticks, estimates, rejected.
    """
    ticks = int(control[TICKS])
    return {
        'substeps': int(control[LAST]) if ticks else int(control[SUBSTEPS]),
        'substeps_min': int(control[LOWEST]) if ticks else int(control[SUBSTEPS]),
        'substeps_max': int(control[HIGHEST]) if ticks else int(control[SUBSTEPS]),
        'substeps_mean': control[TAKEN] / ticks if ticks else float(control[SUBSTEPS]),
        'error_rate': float(control[RATE]),
        'error_rate_max': float(control[HIGHEST_RATE]),
        'steps': int(control[STEPS]),
        'ticks': ticks,
        'estimates': int(control[ESTIMATES]),
        'rejected': int(control[REJECTED]),
    }


@helper
def step_difference(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64],
                    body: npt.NDArray[np.float64], h: float) -> float:
    """
    Return the difference (rad) of two packed states after the same span, h s a step.

    The rotation angle between their orientations, 2 atan2(|vec(a^* b)|, |a^* b|_w), exact
    for tiny angles (the vector part is formed from products, not from a difference of
    near-equal angles), plus h |I_b^-1 R_a^T (L_a - L_b)|: the turn a momentum discrepancy
    makes within one step (body: the packed body of kernels/layout.py).
    """
    qa = (a[0], a[1], a[2], a[3])
    vx, vy, vz, w = quaternion_product(conjugate(qa), (b[0], b[1], b[2], b[3]))
    angle = 2.0 * math.atan2(math.sqrt(vx * vx + vy * vy + vz * vz), abs(w))
    dx, dy, dz = a[10] - b[10], a[11] - b[11], a[12] - b[12]
    if dx == 0.0 and dy == 0.0 and dz == 0.0:
        return angle
    # R_a^T dL, then I_b^-1 of it.
    ox, oy, oz = inverse_inertia_times(body, rotate_back(qa, (dx, dy, dz)))
    return angle + h * math.sqrt(ox * ox + oy * oy + oz * oz)


@helper
def next_substeps(control: npt.NDArray[np.float64], substeps: int, rate: float, constant: float,
                  tick: float) -> int:
    """
    Return the substep count after an estimate at `substeps` substeps of a `tick` s tick.

    rate: the largest error rate estimated (rad/s, at the body or a turning point);
    constant: its error constant r / h^q.  Updates the held constant (HOLD) in `control`
    and applies the decision of the module docstring.  A rate that is not a number (a
    diverged state) keeps the count.
    """
    if not rate >= 0.0:
        return substeps
    tolerance, order = control[TOLERANCE], control[ORDER]
    lowest, cap = control[MIN_SUBSTEPS], control[CAP]
    held = max(constant, control[HELD] * math.exp(-control[SINCE] / HOLD))
    control[HELD] = held
    control[SINCE] = 0.0
    # r = C h^q: the count that brings r to SAFETY x tolerance (capped before ceil: it may
    # be huge).
    ideal = min(tick * (held / (SAFETY * tolerance)) ** (1.0 / order), cap)
    best = int(max(lowest, math.ceil(ideal)))
    if rate > tolerance:
        return int(min(cap, max(best, substeps + 1)))
    if best <= DECREASE_FRACTION * substeps:
        return best
    return substeps


@helper
def turning_points(state: npt.NDArray[np.float64],
                   body: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.float64], int]:
    """
    Return the body momenta (kg m^2/s, body frame) at the turning points of the polhode.

    Torque-free, m = R^T L keeps |m| = |L| and m . I_b^-1 m = 2T; in principal coordinates
    its curve (the polhode) crosses the principal plane m_k = 0 where, with i, j the other
    two axes, m_i^2 + m_j^2 = L^2 and m_i^2 / I_i + m_j^2 / I_j = 2T:

        m_i^2 = (2T - L^2 / I_j) / (1 / I_i - 1 / I_j),   m_j^2 = L^2 - m_i^2,

    a turning point where both are >= 0 (an orbit about an extreme axis crosses two of the
    three planes: on the T-handle's, next to the unstable axis and half-way through a
    flip).  Returns (points (3, 3), count); none for a body at rest or with two equal
    moments (its polhode is a circle, every point alike).
    """
    points = np.zeros((3, 3))
    if state[10] == 0.0 and state[11] == 0.0 and state[12] == 0.0:
        return points, 0
    if body[BODY_KIND] != 0.0:
        return points, 0
    momentum = rotate_back((state[0], state[1], state[2], state[3]),
                           (state[10], state[11], state[12]))
    moments = body[BODY_MOMENTS:BODY_MOMENTS + 3]
    axes = body[BODY_AXES:BODY_AXES + 9].reshape((3, 3))
    principal = np.empty(3)
    for k in range(3):
        principal[k] = axes[0, k] * momentum[0] + axes[1, k] * momentum[1] \
            + axes[2, k] * momentum[2]
    square = principal[0] ** 2 + principal[1] ** 2 + principal[2] ** 2
    twice_energy = (principal[0] ** 2 / moments[0] + principal[1] ** 2 / moments[1]
                    + principal[2] ** 2 / moments[2])
    count = 0
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        first = (twice_energy - square / moments[j]) / (1.0 / moments[i] - 1.0 / moments[j])
        second = square - first
        if first < 0.0 or second < 0.0:
            continue
        point = np.zeros(3)
        point[i], point[j] = math.sqrt(first), math.sqrt(second)
        for r in range(3):
            points[count, r] = axes[r, 0] * point[0] + axes[r, 1] * point[1] \
                + axes[r, 2] * point[2]
        count += 1
    return points, count


@helper
def _turn_rate(state: Array, body: Array) -> float:
    """Return |Omega| (rad/s) of a packed state: |I_b^-1 R^T L|."""
    ox, oy, oz = inverse_inertia_times(body, rotate_back(
        (state[0], state[1], state[2], state[3]), (state[10], state[11], state[12])))
    return math.sqrt(ox * ox + oy * oy + oz * oz)


@helper
def _ticks_between_estimates(substeps: int, tick: float, turn_rate: float) -> float:
    """Return the ticks to take without an estimate after one (see OVERHEAD, MAX_TURN)."""
    extra = (1.0 if substeps >= 2 else 2.0) + ESTIMATE_WORK
    by_cost = math.ceil(extra / (OVERHEAD * substeps)) - 1.0
    turn = tick * turn_rate
    by_turn = math.floor(MAX_TURN / turn) - 1.0 if turn > 0.0 else by_cost
    return max(0.0, min(by_cost, by_turn))


@helper
def _record(control: Array, substeps: int, steps: int, ticks: int = 1) -> None:
    """Note `ticks` ticks of `substeps` substeps each that took `steps` integrator steps."""
    control[LAST] = substeps
    control[LOWEST] = min(control[LOWEST], substeps)
    control[HIGHEST] = max(control[HIGHEST], substeps)
    control[STEPS] += steps
    control[TAKEN] += substeps * ticks
    control[TICKS] += ticks


@structref.register
class ControllerType(types.StructRef):
    """numba's type of a :class:`Controller`."""

    def preprocess_fields(self, fields: Any) -> tuple[Any, ...]:
        """Drop literal types: every Controller has the one type."""
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class Controller(structref.StructRefProxy):
    """
    What the compiled controller drives: an integrator's run kernel, held compiled.

    Build one with :func:`new_controller`, once per integrator (numba resolved the run
    kernel's address then), and pass it to :data:`controlled` at every call.  Field ``run``:
    the run kernel, a first-class function of kernels/loop.py's RUN_SIGNATURE.
    """

    run: Callable[..., int]


_RUN_FUNCTION = types.FunctionType(RUN_SIGNATURE)
structref.define_proxy(Controller, ControllerType, ['run'])
# The kernels run as Python (kernels/interpreted.py) see a Controller as a named tuple.
stand_in(Controller, collections.namedtuple('InterpretedController', ['run']))
CONTROLLER_TYPE = ControllerType([('run', _RUN_FUNCTION)])
"""numba's type of every Controller: one type, so the controller compiles once."""


def _controller_of(run: Callable[..., int]) -> Controller:
    return Controller(run)


controller_of = LazyKernel(CONTROLLER_TYPE(_RUN_FUNCTION), _controller_of, compile_seconds=0.1)
"""The compiled constructor of a :class:`Controller` from a compiled run kernel (compiled
with :data:`controlled`, in the same compile job)."""


def new_controller(run_kernel: LazyKernel, interpreted: bool = False) -> Controller:
    """
    Return the :class:`Controller` of an integrator's run kernel (its ``run_kernel``).

    Compiled: the run kernel compiled (or loaded from the cache) and held; interpreted
    (kernels/interpreted.py): its source, in the controller's stand-in (a named tuple), made
    without compiling anything.
    """
    if interpreted:
        return controller_of.source(run_kernel.source)
    return controller_of.dispatcher(run_kernel.dispatcher)


def controlled_ticks(controller: Controller, state: npt.NDArray[np.float64], model: Model,
                     method: tuple[float, ...], tick: float, ticks: int, time: float,
                     control: npt.NDArray[np.float64]) -> int:
    """
    Advance a packed state in place by `ticks` ticks of `tick` s from `time` (s), controlled.

    controller: the :class:`Controller` of an integrator, whose run kernel
    (kernels/loop.py's RUN_SIGNATURE) takes the steps; model (a kernels.model.Model) and
    method (its constants) are passed on to it.  control: the control array (updated: n,
    the countdown, the votes, the statistics).  Returns the integrator steps taken, or -1 if
    the state it leaves holds a value that is not finite.
    Compiled as :data:`controlled`, where the run is a first-class function (an indirect
    call a few times a tick); interpreted (kernels/interpreted.py), it drives the run
    kernels' source.
    """
    run = controller.run
    order = control[ORDER]
    taken = 0
    start = state.copy()
    companion = state.copy()
    virtual = state.copy()
    done = 0
    while done < ticks:
        n = int(max(control[SUBSTEPS], control[MIN_SUBSTEPS]))
        now = time + done * tick
        if control[COUNTDOWN] > 0.0:
            # The ticks up to the next estimate are steps of one h in a row: one call takes
            # them (a call per tick cost more than the step itself at a few substeps).
            merged = int(min(control[COUNTDOWN], ticks - done))
            control[COUNTDOWN] -= merged
            run(state, model, method, tick / n, n * merged, now)
            taken += n * merged
            control[SINCE] += tick * merged
            _record(control, n, n * merged, merged)
            done += merged
            continue
        done += 1
        start[:] = state
        steps = 0
        if control[TORQUE_FREE] != 0.0 and control[ORBIT_COUNTDOWN] <= 0.0:
            # The largest error constant r / h^q at the polhode's turning points, each a
            # virtual torque-free state (identity orientation, L = m there) stepped as a
            # pair of h and a companion of 2 h like the real state.
            points, count = turning_points(state, model.body)
            h = tick / n
            largest = 0.0
            for index in range(count):
                virtual[:] = 0.0
                virtual[3] = 1.0
                virtual[10:13] = points[index]
                companion[:] = virtual
                run(virtual, model, method, h, _TWO, now)
                run(companion, model, method, 2.0 * h, _ONE, now)
                error = step_difference(virtual, companion, model.body, h) / (
                    2.0 ** (order + 1) - 2.0)
                largest = max(largest, error / h)
            control[ORBIT_CONSTANT] = largest / h ** order
            steps += 3 * count
            control[ORBIT_COUNTDOWN] = ORBIT_EVERY
        control[ORBIT_COUNTDOWN] -= 1.0
        for attempt in range(_RETAKES + 1):
            h = tick / n
            if n >= 2:
                # The last two substeps are the pair, one step of 2h from before them the
                # companion: e(h) = |difference| / (2^(q+1) - 2).
                run(state, model, method, h, n - 2, now)
                companion[:] = state
                middle = now + (n - 2) * h
                run(state, model, method, h, _TWO, middle)
                run(companion, model, method, 2.0 * h, _ONE, middle)
                error = step_difference(state, companion, model.body, h) / (
                    2.0 ** (order + 1) - 2.0)
                steps += n + 1
            else:
                # One substep: the companion is two half steps, e(h) = |diff| / (1 - 2^-q).
                companion[:] = state
                run(state, model, method, h, _ONE, now)
                run(companion, model, method, 0.5 * h, _TWO, now)
                error = step_difference(state, companion, model.body, h) / (
                    1.0 - 2.0 ** -order)
                steps += 3
            rate = error / h
            # The count must also hold the polhode's worst point (see the module docstring).
            constant = max(rate / h ** order, control[ORBIT_CONSTANT])
            following = next_substeps(control, n, constant * h ** order, constant, tick)
            if following > n and attempt < _RETAKES:
                # Above the tolerance: take the tick again from its start.
                control[REJECTED] += 1.0
                state[:] = start
                n = following
                continue
            break
        control[ESTIMATES] += 1.0
        control[SINCE] = tick
        control[RATE] = rate
        if not control[HIGHEST_RATE] >= rate:
            control[HIGHEST_RATE] = rate
        _record(control, n, steps)
        taken += steps
        if following != n:
            # The turning points' constant was taken at the old step: take it anew.
            control[ORBIT_COUNTDOWN] = 0.0
        control[SUBSTEPS] = following
        control[COUNTDOWN] = _ticks_between_estimates(following, tick,
                                                      _turn_rate(state, model.body))
    # Tested here, compiled, at next to no cost, rather than by the Simulator in Python (as
    # the run kernels do: kernels/loop.py).
    for i in range(STATE_SIZE):
        if not math.isfinite(state[i]):
            return -1
    return taken


CONTROLLED_SIGNATURE = types.int64(CONTROLLER_TYPE, types.float64[::1], MODEL_TYPE,
                                   METHOD_TYPE, types.float64, types.int64, types.float64,
                                   types.float64[::1])
controlled = LazyKernel(CONTROLLED_SIGNATURE, controlled_ticks, compile_seconds=5.5)
"""The compiled controller: ``controlled(controller, state, model, method, tick, ticks, time,
control)``, one kernel for every integrator (see :func:`controlled_ticks`); 5.5 CPU s to
compile on the 2-core development machine (`rigid-body-sim compile` prints the figure)."""

CONTROLLER_KERNELS = (controlled, controller_of)
"""The kernels of the ``controller`` compile job (physics/warm_up.py)."""
