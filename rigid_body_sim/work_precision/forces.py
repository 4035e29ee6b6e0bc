"""
What accuracy costs when forces act: the work-precision benchmark on forced bodies.

Five cases, each a scene (body, initial state, effects) plus an optional held wrench:

- ``heavy_top``: the built-in scene, a symmetric top on a pivot under gravity (150 rad/s);
- ``bike_wheel``: the built-in scene, a wheel spinning at 40 rad/s held at one end of its
  axle, precessing under gravity;
- ``offaxis_pivot``: a body whose inertia tensor is not diagonal in its frame, on a pivot off
  every principal axis, under gravity, started tumbling;
- ``van_zon_sinusoid``: van Zon's body (I = 10, 20, 26; Omega0 = 1, 15, 1) under a world-frame
  torque oscillating at 0.4 Hz (the ``sinusoidal_torque`` effect);
- ``body_torque``: a box under a constant torque fixed in the body (held, frame 'body').

For each case, method and step dt: the orientation error (rotation angle, rad) at the
horizon against an independent reference, and the CPU time per simulated second (median of
fresh timed runs, :data:`.cells.CPU_CLOCK`).  The sweep is a :class:`.cells.Plan`
(:func:`forces_plan`: per case the reference and its check, then a cell per run) that any
process can run; :func:`run_forces` runs it here.  Methods: every registered integrator at fixed
steps, ``buss`` under error control at a range of tolerances (its tick 1/rate of the scene),
and MuJoCo's Euler, RK4 and implicitfast.

Reference: the equations of motion solved by scipy's DOP853 at rtol 1e-13 with a relative
error test, independent of every integrator scored: Euler's equations for the body-frame
angular momentum m with the quaternion, about the COM for a free body (forces do not turn
it), about the pivot with the parallel-axis inertia and the moment of the forces about it
on a pivot.  Its uncertainty is not a tolerance gap (a tolerance says how much error a solver
admits per step, not how much the flow then grows it) but the largest angle, over the
run's times, between it and a second solution of another formulation: the orientation as
a rotation matrix, dR/dt = R [Omega]x (:func:`forced_reference_check`).  Error levels below
it are not judged.

The MuJoCo twin is built from the scene, not by hand per case: a free joint (or, with a
pivot, a ball joint at the anchor with the COM offset in `inertial pos`), the inertia tensor
(`fullinertia`), the scene's gravity; a body-fixed torque as the generalised force of the
joint's rotational dofs (`qfrc_applied`, which are body-frame: constant, set once); every
other effect (a time-varying world torque, or any effect added later) through
`xfrc_applied`, its wrench taken each step at the step's mid time in a Python loop, as a user
of MuJoCo's Python API would (MuJoCo has no time-dependent applied force; its RK4 then sees
the midpoint value in all four stages).  The reference takes the scene's wrench the same
generic way (Simulator.wrench_function): no effect is named in this module.
"""

from dataclasses import asdict
from dataclasses import dataclass
import functools
import math

import numpy as np

from .cells import Plan
from .cells import run_in_process
from .measure import _timing as measured_timing
from .peer_mujoco import mujoco_available
from .peer_mujoco import MUJOCO_INTEGRATORS
from .reference import rotation_angle
from ..physics import INTEGRATORS
from ..physics import matrix_from_quaternion
from ..physics import quaternion_from_matrix
from ..physics import State
from ..physics.kernels.algebra import rotate
from ..physics.simulator import DivergedError
from ..scenes import load_scene
from ..scenes import parse_scene

# Effects MuJoCo's twin models itself (see forced_mjcf); the rest it applies each step.
_NATIVE_TO_MUJOCO = ('gravity', 'pivot', 'external_wrench')

__all__ = ['FORCED_CASE_NAMES', 'ForcedCase', 'forced_cases', 'forced_reference',
           'forced_reference_check',
           'ForcesConfig', 'FORCES_FULL', 'FORCES_QUICK', 'run_forces', 'forces_plan',
           'measure_forced_run', 'reference_of', 'forces_goal_table', 'forces_units']

FORCED_CASE_NAMES = ('heavy_top', 'bike_wheel', 'offaxis_pivot', 'van_zon_sinusoid',
                     'body_torque')
REFERENCE_RTOL = 1e-13
# atol of the reference solves as a fraction of rtol times the initial state's largest
# component (see _solve).
_ATOL_FRACTION = 1e-5
REFERENCE_FORMULATION = 'quaternion and body-frame angular momentum'
CHECK_FORMULATION = 'rotation matrix and body-frame angular momentum'
LEVELS = tuple(10.0 ** -k for k in range(2, 11))

_OFFAXIS = {
    'name': 'offaxis_pivot', 'description': 'non-diagonal body on a pivot off its axes',
    'body': {'mass': 1.5, 'inertia': [[0.020, 0.003, -0.002], [0.003, 0.030, 0.004],
                                      [-0.002, 0.004, 0.040]]},
    'initial': {'orientation': [0.2, -0.1, 0.3, 0.92736184954957],
                'angular_velocity_body': [3.0, -2.0, 12.0]},
    'effects': [{'pivot': {'point': [0.05, -0.03, 0.08]}}, 'gravity']}
_VAN_ZON = {
    'name': 'van_zon_sinusoid', 'description': "van Zon's body under an oscillating torque",
    'body': {'mass': 1.0, 'inertia': [10.0, 20.0, 26.0]},
    'initial': {'angular_velocity_body': [1.0, 15.0, 1.0]},
    'effects': [{'sinusoidal_torque': {'amplitude': [3.0, -2.0, 4.0], 'frequency': 0.4}}]}
_BODY_TORQUE = {
    'name': 'body_torque', 'description': 'box under a torque fixed in the body',
    'body': {'mass': 2.0, 'shape': 'box', 'size': [0.4, 0.25, 0.1]},
    'initial': {'angular_velocity_body': [0.5, 1.0, 2.0]}}


@dataclass(frozen=True)
class ForcedCase:
    """A scene, an optional held body-frame torque (N m) and the steps it is run at."""

    name: str
    scene: object
    held_torque_body: tuple
    dts: tuple

    @property
    def description(self):
        """Return the scene's one-line description."""
        return self.scene.description


def forced_cases(names=FORCED_CASE_NAMES):
    """Return the ForcedCase of each name."""
    built = {
        'heavy_top': lambda: ForcedCase('heavy_top', load_scene('heavy_top'), None,
                                        (3e-3, 1e-3, 3e-4, 1e-4, 3e-5)),
        'bike_wheel': lambda: ForcedCase('bike_wheel', load_scene('bike_wheel'), None,
                                         (1e-2, 3e-3, 1e-3, 3e-4, 1e-4)),
        'offaxis_pivot': lambda: ForcedCase('offaxis_pivot', parse_scene(_OFFAXIS, 'forces'),
                                            None, (1e-2, 3e-3, 1e-3, 3e-4, 1e-4)),
        'van_zon_sinusoid': lambda: ForcedCase(
            'van_zon_sinusoid', parse_scene(_VAN_ZON, 'forces'), None,
            (3e-2, 1e-2, 3e-3, 1e-3, 3e-4)),
        'body_torque': lambda: ForcedCase('body_torque', parse_scene(_BODY_TORQUE, 'forces'),
                                          (0.05, -0.02, 0.1), (3e-2, 1e-2, 3e-3, 1e-3, 3e-4)),
    }
    unknown = sorted(set(names) - set(built))
    if unknown:
        raise ValueError(f'unknown forced case(s) {", ".join(unknown)}; valid: '
                         f'{", ".join(FORCED_CASE_NAMES)}')
    return [built[name]() for name in names]


# -- the reference


def _case_simulator(case):
    """Return the case's Simulator with its held torque (its effects and wrench in one)."""
    simulator = case.scene.simulator()
    if case.held_torque_body is not None:
        simulator.set_wrench(torque=case.held_torque_body, frame='body')
    return simulator


def _torque_function(case):
    """
    Return torque(q, L, t) in N m, world: about the pivot for a pivot scene, else the COM.

    The scene's own wrench (its effects' Python faces and the held torque,
    Simulator.wrench_function) at the physical state of (q, L), its moment about the pivot
    added under one: no effect is named here, so a new one is in the reference as it is.
    """
    simulator = _case_simulator(case)
    wrench = simulator.wrench_function()
    scene = case.scene
    pivot = scene.pivot
    constraint = None if pivot is None else pivot.constrain(scene.body)
    anchor = np.zeros(3) if pivot is None else np.asarray(pivot.anchor, dtype=float)

    def torque(quaternion, angular_momentum, time):
        if wrench is None:
            return np.zeros(3)
        integrated = State._from_arrays(np.asarray(quaternion, dtype=float), anchor,
                                        np.zeros(3), np.asarray(angular_momentum, dtype=float))
        if constraint is None:
            return wrench(integrated, time)[1]
        force, moment = wrench(constraint.expand(integrated), time)
        return moment + np.cross(integrated.rotation @ constraint.offset_body, force)
    return torque


def _reference_problem(case):
    """
    Return (inertia, initial world L, torque function) of the equations both references solve.

    For a free body: the inertia tensor about the COM and L about it (a force does not turn
    a free body); on a pivot: the parallel-axis inertia about the pivot, L about it (L_com +
    r x p) and the moment of the forces about it (:func:`_torque_function`).  kg m^2, kg m^2/s,
    body and world frames.
    """
    scene = case.scene
    body, state = scene.body, scene.state
    inertia = np.array(body.inertia)
    momentum = np.array(state.angular_momentum)
    pivot = scene.pivot
    if pivot is not None:
        offset = -np.asarray(pivot.point, dtype=float)
        inertia = inertia + body.mass * (offset @ offset * np.eye(3) - np.outer(offset, offset))
        r = state.rotation @ offset
        momentum = momentum + np.cross(r, state.linear_momentum)
    return inertia, momentum, _torque_function(case)


def _solve(derivative, y0, times, rtol, name):
    """Return DOP853's solution of y' = derivative(t, y) at `times` (s), rtol `rtol`."""
    from scipy.integrate import solve_ivp

    # A relative error test (atol far below rtol times any component's size): an absolute
    # tolerance at the state's largest scale (|L|) admits, in the quaternion's components,
    # errors many times rtol, which the flips of a tumbling body amplify.
    solution = solve_ivp(derivative, (0.0, max(times)), y0, method='DOP853', rtol=rtol,
                         atol=_ATOL_FRACTION * rtol * np.abs(y0).max(),
                         t_eval=sorted(set(times)))
    if not solution.success:
        raise RuntimeError(f'{name}: the reference solve failed: {solution.message}')
    return solution


def forced_reference(case, times, rtol=REFERENCE_RTOL):
    """
    Return the reference rotation matrices at `times` (s): quaternion and body-frame m.

    y = (q (x, y, z, w), m = R^T L): dq/dt = 1/2 q (Omega, 0), Omega = I^-1 m,
    dm/dt = m x Omega + R^T tau(R, t) (Euler's equations with the torque taken into the body
    frame); about the pivot (I the parallel-axis inertia, L = L_com + r x p) in a pivot
    scene.  Solved by scipy's DOP853 at `rtol`: independent of the integrators.

    The body frame, not the world frame: Euler's equations keep the spin about a symmetric
    body's axis in one component of m, which no torque about the pivot changes, where the
    world L carries it in all three components with errors that turn into a drift of the
    spin's phase (at the same rtol the world-L form was far off: docs/benchmark.md).
    """
    inertia, momentum, torque = _reference_problem(case)
    inverse = np.linalg.inv(inertia)

    def derivative(time, y):
        q = y[:4] / np.linalg.norm(y[:4])
        m = y[4:]
        omega = inverse @ m
        x, yq, z, w = q
        ox, oy, oz = omega
        # q (Omega, 0), the Hamilton product in (x, y, z, w) storage.
        dq = 0.5 * np.array([w * ox + yq * oz - z * oy, w * oy + z * ox - x * oz,
                             w * oz + x * oy - yq * ox, -x * ox - yq * oy - z * oz])
        rotation = matrix_from_quaternion(q)
        body_torque = rotation.T @ torque(q, rotation @ m, time)
        return np.concatenate([dq, np.cross(m, omega) + body_torque])

    state = case.scene.state
    y0 = np.concatenate([state.quaternion, state.rotation.T @ momentum])
    solution = _solve(derivative, y0, times, rtol, case.name)
    return {float(t): matrix_from_quaternion(y[:4] / np.linalg.norm(y[:4]))
            for t, y in zip(solution.t, solution.y.T)}


def _nearest_rotation(matrix):
    """Return the rotation nearest a nearly orthonormal matrix (one Newton step of polar)."""
    return 0.5 * matrix @ (3.0 * np.eye(3) - matrix.T @ matrix)


def forced_reference_check(case, times, rtol=REFERENCE_RTOL):
    """
    Return the check rotation matrices at `times` (s): rotation matrix and body-frame m.

    The second formulation of the problem of :func:`forced_reference`, the orientation as a
    rotation matrix instead of a quaternion: y = (R (9 entries, body to world), m = R^T L),
    dR/dt = R [Omega]x, Omega = I^-1 m, dm/dt = m x Omega + R^T tau, the torque taken at the
    rotation nearest R; solved by DOP853 at `rtol`.  Another state, another kinematic
    equation, other steps: the angle between the two solutions is the reference's
    uncertainty.
    """
    inertia, momentum, torque = _reference_problem(case)
    inverse = np.linalg.inv(inertia)

    def derivative(time, y):
        rotation = y[:9].reshape(3, 3)
        m = y[9:]
        omega = inverse @ m
        ox, oy, oz = omega
        skew = np.array([[0.0, -oz, oy], [oz, 0.0, -ox], [-oy, ox, 0.0]])
        unit = _nearest_rotation(rotation)
        world_torque = torque(quaternion_from_matrix(unit), unit @ m, time)
        return np.concatenate([(rotation @ skew).ravel(),
                               np.cross(m, omega) + unit.T @ world_torque])

    rotation = case.scene.state.rotation
    y0 = np.concatenate([rotation.ravel(), rotation.T @ momentum])
    solution = _solve(derivative, y0, times, rtol, case.name)
    return {float(t): _nearest_rotation(y[:9].reshape(3, 3))
            for t, y in zip(solution.t, solution.y.T)}


# -- our runs and MuJoCo's


class _Ours:
    family = 'ours'

    def __init__(self, case, integrator, dt, tolerance=None):
        self.case, self.integrator, self.dt, self.tolerance = case, integrator, dt, tolerance
        self.reset()

    def reset(self):
        simulator = self.case.scene.simulator(integrator=self.integrator,
                                              tolerance=self.tolerance or 0.0)
        simulator.substeps = 1
        if self.case.held_torque_body is not None:
            simulator.set_wrench(torque=self.case.held_torque_body, frame='body')
        self.simulator = simulator
        self.blew_up = False

    def advance(self, steps):
        # A divergence at a long step is a result (no error level reached), not a failure.
        if not self.blew_up:
            try:
                self.simulator.run(steps * self.dt, self.dt)
            except (DivergedError, ValueError):
                self.blew_up = True

    def rotation(self):
        return None if self.blew_up else self.simulator.state.rotation


def forced_mjcf(case, integrator, dt):
    """Return the MJCF text of the case's scene with MuJoCo's `integrator` at step dt."""
    scene = case.scene
    body = scene.body
    inertia = np.asarray(body.inertia)
    number = repr
    full = (f'fullinertia="{number(float(inertia[0, 0]))} {number(float(inertia[1, 1]))} '
            f'{number(float(inertia[2, 2]))} {number(float(inertia[0, 1]))} '
            f'{number(float(inertia[0, 2]))} {number(float(inertia[1, 2]))}"')
    gravity = ' '.join(number(float(g)) for g in scene.gravity)
    pivot = scene.pivot
    if pivot is None:
        joint, position, com = '<freejoint name="joint"/>', '0 0 0', '0 0 0'
    else:
        joint = '<joint name="joint" type="ball" pos="0 0 0"/>'
        position = ' '.join(number(float(a)) for a in pivot.anchor)
        com = ' '.join(number(-float(p)) for p in pivot.point)
    return f"""<mujoco model="rigid_body_sim_forces">
  <option timestep="{number(float(dt))}" integrator="{integrator}" gravity="{gravity}">
    <flag contact="disable" constraint="disable"/>
  </option>
  <worldbody>
    <body name="body" pos="{position}">
      {joint}
      <inertial pos="{com}" mass="{number(float(body.mass))}" {full}/>
    </body>
  </worldbody>
</mujoco>
"""


class _Mujoco:
    family = 'mujoco'

    def __init__(self, case, integrator, dt):
        import mujoco
        self.mujoco = mujoco
        self.case, self.dt = case, dt
        self.model = mujoco.MjModel.from_xml_string(
            forced_mjcf(case, MUJOCO_INTEGRATORS[integrator], dt))
        self.data = mujoco.MjData(self.model)
        scene = case.scene
        # The effects MuJoCo does not model itself (it has gravity and the ball joint of a
        # pivot): applied each step through xfrc_applied, from their Python faces.
        self.applied = [effect for effect in scene.effects
                        if getattr(effect, 'effect_name', None) not in _NATIVE_TO_MUJOCO]
        self.held = None if case.held_torque_body is None else np.array(case.held_torque_body)
        self.per_step = bool(self.applied)
        self.reset()

    def reset(self):
        mujoco, data, scene = self.mujoco, self.data, self.case.scene
        mujoco.mj_resetData(self.model, data)
        state, body = scene.state, scene.body
        x, y, z, w = state.quaternion
        if scene.pivot is None:
            data.qpos[:] = np.concatenate([state.position, [w, x, y, z]])
            data.qvel[:] = np.concatenate([state.velocity(body),
                                           state.angular_velocity_body(body)])
        else:
            data.qpos[:] = [w, x, y, z]
            data.qvel[:] = state.angular_velocity_body(body)
        if self.held is not None:
            # The joint's rotational dofs are body-frame angular velocities, so their
            # generalised force is the body-frame torque: constant, set once, seen by every
            # stage of MuJoCo's RK4 as our kernels see the held torque.
            rotational = slice(3, 6) if scene.pivot is None else slice(0, 3)
            data.qfrc_applied[rotational] = self.held

    def _quaternion(self):
        qpos = self.data.qpos
        w, x, y, z = qpos[3:7] if self.case.scene.pivot is None else qpos[0:4]
        return np.array([x, y, z, w])

    def advance(self, steps):
        mujoco, model, data = self.mujoco, self.model, self.data
        if not self.per_step:
            mujoco.mj_step(model, data, nstep=int(steps))
            return
        applied = data.xfrc_applied[1]
        body = self.case.scene.body
        terms = [(effect.compiled_wrench,
                  np.ascontiguousarray(effect.wrench_parameters(body), dtype=float))
                 for effect in self.applied]
        # An effect that reads no more than the orientation gets it alone (the rest zero).
        whole = any(effect.reads_state for effect in self.applied)
        values = np.zeros(13)
        for _ in range(int(steps)):
            if whole:
                values = self._packed_state()
            else:
                values[0:4] = self._quaternion()
            time = data.time + 0.5 * self.dt
            force, torque = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            for term, parameters in terms:
                fx, fy, fz, tx, ty, tz = term(values, time, parameters)
                force = [force[0] + fx, force[1] + fy, force[2] + fz]
                torque = [torque[0] + tx, torque[1] + ty, torque[2] + tz]
            applied[0:3], applied[3:6] = force, torque
            mujoco.mj_step(model, data)

    def _packed_state(self):
        """
        Return MuJoCo's physical state packed as the kernels take it (q, x, p, L; world).

        Built from qpos and qvel directly, as a user of MuJoCo's Python API would write it (a
        State with its checks would cost the twin far more than its step).
        """
        data, scene = self.data, self.case.scene
        body = scene.body
        quaternion = self._quaternion()
        quaternion = quaternion / np.linalg.norm(quaternion)
        if scene.pivot is None:
            momentum = rotate(tuple(quaternion.tolist()),
                              tuple((body.inertia @ data.qvel[3:6]).tolist()))
            return np.concatenate([quaternion, data.qpos[0:3], body.mass * data.qvel[0:3],
                                   momentum])
        state = scene.pivot.constrain(body).project(State.from_velocity(
            body, rotation=quaternion, angular_velocity_body=data.qvel[0:3]))
        return np.concatenate(state._fields())

    def rotation(self):
        if any(self.data.warning[i].number > 0 for i in range(len(self.data.warning))):
            return None
        quaternion = self._quaternion()
        if not np.all(np.isfinite(quaternion)):
            return None
        return matrix_from_quaternion(quaternion / np.linalg.norm(quaternion))


# -- the sweep


@dataclass(frozen=True)
class ForcesConfig:
    """Cases, horizon (s), tolerances of controlled buss, timing repeats and budget (CPU s)."""

    cases: tuple
    horizon: float
    tolerances: tuple
    repeats: int
    time_budget: float
    dts_per_case: int = 0  # 0: all of the case's steps; else the first n


FORCES_FULL = ForcesConfig(FORCED_CASE_NAMES, 10.0, (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8), 3,
                           2.0)
FORCES_QUICK = ForcesConfig(('heavy_top', 'body_torque'), 0.5, (1e-4,), 1, 0.2, 2)


@dataclass
class ForcedRecord:
    """One (case, method, dt or tolerance): orientation error at the horizon, CPU cost."""

    case: str
    method: str
    family: str
    dt: float
    tolerance: float
    steps: int
    error: float
    us_per_step: float
    cpu_per_sim_second: float
    diverged: bool


def _measure(run, steps, reference, config):
    """Return (error at the horizon, CPU s of `steps` steps): measure.py's timing."""
    run.advance(steps)  # the accuracy run, also the warm-up (no compilation timed)
    rotation = run.rotation()
    error = math.inf if rotation is None else rotation_angle(rotation, reference)
    cpu, _ = measured_timing(run, steps, config.repeats, config.time_budget)
    return error, cpu


def _dts(case, config):
    return case.dts[:config.dts_per_case] if config.dts_per_case else case.dts


def forces_units(config, with_mujoco=True):
    """Return the number of progress units :func:`run_forces` reports."""
    methods = len(INTEGRATORS) + (len(MUJOCO_INTEGRATORS) if with_mujoco and
                                  mujoco_available() else 0)
    return sum(2 + methods * len(_dts(case, config)) + len(config.tolerances)
               for case in forced_cases(config.cases))


@functools.lru_cache(maxsize=None)
def _forced_case(name):
    """Return the ForcedCase of a name, built once per process."""
    return forced_cases([name])[0]


def reference_of(name, times, check=False):
    """Return the named case's :func:`forced_reference` (or its check) at `times` (s)."""
    solve = forced_reference_check if check else forced_reference
    return solve(_forced_case(name), times)


def measure_forced_run(name, method, dt, tolerance, steps, config, reference):
    """
    Measure `steps` steps of dt of one method on the named case; return its ForcedRecord.

    method: a registered integrator or a MuJoCo one at fixed steps, or 'buss_controlled'
    (``buss`` under error control at `tolerance`, dt the scene's tick).  reference: the
    reference rotation at the horizon, steps x dt.  As a dict.
    """
    case = _forced_case(name)
    if method == 'buss_controlled':
        run = _Ours(case, 'buss', dt, tolerance)
    else:
        run = (_Mujoco if method in MUJOCO_INTEGRATORS else _Ours)(case, method, dt)
    error, cpu = _measure(run, steps, reference, config)
    return asdict(ForcedRecord(case.name, method, run.family, dt, tolerance or 0.0, steps,
                               error, cpu / steps * 1e6, cpu / (steps * dt),
                               not math.isfinite(error)))


def forces_plan(config, with_mujoco=True):
    """Return the forced sweep as a Plan (its result: see :func:`run_forces`)."""
    methods = sorted(INTEGRATORS)
    mujoco_status = 'skipped on request (--no-mujoco)'
    if with_mujoco and mujoco_available():
        methods += list(MUJOCO_INTEGRATORS)
        mujoco_status = 'included'
    elif with_mujoco:
        mujoco_status = 'not installed (import mujoco failed): peer skipped'
    cases = forced_cases(config.cases)
    plan = None

    def assemble(references, values):
        found = {}
        for case in cases:
            reference = references[f'{plan.part}/{case.name}/reference']
            check = references[f'{plan.part}/{case.name}/reference check']
            found[case.name] = {
                'solver': f'DOP853 rtol {REFERENCE_RTOL:g}',
                'formulation': REFERENCE_FORMULATION, 'check': CHECK_FORMULATION,
                'uncertainty': max(rotation_angle(reference[t], check[t]) for t in reference),
                'description': case.description}
        return {'records': [values[name] for name in order], 'references': found,
                'methods': methods, 'mujoco': mujoco_status}

    plan = Plan('forces', assemble)
    order = []
    for case in cases:
        dts = _dts(case, config)
        tick = 1.0 / case.scene.rate
        runs = {dt: max(1, int(round(config.horizon / dt))) for dt in dts + (tick,)}
        times = sorted({steps * dt for dt, steps in runs.items()})
        reference = plan.add_reference(f'{case.name}/reference', reference_of,
                                       (case.name, times), weight=math.inf)
        plan.add_reference(f'{case.name}/reference check', reference_of,
                           (case.name, times, True), weight=math.inf)
        for method in methods:
            for dt in dts:
                order.append(plan.add_cell(
                    f'{case.name}/{method}/dt={dt:g}', measure_forced_run,
                    (case.name, method, dt, None, runs[dt], config), reference,
                    lambda rotations, time=runs[dt] * dt: rotations[time], weight=runs[dt]))
        for tolerance in config.tolerances:
            order.append(plan.add_cell(
                f'{case.name}/buss_controlled/tolerance={tolerance:g}', measure_forced_run,
                (case.name, 'buss_controlled', tick, tolerance, runs[tick], config), reference,
                lambda rotations, time=runs[tick] * tick: rotations[time], weight=runs[tick]))
    return plan


def run_forces(config, with_mujoco=True, progress=None):
    """Run the forced sweep here; return {'records', 'references', 'methods', 'mujoco'}."""
    return run_in_process(forces_plan(config, with_mujoco), progress)


def forces_goal_table(result, levels=LEVELS):
    """
    Return per (case, level) our best and MuJoCo's best CPU per simulated second.

    Best: the least CPU among the runs whose error at the horizon is at or below the level.
    Verdict 'holds' (ours <= 1/2 MuJoCo's), 'fails' (more, or only MuJoCo reaches it),
    'peer not reached' (only ours reaches it at the steps tried), 'no peer', or 'undecided'
    (neither reaches it, or it is below the reference's uncertainty).
    """
    rows = []
    for case, reference in result['references'].items():
        records = [r for r in result['records'] if r['case'] == case]
        for level in levels:
            def best(family):
                reached = [r for r in records if r['family'] == family and r['error'] <= level]
                return min(reached, key=lambda r: r['cpu_per_sim_second'], default=None)
            ours, peer = best('ours'), best('mujoco')
            if level < reference['uncertainty']:
                verdict = 'undecided'
            elif ours is None and peer is None:
                verdict = 'undecided'
            elif not any(r['family'] == 'mujoco' for r in records):
                verdict = 'no peer'
            elif peer is None:
                verdict = 'peer not reached'  # ours reaches it; MuJoCo at no step tried
            elif ours is None:
                verdict = 'fails'
            else:
                verdict = ('holds' if ours['cpu_per_sim_second']
                           <= 0.5 * peer['cpu_per_sim_second'] else 'fails')
            rows.append({'case': case, 'level': level, 'ours': ours, 'mujoco': peer,
                         'verdict': verdict})
    return rows
