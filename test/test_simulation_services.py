"""
The standard simulation services over real DDS, called as any simulation_interfaces client.

The client here uses rclpy and the simulation_interfaces definitions only (no package code):
what a peer that knows the standard, and nothing of this package, can do.  The host runs in a
process of its own, in a namespace of its own, for the whole module: :data:`HOST_COMMAND`,
the package's node with the built-in scene juggling_clubs (three clubs under gravity,
100 Hz), publish_clock on so that the stamps are the simulated time, and no frame prefix.
Each test starts from a full reset in the state it needs.
"""

import math
from pathlib import Path
import signal
import sys
import time

from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import RecorderProcess
from node_harness import SpunNode
from node_harness import unique_namespace
import pytest
from rclpy.action import ActionClient

try:  # built by interfaces/build_interfaces.sh in the set-up (make venv)
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import EntityCategory
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
except ImportError as error:
    pytest.skip(f'simulation_interfaces is not built here ({error}): make venv builds it',
                allow_module_level=True)

pytestmark = pytest.mark.xdist_group('node')

HOST_COMMAND = [sys.executable, '-m', 'rigid_body_sim.node.entry_point']
HOST_PARAMETERS = {'scene': 'juggling_clubs', 'publish_clock': 'true', 'frame_prefix': "''"}
SCENE_BODIES = ['club_left', 'club_middle', 'club_right']
TICK_NANOSECONDS = 10_000_000  # the scene's 100 Hz
SERVICES = {
    GetSimulatorFeatures: 'get_simulator_features', ResetSimulation: 'reset_simulation',
    GetSimulationState: 'get_simulation_state', SetSimulationState: 'set_simulation_state',
    StepSimulation: 'step_simulation', GetEntities: 'get_entities',
    GetEntityState: 'get_entity_state', GetEntitiesStates: 'get_entities_states',
    SetEntityState: 'set_entity_state', SpawnEntity: 'spawn_entity',
    DeleteEntity: 'delete_entity'}
# A request of each kind that changes nothing, sent until answered (see StandardClient).
HARMLESS = {ResetSimulation: {'scope': ResetSimulation.Request.SCOPE_TIME},
            SetSimulationState: {'state': {'state': 99}}, StepSimulation: {'steps': 0},
            SetEntityState: {'entity': ''}, SpawnEntity: {}, DeleteEntity: {'entity': ''}}
# A ball of 1 kg and 0.1 m radius, thrown sideways with a spin, falling.
BALL = """
body: {mass: 1.0, shape: sphere, radius: 0.1}
initial:
  position: [0.0, 1.0, 2.0]
  velocity: [1.0, 0.0, 0.0]
  angular_velocity_body: [0.0, 0.0, 3.0]
effects: [gravity]
"""
RESPONSE_TIMEOUT = 60.0


def fill(message, fields):
    """Set `fields` ({name: value or nested dict}) on a ROS message; return it."""
    for name, value in fields.items():
        if isinstance(value, dict):
            fill(getattr(message, name), value)
        else:
            setattr(message, name, value)
    return message


class StandardClient(SpunNode):
    """
    An rclpy node that calls the host's services by their standard types and names.

    Its own context, spun in a background thread.  Before the tests, each client is called
    with a harmless request until answered: a response can be lost before the host's DDS
    has matched the client's response reader (node_harness.Client.call says more), and
    the requests of the tests, which spawn and step, must be sent once.
    """

    def __init__(self, namespace):
        super().__init__('standard_client', namespace)
        self.clients = {kind: self.node.create_client(kind, name)
                        for kind, name in SERVICES.items()}
        self.steps_action = ActionClient(self.node, SimulateSteps, 'simulate_steps')
        self.start_spinning()

    @staticmethod
    def wait_for(condition, timeout, what):
        """Poll `condition()` until it is true; fail with `what` after `timeout` s."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out after {timeout:g} s waiting for {what}')
            time.sleep(0.01)  # waits-for: poll interval of wait_for(condition)

    def call(self, kind, timeout=RESPONSE_TIMEOUT, **fields):
        """Call the service of type `kind` with request `fields`; return the response."""
        client = self.clients[kind]
        future = client.call_async(fill(kind.Request(), fields))
        self.wait_for(future.done, timeout, f'a response from {client.srv_name}')
        return future.result()

    def await_matched(self):
        """Call every service with a harmless request until it answers, and the action."""
        for kind, client in self.clients.items():
            self.wait_for(client.service_is_ready, DISCOVERY_TIMEOUT, f'{client.srv_name}')
            for attempt in range(3):
                future = client.call_async(fill(kind.Request(), HARMLESS.get(kind, {})))
                try:
                    self.wait_for(future.done, 10.0, f'a response from {client.srv_name}')
                    break
                except AssertionError:
                    client.remove_pending_request(future)
                    if attempt == 2:
                        raise
        self.wait_for(self.steps_action.server_is_ready, DISCOVERY_TIMEOUT,
                      'the simulate_steps action')

    def simulate_steps(self, steps):
        """Send a SimulateSteps goal; return (result response, [feedback messages])."""
        feedback = []
        sent = self.steps_action.send_goal_async(
            SimulateSteps.Goal(steps=steps),
            feedback_callback=lambda message: feedback.append(message.feedback))
        self.wait_for(sent.done, RESPONSE_TIMEOUT, 'the simulate_steps goal to be taken')
        goal = sent.result()
        assert goal.accepted
        finished = goal.get_result_async()
        self.wait_for(finished.done, RESPONSE_TIMEOUT, 'the simulate_steps result')
        return finished.result(), feedback

    # -- shorthands

    def entities(self, pattern=''):
        """Return the names GetEntities gives for name filter `pattern`."""
        response = self.call(GetEntities, filters={'filter': pattern})
        assert response.result.result == Result.RESULT_OK, response.result.error_message
        return list(response.entities)

    def state(self, name):
        """Return the EntityState of `name`."""
        response = self.call(GetEntityState, entity=name)
        assert response.result.result == Result.RESULT_OK, response.result.error_message
        return response.state

    def simulation_state(self):
        """Return the SimulationState value."""
        return self.call(GetSimulationState).state.state

    def set_simulation_state(self, state):
        """Set the simulation state; return the Result."""
        return self.call(SetSimulationState, state={'state': state}).result

    def spawn(self, **fields):
        """Call SpawnEntity; return the response."""
        return self.call(SpawnEntity, **fields)


def stamp_nanoseconds(header):
    """Return a header's stamp in ns."""
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def pose_values(state):
    """Return (position, quaternion x y z w) of an EntityState as lists."""
    pose = state.pose
    return ([pose.position.x, pose.position.y, pose.position.z],
            [pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w])


def assert_refused(result, code, *words):
    """Assert a Result has `code` and a one-line reason that holds each of `words`."""
    assert result.result == code, (result.result, result.error_message)
    reason = result.error_message
    assert reason and reason.isprintable() and len(reason) <= 500, reason
    for word in words:
        assert word in reason, reason


@pytest.fixture(scope='module')
def host(tmp_path_factory):
    """Start the host and a standard client; stop both at the end."""
    isolate_ros_environment()
    namespace = unique_namespace()
    process = NodeProcess(tmp_path_factory.mktemp('host') / 'host.log', namespace=namespace,
                          parameters=HOST_PARAMETERS, command=HOST_COMMAND)
    client = StandardClient(namespace)
    try:
        client.await_matched()
    except AssertionError as error:
        client.close()
        process.stop()
        raise AssertionError(f'{error}; host output:\n{process.output()}') from None
    client.process = process
    yield client
    client.close()
    process.stop()


def fresh(host, state):
    """Pause, reset fully (spawned bodies gone, the scene's back, time 0), set `state`."""
    for step in ('pause', 'reset', 'set'):
        if step == 'reset':
            result = host.call(ResetSimulation, scope=ResetSimulation.Request.SCOPE_ALL).result
        else:
            result = host.set_simulation_state(
                SimulationState.STATE_PAUSED if step == 'pause' else state)
        assert result.result in (Result.RESULT_OK,
                                 SetSimulationState.Response.ALREADY_IN_TARGET_STATE), \
            result.error_message
    assert host.simulation_state() == state


def test_features_list_exactly_what_is_served(host):
    features = host.call(GetSimulatorFeatures).features
    assert sorted(features.features) == sorted([
        SimulatorFeatures.SPAWNING, SimulatorFeatures.DELETING,
        SimulatorFeatures.SPAWNING_RESOURCE_STRING, SimulatorFeatures.ENTITY_STATE_GETTING,
        SimulatorFeatures.ENTITY_STATE_SETTING, SimulatorFeatures.SIMULATION_RESET,
        SimulatorFeatures.SIMULATION_RESET_SPAWNED, SimulatorFeatures.SIMULATION_STATE_GETTING,
        SimulatorFeatures.SIMULATION_STATE_SETTING, SimulatorFeatures.SIMULATION_STATE_PAUSE,
        SimulatorFeatures.STEP_SIMULATION_SINGLE, SimulatorFeatures.STEP_SIMULATION_MULTIPLE,
        SimulatorFeatures.STEP_SIMULATION_ACTION])
    # A service whose feature is not listed is not there either.
    names = {name for name, _ in host.node.get_service_names_and_types()}
    assert not any(name.endswith(('/get_spawnables', '/get_named_poses', '/load_world',
                                  '/get_entity_info', '/spawn_entities')) for name in names)


def test_a_body_spawned_from_a_string_is_found_read_set_and_deleted(host):
    fresh(host, SimulationState.STATE_PAUSED)
    response = host.spawn(name='ball', resource_string=BALL)
    assert response.result.result == Result.RESULT_OK, response.result.error_message
    assert response.entity_name == 'ball'
    assert host.entities() == SCENE_BODIES + ['ball']
    assert host.entities('^ba') == ['ball']
    assert host.entities('club_(left|right)') == ['club_left', 'club_right']
    state = host.state('ball')
    assert pose_values(state) == ([0.0, 1.0, 2.0], [0.0, 0.0, 0.0, 1.0])
    assert [state.twist.linear.x, state.twist.angular.z] == pytest.approx([1.0, 3.0], rel=1e-15)
    # Gravity's alone: down, nothing sideways.
    acceleration = state.acceleration.linear
    assert acceleration.x == acceleration.y == 0.0 and acceleration.z < -9.0
    assert state.header.frame_id == 'world'
    # GetEntitiesStates gives the same, in the order of the names.
    both = host.call(GetEntitiesStates, filters={'filter': 'ball|club_left'})
    assert list(both.entities) == ['club_left', 'ball']
    assert pose_values(both.states[1]) == pose_values(state)
    # Set a state (a quarter turn about z, at rest) and read it back.
    half = math.sqrt(0.5)
    result = host.call(SetEntityState, entity='ball', state={
        'header': {'frame_id': 'world'},
        'pose': {'position': {'x': 5.0, 'y': -1.0, 'z': 0.5},
                 'orientation': {'x': 0.0, 'y': 0.0, 'z': half, 'w': half}},
        'twist': {'linear': {'x': 0.0}, 'angular': {'z': 0.0}}}).result
    assert result.result == Result.RESULT_OK, result.error_message
    position, quaternion = pose_values(host.state('ball'))
    assert position == [5.0, -1.0, 0.5]
    assert quaternion == pytest.approx([0.0, 0.0, half, half], abs=1e-15)
    assert host.state('ball').twist.angular.z == 0.0
    # Deleted: gone, and unknown from then on.
    assert host.call(DeleteEntity, entity='ball').result.result == Result.RESULT_OK
    assert host.entities() == SCENE_BODIES
    assert_refused(host.call(GetEntityState, entity='ball').result, Result.RESULT_NOT_FOUND,
                   "'ball'")


@pytest.mark.parametrize('as_uri', [str, Path.as_uri], ids=['path', 'file_uri'])
def test_a_body_spawned_from_a_file_moves_with_the_simulation(host, tmp_path, as_uri):
    fresh(host, SimulationState.STATE_PLAYING)
    path = tmp_path / 'ball.yaml'
    path.write_text('name: thrown\n' + BALL)
    response = host.spawn(uri=as_uri(path))
    assert response.result.result == Result.RESULT_OK, response.result.error_message
    # No name in the request: the entry's.
    assert response.entity_name == 'thrown'
    start = stamp_nanoseconds(host.state('thrown').header)
    host.wait_for(lambda: stamp_nanoseconds(host.state('thrown').header) > start,
                  RESPONSE_TIMEOUT, 'the spawned body to move on')
    assert pose_values(host.state('thrown'))[0][0] > 0.0


def test_record_takes_a_body_spawned_while_it_records(host, tmp_path):
    """`record` (default topics) finds a spawned body's topics and records them."""
    fresh(host, SimulationState.STATE_PLAYING)
    namespace = host.node.get_namespace()
    bag = tmp_path / 'spawned'
    recorder = RecorderProcess(tmp_path / 'recorder.log', bag, '--namespace', namespace)
    try:
        recorder.wait_for_counts(bag, {f'{namespace}/club_left/pose': 10})
        response = host.spawn(name='recorded_ball', resource_string=BALL)
        assert response.result.result == Result.RESULT_OK, response.result.error_message
        recorder.wait_for_counts(bag, {f'{namespace}/recorded_ball/{topic}': 10 for topic in (
            'pose', 'twist', 'angular_momentum', 'odom', 'imu')})
        recorder.process.send_signal(signal.SIGINT)
        assert recorder.finish() == 0, recorder.output()
    finally:
        if recorder.process.poll() is None:
            recorder.process.kill()
            recorder.finish()
        host.call(DeleteEntity, entity='recorded_ball')
    assert 'topics of a node of bodies' in recorder.output()


def test_an_initial_pose_replaces_the_entry_pose(host):
    fresh(host, SimulationState.STATE_PAUSED)
    response = host.spawn(name='placed', resource_string=BALL, initial_pose={'pose': {
        'position': {'x': -2.0, 'y': 0.0, 'z': 3.0},
        'orientation': {'x': 1.0, 'y': 0.0, 'z': 0.0, 'w': 0.0}}})
    assert response.result.result == Result.RESULT_OK, response.result.error_message
    state = host.state('placed')
    assert pose_values(state) == ([-2.0, 0.0, 3.0], [1.0, 0.0, 0.0, 0.0])
    assert state.twist.linear.x == 1.0  # the entry's velocity stays


@pytest.mark.parametrize('steps', [1, 7])
def test_step_simulation_advances_a_paused_simulation_by_exactly_its_steps(host, steps):
    fresh(host, SimulationState.STATE_PAUSED)
    before = host.call(GetEntitiesStates).states
    result = host.call(StepSimulation, steps=steps).result
    assert result.result == Result.RESULT_OK, result.error_message
    after = host.call(GetEntitiesStates).states
    for old, new in zip(before, after):
        assert stamp_nanoseconds(new.header) - stamp_nanoseconds(old.header) == \
            steps * TICK_NANOSECONDS
        assert pose_values(new) != pose_values(old)
    # Paused: nothing moves on between requests.
    assert [pose_values(state) for state in host.call(GetEntitiesStates).states] == \
        [pose_values(state) for state in after]
    assert host.simulation_state() == SimulationState.STATE_PAUSED


def test_simulate_steps_gives_feedback_after_every_step(host):
    # Feedback goes out on a topic of its own, which a loaded machine may match after the
    # goal's services: one-step goals until one's feedback arrives, then the test afresh.
    for attempt in range(10):
        fresh(host, SimulationState.STATE_PAUSED)
        _, warm_up = host.simulate_steps(1)
        try:
            host.wait_for(lambda: warm_up, 5.0, 'the feedback of a one-step goal')
            break
        except AssertionError:
            if attempt == 9:
                raise
    fresh(host, SimulationState.STATE_PAUSED)
    before = stamp_nanoseconds(host.state('club_left').header)
    response, feedback = host.simulate_steps(5)
    assert response.result.result.result == Result.RESULT_OK, response.result.result
    host.wait_for(lambda: len(feedback) == 5, RESPONSE_TIMEOUT, 'the feedback of 5 steps')
    assert [(message.completed_steps, message.remaining_steps) for message in feedback] == \
        [(1, 4), (2, 3), (3, 2), (4, 1), (5, 0)]
    assert stamp_nanoseconds(host.state('club_left').header) - before == 5 * TICK_NANOSECONDS


def test_steps_are_refused_while_playing(host):
    fresh(host, SimulationState.STATE_PLAYING)
    assert_refused(host.call(StepSimulation, steps=3).result, Result.RESULT_OPERATION_FAILED,
                   'playing')
    response, feedback = host.simulate_steps(3)
    assert_refused(response.result.result, Result.RESULT_OPERATION_FAILED, 'playing')
    assert feedback == []


def test_simulation_states_play_pause_and_stop(host):
    fresh(host, SimulationState.STATE_PLAYING)
    host.spawn(name='extra', resource_string=BALL)
    assert host.call(DeleteEntity, entity='club_left').result.result == Result.RESULT_OK
    assert_refused(host.set_simulation_state(SimulationState.STATE_PLAYING),
                   SetSimulationState.Response.ALREADY_IN_TARGET_STATE, 'playing')
    assert host.set_simulation_state(SimulationState.STATE_PAUSED).result == Result.RESULT_OK
    assert host.simulation_state() == SimulationState.STATE_PAUSED
    paused_at = stamp_nanoseconds(host.state('club_middle').header)
    # Stopped: paused after a full reset, with the scene's bodies only, at their initial
    # states; the stamps do not go back (the node's /clock counts on through a reset, as its
    # ~/reset says: a sim-time consumer's clock never runs backwards).
    assert host.set_simulation_state(SimulationState.STATE_STOPPED).result == Result.RESULT_OK
    assert host.simulation_state() == SimulationState.STATE_STOPPED
    assert host.entities() == SCENE_BODIES
    assert stamp_nanoseconds(host.state('club_middle').header) >= paused_at
    assert pose_values(host.state('club_middle'))[0] == [0.0, 0.0, 1.0]
    assert_refused(host.set_simulation_state(SimulationState.STATE_STOPPED),
                   SetSimulationState.Response.ALREADY_IN_TARGET_STATE, 'stopped')
    # A step leaves stopped for paused.
    assert host.call(StepSimulation, steps=1).result.result == Result.RESULT_OK
    assert host.simulation_state() == SimulationState.STATE_PAUSED
    assert host.set_simulation_state(SimulationState.STATE_PLAYING).result == Result.RESULT_OK
    assert host.simulation_state() == SimulationState.STATE_PLAYING


def test_reset_scopes_remove_spawned_bodies_and_reset_time(host):
    fresh(host, SimulationState.STATE_PAUSED)
    started = stamp_nanoseconds(host.state('club_left').header)
    host.spawn(name='extra', resource_string=BALL)
    host.call(StepSimulation, steps=4)
    spawned = ResetSimulation.Request.SCOPE_SPAWNED
    assert host.call(ResetSimulation, scope=spawned).result.result == Result.RESULT_OK
    assert host.entities() == SCENE_BODIES
    stepped = stamp_nanoseconds(host.state('club_left').header)
    assert stepped == started + 4 * TICK_NANOSECONDS
    both = ResetSimulation.Request.SCOPE_TIME | ResetSimulation.Request.SCOPE_STATE
    assert host.call(ResetSimulation, scope=both).result.result == Result.RESULT_OK
    # Simulated time 0 again for the bodies; the stamps count on (see the test above).
    assert stamp_nanoseconds(host.state('club_left').header) >= stepped
    assert pose_values(host.state('club_left'))[0] == [-0.3, 0.0, 1.0]
    assert_refused(host.call(ResetSimulation, scope=ResetSimulation.Request.SCOPE_TIME).result,
                   Result.RESULT_FEATURE_UNSUPPORTED, 'together')


def test_a_taken_name_is_refused_unless_renaming_is_allowed(host):
    fresh(host, SimulationState.STATE_PAUSED)
    assert_refused(host.spawn(name='club_left', resource_string=BALL).result,
                   SpawnEntity.Response.NAME_NOT_UNIQUE, "'club_left'", 'allow_renaming')
    response = host.spawn(name='club_left', allow_renaming=True, resource_string=BALL)
    assert response.result.result == Result.RESULT_OK, response.result.error_message
    assert response.entity_name == 'club_left_1'
    response = host.spawn(allow_renaming=True, resource_string=BALL)
    assert response.result.result == Result.RESULT_OK
    assert response.entity_name == 'body_1'


INVALID_POSES = [
    ({'pose': {'position': {'x': math.nan}}}, 'finite'),
    ({'pose': {'position': {'z': math.inf}}}, 'finite'),
    ({'pose': {'orientation': {'x': 0.5, 'w': 0.5}}}, 'unit quaternion'),
    ({'pose': {'orientation': {'w': 0.0}}}, 'unit quaternion'),
    ({'header': {'frame_id': 'elsewhere'}}, "'elsewhere'"),
]


@pytest.mark.parametrize('fields,words', INVALID_POSES)
def test_an_invalid_pose_is_refused_with_its_reason(host, fields, words):
    fresh(host, SimulationState.STATE_PAUSED)
    before = pose_values(host.state('club_middle'))
    state = fill(GetEntityState.Response().state, fields)
    assert_refused(_set_state(host, 'club_middle', state).result,
                   SetEntityState.Response.INVALID_POSE, words)
    initial_pose = {'header': fields.get('header', {}), 'pose': fields.get('pose', {})}
    if 'header' not in fields:
        initial_pose['pose'].setdefault('position', {}).setdefault('y', 1.0)
    assert_refused(host.spawn(name='posed', resource_string=BALL,
                              initial_pose=initial_pose).result,
                   SpawnEntity.Response.INVALID_POSE, words)
    assert 'posed' not in host.entities()
    assert pose_values(host.state('club_middle')) == before


def _set_state(host, name, state):
    """Call SetEntityState with a whole EntityState message."""
    client = host.clients[SetEntityState]
    future = client.call_async(SetEntityState.Request(entity=name, state=state))
    host.wait_for(future.done, RESPONSE_TIMEOUT, 'a response from set_entity_state')
    return future.result()


@pytest.mark.parametrize('twist', [{'linear': {'x': math.nan}}, {'angular': {'y': -math.inf}}])
def test_a_twist_that_is_not_finite_is_refused(host, twist):
    state = fill(GetEntityState.Response().state, {'twist': twist})
    assert_refused(_set_state(host, 'club_middle', state).result,
                   Result.RESULT_OPERATION_FAILED, 'twist')


@pytest.mark.parametrize('entity,quoted', [('nobody', "'nobody'"),
                                           ('\x1b[31m' * 100_000, '\\x1b[31m')],
                         ids=['name', 'megabyte_of_escapes'])
def test_an_unknown_entity_is_refused_by_every_service(host, entity, quoted):
    for kind in (GetEntityState, SetEntityState, DeleteEntity):
        # assert_refused: one printable line of at most 500 characters, quoting the name.
        assert_refused(host.call(kind, entity=entity).result, Result.RESULT_NOT_FOUND, quoted)


@pytest.mark.parametrize('fields,code,words', [
    ({}, SpawnEntity.Response.NO_RESOURCE, 'empty'),
    ({'name': 'x', 'resource_string': 'body: {mass: -1.0, shape: sphere, radius: 0.1}'},
     SpawnEntity.Response.RESOURCE_PARSE_ERROR, 'body.mass'),
    ({'name': 'x', 'resource_string': 'body: {mass: 1.0, shape: sphere, radius: 0.1}\n'
                                      'rate: 5'},
     SpawnEntity.Response.RESOURCE_PARSE_ERROR, 'rate'),
    ({'name': 'x', 'resource_string': '[1, 2'}, SpawnEntity.Response.RESOURCE_PARSE_ERROR,
     'YAML'),
    ({'name': 'x', 'resource_string': '- 1\n- 2'}, SpawnEntity.Response.RESOURCE_PARSE_ERROR,
     'mapping'),
    ({'name': 'x', 'resource_string': 'a: &a [1, 2]\n' + ''.join(
        f'{key}: &{key} [*{previous}, *{previous}, *{previous}, *{previous}]\n'
        for previous, key in zip('abcdefghijklmn', 'bcdefghijklmno'))},
     SpawnEntity.Response.RESOURCE_PARSE_ERROR, 'values'),
    ({'name': 'bad name', 'resource_string': BALL}, SpawnEntity.Response.NAME_INVALID,
     'letters'),
    ({'name': 'x' * 65, 'resource_string': BALL}, SpawnEntity.Response.NAME_INVALID, '64'),
    ({'resource_string': BALL}, SpawnEntity.Response.NAME_INVALID, 'allow_renaming'),
    ({'name': 'x', 'uri': 'https://example.com/ball.yaml'},
     SpawnEntity.Response.UNSUPPORTED_FORMAT, 'https'),
    ({'name': 'x', 'uri': '/no/such/ball.yaml'}, Result.RESULT_NOT_FOUND, 'No such file'),
    ({'name': 'x', 'uri': '/'}, Result.RESULT_NOT_FOUND, 'regular file'),
    ({'name': 'x', 'resource_string': BALL, 'entity_namespace': 'robots'},
     Result.RESULT_FEATURE_UNSUPPORTED, 'entity_namespace'),
], ids=['no_resource', 'schema', 'scene_key', 'not_yaml', 'not_a_mapping', 'alias_bomb',
        'invalid_name', 'long_name', 'no_name', 'https', 'no_file', 'directory', 'namespace'])
def test_a_spawn_is_refused_with_its_code_and_reason(host, fields, code, words):
    assert_refused(host.spawn(**fields).result, code, words)
    assert 'x' not in host.entities()


@pytest.mark.parametrize('filters,code,words', [
    ({'filter': '(unclosed'}, Result.RESULT_OPERATION_FAILED, 'regular expression'),
    ({'filter': 'a' * 300}, Result.RESULT_OPERATION_FAILED, '256'),
    ({'filter': '^(a|aa)*c'}, Result.RESULT_OPERATION_FAILED, 'exponential'),
    ({'filter': '(l)\\1'}, Result.RESULT_OPERATION_FAILED, 'back-references'),
    ({'categories': [{'category': 1}]}, Result.RESULT_FEATURE_UNSUPPORTED, 'categories'),
    ({'tags': {'tags': ['red']}}, Result.RESULT_FEATURE_UNSUPPORTED, 'tags'),
    ({'bounds': {'type': 3}}, Result.RESULT_FEATURE_UNSUPPORTED, 'bounds'),
])
def test_filters_not_served_are_refused(host, filters, code, words):
    request = fill(GetEntities.Request(), {})
    for name, value in filters.items():
        if name == 'categories':
            request.filters.categories = [EntityCategory(**item) for item in value]
        else:
            fill(request.filters, {name: value})
    client = host.clients[GetEntities]
    future = client.call_async(request)
    host.wait_for(future.done, RESPONSE_TIMEOUT, 'a response from get_entities')
    assert_refused(future.result().result, code, words)


def test_requests_outside_the_definitions_are_refused(host):
    fresh(host, SimulationState.STATE_PAUSED)
    assert_refused(host.call(StepSimulation, steps=2**64 - 1).result,
                   Result.RESULT_OPERATION_FAILED, 'at most')
    assert_refused(host.set_simulation_state(SimulationState.STATE_QUITTING),
                   Result.RESULT_FEATURE_UNSUPPORTED, 'quitting')
    assert_refused(host.set_simulation_state(SimulationState.STATE_NO_WORLD),
                   SetSimulationState.Response.INCORRECT_TRANSITION, 'world')
    assert_refused(host.set_simulation_state(77), Result.RESULT_OPERATION_FAILED, '77')
    assert_refused(host.call(ResetSimulation, scope=8).result,
                   Result.RESULT_FEATURE_UNSUPPORTED, 'scope 8')
    # The host still serves, paused at time 0.
    assert host.simulation_state() == SimulationState.STATE_PAUSED
    assert host.process.alive()


def test_the_client_side_imports_no_package_code():
    source = Path(__file__).read_text()
    imported = [line for line in source.splitlines()
                if line.startswith(('import ', 'from ')) and 'rigid_body_sim' in line]
    assert imported == []


# A DDS string is UTF-8 without NUL (rmw passes C strings): any other character, lone
# surrogates (which UTF-8 cannot encode, so no peer can send them) excepted.
TEXT = st.text(st.characters(blacklist_characters='\x00', blacklist_categories=('Cs',)),
               max_size=40)
NAMES = st.one_of(TEXT, st.sampled_from(SCENE_BODIES + ['ball', 'ball_1', '']))
NUMBERS = st.floats(allow_nan=True, allow_infinity=True)
ENTRIES = st.one_of(TEXT, st.just(BALL), st.builds(
    lambda mass, radius, x: f'body: {{mass: {mass!r}, shape: sphere, radius: {radius!r}}}\n'
                            f'initial: {{position: [{x!r}, 0, 0]}}', NUMBERS, NUMBERS, NUMBERS))


def _pose(values):
    return {'position': dict(zip('xyz', values[:3])),
            'orientation': dict(zip('xyzw', values[3:]))}


def _spawn_request(name, renaming, entry, uri, namespace, pose):
    return (SpawnEntity, {'name': name, 'allow_renaming': renaming, 'resource_string': entry,
                          'uri': uri, 'entity_namespace': namespace,
                          'initial_pose': {'pose': pose}})


def _set_state_request(name, frame, pose, twist):
    return (SetEntityState, {'entity': name, 'state': {
        'header': {'frame_id': frame}, 'pose': pose,
        'twist': {'linear': dict(zip('xyz', twist[:3])), 'angular': dict(zip('xyz', twist[3:]))}}})


POSES = st.lists(NUMBERS, min_size=7, max_size=7).map(_pose)
REQUESTS = st.one_of(
    st.builds(_spawn_request, NAMES, st.booleans(), ENTRIES, st.one_of(st.just(''), TEXT),
              st.one_of(st.just(''), TEXT), POSES),
    st.builds(_set_state_request, NAMES,
              st.one_of(st.sampled_from(['', 'world', '/world']), TEXT), POSES,
              st.lists(NUMBERS, min_size=6, max_size=6)),
    st.builds(lambda name: (GetEntityState, {'entity': name}), NAMES),
    st.builds(lambda name: (DeleteEntity, {'entity': name}), NAMES),
    st.builds(lambda pattern: (GetEntities, {'filters': {'filter': pattern}}), TEXT),
    st.builds(lambda pattern: (GetEntitiesStates, {'filters': {'filter': pattern}}), TEXT),
    st.builds(lambda steps: (StepSimulation, {'steps': steps}),
              st.one_of(st.integers(0, 20), st.integers(10001, 2**64 - 1))),
    st.builds(lambda state: (SetSimulationState, {'state': {'state': state}}),
              st.integers(0, 255)),
    st.builds(lambda scope: (ResetSimulation, {'scope': scope}), st.integers(0, 255)),
)
CODES = {Result.RESULT_OK, Result.RESULT_NOT_FOUND, Result.RESULT_OPERATION_FAILED,
         Result.RESULT_FEATURE_UNSUPPORTED, *range(101, 110)}


@settings(derandomize=True, database=None, deadline=None, max_examples=300,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(requests=st.lists(REQUESTS, min_size=1, max_size=3))
def test_any_request_is_answered_with_a_code_and_a_reason_and_the_host_lives(host, requests):
    for kind, fields in requests:
        response = host.call(kind, **fields)
        assert host.process.alive(), host.process.output()[-5000:]
        assert response.result.result in CODES, response.result
        if response.result.result != Result.RESULT_OK:
            assert_refused(response.result, response.result.result)
    # Every refusal was foreseen: none came from the services' safety net.
    assert 'request not served' not in host.process.output()
