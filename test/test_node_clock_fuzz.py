"""
Property-based fuzzing of the node's /clock over DDS: no clock a peer sends breaks or fools it.

One node (use_sim_time, the t_handle scene at 100 Hz) for the module, its /clock remapped
into a namespace of its own; a peer in this process publishes /clock messages drawn by
hypothesis: any int32 ``sec`` and uint32 ``nanosec`` (negative seconds, a nanosecond field
of a second or more, 2^31 - 1 s, backwards, repeated), one to five per example, each left to
the node for three ticks (three states arrive after it: the ticks between stamp with it if
it is taken).  After each example the peer publishes a valid clock of its own, at a time no
example draws, and waits for a state stamped with it: /clock keeps the order of one
publisher, so every message of the example has then been taken (or lost: /clock is best
effort).  The properties:

- the node process is alive after every example, and still ticks at the end;
- every stamp of the state topics is a valid /clock time the peer sent (or 0, before the
  first): never one made of a refused message;
- a /diagnostics report whose count of refused /clock messages rose since the report
  before is a WARN that says so.

Derandomized, no example database, a fixed number of examples, no deadline (a loaded
machine is no failure).
"""

import time

from diagnostic_msgs.msg import DiagnosticStatus
from hypothesis import given
from hypothesis import HealthCheck
from hypothesis import settings
from hypothesis import strategies as st
from node_harness import Client
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import unique_namespace
import pytest
from rigid_body_sim.messages.qos import CLOCK_QOS
from rosgraph_msgs.msg import Clock

pytestmark = pytest.mark.xdist_group('node')

EXAMPLES = 200
TICKS_PER_CLOCK = 3
DETERMINISTIC = settings(derandomize=True, database=None, deadline=None, max_examples=EXAMPLES,
                         suppress_health_check=[HealthCheck.too_slow,
                                                HealthCheck.function_scoped_fixture])
SYNC_TIMEOUT = 60.0  # s: a failure detector
STAMPED = ('pose', 'angular_momentum', 'odom')
NANOSECONDS = 1_000_000_000
# The peer's own clock after each example: seconds no example draws (they are in the range
# drawn below only as the sampled edge values, which are elsewhere).
SYNC_SECONDS = 1_500_000_000

SECONDS = st.one_of(st.integers(-2**31, 2**31 - 1),
                    st.sampled_from([-2**31, -5, -1, 0, 1, 48, 49, 2**31 - 1]))
NANOSECONDS_FIELD = st.one_of(st.integers(0, 2**32 - 1),
                              st.sampled_from([0, 1, NANOSECONDS - 1, NANOSECONDS,
                                               2**32 - 1]))
CLOCKS = st.lists(st.tuples(SECONDS, NANOSECONDS_FIELD), min_size=1, max_size=5)


def _is_time(sec, nanosec):
    return sec >= 0 and nanosec < NANOSECONDS


def _stamp(message):
    return message.header.stamp.sec * NANOSECONDS + message.header.stamp.nanosec


class _Peer:
    """The node, a client recording its topics, and a /clock publisher into its namespace."""

    def __init__(self, log_path):
        isolate_ros_environment()
        namespace = unique_namespace()
        self.node = NodeProcess(log_path, namespace=namespace,
                                parameters={'scene': 't_handle', 'use_sim_time': True,
                                            'rate': 100.0},
                                extra_arguments=['-r', f'/clock:={namespace}/clock'])
        self.client = Client(namespace)
        self.publisher = self.client.node.create_publisher(Clock, f'{namespace}/clock',
                                                           CLOCK_QOS)
        self.valid = {0}  # ns: every valid time sent, and 0 (before the first)
        self.synced = 0

    def publish(self, sec, nanosec):
        message = Clock()
        message.clock.sec, message.clock.nanosec = sec, nanosec
        if _is_time(sec, nanosec):
            self.valid.add(sec * NANOSECONDS + nanosec)
        self.publisher.publish(message)

    def sync(self):
        """Send a clock of the peer's own until a state stamped with it comes back."""
        self.synced += 1
        sec = SYNC_SECONDS + self.synced
        since = time.monotonic()
        deadline = since + SYNC_TIMEOUT
        while True:
            self.publish(sec, 0)
            try:
                self.client.wait_for(lambda: any(
                    _stamp(m) == sec * NANOSECONDS for m in self.client.messages('pose', since)),
                    0.5, 'a pose stamped with the peer clock')
                return
            except AssertionError:
                if time.monotonic() > deadline or not self.node.alive():
                    raise

    def close(self):
        self.client.close()
        return self.node.stop()


@pytest.fixture(scope='module')
def peer(tmp_path_factory):
    """Start the node and its peer for the module; the node must exit cleanly at the end."""
    peer = _Peer(tmp_path_factory.mktemp('clock_fuzz') / 'node.log')
    try:
        peer.client.wait_until_connected(inputs=False)
        peer.client.wait_for(lambda: peer.publisher.get_subscription_count() > 0, SYNC_TIMEOUT,
                             'the node subscribed to /clock')
        peer.sync()
    except AssertionError as error:
        peer.close()
        raise AssertionError(f'{error}; node output:\n{peer.node.output()}') from None
    yield peer
    assert peer.close() == 0, peer.node.output()


def test_no_clock_a_peer_sends_ends_the_node_or_stamps_its_messages(peer):
    """Any /clock messages: the node lives, and its stamps are only valid clocks sent."""
    started = time.monotonic()

    @DETERMINISTIC
    @given(clocks=CLOCKS)
    def example(clocks):
        since = time.monotonic()
        for sec, nanosec in clocks:
            sent = time.monotonic()
            peer.publish(sec, nanosec)
            peer.client.wait_for_messages('pose', TICKS_PER_CLOCK, since=sent,
                                          timeout=SYNC_TIMEOUT)
        peer.sync()
        assert peer.node.alive(), peer.node.output()
        for topic in STAMPED:
            foreign = {_stamp(m) for m in peer.client.messages(topic, since)} - peer.valid
            assert not foreign, (topic, sorted(foreign)[:5], clocks)

    example()
    # Still ticking: states after the last example, stamped with the last valid clock.
    peer.sync()
    print(f'{EXAMPLES} examples in {time.monotonic() - started:.1f} s')


def test_a_report_after_a_refused_clock_is_a_warn_saying_so(peer):
    """
    Every report whose count of refused /clock messages rose is a WARN naming the refusal.

    Runs after the fuzzing above.  The count is compared with the last report before the
    refused messages were sent, and the reports are awaited until one counts them: a burst
    may reach the node's /clock queue (depth 1) as one message on a loaded machine, and the
    client keeps only the recent reports.
    """
    def counted(since=None):
        reports = []
        for message in peer.client.messages('/diagnostics', since):
            status = next(s for s in message.status
                          if s.hardware_id == f'{peer.client.namespace}/{NODE_NAME}')
            values = {pair.key: pair.value for pair in status.values}
            if '/clock refused' in values:
                reports.append((int(values['/clock refused']), status.level, status.message))
        return reports
    peer.client.wait_for_messages('/diagnostics', 1, since=time.monotonic(),
                                  timeout=SYNC_TIMEOUT)
    baseline = counted()[-1]
    since = time.monotonic()
    for _ in range(5):
        peer.publish(-5, 0)
    peer.client.wait_for(lambda: any(count > baseline[0] for count, _, _ in counted(since)),
                         SYNC_TIMEOUT, 'a report counting the refused /clock messages')
    reports = [baseline] + counted(since)
    risen = [(level, text) for (before, _, _), (after, level, text) in zip(reports, reports[1:])
             if after > before]
    assert risen, reports
    for level, text in risen:
        assert level == DiagnosticStatus.WARN and '/clock message(s) refused' in text, text
    assert peer.node.alive(), peer.node.output()
