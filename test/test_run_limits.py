"""
``run`` and ``simulate`` refuse, in one line, what cannot make progress or overflows.

Every step, duration and rate is checked before any simulation starts; the values they take
always end.
"""

import pytest
from rigid_body_sim import cli
from rigid_body_sim.physics import Simulator
import rigid_body_sim.recording.simulate
import rigid_body_sim.tools.summary


def _one_error_line(capsys, command):
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f'rigid-body-sim {command}: error: --'), lines[0]
    return lines[0]


def _never(*args, **kwargs):
    raise AssertionError('the simulation started on a value the command line should refuse')


@pytest.mark.parametrize('arguments, option', [
    (['--dt', '1e15'], '--dt'),  # Simulator.run advanced nothing: the same row forever
    (['--dt', '5e-324', '--duration', '0.01'], '--dt'),  # OverflowError: steps inf
    (['--dt', '1e-300', '--duration', '0.01'], '--dt'),  # too many steps for int64
    (['--dt', 'nan'], '--dt'),
    (['--dt', 'inf'], '--dt'),
    (['--dt', '0'], '--dt'),
    (['--dt', '-0.01'], '--dt'),
    (['--duration', 'nan'], '--duration'),  # exited 0 printing "(nanx real time)"
    (['--duration', 'inf'], '--duration'),
    (['--duration', '-1'], '--duration'),
    (['--duration', '0'], '--duration'),
    (['--duration', '1e300'], '--duration'),
    (['--every', 'nan'], '--every'),
    (['--every', '0.001'], '--every'),  # rows between steps: steps shorter than --dt
    (['--every', '1e-300'], '--every'),  # a row per 1e-300 s: never done
    (['--tolerance', 'nan'], '--tolerance'),
    (['--tolerance', '-1'], '--tolerance'),
    (['--tolerance', '1e300'], '--tolerance'),  # beyond the node's range
])
def test_run_refuses_a_value_that_cannot_make_progress_in_one_line(
        arguments, option, capsys, monkeypatch):
    monkeypatch.setattr(rigid_body_sim.tools.summary, 'Simulator', _never)
    assert cli.main(['run'] + arguments) == 2
    line = _one_error_line(capsys, 'run')
    assert line.startswith(f'rigid-body-sim run: error: {option} ')


@pytest.mark.parametrize('arguments, option', [
    (['--rate', '1e300'], '--rate'),  # OverflowError in the stamps
    (['--rate', '1e-300'], '--rate'),  # a warning line, then an error
    (['--rate', '5e-324'], '--rate'),
    (['--rate', 'nan'], '--rate'),
    (['--rate', 'inf'], '--rate'),
    (['--rate', '0'], '--rate'),
    (['--substeps', '10000000000000'], '--substeps'),  # ran for ever, deaf to SIGTERM
    (['--substeps', '0'], '--substeps'),
    (['--tolerance', '1e300'], '--tolerance'),  # accepted: beyond the node's range
    (['--tolerance', 'nan'], '--tolerance'),
    (['--tolerance', '-1'], '--tolerance'),
    (['--duration', 'nan'], '--duration'),
    (['--duration', 'inf'], '--duration'),
    (['--duration', '-1'], '--duration'),
    (['--duration', '1e300'], '--duration'),
])
def test_simulate_refuses_a_value_that_cannot_make_progress_in_one_line(
        arguments, option, capsys, monkeypatch, tmp_path):
    monkeypatch.setattr(rigid_body_sim.recording.simulate, 'simulate_to_bag', _never)
    if '--duration' not in arguments:
        arguments = ['--duration', '1'] + arguments
    bag = tmp_path / 'bag'
    assert cli.main(['simulate', '--quiet', '--bag', str(bag)] + arguments) == 2
    line = _one_error_line(capsys, 'simulate')
    assert line.startswith(f'rigid-body-sim simulate: error: {option} ')
    assert not bag.exists()


@pytest.mark.parametrize('arguments, last_row', [
    # Rows at 10, 20, then 30.000000005: the last 5e-9 s is below what Simulator.run
    # advances for a dt of 10 s, so a loop waiting for the clock to reach the end never ended.
    (['--dt', '10', '--every', '10', '--duration', '30.000000005'], '30.00'),
    # A run shorter than one step: one step of the run's length.
    (['--duration', '0.005'], '0.01'),
    (['--dt', '10', '--every', '10', '--duration', '10'], '10.00'),
])
def test_run_ends_on_every_value_it_takes(arguments, last_row, capsys, monkeypatch):
    calls = []

    def counted_run(simulator, duration, dt, progress=None):
        calls.append(duration)
        assert len(calls) < 100, 'the run loop does not end'
        return Simulator.run(simulator, duration, dt, progress)

    class CountedSimulator(Simulator):
        run = counted_run

    monkeypatch.setattr(rigid_body_sim.tools.summary, 'Simulator', CountedSimulator)
    assert cli.main(['run'] + arguments) == 0
    rows = [line.split()[0] for line in capsys.readouterr().out.splitlines()
            if line.split() and line.split()[0].count('.') == 1
            and line.split()[0].replace('.', '').isdigit()]
    assert rows[-1] == last_row
