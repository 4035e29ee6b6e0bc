"""
Sim time over real DDS: /clock from simulated time, real_time_factor, and use_sim_time.

Each test starts its own node.  /clock is an absolute name, so each node's is remapped into
its namespace (``-r /clock:=<ns>/clock``, which also moves its own use_sim_time
subscription): concurrent test nodes never hear each other's clock.
"""

import time

from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import STATE_TYPES
from node_harness import unique_namespace
import pytest
from rigid_body_sim.messages.qos import CLOCK_QOS
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
