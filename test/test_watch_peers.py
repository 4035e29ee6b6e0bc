"""
rigid-body-sim watch against any peer: arbitrary /diagnostics, pose and odom over DDS.

A stand-in node in this process (named as the node, in a namespace of its own) publishes
what watch reads: odom, angular_momentum, a marker and /diagnostics reports in its name.
Hypothesis generates their contents (any float, NaN, inf, 1e308; any text, control
characters, '$' and 100 kB strings; numbers as text); after each example a valid tick and
a report naming the example ('sentinel-N') follows on the same reliable publisher, so
watch has read the example once it shows the sentinel, while its newest tick is still the
example's if it took it.  The properties:

- watch stays alive and keeps showing what follows;
- no number it prints is non-finite or absurd (beyond 1e12): such values are said as
  'not finite' or 'absurd', and never reach the history;
- no control character reaches the terminal, and every line is bounded;
- its memory stays bounded (at most +50 MB over the examples).

Deterministic: derandomized, no example database, a fixed number of examples.
"""

import itertools
import math
from pathlib import Path
import re

from diagnostic_msgs.msg import DiagnosticArray
from diagnostic_msgs.msg import DiagnosticStatus
from diagnostic_msgs.msg import KeyValue
from geometry_msgs.msg import Vector3Stamped
from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from node_harness import isolate_ros_environment
from node_harness import unique_namespace
import pytest
import rclpy
from rigid_body_sim.messages.qos import DIAGNOSTICS_QOS
from rigid_body_sim.messages.qos import STATE_QOS
from rigid_body_sim.watch.live import ABSURD
from rigid_body_sim.watch.live import DIAGNOSTICS_KEYS
from test_watch import WatchProcess
from visualization_msgs.msg import Marker

EXAMPLES = 12
DETERMINISTIC = settings(derandomize=True, database=None, deadline=None,
                         max_examples=EXAMPLES,
                         suppress_health_check=[HealthCheck.too_slow,
                                                HealthCheck.function_scoped_fixture])
ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
# Text a ROS string can carry (UTF-8, no NUL), with the hostile ones named in issue 33.
TEXT = st.one_of(
    st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'),
            max_size=200),
    st.sampled_from(['spin $\\omega$ and $\\foo$', '\x1b]0;PWNED-TITLE\x07\x1b[2J',
                     'x' * 100_000, '1' + '0' * 308, 'nan', '-inf', '1e308', 'None']))
NUMBER_TEXT = st.one_of(ANY_FLOAT.map(repr), st.sampled_from(['1e308', '-1', '', '0']))
REPORT = st.dictionaries(st.sampled_from(sorted(DIAGNOSTICS_KEYS.values())),
                         st.one_of(TEXT, NUMBER_TEXT), max_size=25)
VECTOR = st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT)
QUATERNION = st.one_of(st.tuples(ANY_FLOAT, ANY_FLOAT, ANY_FLOAT, ANY_FLOAT),
                       st.just((0.0, 0.0, 0.0, 0.0)), st.just((0.0, 0.0, 0.0, 1.0)))
# The fields of watch's terminal block that hold numbers, and the words it says instead.
NUMBER_FIELDS = ('time', 'omega body', '|L|', 'energy drift')
VERDICTS = ('not finite', 'absurd', 'not reported')
PERIOD_NS = 10_000_000
FIRST_STAMP = 1_700_000_000_000_000_000


def simulated_time(stamp):
    """Return the simulated time (s) of the tick stamped `stamp`: 100 Hz from 0."""
    return (stamp - FIRST_STAMP) / 1e9


class StandIn:
    """A node in this process that publishes what the rigid_body_sim node does."""

    def __init__(self, namespace):
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('rigid_body_sim', namespace=namespace,
                                      context=self.context)
        self.name = f'{namespace}/rigid_body_sim'
        self.odom = self.node.create_publisher(Odometry, 'odom', STATE_QOS)
        self.momentum = self.node.create_publisher(Vector3Stamped, 'angular_momentum',
                                                   STATE_QOS)
        self.marker = self.node.create_publisher(Marker, 'marker', STATE_QOS)
        self.diagnostics = self.node.create_publisher(DiagnosticArray, '/diagnostics',
                                                      DIAGNOSTICS_QOS)
        self.ticks = itertools.count(1)

    def close(self):
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def tick(self, quaternion=(0.0, 0.0, 0.0, 1.0), position=(0.0, 0.0, 0.0),
             omega=(0.1, 2.0, 0.0), momentum=(0.0, 4.0, 0.0), frame='world'):
        """Publish one tick's odom, angular_momentum and marker; return its stamp (ns)."""
        stamp = FIRST_STAMP + next(self.ticks) * PERIOD_NS
        odom = Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        odom.header.frame_id = odom.child_frame_id = frame
        pose, twist = odom.pose.pose, odom.twist.twist
        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
         pose.orientation.w) = quaternion
        pose.position.x, pose.position.y, pose.position.z = position
        twist.angular.x, twist.angular.y, twist.angular.z = omega
        vector = Vector3Stamped(header=odom.header)
        vector.vector.x, vector.vector.y, vector.vector.z = momentum
        marker = Marker(header=odom.header, type=Marker.CUBE)
        marker.scale.x, marker.scale.y, marker.scale.z = 0.1, 0.3, 0.5
        marker.pose.orientation = pose.orientation
        self.odom.publish(odom)
        self.momentum.publish(vector)
        self.marker.publish(marker)
        return stamp

    def report(self, stamp, values, message='running'):
        """Publish a /diagnostics report in the node's name, stamped just after `stamp`."""
        array = DiagnosticArray()
        array.header.stamp.sec, array.header.stamp.nanosec = divmod(stamp + 1,
                                                                    1_000_000_000)
        array.status = [DiagnosticStatus(
            name='rigid_body_sim: simulation', hardware_id=self.name, message=message,
            values=[KeyValue(key=key, value=value) for key, value in values.items()])]
        self.diagnostics.publish(array)


def _sane(key, value):
    return {DIAGNOSTICS_KEYS['rate']: '100', DIAGNOSTICS_KEYS['scene']: key,
            DIAGNOSTICS_KEYS['effects']: 'none', DIAGNOSTICS_KEYS['integrator']: 'buss',
            DIAGNOSTICS_KEYS['paused']: 'False', DIAGNOSTICS_KEYS['wrench_active']: 'False',
            DIAGNOSTICS_KEYS['simulated_time']: f'{value:.6f}',
            DIAGNOSTICS_KEYS['energy_drift']: '+1.000e-12'}


def _fields(block):
    fields = {}
    for line in block[1:]:
        label, _, text = line.strip().partition('  ')
        fields[label] = text.strip()
    return fields


def _numbers_shown_are_finite_and_sane(block):
    """Return the first number of the block's number fields that is not, or None."""
    fields = _fields(block)
    for name in NUMBER_FIELDS:
        text = fields.get(name, '')
        for verdict in VERDICTS:
            text = text.replace(verdict, '')
        for token in re.findall(r'[-+]?[\w.]+', text):
            try:
                number = float(token)
            except ValueError:
                continue
            if not (math.isfinite(number) and abs(number) <= ABSURD):
                return f'{name}: {token}'
    return None


def _resident_megabytes(pid):
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return 0.0


@pytest.fixture(scope='module')
def watched():
    """Yield (stand-in node, watch process) once watch shows the stand-in."""
    isolate_ros_environment()
    namespace = unique_namespace()
    stand_in = StandIn(namespace)
    watch = WatchProcess(['--terminal', '--namespace', namespace, '--interval', '0.1'])
    try:
        stamp = stand_in.tick()

        def shown(blocks, lines):
            # Publish until watch has subscribed and shows a report (discovery takes a while).
            nonlocal stamp
            stamp = stand_in.tick()
            stand_in.report(stamp, _sane('start', 0.5))
            stand_in.tick()
            return blocks and _fields(blocks[-1]).get('scene', '').startswith('start')
        watch.wait_for(shown, 'the stand-in node shown')
        yield stand_in, watch
    finally:
        code, errors = watch.stop()
        stand_in.close()
    assert 'Traceback' not in errors, errors


examples = itertools.count()
memory = []


@DETERMINISTIC
@given(report=REPORT, status=TEXT, quaternion=QUATERNION, position=VECTOR, omega=VECTOR,
       momentum=VECTOR, frame=TEXT)
def test_any_peer_message_leaves_watch_alive_finite_escaped_and_bounded(
        watched, report, status, quaternion, position, omega, momentum, frame):
    stand_in, watch = watched
    index = next(examples)
    seen = len(watch.lines)
    stamp = stand_in.tick(quaternion, position, omega, momentum, frame[:1000])
    stand_in.report(stamp, report, status)
    stamp = stand_in.tick(quaternion, position, omega, momentum, frame[:1000])
    # A valid report and no tick after it: watch has read the example once it shows the
    # report, and its newest tick is still the example's if it took it.
    sentinel = f'sentinel-{index}'
    stand_in.report(stamp, _sane(sentinel, 100.0 + index))
    block = watch.wait_for(lambda blocks, lines: next((
        block for block in reversed(blocks)
        if _fields(block).get('scene', '').startswith(sentinel)), None), sentinel)
    assert watch.process.poll() is None
    lines = watch.lines[seen:]
    assert not any(character in line for line in lines for character in '\x1b\x07\r'), \
        'a control character reached the terminal'
    assert max(map(len, lines)) < 2000
    blocks = [block for block in watch.blocks if block[0] in lines]
    for shown in blocks + [block]:
        assert _numbers_shown_are_finite_and_sane(shown) is None, shown
    memory.append(_resident_megabytes(watch.process.pid))
    assert memory[-1] - memory[0] <= 50.0, memory


def _watch_stand_in(namespace):
    """Return (stand-in, watch) once watch shows the stand-in's reports."""
    stand_in = StandIn(namespace)
    watch = WatchProcess(['--terminal', '--namespace', namespace, '--interval', '0.1'])

    def shown(blocks, lines):
        stamp = stand_in.tick()
        stand_in.report(stamp, _sane('start', simulated_time(stamp)))
        stand_in.tick()
        return blocks and _fields(blocks[-1]).get('scene', '').startswith('start')
    watch.wait_for(shown, 'the stand-in node shown')
    # One report more, awaited alone: watch then has taken the stand-in's last report, the
    # one whose sequence number a later claim must continue (the loop above may have
    # published more while watch lagged, and a reader of /diagnostics keeps only a few).
    stamp = stand_in.tick()
    stand_in.report(stamp, _sane('start-last', simulated_time(stamp)))
    watch.wait_for(lambda blocks, lines: blocks and _fields(blocks[-1]).get(
        'scene', '').startswith('start-last'), "the stand-in's last report shown")
    return stand_in, watch


def test_a_second_node_of_the_same_name_is_said_and_never_mixed_in():
    isolate_ros_environment()
    namespace = unique_namespace()
    first, watch = _watch_stand_in(namespace)
    second = StandIn(namespace)  # another participant: publisher GIDs of its own
    try:
        def warned(blocks, lines):
            first.tick()
            second.tick(omega=(9.0, 0.0, 0.0), momentum=(9.0, 0.0, 0.0))
            return blocks and any('a second node named' in line for line in blocks[-1])
        block = watch.wait_for(warned, 'the warning of a second node')
        seen = len(watch.lines)
        for _ in range(50):
            second.tick(omega=(9.0, 0.0, 0.0), momentum=(9.0, 0.0, 0.0))
        stamp = first.tick()
        first.report(stamp, _sane('after', simulated_time(stamp)))
        block = watch.wait_for(lambda blocks, lines: next((
            block for block in reversed(blocks)
            if _fields(block).get('scene', '').startswith('after')), None), 'the report after')
        assert not any('+9.0000' in line for line in watch.lines[seen:]), block
        assert any('refused' in line and 'another publisher' in line for line in block), block
    finally:
        code, errors = watch.stop()
        first.close()
        second.close()
    assert 'Traceback' not in errors, errors


def test_a_report_in_the_nodes_name_from_another_publisher_is_not_taken():
    isolate_ros_environment()
    namespace = unique_namespace()
    node, watch = _watch_stand_in(namespace)
    spoofer = StandIn(unique_namespace())  # another node, on the shared /diagnostics
    spoofer.name = node.name
    try:
        def warned(blocks, lines):
            stamp = node.tick()
            node.report(stamp, _sane('steady', simulated_time(stamp)))
            # A reset claimed: time 0, and a scene of its own.
            spoofer.report(stamp, _sane('spoofed', 0.0))
            return blocks and any('claimed the node' in line for line in blocks[-1])
        watch.wait_for(warned, 'the spoofed report refused')
        assert not any('spoofed' in line for line in watch.lines)
        assert not any('reset' in _fields(block).get('changes', '') for block in watch.blocks)
    finally:
        code, errors = watch.stop()
        node.close()
        spoofer.close()
    assert 'Traceback' not in errors, errors
