"""
Determinism: the same scene, integrator and step give a bit-identical trajectory.

Each step's state (the float64 bytes, little-endian, of the quaternion, the COM position and
the linear and angular momenta, world frame) goes into one SHA-256 per trajectory, so a
change of any bit at any step shows, not only one that survives to the final state.  Runs
are compared within this process and against a fresh Python process (another hash seed), also
one whose compiled kernels are built afresh for a generic x86-64 CPU.

No golden hash is pinned: the bits depend on more than the pinned numpy and numba.  Measured
on this machine (glibc 2.36): glibc's sin, which the compiled kernels call, returns another
last bit for 218 of 300,000 arguments uniform in [-4, 4] when its FMA variant is switched off
(GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA, as on a CPU without FMA), and that changes the
t_handle, thrown_box and driven trajectories within 20,000 steps; the pivot scenes (heavy_top,
bike_wheel) change within 300 steps under another OpenBLAS kernel (OPENBLAS_CORETYPE=Prescott
or Sandybridge), which OpenBLAS picks by CPU at run time.  A pinned hash would test the
machine and its C library, not the code.
"""

import hashlib
import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.scenes import load_scene
from rigid_body_sim.scenes import scene_names

# A few hundred steps: all ten built-in scenes take about 0.5 s of CPU (time.process_time).
STEPS = 300
# What pushes a scene that takes outside input (world frame): a held force (N) through the
# COM and a torque (N m), so that translation and rotation are both driven.
PUSH_FORCE = (0.2, 0.0, 0.1)
PUSH_TORQUE = (0.0, 0.01, 0.02)

# Runs in a child Python process: the trajectory hashes of every built-in scene, as JSON.
_CHILD = """\
import json, sys
sys.path.insert(0, {directory!r})
from test_scene_determinism import trajectory_hashes
print(json.dumps(trajectory_hashes()))
"""


def trajectory_hash(name, integrator=None, dt=None, state=None, steps=STEPS):
    """
    Return the SHA-256 (hex) of the states after each of `steps` steps of the scene `name`.

    As the node steps: one ``step(dt)`` per tick, dt the scene's unless given, the push
    above held in scenes that take one.  `integrator` and `state` (initial) replace the
    scene's.
    """
    scene = load_scene(name)
    simulator = scene.simulator(state=state, integrator=integrator)
    if scene.accepts_external_wrench:
        simulator.set_wrench(force=PUSH_FORCE, torque=PUSH_TORQUE)
    dt = scene.dt if dt is None else dt
    digest = hashlib.sha256()
    for _ in range(steps):
        _add_state(digest, simulator.step(dt))
    return digest.hexdigest()


def _add_state(digest, state):
    for values in (state.quaternion, state.position, state.linear_momentum,
                   state.angular_momentum):
        digest.update(np.ascontiguousarray(values, dtype='<f8').tobytes())


def trajectory_hashes():
    """Return {scene name: trajectory_hash} of every built-in scene with its own settings."""
    return {name: trajectory_hash(name) for name in scene_names(several_bodies=False)}


def _hashes_in_a_child(tmp_path, **environment):
    """Return trajectory_hashes() computed by a fresh Python process."""
    code = _CHILD.format(directory=str(Path(__file__).resolve().parent))
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            env={**os.environ, **environment}, cwd=tmp_path, timeout=600,
                            check=False)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.splitlines()[-1])


@pytest.mark.parametrize('name', scene_names(several_bodies=False))
def test_two_runs_of_a_scene_give_bit_identical_trajectories(name):
    assert trajectory_hash(name) == trajectory_hash(name)


@pytest.mark.parametrize('integrator', sorted(INTEGRATORS))
@pytest.mark.parametrize('name', ['driven', 'heavy_top', 'flat_spin', 'thrown_box'])
def test_every_integrator_gives_bit_identical_trajectories_with_effects(name, integrator):
    # A held push, a pivot with gravity, internal dissipation, gravity on a free body: each
    # takes another path through the Simulator.
    assert trajectory_hash(name, integrator) == trajectory_hash(name, integrator)


def test_a_fresh_process_gives_the_same_trajectories(tmp_path):
    # Another hash seed: no set or dict order may reach the numbers.
    assert _hashes_in_a_child(tmp_path, PYTHONHASHSEED='4021') == trajectory_hashes()


@pytest.mark.slow
def test_kernels_compiled_afresh_for_a_generic_cpu_give_the_same_trajectories(tmp_path):
    # An empty kernel cache makes the child compile every kernel, for a baseline x86-64
    # instead of this CPU: the same bits show that the kernels' machine code does not depend
    # on the host's instruction set (no fused multiply-add or reassociation by the compiler).
    hashes = _hashes_in_a_child(tmp_path, PYTHONHASHSEED='7', NUMBA_CPU_NAME='generic',
                                RIGID_BODY_SIM_CACHE_DIR=str(tmp_path / 'kernel_cache'))
    assert list((tmp_path / 'kernel_cache').rglob('*.nbi')), 'the child used no fresh cache'
    assert hashes == trajectory_hashes()


@pytest.mark.parametrize('name', scene_names(several_bodies=False))
def test_the_hash_sees_one_ulp_of_the_step(name):
    # The checks above can fail: the smallest change of the step gives another trajectory.
    scene = load_scene(name)
    assert trajectory_hash(name, dt=np.nextafter(scene.dt, np.inf)) != trajectory_hash(name)


@pytest.mark.parametrize('name', [name for name in scene_names(several_bodies=False)
                                  if np.any(load_scene(name).state.angular_momentum)])
def test_the_hash_sees_one_ulp_of_the_initial_angular_momentum(name):
    # The initial state is not hashed: the one-ulp change must carry into the steps.
    scene = load_scene(name)
    momentum = np.array(scene.state.angular_momentum)
    largest = np.argmax(np.abs(momentum))
    momentum[largest] = np.nextafter(momentum[largest], np.inf)
    nudged = scene.state.replace(angular_momentum=momentum)
    assert nudged != scene.state
    assert trajectory_hash(name, state=nudged) != trajectory_hash(name)
