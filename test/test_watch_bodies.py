"""
rigid-body-sim watch on a node of several bodies: one body (--body), or the table of them.

The views' text is checked on made-up states; over DDS against the juggler's three clubs
(config/scenes/juggling_clubs.yaml), paused so that every number is fixed: ``--body`` shows
that club's numbers (not another's), an unknown body is one line naming the clubs and exit
2, and the table lists every club, sorted, cut to the terminal's height.  The window, under
Xvfb, shows the first club and the next one at the key n (pressed through XTEST).
"""

import ctypes
import ctypes.util
import os
import re
import signal
import time

from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import unique_namespace
import numpy as np
import pytest
from rigid_body_sim.messages.qos import STATE_QOS
from rigid_body_sim.watch.live import bodies_text
from rigid_body_sim.watch.live import BodyTable
from rigid_body_sim.watch.live import DIAGNOSTICS_KEYS
from rigid_body_sim.watch.live import format_number
from rigid_body_sim.watch.live import LiveState
from rigid_body_sim.watch.terminal import render_lines
from rigid_body_sim.watch.terminal import table_lines
from rigid_body_sim.watch.terminal import TABLE_MARGIN
from test_watch import _fields
from test_watch import _start_xvfb
from test_watch import _window_only
from test_watch import WatchProcess

CLUBS = ('club_left', 'club_middle', 'club_right')
FIRST_STAMP = 1_700_000_000_000_000_000
PERIOD_NS = 10_000_000


def _report(state, k, simulated, extra=None):
    values = {DIAGNOSTICS_KEYS['simulated_time']: f'{simulated:.6f}',
              DIAGNOSTICS_KEYS['rate']: '100', DIAGNOSTICS_KEYS['integrator']: 'buss',
              DIAGNOSTICS_KEYS['paused']: 'False', DIAGNOSTICS_KEYS['scene']: 'juggling_clubs',
              DIAGNOSTICS_KEYS['bodies']: '3', DIAGNOSTICS_KEYS['effects']: 'gravity'}
    values.update(extra or {})
    state.add_diagnostics(FIRST_STAMP + k * PERIOD_NS + 50_000, values)


def _feed(state, ticks, every=1):
    """Feed a body turning at 2 rad/s about y, its state published every `every` ticks."""
    for k in ticks:
        if k % every:
            continue
        angle = 0.01 * k
        stamp = FIRST_STAMP + k * PERIOD_NS
        state.add_odometry(stamp, (0.0, np.sin(angle), 0.0, np.cos(angle)), (0.0, 0.0, 1.0),
                           (0.0, 2.0, 0.0))
        state.add_angular_momentum(stamp, (0.0, 4.0, 0.0))


def test_states_published_every_kth_tick_are_k_periods_apart():
    state = LiveState(history=100.0)
    state.set_node('/rigid_body_sim', 'club_left', CLUBS)
    _feed(state, range(0, 40, 4))
    _report(state, 20, 0.2, extra={DIAGNOSTICS_KEYS['publish_every']: '4'})
    _feed(state, range(40, 80), every=4)
    snapshot = state.snapshot()
    np.testing.assert_allclose(np.diff(snapshot.time), 0.04, atol=1e-9)
    assert snapshot.current_time == pytest.approx(0.76, abs=1e-9)


def test_a_bodys_view_names_it_and_gives_the_drift_its_effects_conserve():
    state = LiveState(history=100.0)
    state.set_node('/rigid_body_sim', 'club_middle', CLUBS)
    _feed(state, range(1, 20))
    _report(state, 10, 0.1)
    _feed(state, range(20, 30))
    lines = render_lines(state.snapshot())
    assert lines[0].startswith('rigid-body-sim watch: /rigid_body_sim body club_middle (2 of '
                               '3): ')
    fields = _fields(lines)
    assert fields['scene'].startswith('juggling_clubs (3 bodies; effects on club_middle: '
                                      'gravity)')
    # T_rot = 1/2 Omega . R^T L = 1/2 (2 rad/s)(4 kg m^2/s), constant: no drift (but the
    # rounding of R^T L).
    assert fields['energy'].startswith(f'T_rot {format_number(4.0, signed=False)} J')
    energy, momentum, since = re.fullmatch(r'T_rot (\S+), \|L\| (\S+) \(relative, (.*)\)',
                                           fields['drift']).groups()
    assert abs(float(energy)) < 1e-14 and abs(float(momentum)) < 1e-14
    assert since == 'since watch started; its effects conserve both'


def test_a_body_under_effects_that_conserve_nothing_has_no_drift_shown():
    state = LiveState(history=100.0)
    state.set_node('/rigid_body_sim', 'club_left', CLUBS)
    _feed(state, range(1, 20))
    _report(state, 10, 0.1, extra={DIAGNOSTICS_KEYS['effects']: 'gravity, linear_drag'})
    _feed(state, range(20, 30))
    assert _fields(render_lines(state.snapshot()))['drift'].startswith(
        'not charted: T_rot and |L| are not conserved under its effects (gravity, linear_drag)')


def _table(count):
    state = LiveState()
    names = tuple(sorted(f'debris_{k:03d}' for k in range(count)))
    state.set_node('/rigid_body_sim', None, names)
    table = BodyTable()
    for k, name in enumerate(names):
        table.add_odometry(name, (0.0, 0.0, 0.0, 1.0), (float(k), 0.0, 0.0), (0.0, 0.0, 3.0),
                           (3.0, 4.0, 0.0))
        table.add_angular_momentum(name, (0.0, 0.0, 2.0))
    return state.snapshot(), table


def test_the_table_shows_a_line_per_body_shown_and_counts_the_others():
    snapshot, table = _table(100)
    shown = snapshot.bodies[:7]
    lines = table_lines(snapshot, table.rows(), shown)
    rows = [line.split() for line in lines[2:9]]
    assert [row[0] for row in rows] == list(shown)
    assert rows[3][1:] == [format_number(3.0, 6, signed=False),
                           format_number(2.0, 6, signed=False), format_number(3.0, 6),
                           format_number(0.0, 6), format_number(0.0, 6),
                           format_number(5.0, 5, signed=False)]
    assert lines[9] == '  ... and 93 more (--body NAME to watch one)'
    assert '100 bodies' in lines[0]


def test_a_refused_state_is_said_in_its_row_and_never_shown():
    snapshot, table = _table(3)
    table.add_odometry('debris_001', (0.0, 0.0, 0.0, 1.0), (float('nan'), 0.0, 0.0),
                       (0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    lines = table_lines(snapshot, table.rows(), snapshot.bodies)
    assert lines[3].split() == ['debris_001', 'refused:', 'not', 'finite', '(not', 'shown)']


def test_a_list_of_bodies_is_one_line_of_the_first_few_and_a_count():
    assert bodies_text(CLUBS) == 'club_left, club_middle, club_right'
    assert bodies_text([f'b{k}' for k in range(100)]) == 'b0, b1, b2, b3, b4 ... and 95 more'


# -- over DDS: the clubs' node, the watch as a subprocess


@pytest.fixture(scope='module')
def clubs(tmp_path_factory):
    """Start juggling_clubs in a namespace of its own; yield a client of its clubs."""
    isolate_ros_environment()
    namespace = unique_namespace()
    process = NodeProcess(tmp_path_factory.mktemp('watch_clubs') / 'node.log',
                          namespace=namespace, parameters={'scene': 'juggling_clubs'})
    topics = {}
    for club in CLUBS:
        topics[f'{club}/odom'] = (Odometry, STATE_QOS)
        topics[f'{club}/angular_momentum'] = (Vector3Stamped, STATE_QOS)
    client = Client(namespace, extra_topics=topics)
    try:
        client.wait_for(lambda: all(client.received(topic) for topic in topics)
                        and client.pause_client.service_is_ready(), DISCOVERY_TIMEOUT,
                        'every club and the pause service')
    except AssertionError as error:
        client.close()
        process.stop()
        raise AssertionError(f'{error}; node output:\n{process.output()}') from None
    yield client
    client.close()
    process.stop()


def _pause(client):
    """Pause the node; return once every state it publishes is the frozen one."""
    client.pause(True)
    since = time.monotonic()
    # Two paused reports: every state after the first one is the frozen one.
    client.wait_for(lambda: sum(client.diagnostics_values(message)['paused'] == 'True'
                                for message in client.messages('/diagnostics', since))
                    >= 2, DISCOVERY_TIMEOUT, 'two paused reports')


def _frozen(client, club):
    """Return (omega body, |L|) of `club` as the paused node publishes it."""
    angular = client.messages(f'{club}/odom')[-1].twist.twist.angular
    vector = client.messages(f'{club}/angular_momentum')[-1].vector
    return ((angular.x, angular.y, angular.z),
            float(np.linalg.norm([vector.x, vector.y, vector.z])))


@pytest.mark.xdist_group('clubs_watch')
def test_watch_body_shows_that_bodys_numbers(clubs):
    _pause(clubs)
    omega, momentum = _frozen(clubs, 'club_middle')
    expected = '  '.join(format_number(w) for w in omega) + ' rad/s'
    watch = WatchProcess(['--terminal', '--namespace', clubs.namespace, '--body',
                          'club_middle', '--interval', '0.1'])
    try:
        block = watch.wait_for(lambda blocks, lines: next((
            block for block in reversed(blocks)
            if block[0].endswith('body club_middle (2 of 3): paused')
            and _fields(block).get('omega body') == expected
            # The drift once a report has timed a tick (under load, a refresh or more after
            # the first block): an event awaited, not the first block's placeholder.
            and 'its effects conserve both' in _fields(block).get('drift', '')), None),
            f'club_middle at omega {expected}, its drift shown')
    finally:
        code, errors = watch.stop()
    fields = _fields(block)
    assert fields['|L|'] == f'{format_number(momentum, signed=False)} kg m^2/s'
    other, _ = _frozen(clubs, 'club_left')
    assert fields['omega body'] != '  '.join(format_number(w) for w in other) + ' rad/s'
    assert fields['scene'].startswith('juggling_clubs (3 bodies; effects on club_middle: '
                                      'gravity)')
    assert 'its effects conserve both' in fields['drift']
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors


@pytest.mark.xdist_group('clubs_watch')
def test_an_unknown_body_is_one_line_naming_the_bodies_and_exit_2(clubs):
    watch = WatchProcess(['--terminal', '--namespace', clubs.namespace, '--body', 'club_top'])
    code, errors = watch.stop(signal_number=None, timeout=DISCOVERY_TIMEOUT)
    assert code == 2, errors
    assert errors.strip().splitlines() == [
        f'rigid-body-sim watch: {clubs.namespace}/rigid_body_sim has no body named '
        "'club_top'; its 3 bodies: club_left, club_middle, club_right"]


@pytest.mark.xdist_group('clubs_watch')
def test_the_table_lists_every_body_sorted_with_its_numbers(clubs):
    _pause(clubs)
    expected = {club: format_number(float(np.linalg.norm(_frozen(clubs, club)[0])), 6,
                                    signed=False) for club in CLUBS}

    def table(blocks, lines):
        for block in reversed(blocks):
            rows = [line.split() for line in block if line.startswith('  club_')]
            if block[0].endswith(' paused; 3 bodies (scene juggling_clubs): --body NAME '
                                 'watches one') and len(rows) == 3 \
                    and all(row[1] == expected[row[0]] for row in rows):
                return rows
        return None
    watch = WatchProcess(['--terminal', '--namespace', clubs.namespace, '--interval', '0.1'])
    try:
        rows = watch.wait_for(table, f'the table of the three clubs at {expected}')
    finally:
        code, errors = watch.stop()
    assert [row[0] for row in rows] == list(CLUBS)
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors


@pytest.mark.xdist_group('clubs_watch')
def test_the_table_is_cut_to_the_terminals_height(clubs):
    watch = WatchProcess(['--terminal', '--namespace', clubs.namespace, '--interval', '0.1'],
                         environment={'LINES': str(TABLE_MARGIN + 2)})
    try:
        block = watch.wait_for(lambda blocks, lines: next((
            block for block in reversed(blocks)
            if '  ... and 1 more (--body NAME to watch one)' in block
            and sum(line.startswith('  club_') and 'waiting' not in line for line in block)
            == 2), None), 'two clubs and one more')
    finally:
        code, errors = watch.stop()
    assert [line.split()[0] for line in block if line.startswith('  club_')] == list(CLUBS[:2])
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors


# -- the window, under Xvfb: n shows the next club


def _press(display, key):
    """Press and release `key` on the X `display` through the XTEST extension."""
    x11 = ctypes.CDLL(ctypes.util.find_library('X11'))
    xtst = ctypes.CDLL(ctypes.util.find_library('Xtst'))
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XStringToKeysym.restype = ctypes.c_ulong
    x11.XKeysymToKeycode.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
    x11.XFlush.argtypes = [ctypes.c_void_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    xtst.XTestFakeKeyEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int,
                                       ctypes.c_ulong]
    connection = x11.XOpenDisplay(display.encode())
    assert connection, f'cannot open X display {display}'
    code = x11.XKeysymToKeycode(connection, x11.XStringToKeysym(key.encode()))
    xtst.XTestFakeKeyEvent(connection, code, 1, 0)
    xtst.XTestFakeKeyEvent(connection, code, 0, 0)
    x11.XFlush(connection)
    x11.XCloseDisplay(connection)


@pytest.mark.xdist_group('clubs_watch')
def test_the_window_shows_the_first_club_then_the_next_at_n(clubs, tmp_path):
    pytest.importorskip('tkinter', reason='this Python has no tkinter (the window needs it)')
    if not (ctypes.util.find_library('X11') and ctypes.util.find_library('Xtst')):
        pytest.skip('libX11 or libXtst is missing (the test presses n through XTEST)')
    from PIL import ImageGrab
    # The window says it shows a body once its charts hold 2 simulated s: running.
    clubs.pause(False)
    xvfb, display = _start_xvfb()
    watch = WatchProcess(['--namespace', clubs.namespace], environment={'DISPLAY': display})
    try:
        watch.wait_for(lambda blocks, lines: any(
            line.endswith('window shows ' f'{clubs.namespace}/rigid_body_sim body club_left '
                          '(1 of 3)') for line in lines), 'club_left drawn')
        _press(display, 'n')
        watch.wait_for(lambda blocks, lines: any(
            line.endswith('body club_middle (2 of 3)') for line in lines), 'club_middle drawn')
        screen = _window_only(ImageGrab.grab(xdisplay=display))
        screen.save(tmp_path / 'watch_club_middle.png')
    finally:
        code, errors = watch.stop()
        xvfb.terminate()
        xvfb.wait(10.0)
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors
    pixels = np.asarray(screen.convert('RGB')).astype(int)
    red, green, blue = np.moveaxis(pixels[:, :int(0.38 * pixels.shape[1])], 2, 0)
    # club_middle is green (0.2, 0.8, 0.2), club_left red (0.9, 0.2, 0.2), both drawn half
    # transparent and shaded: pale, unlike the saturated lines of the body axes.
    pale_green = ((green > 150) & (red > 60) & (red < 200) & (blue > 60) & (blue < 200)
                  & (green - red > 50)).sum()
    pale_red = ((red > 180) & (green > 60) & (green < 190) & (blue > 60) & (blue < 190)
                & (red - green > 50)).sum()
    assert pale_green > 1000, f'club_middle: {pale_green} pale green pixels ({tmp_path})'
    assert pale_red < 500, f'club_left still drawn: {pale_red} pale red pixels ({tmp_path})'
    if os.environ.get('WATCH_BODIES_SCREENSHOT'):
        screen.save(os.environ['WATCH_BODIES_SCREENSHOT'])


def test_a_count_of_ticks_ahead_of_a_node_of_bodies_report_is_no_reset_time_going_back_is():
    state = LiveState(history=100.0)
    state.set_node('/rigid_body_sim', 'club_left', CLUBS)
    _feed(state, range(0, 40, 4))
    _report(state, 20, 0.2, extra={DIAGNOSTICS_KEYS['publish_every']: '4'})
    # The node went to every 3rd tick after the report: counted as 4, the ticks run ahead.
    _feed(state, range(40, 100, 3))
    _report(state, 97, 0.97, extra={DIAGNOSTICS_KEYS['publish_every']: '3'})
    _feed(state, range(100, 130, 3))
    snapshot = state.snapshot()
    assert snapshot.resets_seen == 0
    assert snapshot.current_time == pytest.approx(1.27, abs=1e-9)
    # A reset: the next report's time is behind the last report's.
    _feed(state, range(130, 160, 3))
    _report(state, 142, 0.12, extra={DIAGNOSTICS_KEYS['publish_every']: '3'})
    _feed(state, range(160, 163, 3))
    assert state.snapshot().resets_seen == 1
