"""
interfaces/build_interfaces.sh, the set-up's build of tf2_msgs and simulation_interfaces.

Where it cannot build (no cmake, no C/C++ compiler) it is no error: one line a package says
what the node runs without, and the venv is left as it was.  Where the packages import, it
builds nothing.  (The build itself is what ``make run`` and ``make test`` do once per venv.)
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys
import venv

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / 'interfaces' / 'build_interfaces.sh'
# What the script runs before it looks for cmake and the compilers.
TOOLS = ('bash', 'dirname', 'date')


def _run(target_venv, path):
    return subprocess.run([shutil.which('bash'), str(SCRIPT), str(target_venv)],
                          env=dict(os.environ, PATH=str(path)), capture_output=True,
                          text=True, timeout=120)


def _files(directory):
    return sorted(str(path.relative_to(directory)) for path in directory.rglob('*'))


@pytest.mark.parametrize('missing', ['cmake', 'cc', 'c++'])
def test_without_a_build_tool_it_says_what_the_node_lacks_and_changes_nothing(
        tmp_path, missing):
    target = tmp_path / 'venv'
    venv.create(target, with_pip=False)
    tools = tmp_path / 'bin'
    tools.mkdir()
    for tool in TOOLS + ('cmake', 'cc', 'c++'):
        found = shutil.which(tool) or '/bin/false'
        if tool != missing:
            (tools / tool).symlink_to(found)
    before = _files(target)
    ran = _run(target, tools)
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.splitlines() == [
        f'tf2_msgs: not built, no {missing} on PATH: the node will run without TF '
        '(/tf, /tf_static)',
        f'simulation_interfaces: not built, no {missing} on PATH: the node will run without '
        'the simulation services (simulation_interfaces)']
    assert _files(target) == before


def test_where_both_packages_import_it_builds_nothing():
    probe = subprocess.run(
        [sys.executable, '-c', 'import tf2_msgs.msg, simulation_interfaces.msg'],
        capture_output=True, text=True, timeout=120)
    if probe.returncode != 0:
        pytest.skip('tf2_msgs or simulation_interfaces is not built in this venv (make venv '
                    'builds them where cmake and a C/C++ compiler exist)')
    ran = _run(Path(sys.prefix), Path(os.environ.get('PATH', '/usr/bin')))
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.splitlines() == ['tf2_msgs: already importable, not built',
                                       'simulation_interfaces: already importable, not built']
