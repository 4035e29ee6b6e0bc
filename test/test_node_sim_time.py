"""
Sim time over real DDS: /clock from simulated time, real_time_factor, and use_sim_time.

Each test starts its own node.  /clock is an absolute name, so each node's is remapped into
its namespace (``-r /clock:=<ns>/clock``, which also moves its own use_sim_time
subscription): concurrent test nodes never hear each other's clock.
"""

import time

from diagnostic_msgs.msg import DiagnosticStatus
from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import STATE_TYPES
from node_harness import unique_namespace
import pytest
from rigid_body_sim.messages.qos import CLOCK_QOS
from rigid_body_sim.node.clock_guard import ClockGuard
from rigid_body_sim.node.clock_guard import STALL_SECONDS
from rosgraph_msgs.msg import Clock

pytestmark = pytest.mark.xdist_group('node')

SCENE = 't_handle'  # no inputs to wait for
# Simulated time starts at 0: a stamp below this (s) is simulated, not the system clock.
SIMULATED = 1.0e6


@pytest.fixture(autouse=True)
def ros_environment():
    """Isolate this process's ROS domain (and so its children's)."""
    isolate_ros_environment()


def nanoseconds(stamp):
    """Return a builtin_interfaces/Time in ns."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def start(tmp_path, parameters):
    """Start a node of SCENE with `parameters` and a client that also records its clock."""
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'scene': SCENE, **parameters},
                       extra_arguments=['-r', f'/clock:={namespace}/clock'])
    client = Client(namespace, extra_topics={'clock': (Clock, CLOCK_QOS)})
    try:
        client.wait_until_connected(inputs=False)
    except AssertionError as error:
        client.close()
        node.stop()
        raise AssertionError(f'{error}; node output:\n{node.output()}') from None
    return node, client


def stop(node, client):
    """Stop the client and the node; the node must exit cleanly."""
    client.close()
    assert node.stop() == 0, node.output()


def assert_nominal_spacing(stamps, period_ns, what):
    """Stamps (ns) strictly increase by whole periods, mostly by exactly one."""
    steps = [after - before for before, after in zip(stamps, stamps[1:])]
    assert steps, f'too few {what}'
    assert all(step > 0 and step % period_ns == 0 for step in steps), (what, steps)
    # Best effort (/clock) or a slow client may lose some; most are consecutive.
    assert steps.count(period_ns) >= 0.5 * len(steps), (what, steps)


def test_clock_is_published_monotonic_at_the_nominal_spacing(tmp_path):
    """With publish_clock, /clock counts 1/rate per tick from 0 and stamps every message."""
    rate = 100.0
    period_ns = round(1e9 / rate)
    node, client = start(tmp_path, {'publish_clock': True, 'rate': rate})
    try:
        since = time.monotonic()
        client.wait_for_messages('clock', 100, since=since)
        client.wait_for_messages('/diagnostics', 1, since=since)
        clocks = [nanoseconds(m.clock) for m in client.messages('clock', since)]
        assert_nominal_spacing(clocks, period_ns, '/clock messages')
        assert clocks[-1] < SIMULATED * 1e9, clocks[-1]
        for topic in ('pose', 'angular_momentum', 'odom', 'marker'):
            stamps = [nanoseconds(m.header.stamp) for m in client.messages(topic, since)]
            assert_nominal_spacing(stamps, period_ns, topic)
            # The same simulated time as the clock: no stamp ahead of the latest clock.
            assert stamps[-1] <= nanoseconds(client.messages('clock')[-1].clock)
        diagnostics = client.messages('/diagnostics', since)[-1]
        assert nanoseconds(diagnostics.header.stamp) < SIMULATED * 1e9
        # The clock is the simulated time since start-up.
        status = next(s for s in diagnostics.status
                      if s.hardware_id == f'{client.namespace}/{NODE_NAME}')
        values = {kv.key: kv.value for kv in status.values}
        assert float(values['clock [s]']) == pytest.approx(
            float(values['simulated time [s]']), abs=1e-6)
        # A reset restarts the body, not the clock: it never goes back.
        assert client.reset().success
        replied = time.monotonic()
        later = [nanoseconds(m.clock) for m in client.wait_for_messages('clock', 10, replied)]
        assert min(later) > clocks[-1]
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        stop(node, client)


@pytest.mark.parametrize('rate, real_time_factor', [(50.0, 2.0), (200.0, 0.5)])
def test_real_time_factor_scales_the_wall_rate_not_the_stamps(tmp_path, rate,
                                                              real_time_factor):
    """Tick rate x real_time_factor times per wall-clock second, stamped 1/rate apart."""
    period_ns = round(1e9 / rate)
    wall_rate = rate * real_time_factor  # 100 messages per second in both cases
    node, client = start(tmp_path, {'publish_clock': True, 'rate': rate,
                                    'real_time_factor': real_time_factor})
    try:
        # The wall rate is the node's schedule (Client.scheduled_rate: ticks taken plus
        # missed per wall second, as a starved machine cannot take them all); the stamps
        # are 1/rate apart and advance by one period per tick taken.
        since = time.monotonic()
        assert abs(client.scheduled_rate(since) / wall_rate - 1.0) <= 0.15
        stamps = [nanoseconds(m.header.stamp) for m in client.messages('pose', since)]
        assert len(stamps) >= 10
        assert_nominal_spacing(stamps, period_ns, 'pose stamps')
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        stop(node, client)


@pytest.mark.parametrize('publish_clock', [True, False])
def test_a_node_on_sim_time_still_ticks(tmp_path, publish_clock):
    """
    use_sim_time:=true: the tick does not wait for a /clock, even one it publishes itself.

    With publish_clock its clock and stamps are the simulated time; without, nothing
    publishes /clock, so the node's ROS clock stays at 0 and so do its stamps.
    """
    rate = 100.0
    node, client = start(tmp_path, {'use_sim_time': True, 'publish_clock': publish_clock,
                                    'rate': rate})
    try:
        since = time.monotonic()
        for topic in STATE_TYPES:
            client.wait_for_messages(topic, int(0.5 * rate), since=since)
        stamps = [nanoseconds(m.header.stamp) for m in client.messages('pose', since)]
        if publish_clock:
            assert_nominal_spacing(stamps, round(1e9 / rate), 'pose stamps')
            # Best effort: waited for, not counted within a window.
            client.wait_for_messages('clock', int(0.5 * rate), since=since)
        else:
            assert set(stamps) == {0}
            assert not client.messages('clock')
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        stop(node, client)


def test_a_change_of_pace_or_a_parameter_applies_at_once_not_after_the_old_deadline(tmp_path):
    """
    At 1 Hz x 0.001 the next tick is 1000 s away: a change must not wait for it.

    A parameter change (the integrator, logged when applied) and a new real_time_factor
    (1000: a tick every ms) both take effect at once; the node then publishes.
    """
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'scene': SCENE, 'rate': 1.0, 'real_time_factor': 0.001})
    client = Client(namespace)
    try:
        client.wait_for(client.parameters_client.service_is_ready, 120.0,
                        'the parameter service')
        assert client.set_parameter('integrator', 'rk4').successful
        client.wait_for(lambda: 'integrator is now rk4' in node.output(), 60.0,
                        'the integrator change to be applied')
        assert client.set_parameter('real_time_factor', 1000.0).successful
        client.wait_for_messages('pose', 5, timeout=60.0)
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        stop(node, client)


def publish_clock_messages(client, namespace, times, until, what, timeout=30.0):
    """
    Publish /clock messages of (sec, nanosec) into the node's remapped clock topic.

    Again every half second until `until()` holds: that this side sees the node's
    subscription does not mean the node's side has matched this publisher yet, and a message
    sent before that is lost.
    """
    publisher = client.node.create_publisher(Clock, f'{namespace}/clock', CLOCK_QOS)
    client.wait_for(lambda: publisher.get_subscription_count() > 0, timeout,
                    'the node subscribed to /clock')
    deadline = time.monotonic() + timeout
    while True:
        for sec, nanosec in times:
            message = Clock()
            message.clock.sec = sec
            message.clock.nanosec = nanosec
            publisher.publish(message)
        try:
            client.wait_for(until, 0.5, what)
            return publisher
        except AssertionError:
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out after {timeout:g} s waiting for {what}')


def latest_status(client, since):
    """Return (level, message, values) of the node's first /diagnostics report after `since`."""
    message = client.wait_for_messages('/diagnostics', 1, since=since)[-1]
    status = next(s for s in message.status if s.hardware_id.endswith(NODE_NAME))
    return status.level, status.message, {kv.key: kv.value for kv in status.values}


def test_a_clock_message_that_is_not_a_time_is_refused_and_the_node_lives_on(tmp_path):
    """
    /clock {sec: -5} once ended the node (rclpy's TimeSource raised in the executor).

    Now it is refused in one log line, /diagnostics says so (WARN), and a valid /clock
    after it still sets the clock the stamps come from.
    """
    node, client = start(tmp_path, {'use_sim_time': True, 'rate': 100.0})
    try:
        publish_clock_messages(client, client.namespace, [(-5, 0), (3, 2_000_000_000)],
                               lambda: 'refused a /clock message' in node.output(),
                               'the refusal')
        assert node.alive(), node.output()
        refusals = [line for line in node.output().splitlines() if 'refused a /clock' in line]
        assert len(refusals) == 1, refusals
        since = time.monotonic()
        level, message, values = latest_status(client, since)
        # Every /clock message that came was refused (each of the two is not a time).
        assert int(values['/clock refused']) >= 1, values
        assert values['/clock refused'] == values['/clock received'], values
        assert level == DiagnosticStatus.WARN and 'no /clock received yet' in message, message
        publish_clock_messages(client, client.namespace, [(42, 5)],
                               lambda: any(nanoseconds(m.header.stamp) == 42_000_000_005
                                           for m in client.messages('pose', since)),
                               'a pose stamped with the valid /clock')
    finally:
        stop(node, client)


def test_an_input_expires_on_the_steady_clock_when_the_ros_clock_stands_still(tmp_path):
    """
    use_sim_time with a /clock that never advances: a torque still ends after input_timeout.

    Before: one /torque {z: 0.5} drove the body forever (L_z rising by 0.5 a second).  The
    node runs at 100 Hz, input_timeout 0.5 s: the torque acts for 0.5 s of ticks (within a
    tick or two of the time the tick that applies it comes), so L_z changes by 0.25 N m s.
    """
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'scene': 'default', 'use_sim_time': True, 'rate': 100.0,
                                   'input_timeout': 0.5},
                       extra_arguments=['-r', f'/clock:={namespace}/clock'])
    client = Client(namespace, extra_topics={'clock': (Clock, CLOCK_QOS)})
    try:
        client.wait_until_connected()
        publish_clock_messages(client, namespace, [(7, 0)],
                               lambda: any(nanoseconds(m.header.stamp) == 7_000_000_000
                                           for m in client.messages('angular_momentum')),
                               'a state stamped with /clock')
        before = client.wait_for_messages('angular_momentum', 1, since=time.monotonic())[-1]
        client.publish_torque((0.0, 0.0, 0.5))
        # 100 ticks (1 s at 100 Hz: twice the timeout), then 50 more: the torque must have
        # ended in between; torque-free, buss keeps world L exactly.
        held = client.wait_for_messages('angular_momentum', 100, since=time.monotonic())[-1]
        later = client.wait_for_messages('angular_momentum', 50, since=time.monotonic())[-1]
        assert later.vector.z == held.vector.z, (held.vector.z, later.vector.z)
        # At most 0.5 s of torque: 0.25 N m s, and a tick of 0.005 more for the tick that
        # applies it.
        change = held.vector.z - before.vector.z
        assert 0.0 < change <= 0.25 + 0.005 + 1e-9, change
        level, message, _ = latest_status(client, time.monotonic())
        assert level == DiagnosticStatus.WARN and '/clock has not advanced' in message, message
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def test_use_sim_time_is_refused_at_run_time_with_a_reason(tmp_path):
    node, client = start(tmp_path, {})
    try:
        result = client.set_parameter('use_sim_time', True)
        assert not result.successful and 'set at start-up only' in result.reason
    finally:
        stop(node, client)


def test_the_clock_guard_refuses_what_is_not_a_time_and_says_what_the_stamps_mean():
    guard = ClockGuard()
    assert guard.receive(-5, 0, now=0.0) is None
    assert guard.receive(0, 1_000_000_000, now=0.0) is None
    assert guard.time is None and guard.rejected == 2
    problems, _ = guard.status(now=0.0)
    assert [kind for _, kind in problems] == ['stamps', 'peer']
    assert guard.receive(2**31 - 1, 999_999_999, now=1.0) == (2**31 - 1) * 10**9 + 999_999_999
    assert guard.receive(48, 0, now=1.5) == 48 * 10**9 and guard.went_back == 1
    assert guard.stamps_ordered(now=1.5)
    # Standing still: the stamps no longer tell before from after.
    assert guard.receive(48, 0, now=1.5 + 2 * STALL_SECONDS) == 48 * 10**9
    assert not guard.stamps_ordered(now=1.5 + 2 * STALL_SECONDS)
    problems, values = guard.status(now=1.5 + 2 * STALL_SECONDS)
    assert dict(values)['/clock went back'] == '1'
    assert any('has not advanced' in text for text, _ in problems)
    # Each period reports what happened in it: nothing new refused or gone back.
    problems, _ = guard.status(now=1.5 + 2 * STALL_SECONDS)
    assert [kind for _, kind in problems] == ['stamps']
