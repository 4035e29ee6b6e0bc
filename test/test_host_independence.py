"""
Host independence: physics that must hold whatever CPU the kernels are compiled for.

numba compiles each kernel for the CPU it runs on, and the numpy side of the package runs
on BLAS and libm code chosen per CPU at run time (OpenBLAS's kernel, glibc's FMA variants),
so a test that holds on one machine because two computations happen to round alike may
fail on another.  Here a child process compiles the Buss kernels afresh for a generic x86-64
CPU (NUMBA_CPU_NAME=generic) into a kernel cache of its own (RIGID_BODY_SIM_CACHE_DIR in
tmp_path: the machine's cache is neither read nor written), and runs what no CPU
may change:

- torque-free, world L and p are never written: bit-identical after the run (and under
  gravity, which has no torque about the COM, L too);
- the T-handle's run agrees with this process's (host-compiled kernels) to the round-off
  the steps can accumulate, a bound from the step count (measured on an AVX-512 host: the
  same bits; numba fuses no multiply-add without fastmath);
- an IMU at the COM of a body in free fall reads zero specific force, to the roundings of
  m g / m - g, and its gyro equals State's numpy Omega = I^-1 R^T L to their roundings.

Only what the checks call is compiled (buss's run kernel, gravity's term, the IMU's truth):
under a minute from an empty cache on 2 cores.
"""

import json
import os
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from reference import rotation_angle_between
from rigid_body_sim.physics import RigidBody
from rigid_body_sim.physics import Simulator
from rigid_body_sim.physics import State

EPS = np.finfo(float).eps
# The T-handle (I = 1, 2, 3) spun near its unstable middle axis, as the default scene.
MOMENTS = (1.0, 2.0, 3.0)
SPIN = (0.002, 2.0, 0.0)
STEPS, DT = 500, 1e-3

# Runs in the child, compiled for the generic CPU: the results as exact hex floats (JSON).
_CHILD = """\
import json

import numba
import numpy as np
from rigid_body_sim.physics import RigidBody, Simulator, State
from rigid_body_sim.physics.effects import Gravity
from rigid_body_sim.physics.imu import Imu, ImuModel
import rigid_body_sim.physics.integrators.buss as buss
from rigid_body_sim.scenes import load_scene


def hexed(array):
    return [float(value).hex() for value in np.asarray(array, dtype=float).reshape(-1)]


from rigid_body_sim.physics.kernels import cache
report = {{'cpu': numba.config.CPU_NAME, 'cache': str(cache.cache_root())}}
body = RigidBody(1.0, {moments!r})
start = State.from_velocity(body, angular_velocity_body={spin!r})
final = Simulator(body, start, integrator='buss').run({steps} * {dt!r}, {dt!r})
report['t_handle'] = {{field: hexed(getattr(final, field)) for field in (
    'quaternion', 'position', 'linear_momentum', 'angular_momentum')}}
report['t_handle_start'] = {{field: hexed(getattr(start, field)) for field in (
    'quaternion', 'position', 'linear_momentum', 'angular_momentum')}}
# A box thrown up, tumbling, in free fall: buss with gravity's kicks (the pushed loop).
scene = load_scene('thrown_box')
falling = Simulator(scene.body, scene.state, integrator='buss', effects=[Gravity()])
state = falling.run(0.5, 0.01)
force = scene.body.mass * scene.gravity
_, omega, specific_force = Imu(ImuModel(), scene.body, scene.gravity).truth(
    state, force, np.zeros(3))
report['free_fall'] = {{
    'start_angular_momentum': hexed(scene.state.angular_momentum),
    'angular_momentum': hexed(state.angular_momentum),
    'specific_force': hexed(specific_force), 'gravity': hexed(scene.gravity),
    'omega': hexed(omega), 'numpy_omega': hexed(state.angular_velocity_body(scene.body)),
    'scale': hexed(np.abs(scene.body.inertia_inverse).sum(axis=1)
                   * np.abs(state.angular_momentum).sum())}}
# The run kernel's machine code: a generic x86-64 has no AVX registers.
asm = '\\n'.join(buss.run.dispatcher.inspect_asm().values())
report['wide_registers'] = sorted({{register for register in ('ymm', 'zmm') if register in asm}})
print(json.dumps(report))
"""


def _unhexed(values):
    return np.array([float.fromhex(value) for value in values])


def _generic_cpu_report(tmp_path):
    """Run _CHILD with kernels compiled for a generic CPU in a fresh cache; its report."""
    cache = tmp_path / 'kernel_cache'
    code = _CHILD.format(moments=MOMENTS, spin=SPIN, steps=STEPS, dt=DT)
    environment = {**os.environ, 'NUMBA_CPU_NAME': 'generic',
                   'RIGID_BODY_SIM_CACHE_DIR': str(cache)}
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            env=environment, cwd=tmp_path, timeout=600, check=False)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.splitlines()[-1])
    # The child compiled for the generic CPU, into its own cache, and that cache was used.
    assert report['cpu'] == 'generic' and Path(report['cache']) == cache, report
    assert any('buss.run' in path.name for path in cache.rglob('*.nbi')), \
        'the child did not compile buss.run into its fresh cache'
    assert report['wide_registers'] == [], 'buss.run was not compiled for a generic CPU'
    return report


@pytest.mark.slow
def test_buss_compiled_for_a_generic_cpu_keeps_what_no_cpu_may_change(tmp_path):
    report = _generic_cpu_report(tmp_path)

    # Torque-free, buss never writes world L or p (nor x, at p = 0): exact on any CPU.
    start, final = report['t_handle_start'], report['t_handle']
    for field in ('position', 'linear_momentum', 'angular_momentum'):
        assert final[field] == start[field], field

    # The same run here, on the kernels compiled for this host.  Each step rounds the
    # quaternion in the product q exp(v) (sums of four products: <= 4 roundings of
    # u = eps / 2 an entry) and in its normalisation (sum of four squares, square root,
    # division: <= 4 more), <= 8 u = 4 eps of turn a step (the turn vector's own roundings
    # are relative to the 2e-3 rad turned, negligible beside them); the two runs' roundings
    # add up over the steps, and a deviation near the unstable middle axis grows at most
    # by exp(lambda t), lambda = Omega_2 sqrt((I2 - I1)(I3 - I2) / (I1 I3)) = 1.15 /s:
    # <= 1.8 over the 0.5 s run.
    body = RigidBody(1.0, MOMENTS)
    host = Simulator(body, State.from_velocity(body, angular_velocity_body=SPIN),
                     integrator='buss').run(STEPS * DT, DT)
    i1, i2, i3 = MOMENTS
    growth = np.exp(SPIN[1] * np.sqrt((i2 - i1) * (i3 - i2) / (i1 * i3)) * STEPS * DT)
    assert growth < 2.0
    generic = State._from_arrays(_unhexed(final['quaternion']), _unhexed(final['position']),
                                 _unhexed(final['linear_momentum']),
                                 _unhexed(final['angular_momentum']))
    angle = rotation_angle_between(host.rotation, generic.rotation)
    assert angle <= 2 * STEPS * 4 * EPS * 2.0, angle
    np.testing.assert_array_equal(generic.angular_momentum, host.angular_momentum)

    # Free fall: gravity kicks p, never L (its torque about the COM is exactly zero).
    falling = report['free_fall']
    assert falling['angular_momentum'] == falling['start_angular_momentum']
    # At the COM an IMU reads a_COM - g = R^T (m g / m - g): m g and / m round once each
    # (u |g| each), the rotation adds one more rounding of that: <= 3 u |g| a component.
    gravity = np.linalg.norm(_unhexed(falling['gravity']))
    specific_force = _unhexed(falling['specific_force'])
    assert np.all(np.abs(specific_force) <= 3 * (EPS / 2) * gravity), specific_force
    # The gyro, compiled for the generic CPU, against State's numpy Omega = I^-1 R^T L
    # (BLAS): each side forms R from q (entries <= 1, <= 4 roundings each; the numpy side
    # normalises q once more: <= 4 more), then two products of a 3x3 matrix and a vector
    # (<= 3 roundings an entry each, in any order, fused or not): per component <= 14
    # roundings of u of terms at most sum_j |I^-1_ij| |L|_1 in size; twice that between them.
    omega, numpy_omega = _unhexed(falling['omega']), _unhexed(falling['numpy_omega'])
    tolerance = 2 * 14 * (EPS / 2) * _unhexed(falling['scale'])
    assert np.all(np.abs(omega - numpy_omega) <= tolerance), (omega, numpy_omega, tolerance)
