"""
Kernels not compiled yet: compiled beside the node, never blocking its services or ticks.

Until they are, the node integrates with the kernels' source interpreted (the same steps):
its first state comes at once, whatever the compile takes.

The set-up compiled every integrator, so these nodes run with the test hook
``RIGID_BODY_SIM_ASSUME_UNCOMPILED`` (:mod:`rigid_body_sim.node.background_compile`) naming the
integrators they must take for not compiled.  The compilation is the real command
(``python -m rigid_body_sim.cli compile NAME --quiet``) behind a gate: a
``sitecustomize`` module on its PYTHONPATH holds it at start until the test writes the gate
file (``ok``, or ``fail`` for a compilation that fails), and notes that it started.  So the
test sees the node while a compilation runs, however fast or slow the machine, and decides
when it ends; a node that compiled in its own process would not answer until the gate
opened, which the test only does after the answers came.
"""

from pathlib import Path

from node_harness import Client
from node_harness import DISCOVERY_TIMEOUT
from node_harness import isolate_ros_environment
from node_harness import NODE_NAME
from node_harness import NodeProcess
from node_harness import unique_namespace
import pytest
from rcl_interfaces.srv import GetParameters
from rigid_body_sim.node.background_compile import ASSUME_UNCOMPILED

pytestmark = pytest.mark.xdist_group('node')

GATE = """
import os
import sys
import time

# python -m rigid_body_sim.cli compile NAME --quiet: sys.argv here is ['-m', 'compile', ...]
if os.environ.get('TEST_COMPILE_GATE') and sys.argv[1:2] == ['compile']:
    gate = os.path.join(os.environ['TEST_COMPILE_GATE'], sys.argv[2])
    # Written whole, then named: the test reads it as soon as the name exists.
    with open(gate + '.started.tmp', 'w') as started:
        started.write(str(os.getpid()))
    os.replace(gate + '.started.tmp', gate + '.started')
    while not os.path.exists(gate):
        time.sleep(0.02)  # waits-for: the test opening the gate
    if open(gate).read() == 'fail':
        print('error: the test gate failed this compilation', file=sys.stderr, flush=True)
        os._exit(3)
"""


def open_gate(gate, verdict):
    """Open a compilation's gate with `verdict` ('ok' or 'fail'), written whole, then named."""
    partial = gate.with_name(gate.name + '.tmp')
    partial.write_text(verdict)
    partial.replace(gate)


@pytest.fixture(autouse=True)
def ros_environment():
    """Isolate this process's ROS domain (and so its children's)."""
    isolate_ros_environment()


def start(tmp_path, uncompiled):
    """Start a node (default scene, 100 Hz) taking `uncompiled` for not compiled."""
    site = tmp_path / 'site'
    site.mkdir()
    (site / 'sitecustomize.py').write_text(GATE)
    gates = tmp_path / 'gates'
    gates.mkdir()
    namespace = unique_namespace()
    node = NodeProcess(tmp_path / 'node.log', namespace=namespace, parameters={'rate': 100.0},
                       environment={'PYTHONPATH': str(site), 'TEST_COMPILE_GATE': str(gates),
                                    ASSUME_UNCOMPILED: ','.join(uncompiled)})
    client = Client(namespace)
    client.get_parameters = client.node.create_client(GetParameters,
                                                      f'{NODE_NAME}/get_parameters')
    return node, client, gates


def wait_until_started(client, node, gates, name):
    """Wait until the compilation of `name` runs (held at the gate)."""
    client.wait_for(lambda: (gates / f'{name}.started').exists() or not node.alive(),
                    DISCOVERY_TIMEOUT, f'the compilation of {name} to start')
    assert node.alive(), node.output()


def latest_status(client, since):
    """Return (message, values) of our node's next /diagnostics status after `since`."""
    status = _latest(client, since)
    return status.message, {kv.key: kv.value for kv in status.values}


def latest_level(client, since):
    """Return the level (OK, WARN, ...) of our node's next /diagnostics status after `since`."""
    status = _latest(client, since)
    return {status.OK: 'OK', status.WARN: 'WARN', status.ERROR: 'ERROR'}[status.level]


def _latest(client, since):
    message = client.wait_for_messages('/diagnostics', 1, since=since)[-1]
    return next(s for s in message.status if s.hardware_id == f'{client.namespace}/{NODE_NAME}')


def integrator_parameter(client):
    """Return the node's integrator parameter, as ros2 param get reads it."""
    response = client.call(client.get_parameters, GetParameters.Request(names=['integrator']))
    return response.values[0].string_value


def test_the_node_integrates_interpreted_while_its_kernels_compile_and_switches_when_ready(
        tmp_path):
    """
    At start-up and at a switch: services answer and the simulation runs meanwhile.

    Start-up with the scene's integrator (buss) not compiled: the state comes from the first
    ticks, the kernels' source interpreted ('kernels: interpreted' in /diagnostics, which says
    the compile runs), then the compiled kernels once the compile is done; then a switch to
    rk4, not compiled: accepted at once, its reply saying that the switch waits for the
    compile and how long that takes, buss goes on ticking compiled (its name in /diagnostics)
    while rk4 compiles, then rk4 runs.  /diagnostics is WARN while a compile keeps what was
    asked for from running (buss interpreted, then buss in rk4's place), OK once it runs.
    """
    node, client, gates = start(tmp_path, ['buss', 'rk4'])
    try:
        wait_until_started(client, node, gates, 'buss')
        client.wait_for(lambda: client.reset_client.service_is_ready()
                        and client.get_parameters.service_is_ready(),
                        DISCOVERY_TIMEOUT, 'the services while buss compiles')
        client.wait_for(lambda: client.received('pose'), DISCOVERY_TIMEOUT,
                        'the first state while buss compiles')
        assert client.reset().success
        assert integrator_parameter(client) == 'buss'
        since = client.received('pose')[-1][0]
        client.wait_for_messages('pose', 10, since=since)
        message, values = latest_status(client, since=0.0)
        assert values['kernels'] == 'interpreted', values
        assert 'compiling the kernels of buss in the background' in message, message
        assert 'buss interpreted until then' in message, message
        assert latest_level(client, since=0.0) == 'WARN'
        assert node.output().count('compiling them in the background') == 1, node.output()
        open_gate(gates / 'buss', 'ok')
        client.wait_for(lambda: 'integrator is now buss (its kernels compiled in' in
                        node.output(), DISCOVERY_TIMEOUT, 'the switch to the compiled kernels')
        since = client.received('pose')[-1][0]
        client.wait_for_messages('pose', 5, since=since)
        _, values = latest_status(client, since)
        assert values['kernels'] == 'compiled', values
        assert latest_level(client, since) == 'OK'

        result = client.set_parameter('integrator', 'rk4')
        assert result.successful, result.reason
        assert result.reason.startswith('rk4 compiling in the background (about '), result.reason
        assert "s from the registry's compile estimate); buss runs until then" in result.reason
        wait_until_started(client, node, gates, 'rk4')
        since = client.received('pose')[-1][0]
        client.wait_for_messages('pose', 20, since=since)
        message, values = latest_status(client, since)
        assert values['integrator'] == 'buss', values
        assert 'the switch to rk4 is pending' in message, message
        assert 'compiling the kernels of rk4 in the background' in message, message
        assert latest_level(client, since) == 'WARN'
        # Asked again while it compiles: the reply says so, with the time so far.
        again = client.set_parameter('integrator', 'rk4')
        assert again.successful and 'rk4 compiling in the background already' in again.reason
        assert 's so far); buss runs until then' in again.reason, again.reason
        assert client.reset().success
        open_gate(gates / 'rk4', 'ok')
        client.wait_for(lambda: 'integrator is now rk4' in node.output(), DISCOVERY_TIMEOUT,
                        'the switch to rk4 once compiled')
        since = client.received('pose')[-1][0]
        client.wait_for_messages('pose', 1, since=since)
        _, values = latest_status(client, since)
        assert values['integrator'] == 'rk4', values
        assert latest_level(client, since) == 'OK'
        assert integrator_parameter(client) == 'rk4'
        # Compiled (not under the test hook): a switch acts at once, the reply adds nothing.
        assert client.set_parameter('integrator', 'splitting').reason == ''
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def test_a_switch_while_interpreted_acts_at_once_and_its_reply_says_interpreted(tmp_path):
    """Nothing compiled runs yet: rk4 runs at once from its source; the reply says so."""
    node, client, gates = start(tmp_path, ['buss', 'rk4'])
    try:
        wait_until_started(client, node, gates, 'buss')
        client.wait_for(lambda: client.parameters_client.service_is_ready(),
                        DISCOVERY_TIMEOUT, 'the parameter services while buss compiles')
        result = client.set_parameter('integrator', 'rk4')
        assert result.successful, result.reason
        assert result.reason.startswith('rk4 runs at once from its source, interpreted (the '
                                        'same steps, slower), while its kernels compile in the '
                                        'background (about '), result.reason
        wait_until_started(client, node, gates, 'rk4')
        client.wait_for_messages('pose', 1)
        since = client.received('pose')[-1][0]
        message, values = latest_status(client, since)
        assert values['integrator'] == 'rk4' and values['kernels'] == 'interpreted', values
        assert 'rk4 interpreted until then' in message, message
        assert latest_level(client, since) == 'WARN'
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def test_a_failed_compilation_keeps_the_old_integrator_and_says_so_in_one_line(tmp_path):
    node, client, gates = start(tmp_path, ['rk4'])
    try:
        client.wait_until_connected()
        assert client.set_parameter('integrator', 'rk4').successful
        wait_until_started(client, node, gates, 'rk4')
        open_gate(gates / 'rk4', 'fail')
        client.wait_for(lambda: 'compiling the kernels of rk4 failed' in node.output(),
                        DISCOVERY_TIMEOUT, 'the failure')
        failure = [line for line in node.output().splitlines() if 'failed' in line]
        assert len(failure) == 1 and 'the test gate failed this compilation' in failure[0]
        assert 'integrating on with buss' in failure[0]
        assert integrator_parameter(client) == 'buss'
        since = client.received('pose')[-1][0]
        _, values = latest_status(client, since)
        assert values['integrator'] == 'buss'
        client.wait_for_messages('pose', 10, since=since)
    except AssertionError as error:
        raise AssertionError(f'{error}\nnode output:\n{node.output()}') from None
    finally:
        client.close()
        assert node.stop() == 0, node.output()


def test_sigint_while_the_kernels_compile_stops_the_node_and_its_compilation(tmp_path):
    node, client, gates = start(tmp_path, ['buss'])
    try:
        wait_until_started(client, node, gates, 'buss')
        child = int((gates / 'buss.started').read_text())
        assert node.stop() == 0, node.output()
        # The child was ended and reaped by the node: no process of that id is left.
        assert not Path(f'/proc/{child}').exists()
    finally:
        client.close()
        node.stop()
