"""
The compiled kernels' cache: once per machine, by what they are, never stale, never trusted blind.

Kernels are cached in one folder per version of the sources and CPU (kernels/cache.py),
wherever the package sits.  The slow tests here compile into folders of their own (a copy of
the package, a cache root under tmp_path), in processes of their own; the package's cache,
which the set-up filled, is only read.
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys

import numba
from numba import types
from numba.core.datamodel import default_manager
import pytest

from rigid_body_sim import cli
from rigid_body_sim.physics import warm_up
from rigid_body_sim.physics.kernels import borrow
from rigid_body_sim.physics.kernels import cache
from rigid_body_sim.physics.kernels import model_table
from rigid_body_sim.physics.kernels.model import MODEL_TYPE

PACKAGE = Path(cache.__file__).resolve().parents[2]
"""The rigid_body_sim package directory these tests run."""

# A run of buss whose final quaternion, printed with every digit, shows which source of the
# quaternion product its kernels were compiled from.
PROBE = """
import sys
from rigid_body_sim.physics import Simulator, RigidBody, State
from rigid_body_sim.physics import warm_up
body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
state = State.from_velocity(body, angular_velocity_body=(0.1, 2.0, 0.1))
print('missing', warm_up.missing(['buss']))
final = Simulator(body, state, integrator='buss').run(0.1, 0.01)
print('quaternion', repr(tuple(final.quaternion)))
"""


def _copy_package(root):
    """Copy the package under `root` (sources only), as a second clone or install would."""
    shutil.copytree(PACKAGE, root / 'rigid_body_sim',
                    ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
    return root


def _environment(package_root, **variables):
    """Return an environment importing the package from `package_root`, cache variables set."""
    environment = {key: value for key, value in os.environ.items()
                   if key not in ('RIGID_BODY_SIM_CACHE_DIR', 'NUMBA_CACHE_DIR',
                                  'XDG_CACHE_HOME')}
    environment['PYTHONPATH'] = str(package_root)
    environment.update({key: str(value) for key, value in variables.items()})
    return environment


def _run(arguments, environment, timeout=900):
    # Run from the package's root: Python puts the working directory first on the path, and
    # this checkout's package would shadow a copy's.
    return subprocess.run([sys.executable, *arguments], capture_output=True, text=True,
                          env=environment, timeout=timeout, check=False,
                          cwd=environment.get('PYTHONPATH', str(PACKAGE.parent)))


def _compile(environment, *names):
    result = _run(['-m', 'rigid_body_sim.cli', 'compile', *names], environment)
    assert result.returncode == 0, result.stdout + result.stderr
    return result


def _probe(environment):
    result = _run(['-c', PROBE], environment)
    assert result.returncode == 0, result.stderr
    lines = dict(line.split(' ', 1) for line in result.stdout.splitlines())
    return lines['missing'], lines['quaternion']


def _edit_quaternion_product(package_root):
    """Scale the w of kernels/algebra.py's quaternion product by 1.01 (a helper's edit)."""
    algebra = package_root / 'rigid_body_sim' / 'physics' / 'kernels' / 'algebra.py'
    text = algebra.read_text()
    product_w = '            aw * bw - ax * bx - ay * by - az * bz)'
    assert text.count(product_w) == 1, 'the quaternion product changed: update this test'
    algebra.write_text(text.replace(
        product_w, '            (aw * bw - ax * bx - ay * by - az * bz) * 1.01)'))


# -- where the cache is and what names it


def test_the_cache_root_follows_the_variables_in_order(monkeypatch, tmp_path):
    for variable in ('RIGID_BODY_SIM_CACHE_DIR', 'NUMBA_CACHE_DIR', 'XDG_CACHE_HOME'):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv('HOME', str(tmp_path / 'home'))
    assert cache.cache_root() == tmp_path / 'home' / '.cache' / 'rigid_body_sim'
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'xdg'))
    assert cache.cache_root() == tmp_path / 'xdg' / 'rigid_body_sim'
    monkeypatch.setenv('NUMBA_CACHE_DIR', str(tmp_path / 'numba'))
    assert cache.cache_root() == tmp_path / 'numba' / 'rigid_body_sim'
    monkeypatch.setenv('RIGID_BODY_SIM_CACHE_DIR', str(tmp_path / 'ours'))
    assert cache.cache_root() == tmp_path / 'ours'


def test_the_sources_key_follows_content_not_path_and_leaves_the_effects_out(tmp_path):
    copy = _copy_package(tmp_path) / 'rigid_body_sim' / 'physics'
    assert cache.source_key(copy) == cache.source_key(cache.PHYSICS_ROOT) == cache.SOURCES
    (copy / 'effects' / 'spring.py').write_text('k = 1\n')
    assert cache.source_key(copy) == cache.SOURCES
    algebra = copy / 'kernels' / 'algebra.py'
    algebra.write_text(algebra.read_text() + '\n# an edit\n')
    assert cache.source_key(copy) != cache.SOURCES


def test_the_kernel_folder_names_the_cpu_numba_compiles_for(tmp_path):
    script = 'from rigid_body_sim.physics.kernels import cache; print(cache.kernel_dir().name)'
    environment = _environment(PACKAGE.parent, RIGID_BODY_SIM_CACHE_DIR=tmp_path)
    environment.pop('NUMBA_CPU_NAME', None)  # the host's CPU (a run may set another)
    host = _run(['-c', script], environment).stdout.strip()
    generic = _run(['-c', script], {**environment, 'NUMBA_CPU_NAME': 'generic'}).stdout.strip()
    assert host.startswith('kernels-' + cache.SOURCES[:20]) and generic != host


def test_numba_asks_the_package_locator_first():
    assert numba.config.CACHE_LOCATOR_CLASSES.split(',')[0] == (
        'rigid_body_sim.physics.kernels.cache.KernelCacheLocator')


def test_compile_estimates_count_each_job_once_whatever_the_order(monkeypatch):
    # As on a machine that never compiled: buss_plain alone needs buss's run kernel (it
    # said 'about 1 s' and took minutes when estimates were per integrator).
    monkeypatch.setattr(cache, 'is_marked', lambda job, folder=None: False)
    assert warm_up.compile_estimate(['buss_plain']) == warm_up.compile_estimate(['buss'])
    assert (warm_up.compile_estimate(['buss', 'buss_plain'])
            == warm_up.compile_estimate(['buss_plain', 'buss'])
            == warm_up.compile_estimate(['buss']))
    jobs = [warm_up.job_estimate(job) for job in ('shared', 'controller', 'run-buss')]
    assert warm_up.compile_estimate(['buss']) == warm_up.WORKER_START + sum(jobs)
    assert warm_up.compile_estimate(['buss'], workers=3) == warm_up.WORKER_START + max(jobs)


def test_numbas_array_structure_starts_with_what_a_borrowed_view_clears():
    # borrow.py nulls the first two members of numba's array structure: if a numba release
    # reorders them, this says so before any kernel reads a wrong field.
    model = default_manager.lookup(types.float64[::1])
    positions = [model.get_field_position(name) for name in borrow.BORROWED_MEMBERS]
    assert positions == list(range(len(borrow.BORROWED_MEMBERS))), (
        f'numba {numba.__version__} moved {borrow.BORROWED_MEMBERS} in its array structure: '
        'physics/kernels/borrow.py must follow')


def test_numbas_structref_is_the_one_meminfo_pointer_a_model_table_holds():
    # model_table.py reads a model from its meminfo's address (and casts a borrowed one to
    # a Model by writing it as the one member): if a numba release adds a member, this says
    # so before any kernel reads a wrong model.
    model = default_manager.lookup(MODEL_TYPE)
    assert len(model.get_value_type().elements) == len(model_table.STRUCTREF_MEMBERS) == 1
    assert model.get_field_position(model_table.STRUCTREF_MEMBERS[0]) == 0, (
        f'numba {numba.__version__} changed its StructRef data model: '
        'physics/kernels/model_table.py must follow')


# -- the compile command


def test_the_compile_command_refuses_an_unknown_integrator_in_one_line(capsys):
    assert cli.main(['compile', 'rk5']) == 2
    out = capsys.readouterr().out.strip()
    assert out.startswith('rigid-body-sim compile: error: unknown integrator(s) rk5; valid: ')
    assert '\n' not in out


def test_the_compile_command_says_what_is_compiled_already():
    # The set-up compiled every kernel of these sources on this machine.
    assert warm_up.missing() == []
    result = _run(['-m', 'rigid_body_sim.cli', 'compile', 'buss'], dict(os.environ))
    assert result.returncode == 0, result.stderr
    assert 'buss         already compiled' in result.stdout


def test_a_command_about_to_compile_says_what_and_how_long(monkeypatch, capsys):
    from rigid_body_sim.tools.compile import announce_compile
    announce_compile('simulate', ['buss'])
    assert capsys.readouterr().err == ''
    # As on a fresh install, where nothing is marked compiled yet.
    monkeypatch.setattr(warm_up, 'is_compiled', lambda name: False)
    announce_compile('simulate', ['rk4'])
    line = capsys.readouterr().err.strip()
    assert line.startswith('rigid-body-sim simulate: compiling the rk4 kernel(s) for their '
                           'first use on this machine (about ')
    assert '\n' not in line and 'rigid-body-sim compile' in line


def test_no_writable_cache_is_one_line_saying_what_to_set(tmp_path):
    # Under a file: no one, root included, can make that folder.
    blocked = tmp_path / 'a-file'
    blocked.write_text('')
    environment = _environment(PACKAGE.parent, RIGID_BODY_SIM_CACHE_DIR=blocked / 'cache')
    imported = _run(['-c', 'import rigid_body_sim.physics, rigid_body_sim.cli'], environment)
    assert imported.returncode == 0 and imported.stderr == '', imported.stderr
    result = _run(['-m', 'rigid_body_sim.cli', 'compile'], environment)
    assert result.returncode == 1
    assert result.stderr.count('\n') == 1, result.stderr
    assert 'set RIGID_BODY_SIM_CACHE_DIR to a writable folder' in result.stderr


# -- compiled once per machine, never stale (slow: each compiles buss's kernels)


def test_a_pip_install_elsewhere_finds_the_kernels_compiled(tmp_path):
    """`pip install --target` of the same sources (a read-only install): nothing to compile."""
    target = tmp_path / 'target'
    installed = subprocess.run(
        [sys.executable, '-m', 'pip', 'install', '--quiet', '--no-deps', '--target',
         str(target), str(PACKAGE.parent)], capture_output=True, text=True,
        timeout=600, check=False)
    assert installed.returncode == 0, installed.stderr
    environment = dict(os.environ, PYTHONPATH=str(target))
    probe = _run(['-c', 'from rigid_body_sim.physics import warm_up; print(warm_up.__file__); '
                  'print(warm_up.missing())'], environment)
    module, missing = probe.stdout.strip().splitlines()
    assert Path(module).is_relative_to(target) and missing == '[]', probe.stdout + probe.stderr


@pytest.mark.slow
@pytest.mark.parametrize('variable', ['RIGID_BODY_SIM_CACHE_DIR', 'NUMBA_CACHE_DIR',
                                      'XDG_CACHE_HOME'])
def test_a_second_copy_compiles_nothing_and_an_edited_helper_never_runs_stale(
        tmp_path, variable):
    """
    Two copies of the package (a second clone, a colcon install), one cache root.

    The first compiles; the second finds every kernel compiled and runs them.  An edit to a
    helper in another file than the kernels' (the quaternion product, inlined into every
    kernel) makes them not compiled, and what runs next is the edited product.
    """
    first = _copy_package(tmp_path / 'first')
    second = _copy_package(tmp_path / 'second')
    root = tmp_path / 'cache-root'
    _compile(_environment(first, **{variable: root}), 'buss')
    missing, original = _probe(_environment(second, **{variable: root}))
    assert missing == '[]'
    again = _compile(_environment(second, **{variable: root}), 'buss')
    assert 'buss         already compiled' in again.stdout
    _edit_quaternion_product(second)
    missing, _ = _probe(_environment(second, **{variable: root}))
    assert missing == "['buss']"
    _compile(_environment(second, **{variable: root}), 'buss')
    missing, edited = _probe(_environment(second, **{variable: root}))
    assert missing == '[]' and edited != original
    # The first copy still runs its own sources' kernels.
    assert _probe(_environment(first, **{variable: root})) == ('[]', original)


EDIT_WHILE_COMPILING = """
import sys
from pathlib import Path
from rigid_body_sim import cli
from rigid_body_sim.physics import warm_up
compile_job = warm_up.compile_job
algebra = Path(warm_up.__file__).parent / 'kernels' / 'algebra.py'


def edit_then_compile(job):
    # The edit lands while the compile runs: after the sources were read, before the end.
    algebra.write_text(algebra.read_text() + '\\n# edited while compiling\\n')
    return compile_job(job)


warm_up.compile_job = edit_then_compile
sys.exit(cli.main(['compile', 'first_order', '--jobs', '1']))
"""


@pytest.mark.slow
def test_an_edit_while_compiling_leaves_nothing_marked_for_the_old_sources(tmp_path):
    package = _copy_package(tmp_path / 'package')
    environment = _environment(package, RIGID_BODY_SIM_CACHE_DIR=tmp_path / 'cache')
    folder = Path(_run(['-m', 'rigid_body_sim.cli', 'compile', '--where'],
                       environment).stdout.strip())
    result = _run(['-c', EDIT_WHILE_COMPILING], environment)
    assert result.returncode == 3, result.stdout + result.stderr
    assert 'the sources changed while compiling' in result.stderr
    assert result.stderr.count('\n') == 1, result.stderr
    assert not (folder / 'compiled').exists() or not list((folder / 'compiled').iterdir())
    assert list(folder.rglob('*.nbc')) == [], 'files of a mixed compile were kept'
    # The edited sources are a folder of their own, compiled afresh.
    _compile(environment, 'first_order')
    edited = Path(_run(['-m', 'rigid_body_sim.cli', 'compile', '--where'],
                       environment).stdout.strip())
    assert edited != folder and (edited / 'compiled' / 'run-first_order').exists()


@pytest.mark.slow
def test_two_compiles_at_once_do_the_work_once(tmp_path):
    environment = _environment(PACKAGE.parent, RIGID_BODY_SIM_CACHE_DIR=tmp_path / 'cache')
    command = [sys.executable, '-m', 'rigid_body_sim.cli', 'compile', 'first_order']
    processes = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True, env=environment, cwd=PACKAGE.parent)
                 for _ in range(2)]
    outputs = [process.communicate(timeout=900) for process in processes]
    assert [process.returncode for process in processes] == [0, 0], outputs
    compiled = [out for out, _ in outputs if 'compiled 3 job(s)' in out]
    waited = [out for out, _ in outputs if 'first_order  already compiled' in out]
    assert len(compiled) == 1 and len(waited) == 1, outputs
    assert 'waiting for another compile of these kernels' in waited[0]


@pytest.fixture(scope='module')
def compiled_cache(tmp_path_factory):
    """Return (environment, kernel folder) of a cache holding first_order's kernels."""
    root = tmp_path_factory.mktemp('compiled-cache')
    environment = _environment(PACKAGE.parent, RIGID_BODY_SIM_CACHE_DIR=root)
    _compile(environment, 'first_order')
    folder = Path(_run(['-m', 'rigid_body_sim.cli', 'compile', '--where'],
                       environment).stdout.strip())
    return environment, folder


def _damage_object_file(path):
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 64] = bytes(64)
    path.write_bytes(bytes(data))


def _truncate(path):
    path.write_bytes(path.read_bytes()[:len(path.read_bytes()) // 3])


STEP_FIRST_ORDER = """
from rigid_body_sim.physics import Simulator, RigidBody, State
body = RigidBody.box(1.0, (0.3, 0.2, 0.1))
state = State.from_velocity(body, angular_velocity_body=(0.1, 2.0, 0.1))
Simulator(body, state, integrator='first_order', tolerance=1e-6).run(0.1, 0.01)
print('stepped')
"""


@pytest.mark.slow
@pytest.mark.parametrize('damage', [_damage_object_file, _truncate],
                         ids=['object-file-bytes', 'truncated-index'])
def test_a_damaged_cache_file_is_said_in_one_line_dropped_and_compiled_again(
        compiled_cache, damage):
    environment, folder = compiled_cache
    suffix = '.nbc' if damage is _damage_object_file else '.nbi'
    target = next(folder.glob(f'integrators/first_order.run-*{suffix}'))
    damage(target)
    # Found before anything loads it: not compiled (a node would compile beside itself).
    check = _run(['-c', 'from rigid_body_sim.physics import warm_up; '
                  "print(warm_up.missing(['first_order']))"], environment)
    assert check.stdout.strip() == "['first_order']", check.stdout + check.stderr
    result = _run(['-m', 'rigid_body_sim.cli', 'compile', 'first_order'], environment)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stderr.count('\n') == 1 and 'damaged' in result.stderr, result.stderr
    assert target.name in result.stderr
    stepped = _run(['-c', STEP_FIRST_ORDER], environment)
    assert stepped.returncode == 0 and stepped.stdout.strip() == 'stepped', stepped.stderr
