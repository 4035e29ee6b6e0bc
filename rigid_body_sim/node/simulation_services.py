"""
ROS 2's standard simulation services (``simulation_interfaces``) on a node of many bodies.

:class:`SimulationServices` serves, in the node's namespace (relative names, like the node's
``reset`` and ``pause``; the names Gazebo's ros_gz_sim and O3DE give them):

- ``get_simulator_features`` (GetSimulatorFeatures): exactly the features below;
- ``reset_simulation`` (ResetSimulation), ``get_simulation_state`` and
  ``set_simulation_state`` (Get/SetSimulationState: playing, paused, stopped),
  ``step_simulation`` (StepSimulation) and the action ``simulate_steps`` (SimulateSteps);
- ``get_entities``, ``get_entity_state``, ``get_entities_states``, ``set_entity_state``,
  ``spawn_entity``, ``delete_entity``.

An entity is a body of the node's World, by its name; its state is the body's, in the
world frame (:mod:`rigid_body_sim.messages.simulation`: pose = COM position in m and
orientation body to world, twist = COM velocity in m/s and angular velocity in rad/s, both
world-frame vectors), stamped with the time the node's messages carry
(``node.stamp_nanoseconds()``: simulated time with publish_clock).

Every request gets an answer with a Result code and a one-line reason; whatever a peer
sends, nothing raises out of a callback (an unforeseen error is answered with
RESULT_OPERATION_FAILED and its reason, and logged).  What is refused, and how:

- an unknown entity: RESULT_NOT_FOUND;
- a spawn: a name taken (NAME_NOT_UNIQUE unless allow_renaming), a name that is not a body
  name (NAME_INVALID), no resource (NO_RESOURCE), a uri that is not a file path or
  ``file://`` URI (UNSUPPORTED_FORMAT) or names no file (RESULT_NOT_FOUND), a body the scene
  schema refuses (RESOURCE_PARSE_ERROR, the schema's message), an ``entity_namespace``
  (RESULT_FEATURE_UNSUPPORTED: a body's topics and frames are under its name);
- a pose that is not finite, not a unit quaternion or not in the world frame (INVALID_POSE),
  a twist that is not finite (RESULT_OPERATION_FAILED);
- a step while playing (RESULT_OPERATION_FAILED, as StepSimulation and SimulateSteps
  define it), more than :data:`MAX_STEPS` steps in one request (RESULT_OPERATION_FAILED);
- a filter of categories, tags or bounds, a reset scope of time or state alone, the state
  quitting (RESULT_FEATURE_UNSUPPORTED).

The node is the host: its interface (``world``, ``scene``, ``world_frame``,
``stamp_nanoseconds()``, ``spawn_body``, ``delete_body``, ``set_body_state``,
``reset_simulation``, ``playing``, ``set_playing``, ``step_while_paused``,
``simulated_time``) is all this module uses of it, so these services run on any node that
has it.  docs/node.md, "Standard simulation services", lists what is served and what not.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
import re
import stat
from typing import Any
from urllib.parse import unquote
from urllib.parse import urlsplit

from rclpy.action import ActionServer
from rclpy.action import GoalResponse
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Bounds
from simulation_interfaces.msg import Result
from simulation_interfaces.msg import SimulationState
from simulation_interfaces.msg import SimulatorFeatures
from simulation_interfaces.srv import DeleteEntity
from simulation_interfaces.srv import GetEntities
from simulation_interfaces.srv import GetEntitiesStates
from simulation_interfaces.srv import GetEntityState
from simulation_interfaces.srv import GetSimulationState
from simulation_interfaces.srv import GetSimulatorFeatures
from simulation_interfaces.srv import ResetSimulation
from simulation_interfaces.srv import SetEntityState
from simulation_interfaces.srv import SetSimulationState
from simulation_interfaces.srv import SpawnEntity
from simulation_interfaces.srv import StepSimulation

from ..messages.frames import as_tf2_reads
from ..messages.qos import SERVICE_QOS
from ..messages.simulation import entity_state_message
from ..messages.simulation import features_message
from ..messages.simulation import QUATERNION_TOLERANCE
from ..messages.simulation import result
from ..messages.simulation import state_from_entity_state
from ..scenes import parse_scene
from ..scenes import read_scene_yaml
from ..scenes import Scene
from ..scenes.limits import MAX_BODY_NAME_LENGTH
from ..scenes.limits import MAX_SCENE_SIZE
from ..text import one_line
from ..text import shortened

__all__ = ['FEATURES', 'MAX_FILTER_LENGTH', 'MAX_STEPS', 'SERVICE_NAMES', 'SimulationServices',
           'spawned_member']

SERVICE_NAMES = {
    GetSimulatorFeatures: 'get_simulator_features',
    ResetSimulation: 'reset_simulation',
    GetSimulationState: 'get_simulation_state',
    SetSimulationState: 'set_simulation_state',
    StepSimulation: 'step_simulation',
    GetEntities: 'get_entities',
    GetEntityState: 'get_entity_state',
    GetEntitiesStates: 'get_entities_states',
    SetEntityState: 'set_entity_state',
    SpawnEntity: 'spawn_entity',
    DeleteEntity: 'delete_entity',
}
"""The services, by type, and their names relative to the node's namespace."""
ACTION_NAME = 'simulate_steps'
"""The SimulateSteps action's name, relative to the node's namespace."""

FEATURES = (
    SimulatorFeatures.SPAWNING,
    SimulatorFeatures.DELETING,
    SimulatorFeatures.SPAWNING_RESOURCE_STRING,
    SimulatorFeatures.ENTITY_STATE_GETTING,
    SimulatorFeatures.ENTITY_STATE_SETTING,
    SimulatorFeatures.SIMULATION_RESET,
    SimulatorFeatures.SIMULATION_RESET_SPAWNED,
    SimulatorFeatures.SIMULATION_STATE_GETTING,
    SimulatorFeatures.SIMULATION_STATE_SETTING,
    SimulatorFeatures.SIMULATION_STATE_PAUSE,
    SimulatorFeatures.STEP_SIMULATION_SINGLE,
    SimulatorFeatures.STEP_SIMULATION_MULTIPLE,
    SimulatorFeatures.STEP_SIMULATION_ACTION,
)
"""What GetSimulatorFeatures lists: exactly what these services do.  Not among them:
SIMULATION_RESET_TIME and SIMULATION_RESET_STATE (time and states are reset together,
scope 3, not one without the other), and every feature of a service not served."""
SPAWN_FORMAT = 'rigid_body_sim_scene_body'
"""The spawn format (SimulatorFeatures.spawn_formats): one entry of a scene's ``bodies:``
as YAML (docs/scenes.md), by uri or in resource_string."""
MAX_STEPS = 10000
"""The most steps one StepSimulation or SimulateSteps request takes: the node serves nothing
else while it steps (one executor thread), so a request for 2^64 steps must not hold it for
ever.  Send several requests for more."""
MAX_FILTER_LENGTH = 256
"""The longest name filter (characters) GetEntities and GetEntitiesStates take."""

_SPAWN_SOURCE = 'resource_string'
_GENERATED_NAME = 'body'
# A body name as the scene schema takes it (scenes/schema.py): it starts each of the body's
# topic and frame names.
_BODY_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*')
# The scope bits ResetSimulation takes together: time and states are reset as one.
_TIME_AND_STATE = ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE
_STATE_NAMES = {SimulationState.STATE_STOPPED: 'stopped',
                SimulationState.STATE_PLAYING: 'playing',
                SimulationState.STATE_PAUSED: 'paused',
                SimulationState.STATE_QUITTING: 'quitting',
                SimulationState.STATE_NO_WORLD: 'no world',
                SimulationState.STATE_LOADING_WORLD: 'loading a world'}


class _Refusal(Exception):
    """A request refused: `code` (a Result or service code) and the one-line reason."""

    def __init__(self, code: int, reason: object) -> None:
        super().__init__(reason)
        self.code = code


def spawned_member(entry: Any, source: str, name: str, template: Scene,
                   pose: tuple[list[float], list[float]] | None = None) -> Scene:
    """
    Return the one-body Scene a spawn request's body entry gives, or raise.

    Parameters
    ----------
    entry : object
        One entry of a scene's ``bodies:`` (docs/scenes.md) as YAML gives it
        (:func:`~rigid_body_sim.scenes.read_scene_yaml`): a mapping of ``body`` (required),
        ``initial``, ``effects``, ``imu``, ``draw`` and optionally ``name``.
    source : str
        Where the text came from (the file, or ``resource_string``), for messages.
    name : str
        The body's name; it replaces the entry's own.
    template : Scene
        The node's scene: its integrator, rate and tolerance are the body's.
    pose : (position, quaternion), optional
        Replaces ``initial.position`` (m, world frame) and ``initial.orientation``
        (x, y, z, w, body to world); the entry's velocities stay.

    Raises
    ------
    ValueError
        One line, the scene schema's (``<source>: body.mass: ...``), for data that is not
        such an entry; its ``key`` attribute is ``'pose'`` when the pose is what is refused
        (a pivot's body, whose COM follows from the pivot), ``'name'`` for the name, else
        ``'entry'``.

    """
    if not isinstance(entry, dict):
        raise _keyed(ValueError(f"{source}: expected a mapping (one entry of a scene's "
                                f'bodies: list: body, initial, effects, imu, draw), got '
                                f'{type(entry).__name__}'), 'entry')
    entry = dict(entry, name=name)
    if pose is not None and 'initial' in entry and not isinstance(entry['initial'], dict):
        pose = None  # the schema says what is wrong with this initial
    if pose is not None:
        initial = dict(entry.get('initial') or {})
        initial['position'], initial['orientation'] = pose
        entry['initial'] = initial
    scene = {'name': template.name, 'description': f'{name} spawned',
             'integrator': template.integrator, 'rate': template.rate,
             'tolerance': template.tolerance or 0.0, 'bodies': [entry]}
    prefix = f'{source}: bodies[0]'
    try:
        return parse_scene(scene, source).bodies[0]
    except ValueError as error:
        # The entry was read as the first of a list: its messages name it as the file.
        message = str(error)
        key = 'entry'
        if message.startswith(f'{prefix}.name:'):
            key = 'name'
        elif pose is not None and message.startswith(
                (f'{prefix}: initial.position:', f'{prefix}: initial.orientation:')):
            key = 'pose'
        for head in (f'{prefix}: ', f'{prefix}.'):
            if message.startswith(head):
                message = f'{source}: ' + message[len(head):]
                break
        raise _keyed(ValueError(message), key) from None


def _keyed(error: ValueError, key: str) -> ValueError:
    error.key = key  # type: ignore[attr-defined]
    return error


class SimulationServices:
    """
    The simulation_interfaces services and action of `node`; see the module docstring.

    `node` is an rclpy Node with the host interface the module docstring lists.  Bodies
    spawned here are removed by a reset of scope SCOPE_SPAWNED; scope ALL also brings back
    the scene's bodies that were deleted.
    """

    def __init__(self, node: Any) -> None:
        self._node = node
        self._spawned: list[str] = []
        # Set by SetSimulationState(STOPPED): stopped is paused after a full reset, until
        # the simulation plays, steps or is paused on purpose.
        self._stopped = False
        self._services = [
            node.create_service(kind, name, self._answering(kind, getattr(self, '_' + name)),
                                qos_profile=SERVICE_QOS)
            for kind, name in SERVICE_NAMES.items()]
        self._action = ActionServer(node, SimulateSteps, ACTION_NAME, self._simulate_steps,
                                    goal_callback=self._take_goal)

    def destroy(self) -> None:
        """Remove the services and the action from the node."""
        for service in self._services:
            self._node.destroy_service(service)
        self._action.destroy()

    # -- answering

    def _answering(self, kind: Any, handler: Any) -> Any:
        """Return the callback of service `kind`: `handler`, every error made an answer."""
        node = self._node
        name = SERVICE_NAMES[kind]

        def callback(request: Any, response: Any) -> Any:
            answered = hasattr(response, 'result')
            try:
                if answered:
                    response.result = result(Result.RESULT_OK)
                handler(request, response)
            except _Refusal as refusal:
                response = kind.Response()
                response.result = result(refusal.code, refusal)
            except Exception as error:  # noqa: B902 - a peer's request must get an answer
                reason = one_line(f'{name}: {type(error).__name__}: {error}')
                node.get_logger().error(f'request not served: {reason}')
                response = kind.Response()
                if answered:
                    response.result = result(Result.RESULT_OPERATION_FAILED, reason)
            return response
        return callback

    def _entity(self, name: str) -> str:
        """Return `name` if it is a body's, else refuse with RESULT_NOT_FOUND."""
        world = self._node.world
        if name not in world:
            raise _Refusal(Result.RESULT_NOT_FOUND,
                           f'no entity called {shortened(name, 80)!r} ({len(world)} '
                           'entities: get_entities lists them)')
        return name

    def _state_message(self, name: str) -> Any:
        simulator = self._node.world.simulator(name)
        force, torque = simulator.applied_wrench()
        return entity_state_message(simulator.body, simulator.state,
                                    self._node.stamp_nanoseconds(),
                                    self._node.world_frame, force, torque)

    def _filtered(self, filters: Any) -> list[str]:
        """Return the names of the bodies that `filters` (EntityFilters) keeps, in order."""
        unsupported = [what for what, given in (
            ('categories', len(filters.categories)), ('tags', len(filters.tags.tags)),
            ('bounds', filters.bounds.type != Bounds.TYPE_EMPTY or len(filters.bounds.points)))
            if given]
        if unsupported:
            raise _Refusal(Result.RESULT_FEATURE_UNSUPPORTED,
                           f'filters by {" and ".join(unsupported)} are not served (bodies '
                           'have no categories, tags or bounds); filter by name (filter, a '
                           'regular expression)')
        pattern = filters.filter
        names = list(self._node.world.names)
        if not pattern:
            return names
        if len(pattern) > MAX_FILTER_LENGTH:
            raise _Refusal(Result.RESULT_OPERATION_FAILED,
                           f'filter of {len(pattern)} characters; give at most '
                           f'{MAX_FILTER_LENGTH}')
        slow = _repetition_problem(pattern)
        if slow is not None:
            raise _Refusal(Result.RESULT_OPERATION_FAILED,
                           f'filter {shortened(pattern, 80)!r}: {slow}')
        try:
            expression = re.compile(pattern)
        except (re.error, RecursionError, OverflowError) as error:
            raise _Refusal(Result.RESULT_OPERATION_FAILED,
                           f'filter {shortened(pattern, 80)!r} is not a regular expression: '
                           f'{error}') from None
        return [name for name in names if expression.search(name)]

    # -- the simulation

    def _get_simulator_features(self, request: Any, response: Any) -> None:
        response.features = features_message(
            FEATURES, [SPAWN_FORMAT],
            "rigid_body_sim: entities are rigid bodies; spawn one entry of a scene's "
            'bodies: list (YAML), see docs/node.md')

    def _current_state(self) -> int:
        node = self._node
        if node.playing:
            self._stopped = False
            return SimulationState.STATE_PLAYING
        if self._stopped and node.simulated_time == 0.0:
            return SimulationState.STATE_STOPPED
        self._stopped = False
        return SimulationState.STATE_PAUSED

    def _get_simulation_state(self, request: Any, response: Any) -> None:
        response.state.state = self._current_state()

    def _set_simulation_state(self, request: Any, response: Any) -> None:
        target = request.state.state
        current = self._current_state()
        name = _STATE_NAMES.get(target)
        if name is None:
            raise _Refusal(Result.RESULT_OPERATION_FAILED,
                           f"state {target} is none of SimulationState's STATE_* values")
        if target == current:
            raise _Refusal(SetSimulationState.Response.ALREADY_IN_TARGET_STATE,
                           f'the simulation is {name} already')
        node = self._node
        if target == SimulationState.STATE_PLAYING:
            node.set_playing(True)
            self._stopped = False
        elif target == SimulationState.STATE_PAUSED:
            node.set_playing(False)
            self._stopped = False
        elif target == SimulationState.STATE_STOPPED:
            node.set_playing(False)
            self._reset_all()
            self._stopped = True
        elif target == SimulationState.STATE_QUITTING:
            raise _Refusal(Result.RESULT_FEATURE_UNSUPPORTED,
                           "quitting is not served: stop the node's process (SIGINT)")
        else:
            raise _Refusal(SetSimulationState.Response.INCORRECT_TRANSITION,
                           f'{name} is not a state to set: the node has one world, its '
                           'scene, always loaded')
        response.result = result(Result.RESULT_OK,
                                 f'{_STATE_NAMES[current]} -> {name} at simulated time '
                                 f'{node.simulated_time:.9f} s')

    def _reset_all(self) -> None:
        """Remove the spawned bodies, bring back the scene's in order, reset states, time."""
        node = self._node
        self._remove_spawned()
        members = node.scene.members
        if list(node.world.names) != [member.name for member in members]:
            # A scene body was deleted: all of them again, in the scene's order, as at start.
            for name in list(node.world.names):
                node.delete_body(name)
            for member in members:
                node.spawn_body(member.name, member)
        node.reset_simulation()

    def _remove_spawned(self) -> None:
        node = self._node
        for name in self._spawned:
            if name in node.world:
                node.delete_body(name)
        self._spawned.clear()

    def _reset_simulation(self, request: Any, response: Any) -> None:
        scope = request.scope
        if scope in (ResetSimulation.Request.SCOPE_DEFAULT, ResetSimulation.Request.SCOPE_ALL):
            self._reset_all()
            done = "spawned bodies removed, the scene's bodies back, each in its initial state"
        else:
            partial = scope & _TIME_AND_STATE
            if partial not in (0, _TIME_AND_STATE) or scope & ~(
                    _TIME_AND_STATE | ResetSimulation.Request.SCOPE_SPAWNED):
                raise _Refusal(Result.RESULT_FEATURE_UNSUPPORTED,
                               f'scope {scope} is not served: time and state are reset together '
                               f'(scope {_TIME_AND_STATE}), spawned bodies removed with scope '
                               f'{ResetSimulation.Request.SCOPE_SPAWNED}; 0 or 255 does all')
            parts = []
            if scope & ResetSimulation.Request.SCOPE_SPAWNED:
                count = len(self._spawned)
                self._remove_spawned()
                parts.append(f'{count} spawned bodies removed')
            if partial:
                self._node.reset_simulation()
                parts.append('every body in its initial state')
            done = ', '.join(parts)
        response.result = result(Result.RESULT_OK, f'{done}; simulated time '
                                 f'{self._node.simulated_time:.9f} s')

    def _step_refusal(self, steps: int) -> str | None:
        if self._node.playing:
            return ('the simulation is playing: steps are taken while paused (set_simulation_'
                    'state to paused first)')
        if steps > MAX_STEPS:
            return f'{steps} steps asked; a request takes at most {MAX_STEPS}: send several'
        return None

    def _step_simulation(self, request: Any, response: Any) -> None:
        steps = request.steps
        refusal = self._step_refusal(steps)
        if refusal is not None:
            raise _Refusal(Result.RESULT_OPERATION_FAILED, refusal)
        node = self._node
        if steps:
            node.step_while_paused(steps)
            self._stopped = False
        response.result = result(Result.RESULT_OK, f'{steps} steps taken; simulated time '
                                 f'{node.simulated_time:.9f} s')

    def _take_goal(self, goal: Any) -> GoalResponse:
        # Every goal is taken and answered by its result: a refused one with the reason.
        return GoalResponse.ACCEPT

    def _simulate_steps(self, goal_handle: Any) -> Any:
        answer = SimulateSteps.Result()
        try:
            steps = goal_handle.request.steps
            refusal = self._step_refusal(steps)
            if refusal is not None:
                answer.result = result(Result.RESULT_OPERATION_FAILED, refusal)
                goal_handle.abort()
                return answer
            node = self._node
            feedback = SimulateSteps.Feedback()
            for completed in range(1, steps + 1):
                node.step_while_paused(1)
                self._stopped = False
                feedback.completed_steps, feedback.remaining_steps = completed, steps - completed
                goal_handle.publish_feedback(feedback)
            answer.result = result(Result.RESULT_OK, f'{steps} steps taken; simulated time '
                                   f'{node.simulated_time:.9f} s')
            goal_handle.succeed()
        except Exception as error:  # noqa: B902 - a peer's goal must get an answer
            reason = one_line(f'{ACTION_NAME}: {type(error).__name__}: {error}')
            self._node.get_logger().error(f'goal not served: {reason}')
            answer.result = result(Result.RESULT_OPERATION_FAILED, reason)
            goal_handle.abort()
        return answer

    # -- the entities

    def _get_entities(self, request: Any, response: Any) -> None:
        response.entities = self._filtered(request.filters)

    def _get_entity_state(self, request: Any, response: Any) -> None:
        response.state = self._state_message(self._entity(request.entity))

    def _get_entities_states(self, request: Any, response: Any) -> None:
        names = self._filtered(request.filters)
        response.entities = names
        response.states = [self._state_message(name) for name in names]

    def _set_entity_state(self, request: Any, response: Any) -> None:
        name = self._entity(request.entity)
        body = self._node.world.simulator(name).body
        try:
            state = state_from_entity_state(request.state, body, self._node.world_frame)
        except ValueError as error:
            reason = str(error)
            code = (SetEntityState.Response.INVALID_POSE
                    if reason.startswith(('pose.', 'header.frame_id'))
                    else Result.RESULT_OPERATION_FAILED)
            raise _Refusal(code, reason) from None
        self._node.set_body_state(name, state)
        self._stopped = False
        response.result = result(Result.RESULT_OK, f'state of {name!r} set at simulated time '
                                 f'{self._node.simulated_time:.9f} s')

    def _spawn_entity(self, request: Any, response: Any) -> None:
        codes = SpawnEntity.Response
        if request.entity_namespace:
            raise _Refusal(Result.RESULT_FEATURE_UNSUPPORTED,
                           "entity_namespace is not served: a body's topics and frames are "
                           "under its name in the node's namespace; leave it empty")
        if request.uri:
            source, text = self._read_uri(request.uri)
        elif request.resource_string:
            source, text = _SPAWN_SOURCE, request.resource_string
        else:
            raise _Refusal(codes.NO_RESOURCE, 'uri and resource_string are both empty: give '
                                              'a body entry (YAML) in one of them')
        try:
            entry = read_scene_yaml(text, source)
        except ValueError as error:
            raise _Refusal(codes.RESOURCE_PARSE_ERROR, error) from None
        entry_name = entry.get('name') if isinstance(entry, dict) else None
        name = self._spawn_name(request.name or (
            entry_name if isinstance(entry_name, str) else ''), request.allow_renaming)
        pose = self._initial_pose(request.initial_pose)
        try:
            member = spawned_member(entry, source, name, self._node.scene, pose)
        except ValueError as error:
            key = getattr(error, 'key', 'entry')
            code = {'pose': codes.INVALID_POSE, 'name': codes.NAME_INVALID}.get(
                key, codes.RESOURCE_PARSE_ERROR)
            raise _Refusal(code, f'initial_pose refused: {error}' if key == 'pose'
                           else error) from None
        try:
            self._node.spawn_body(name, member)
        except ValueError as error:
            raise _Refusal(Result.RESULT_OPERATION_FAILED, error) from None
        self._spawned.append(name)
        response.entity_name = name
        response.result = result(Result.RESULT_OK, f'spawned {name!r} from {source} at '
                                 f'simulated time {self._node.simulated_time:.9f} s')

    def _spawn_name(self, name: str, allow_renaming: bool) -> str:
        """Return the name to spawn under: `name`, or one generated if allowed."""
        codes = SpawnEntity.Response
        world = self._node.world
        if name and not (_BODY_NAME.fullmatch(name) and len(name) <= MAX_BODY_NAME_LENGTH):
            raise _Refusal(codes.NAME_INVALID,
                           f'name {shortened(name, 80)!r} is not a body name: letters, digits '
                           f'and _, starting with a letter, at most {MAX_BODY_NAME_LENGTH} '
                           "characters (it names the body's topics and frame)")
        if name and name not in world:
            return name
        if not allow_renaming:
            if not name:
                raise _Refusal(codes.NAME_INVALID, 'no name: give one (name, or name: in the '
                                                   'entry) or set allow_renaming')
            raise _Refusal(codes.NAME_NOT_UNIQUE, f'an entity called {name!r} exists '
                                                  'already; set allow_renaming for another name')
        stem = (name or _GENERATED_NAME)[:MAX_BODY_NAME_LENGTH - 7]
        return next(candidate for candidate in (f'{stem}_{index}' for index in range(1, 10**6))
                    if candidate not in world)

    def _initial_pose(self, pose_stamped: Any) -> tuple[list[float], list[float]] | None:
        """
        Return (position, quaternion) of a spawn's initial_pose, or None if left unset.

        Unset is the message's default: the origin, the identity and no frame; then the
        entry's initial pose stands.  Refused (INVALID_POSE): a frame other than the world
        frame, a non-finite value, a quaternion off unit norm.
        """
        invalid = SpawnEntity.Response.INVALID_POSE
        pose = pose_stamped.pose
        position = [pose.position.x, pose.position.y, pose.position.z]
        quaternion = [pose.orientation.x, pose.orientation.y, pose.orientation.z,
                      pose.orientation.w]
        frame = pose_stamped.header.frame_id
        if not frame and position == [0.0, 0.0, 0.0] and quaternion == [0.0, 0.0, 0.0, 1.0]:
            return None
        world_frame = self._node.world_frame
        if frame and as_tf2_reads(frame) != world_frame:
            raise _Refusal(invalid, f'initial_pose.header.frame_id is '
                                    f'{shortened(frame, 80)!r}: poses are given in the world '
                                    f'frame {world_frame!r} (or an empty frame_id)')
        if not all(math.isfinite(value) for value in position + quaternion):
            raise _Refusal(invalid, f'initial_pose must be finite; got position {position} m, '
                                    f'orientation {quaternion} (x, y, z, w)')
        norm = math.hypot(*quaternion)
        if not abs(norm - 1.0) <= QUATERNION_TOLERANCE:
            raise _Refusal(invalid, f'initial_pose.pose.orientation (x, y, z, w) must be a '
                                    f'unit quaternion (norm 1 to {QUATERNION_TOLERANCE:g}); '
                                    f'got norm {norm:.9g}')
        return position, quaternion

    def _read_uri(self, uri: str) -> tuple[str, str]:
        """Return (source, text) of the file a spawn's uri names, or refuse."""
        codes = SpawnEntity.Response
        quoted = shortened(uri, 120)
        parts = urlsplit(uri)
        if parts.scheme == 'file':
            if parts.netloc not in ('', 'localhost'):
                raise _Refusal(codes.UNSUPPORTED_FORMAT,
                               f'uri {quoted!r}: a file URI of another host; give a local file')
            path = unquote(parts.path)
        elif parts.scheme and len(parts.scheme) > 1:
            raise _Refusal(codes.UNSUPPORTED_FORMAT,
                           f'uri {quoted!r}: {parts.scheme}:// is not served; give a file path '
                           'or a file:// URI, or the YAML in resource_string')
        else:
            path = uri
        if '\0' in path:
            raise _Refusal(codes.RESOURCE_PARSE_ERROR, f'uri {quoted!r} holds a null character')
        source = shortened(path, 120)
        try:
            mode = os.stat(path).st_mode
        except OSError as error:
            raise _Refusal(Result.RESULT_NOT_FOUND,
                           f'uri {quoted!r}: {error.strerror or error}') from None
        if not stat.S_ISREG(mode):
            raise _Refusal(Result.RESULT_NOT_FOUND, f'uri {quoted!r} is not a regular file')
        try:
            with open(Path(path), encoding='utf-8') as stream:
                text = stream.read(MAX_SCENE_SIZE + 1)
        except OSError as error:
            raise _Refusal(Result.RESULT_NOT_FOUND,
                           f'uri {quoted!r}: cannot read: {error.strerror or error}') from None
        except UnicodeDecodeError as error:
            raise _Refusal(codes.RESOURCE_PARSE_ERROR,
                           f'{source}: not UTF-8 text (byte at offset {error.start})') from None
        return source, text

    def _delete_entity(self, request: Any, response: Any) -> None:
        name = self._entity(request.entity)
        self._node.delete_body(name)
        if name in self._spawned:
            self._spawned.remove(name)
        response.result = result(Result.RESULT_OK, f'deleted {name!r} at simulated time '
                                 f'{self._node.simulated_time:.9f} s')


def _repetition_problem(pattern: str) -> str | None:
    """
    Return why name filter `pattern` may take exponential time to match, or None.

    Python's backtracking matcher has no time limit, and the node serves nothing else while
    it matches: a repeated group that itself repeats or alternates (``(a+)+``, ``(a|aa)*``)
    and a back-reference can take exponential time in the name's length.  An optional group
    (``(left|right)?``) is no repetition.  POSIX extended
    expressions have no back-references; the repetitions refused here are rare in name
    filters (``(left|right)`` and ``club_.*`` pass).
    """
    # For each open group: does it hold a quantifier or an alternation?
    groups: list[bool] = []
    closed_risky = False  # the group just closed held one
    index, length = 0, len(pattern)
    while index < length:
        character = pattern[index]
        if character == '\\':
            if index + 1 < length and pattern[index + 1].isdigit():
                return 'back-references are not served (they can take exponential time)'
            index += 2
            closed_risky = False
            continue
        if character == '[':
            # A character class: up to its closing ], a ] first in it included.
            end = index + 1
            if end < length and pattern[end] == '^':
                end += 1
            if end < length and pattern[end] == ']':
                end += 1
            while end < length and pattern[end] != ']':
                end += 2 if pattern[end] == '\\' else 1
            index = end + 1
            closed_risky = False
            continue
        if character in '*+{' or (character == '?' and not closed_risky):
            if closed_risky:
                return ('a repeated group that itself repeats or alternates is not served '
                        '(it can take exponential time): write it without the outer repeat')
            if groups:
                groups[-1] = True
        elif character == '|' and groups:
            groups[-1] = True
        if character == '(':
            groups.append(False)
            closed_risky = False
            if pattern.startswith('?', index + 1):
                index += 1  # (?:, (?P<name>, ...: group syntax, no quantifier
        elif character == ')' and groups:
            closed_risky = groups.pop()
            if closed_risky and groups:
                groups[-1] = True
        elif character not in '*+?{':
            closed_risky = False
        index += 1
    return None
