"""
rigid-body-sim watch: the live view shows what the node publishes, and follows its changes.

The timing model (simulated time from the reports, resets, pauses, flips) is checked on
made-up ticks; the terminal view against a real node's messages over DDS, paused so that
every number is fixed; the window for real, under Xvfb, by the pixels of a screenshot.
"""

import os
import shutil
import signal
import subprocess
import sys
import threading
import time

from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NodeProcess
from node_harness import PACKAGE_ROOT
from node_harness import unique_namespace
import numpy as np
import pytest
from rigid_body_sim.watch.live import DIAGNOSTICS_KEYS
from rigid_body_sim.watch.live import format_number
from rigid_body_sim.watch.live import LiveState
from rigid_body_sim.watch.terminal import render_lines

RATE = 100.0
PERIOD_NS = 10_000_000


def _feed(state, stamps, omega=lambda k: (0.0, 2.0, 0.0), moving=True):
    for k in stamps:
        angle = 0.001 * k if moving else 0.0
        quaternion = (0.0, np.sin(angle), 0.0, np.cos(angle))
        stamp = 1_700_000_000_000_000_000 + k * PERIOD_NS
        state.add_odometry(stamp, quaternion, (0.0, 0.0, 0.0), omega(k))
        state.add_angular_momentum(stamp, (0.0, 4.0, 0.0))


def _t_handle_marker(state, k):
    """Give `state` the marker of a box whose middle edge (and middle moment) is along y."""
    from visualization_msgs.msg import Marker
    marker = Marker(type=Marker.CUBE)
    marker.scale.x, marker.scale.y, marker.scale.z = 0.1, 0.3, 0.5
    marker.pose.orientation.w = 1.0
    state.add_marker(1_700_000_000_000_000_000 + k * PERIOD_NS, marker)


def _report(state, k, simulated, paused=False, extra=None):
    values = {DIAGNOSTICS_KEYS['simulated_time']: f'{simulated:.6f}',
              DIAGNOSTICS_KEYS['rate']: f'{RATE:g}', DIAGNOSTICS_KEYS['integrator']: 'buss',
              DIAGNOSTICS_KEYS['paused']: str(paused),
              DIAGNOSTICS_KEYS['effects']: 'external_wrench'}
    values.update(extra or {})
    # The node stamps its report just after the tick's state, in the same tick.
    state.add_diagnostics(1_700_000_000_000_000_000 + k * PERIOD_NS + 50_000, values)


def test_ticks_get_simulated_time_from_the_report_of_their_tick():
    state = LiveState(history=100.0)
    _feed(state, range(1, 60))
    assert state.snapshot().current_time is None  # no report yet
    _report(state, 50, 7.5)  # the node has run 7.5 s when the watch joins
    _feed(state, range(60, 80))
    snapshot = state.snapshot()
    np.testing.assert_allclose(snapshot.time, 7.5 + (np.arange(1, 80) - 50) / RATE,
                               atol=1e-9)


def test_a_report_behind_the_count_is_a_reset_and_forgets_what_came_before():
    state = LiveState(history=100.0)
    flips = iter([2.0] * 30 + [-2.0] * 40 + [2.0] * 100)
    _feed(state, range(1, 2), omega=lambda k: (0.0, next(flips), 0.0))
    _t_handle_marker(state, 1)  # the middle axis is y
    _feed(state, range(2, 71), omega=lambda k: (0.0, next(flips), 0.0))
    _report(state, 20, 0.2)
    assert state.snapshot().flips == 1
    # Reset at tick 71 (time 0, the state restarts): the report of tick 75 says 0.05 s.
    _feed(state, range(71, 80), omega=lambda k: (0.0, next(flips), 0.0))
    _report(state, 75, 0.05)
    _feed(state, range(80, 82), omega=lambda k: (0.0, next(flips), 0.0))
    snapshot = state.snapshot()
    assert snapshot.resets_seen == 1 and snapshot.flips == 0
    np.testing.assert_allclose(snapshot.time, (np.arange(71, 82) - 70) / RATE, atol=1e-9)
    assert ('reset' in [name for _, name, _ in snapshot.events])


def test_paused_ticks_do_not_advance_simulated_time():
    state = LiveState(history=100.0)
    _feed(state, range(1, 21))
    _report(state, 10, 0.1)
    _feed(state, range(21, 41), moving=False)  # the same state, tick after tick
    snapshot = state.snapshot()
    assert snapshot.current_time == pytest.approx(0.21, abs=1e-9)


def test_an_integrator_switch_is_noted_at_its_time():
    state = LiveState(history=100.0)
    _feed(state, range(1, 21))
    _report(state, 10, 0.1)
    state.add_parameter_change('integrator', 'rk4')
    time_of_switch, name, value = state.snapshot().events[-1]
    assert (name, value) == ('integrator', 'rk4')
    assert time_of_switch == pytest.approx(0.2, abs=1e-9)


def test_an_integrator_switch_is_one_event_though_the_next_report_says_it_too():
    state = LiveState(history=100.0)
    _feed(state, range(1, 21))
    _report(state, 10, 0.1)
    state.add_parameter_change('integrator', 'rk4')
    _feed(state, range(21, 121))
    _report(state, 110, 1.1, extra={DIAGNOSTICS_KEYS['integrator']: 'rk4'})
    assert [name for _, name, _ in state.snapshot().events] == ['integrator']


def test_a_state_not_finite_or_absurd_never_enters_the_history_and_is_said():
    state = LiveState(history=100.0)
    _feed(state, range(1, 21))
    _report(state, 10, 0.1)
    _feed(state, range(21, 23))
    before = state.snapshot()
    for k, omega in ((23, (float('nan'), 0.0, 0.0)), (24, (1e300, 0.0, 0.0))):
        _feed(state, [k], omega=lambda k, omega=omega: omega)
    state.add_odometry(1_700_000_000_000_000_000 + 25 * PERIOD_NS, (0.0, 0.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0), (0.0, 2.0, 0.0))
    snapshot = state.snapshot()
    assert len(snapshot.time) == len(before.time)
    assert snapshot.latest is before.latest
    assert np.all(np.isfinite(snapshot.angular_velocity_body))
    assert snapshot.refused['odom'] == ('absurd', 3)
    text = '\n'.join(render_lines(snapshot))
    assert 'odom: 3 (absurd' in text
    assert format_number(float('nan')) == 'not finite' and format_number(1e300) == 'absurd'


def test_report_numbers_not_finite_or_absurd_are_said_and_keep_the_history_bounded():
    state = LiveState(history=1.0)
    state.set_node('/rigid_body_sim')
    _feed(state, range(1, 21))
    _report(state, 10, 0.1)
    # A spoofed rate: the ticks keep the last rate the node gave, and old ones are dropped.
    _report(state, 20, 0.2, extra={DIAGNOSTICS_KEYS['rate']: 'nan'})
    _feed(state, range(21, 1000))
    snapshot = state.snapshot()
    assert snapshot.time[-1] - snapshot.time[0] <= 1.0 + 1e-9
    _report(state, 999, 9.99, extra={DIAGNOSTICS_KEYS['simulated_time']: '1' + '0' * 308,
                                     DIAGNOSTICS_KEYS['energy_drift']: 'inf'})
    _feed(state, range(1000, 1002))
    text = '\n'.join(render_lines(state.snapshot()))
    assert '0' * 20 not in text and 'None' not in text
    assert 'energy drift  not finite' in text
    assert state.snapshot().current_time == pytest.approx(10.01, abs=1e-9)


def test_peer_strings_reach_the_terminal_cut_and_escaped():
    state = LiveState(history=100.0)
    _feed(state, range(1, 21))
    _report(state, 10, 0.1, extra={
        DIAGNOSTICS_KEYS['status']: '\x1b]0;PWNED-TITLE\x07\x1b[2J',
        DIAGNOSTICS_KEYS['scene']: 'x' * 5_000_000, 'k' * 100_000: 'v'})
    _feed(state, range(21, 23))
    lines = render_lines(state.snapshot())
    assert not any(c in line for line in lines for c in '\x1b\x07')
    assert max(len(line) for line in lines) < 600
    assert 'PWNED-TITLE' in lines[0]


def test_flips_count_sign_changes_along_the_middle_axis_only_while_the_body_is_free():
    state = LiveState(history=100.0)
    _feed(state, range(1, 2))
    _t_handle_marker(state, 1)
    # Pushed, the body turns about z and back: no flips while the input acts.
    _report(state, 1, 0.01, extra={DIAGNOSTICS_KEYS['wrench_active']: 'True'})
    swings = iter([(0.0, 2.0, 0.0)] * 10 + [(0.0, -2.0, 0.0)] * 10 + [(0.0, 2.0, 0.0)] * 10)
    _feed(state, range(2, 32), omega=lambda k: next(swings))
    assert state.snapshot().flips == 0
    # Free: each swing of Omega_y through zero is a flip; Omega_z's swings are not.
    _report(state, 31, 0.31, extra={DIAGNOSTICS_KEYS['wrench_active']: 'False'})
    swings = iter([(0.0, 2.0, 0.0)] * 10 + [(0.0, -2.0, 0.0)] * 10 + [(0.0, 2.0, 0.0)] * 10
                  + [(0.0, 0.1, 2.0)] * 10 + [(0.0, 0.1, -2.0)] * 10)
    _feed(state, range(32, 82), omega=lambda k: next(swings))
    snapshot = state.snapshot()
    assert snapshot.flips == 2
    assert snapshot.flips_since == 'since watch started'


def test_the_trail_keeps_a_pose_each_time_the_body_turned_two_degrees():
    state = LiveState(history=100.0)
    angles = np.radians(np.arange(0.0, 90.0, 0.5))  # half a degree per tick
    for k, angle in enumerate(angles):
        stamp = 1_700_000_000_000_000_000 + k * PERIOD_NS
        state.add_odometry(stamp, (0.0, 0.0, np.sin(angle / 2), np.cos(angle / 2)),
                           (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        state.add_angular_momentum(stamp, (0.0, 0.0, 1.0))
    trail = state.snapshot().trail
    turned = np.degrees(2.0 * np.arctan2(trail[:, 2], trail[:, 3]))
    # Each kept pose at least 2 degrees from the one before, at most one tick more.
    steps = np.diff(turned)
    assert np.all(steps > 2.0 - 1e-6) and np.all(steps < 2.5 + 1e-6), steps
    assert turned[-1] > 89.5 - 2.5


# -- over DDS: the node, the watch as a subprocess


class WatchProcess:
    """`rigid-body-sim watch` as a subprocess; its stdout collected in blocks."""

    def __init__(self, arguments, environment=None):
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'rigid_body_sim.cli', 'watch', *arguments],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=PACKAGE_ROOT,
            env=dict(os.environ, PYTHONUNBUFFERED='1', **(environment or {})))
        self.blocks = []
        self.lines = []
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        block = []
        for line in self.process.stdout:
            line = line.rstrip('\n')
            with self._lock:
                self.lines.append(line)
                if line:
                    block.append(line)
                elif block:
                    self.blocks.append(block)
                    block = []

    def wait_for(self, condition, what, timeout=DISCOVERY_TIMEOUT):
        """Wait until condition(blocks, lines) returns something true; return it."""
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:
                found = condition(list(self.blocks), list(self.lines))
            if found:
                return found
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise AssertionError(f'watch: no {what}; it printed:\n'
                                     + '\n'.join(self.lines) + self.process.stderr.read())
            time.sleep(0.02)  # waits-for: poll interval of the output reader

    def stop(self, signal_number=signal.SIGINT, timeout=20.0):
        """Stop it with a signal (None: let it end); return its exit code and stderr."""
        if self.process.poll() is None and signal_number is not None:
            self.process.send_signal(signal_number)
        try:
            self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(5.0)
        self._reader.join(5.0)
        return self.process.returncode, self.process.stderr.read()


def _fields(block):
    """Return {label: text} of a terminal block's lines '  label   text'."""
    fields = {}
    for line in block[1:]:
        label, _, text = line.strip().partition('  ')
        fields[label] = text.strip()
    return fields


@pytest.fixture(scope='module')
def node(tmp_path_factory):
    """Start the default scene at 100 Hz in a namespace of its own; yield a client."""
    isolate_ros_environment()
    namespace = unique_namespace()
    process = NodeProcess(tmp_path_factory.mktemp('watch') / 'node.log', namespace=namespace,
                          parameters={'rate': RATE})
    client = Client(namespace)
    try:
        client.wait_until_connected()
    except AssertionError as error:
        client.close()
        process.stop()
        raise AssertionError(f'{error}; node output:\n{process.output()}') from None
    yield client
    client.close()
    process.stop()


def _paused_reports(client, since):
    """Return the {key: value} of the reports after `since` that say paused."""
    return [client.diagnostics_values(message)
            for message in client.messages('/diagnostics', since)
            if client.diagnostics_values(message)['paused'] == 'True']


def _frozen_state(client):
    """Pause the node; return (when, reports while paused, last odom, last L)."""
    client.pause(True)
    since = time.monotonic()
    # Two paused reports: every state after the first one is the frozen one.
    client.wait_for(lambda: len(_paused_reports(client, since)) >= 2, DISCOVERY_TIMEOUT,
                    'two paused reports')
    return (since, _paused_reports(client, since), client.messages('odom')[-1],
            client.messages('angular_momentum')[-1])


@pytest.mark.xdist_group('node')
def test_the_terminal_view_prints_the_nodes_numbers(node):
    since, reports, odom, momentum = _frozen_state(node)
    watch = WatchProcess(['--terminal', '--namespace', node.namespace, '--interval', '0.1'])
    try:
        time_text = f'{float(reports[-1]["simulated time [s]"]):.6f} s simulated'

        def paused_block(blocks, lines):
            # (Flips are counted once the marker has told the principal axes.)
            return next((block for block in reversed(blocks) if block[0].endswith('paused')
                         and _fields(block).get('time') == time_text
                         and 'principal axis' in _fields(block).get('flips', '')), None)
        block = watch.wait_for(paused_block, f'block at {time_text}')
        fields = _fields(block)
        angular = odom.twist.twist.angular
        assert fields['omega body'] == '  '.join(
            format_number(w) for w in (angular.x, angular.y, angular.z)) + ' rad/s'
        vector = momentum.vector
        magnitude = float(np.linalg.norm([vector.x, vector.y, vector.z]))
        assert fields['|L|'] == f'{format_number(magnitude, signed=False)} kg m^2/s'
        # The report's own strings, of one of the paused reports (the client may receive
        # the one the watch shows a little later).

        def shown(report):
            return (fields['energy drift'].startswith(report['energy drift since last input'])
                    and fields['substeps'].startswith(report['substeps'] + ' per tick')
                    and fields['ticks/s'].startswith(report['achieved rate [Hz]'] + ' '))
        node.wait_for(lambda: any(shown(report) for report in _paused_reports(node, since)),
                      DISCOVERY_TIMEOUT, f'a report with the numbers of {fields}')
        assert fields['flips'].startswith('0 since watch started (sign changes of Omega along '
                                          'the middle principal axis')

        # A reset shows as time 0 at the next report; a switch of integrator at once.
        node.reset()
        watch.wait_for(lambda blocks, lines: _fields(blocks[-1]).get('time')
                       == '0.000000 s simulated', 'time 0 after the reset')
        assert node.set_parameter('integrator', 'rk4').successful
        watch.wait_for(lambda blocks, lines: 'integrator rk4' in _fields(blocks[-1]).get(
            'changes', ''), 'the switch to rk4')
        node.pause(False)
        watch.wait_for(lambda blocks, lines: blocks[-1][0].endswith(': running')
                       and 'integrator rk4 at 100 Hz' in _fields(blocks[-1]).get('scene', ''),
                       'running under rk4')
    finally:
        code, errors = watch.stop()
        node.pause(False)
        node.set_parameter('integrator', 'buss')
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors


def test_no_node_found_is_said_and_a_timeout_exits_with_1(tmp_path):
    isolate_ros_environment()
    watch = WatchProcess(['--terminal', '--namespace', unique_namespace(), '--timeout', '1.5'])
    watch.wait_for(lambda blocks, lines: any('no rigid_body_sim node named' in line
                                             for line in lines), 'no-node message')
    code, errors = watch.stop(signal_number=None, timeout=DISCOVERY_TIMEOUT)
    assert code == 1 and 'giving up (--timeout)' in errors and 'Traceback' not in errors


# -- the window, under Xvfb


def _start_xvfb():
    """Start Xvfb on a free display; return (process, ':N'), or skip if it is missing."""
    xvfb = shutil.which('Xvfb')
    if xvfb is None:
        pytest.skip('Xvfb is not installed (apt install xvfb; .ci/run installs it)')
    read, write = os.pipe()
    # -s 0: no screen saver blanking the screen under the test.
    process = subprocess.Popen([xvfb, '-displayfd', str(write), '-screen', '0', '1400x900x24',
                                '-nolisten', 'tcp', '-s', '0'], pass_fds=(write,),
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    # Xvfb writes the display number once it accepts clients: the event to wait for.
    with os.fdopen(read) as pipe:
        number = pipe.readline().strip()
    if not number:
        process.kill()
        pytest.fail('Xvfb did not start')
    return process, f':{number}'


_CURVES = (('Omega_x', (214, 39, 40)), ('Omega_y', (44, 160, 44)), ('Omega_z', (31, 119, 180)),
           ('T_rot drift', (255, 127, 14)))
"""The strip charts' curves: Omega_x, _y, _z in tab red, green, blue, the drift in orange."""


def _regions(screen):
    """Return the screenshot's pixels (int RGB) left of the charts (the body) and the charts."""
    pixels = np.asarray(screen.convert('RGB')).astype(int)
    width = pixels.shape[1]
    return pixels[:, :int(0.38 * width)], pixels[:, int(0.38 * width):]


def near(region, colour, tolerance=30):
    """Return how many pixels of `region` are within `tolerance` of `colour`."""
    return int((np.abs(region - np.array(colour)).max(axis=2) <= tolerance).sum())


def _orange_body_pixels(body):
    # The default scene's body (orange, 0.85 0.55 0.15, shaded and half transparent).
    red, green, blue = body[..., 0], body[..., 1], body[..., 2]
    return int(((red > 180) & (green > 110) & (green < 200) & (blue < 130)).sum())


def _window_drawn(screen):
    body, charts = _regions(screen)
    return (_orange_body_pixels(body) > 2000
            and all(near(charts, colour) > 200 for _, colour in _CURVES))


@pytest.mark.xdist_group('node')
def test_the_window_shows_the_body_and_both_charts(node, tmp_path):
    pytest.importorskip('tkinter', reason='this Python has no tkinter (the window needs it)')
    from PIL import ImageGrab
    xvfb, display = _start_xvfb()
    watch = WatchProcess(['--namespace', node.namespace], environment={'DISPLAY': display})
    try:
        watch.wait_for(lambda blocks, lines: any('window shows' in line for line in lines),
                       'window drawn')
        # The charts grow as messages come (slowly on a loaded machine) and the T-handle's
        # plate shows edge-on at times as it turns: screenshots until the body and every
        # curve are drawn, the bound a failure detector.
        deadline = time.monotonic() + 120.0
        while True:
            screen = ImageGrab.grab(xdisplay=display)
            if _window_drawn(screen) or time.monotonic() > deadline:
                break
            time.sleep(0.2)  # waits-for: poll interval of the loop waiting for the curves
        screen = _window_only(screen)
        screen.save(tmp_path / 'watch.png')
    finally:
        code, errors = watch.stop()
        xvfb.terminate()
        xvfb.wait(10.0)
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors
    body, charts = _regions(screen)
    # The body: a plate of thousands of orange pixels on the left.
    orange = _orange_body_pixels(body)
    assert orange > 2000, f'body: {orange} orange pixels ({tmp_path})'
    for name, colour in _CURVES:
        assert near(charts, colour) > 200, f'{name}: {near(charts, colour)} pixels'
    # The README's picture is this test's: retaken by a passing run with
    # RIGID_BODY_SIM_UPDATE_DOC_IMAGES=1 (never by a plain run: the checkout stays clean).
    if os.environ.get('RIGID_BODY_SIM_UPDATE_DOC_IMAGES') == '1':
        screen.save(PACKAGE_ROOT / 'docs' / 'watch_window.png', optimize=True)


def _window_only(screen):
    """Return the screenshot cut to the window (the Xvfb screen around it is black)."""
    pixels = np.asarray(screen.convert('RGB')).max(axis=2)
    rows, columns = np.nonzero(pixels > 0)
    return screen.crop((columns.min(), rows.min(), columns.max() + 1, rows.max() + 1))


@pytest.mark.xdist_group('node')
def test_the_window_draws_peer_text_with_dollars_as_text(tmp_path):
    # A scene named as mathtext (the scenes command accepts it): every redraw once raised
    # matplotlib's ParseFatalException, and the window never drew while stdout said it did.
    pytest.importorskip('tkinter', reason='this Python has no tkinter (the window needs it)')
    isolate_ros_environment()
    scene = (PACKAGE_ROOT / 'config' / 'scenes' / 'default.yaml').read_text()
    path = tmp_path / 'dollars.yaml'
    path.write_text(scene.replace('name: default', "name: 'spin $\\omega$ and $\\foo$'", 1))
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace,
                       parameters={'scene': str(path)})
    xvfb, display = _start_xvfb()
    watch = WatchProcess(['--namespace', namespace], environment={'DISPLAY': display})
    try:
        watch.wait_for(lambda blocks, lines: any('window shows' in line for line in lines),
                       'window drawn')
    finally:
        code, errors = watch.stop()
        node.stop()
        xvfb.terminate()
        xvfb.wait(10.0)
    assert not any('could not be drawn' in line for line in watch.lines), watch.lines
    assert code == 128 + signal.SIGINT and 'Traceback' not in errors, errors


@pytest.mark.xdist_group('node')
def test_body_on_a_one_body_node_is_one_line_and_exit_2(node):
    watch = WatchProcess(['--terminal', '--namespace', node.namespace, '--body', 'club_left'])
    code, errors = watch.stop(signal_number=None, timeout=DISCOVERY_TIMEOUT)
    assert code == 2, errors
    assert errors.strip().splitlines() == [
        f'rigid-body-sim watch: {node.namespace}/rigid_body_sim simulates one body (its topics '
        'odom, angular_momentum, marker): watch it without --body']
