"""
The public API is annotated, and the annotations are checked (mypy, configured in setup.cfg).

The checked part: rigid_body_sim.physics, rigid_body_sim.scenes, the command line (tools/,
cli.py) and the two modules below them (text.py, paths.py); the package ships py.typed
(PEP 561), so a user's type checker reads these annotations as the package's types.

``python test/test_types.py [CHECKOUT]`` prints the counts of annotated functions (the public
ones of the checked part, and every function of the package) of this checkout or another.
"""

import ast
import importlib.util
from pathlib import Path
import subprocess
import sys

import pytest

PACKAGE_ROOT = Path(__file__).resolve().parent.parent
PACKAGE = PACKAGE_ROOT / 'rigid_body_sim'
CHECKED = ('physics', 'scenes', 'tools', 'cli.py', 'text.py', 'paths.py')

# The mypy runs share one cache, in one worker (a cold run takes ~20 s, a warm one seconds).
pytestmark = pytest.mark.xdist_group('mypy')


def _is_public_module(path, package):
    """Return whether no part of the module's path below the package is private."""
    parts = path.relative_to(package).with_suffix('').parts
    return not any(part.startswith('_') and part != '__init__' for part in parts)


def _is_public_name(name):
    """Return whether a name is public: no leading underscore, or a dunder (__init__)."""
    return not name.startswith('_') or (name.startswith('__') and name.endswith('__'))


def _is_annotated(function, method):
    """Return whether every parameter (but a method's self or cls) and the return are."""
    arguments = function.args
    parameters = arguments.posonlyargs + arguments.args
    if method and 'staticmethod' not in {getattr(d, 'id', None)
                                         for d in function.decorator_list}:
        parameters = parameters[1:]
    parameters = parameters + arguments.kwonlyargs + [
        extra for extra in (arguments.vararg, arguments.kwarg) if extra is not None]
    return function.returns is not None and all(
        parameter.annotation is not None for parameter in parameters)


def _public_functions(path):
    """Yield (qualified name, annotated) of a module's public functions and methods."""
    tree = ast.parse(path.read_text(), str(path))
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            if _is_public_name(node.name):
                yield node.name, _is_annotated(node, method=False)
        elif isinstance(node, ast.ClassDef) and not node.name.startswith('_'):
            for member in node.body:
                if (isinstance(member, (ast.FunctionDef, ast.AsyncFunctionDef))
                        and _is_public_name(member.name)):
                    yield f'{node.name}.{member.name}', _is_annotated(member, method=True)


def checked_sources(package=PACKAGE):
    """Return the sources of the checked part of a copy of the package, sorted."""
    sources = []
    for part in CHECKED:
        path = package / part
        if path.is_dir():
            sources += sorted(path.rglob('*.py'))
        elif path.with_suffix('.py').is_file():  # a module then (scenes.py before issue 31)
            sources.append(path.with_suffix('.py'))
    return sources


def public_function_counts(package=PACKAGE):
    """Return (annotated, all, [unannotated 'module: name']) of the checked public functions."""
    annotated, total, missing = 0, 0, []
    for path in checked_sources(package):
        if not _is_public_module(path, package):
            continue
        for name, is_annotated in _public_functions(path):
            total += 1
            annotated += is_annotated
            if not is_annotated:
                missing.append(f'{path.relative_to(package.parent)}: {name}')
    return annotated, total, missing


def all_function_counts(package=PACKAGE):
    """Return (with any annotation, all) of every function of the package, nested ones too."""
    annotated = total = 0
    for path in package.rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                total += 1
                arguments = node.args
                parameters = (arguments.posonlyargs + arguments.args + arguments.kwonlyargs
                              + [extra for extra in (arguments.vararg, arguments.kwarg)
                                 if extra is not None])
                annotated += node.returns is not None or any(
                    parameter.annotation is not None for parameter in parameters)
    return annotated, total


def _mypy(cache, *options):
    """Run mypy as setup.cfg configures it; return (exit code, its output)."""
    ran = subprocess.run(
        [sys.executable, '-m', 'mypy', '--cache-dir', str(cache), *options],
        cwd=PACKAGE_ROOT, capture_output=True, text=True, timeout=600)
    return ran.returncode, ran.stdout + ran.stderr


@pytest.fixture(scope='module')
def mypy_cache(tmp_path_factory):
    """Return a mypy cache folder for this module's runs (failing if mypy is missing)."""
    if importlib.util.find_spec('mypy') is None:
        pytest.fail('mypy is not installed (pip install -r requirements-test.txt)')
    return tmp_path_factory.mktemp('mypy_cache')


def _shadowed(tmp_path, relative, old, new):
    """Return a copy of a checked source with `old` replaced by `new` (which must be there)."""
    text = (PACKAGE_ROOT / relative).read_text()
    assert text.count(old) == 1, f'{relative} no longer holds {old!r}: update the test'
    shadow = tmp_path / Path(relative).name
    shadow.write_text(text.replace(old, new))
    return shadow


def test_the_type_checker_finds_no_error_in_the_checked_packages(mypy_cache):
    code, output = _mypy(mypy_cache)
    assert code == 0, output
    assert 'Success: no issues found' in output, output


def test_the_type_checker_rejects_a_return_annotation_the_code_contradicts(mypy_cache,
                                                                           tmp_path):
    relative = 'rigid_body_sim/physics/rotations.py'
    shadow = _shadowed(tmp_path, relative,
                       'def skew(vector: VectorLike | Sequence[float]) -> NDArray[np.float64]:',
                       'def skew(vector: VectorLike | Sequence[float]) -> float:')

    code, output = _mypy(mypy_cache, '--shadow-file', relative, str(shadow))

    assert code == 1, output
    assert f'{relative}:' in output and '[return-value]' in output, output


def test_the_type_checker_rejects_an_unannotated_function(mypy_cache, tmp_path):
    relative = 'rigid_body_sim/tools/run_limits.py'
    shadow = _shadowed(tmp_path, relative,
                       "def check_rate(rate: float, option: str = '--rate') -> float:",
                       "def check_rate(rate, option='--rate'):")

    code, output = _mypy(mypy_cache, '--shadow-file', relative, str(shadow))

    assert code == 1, output
    assert f'{relative}:' in output and '[no-untyped-def]' in output, output


def test_every_public_function_of_the_checked_packages_is_annotated():
    annotated, total, missing = public_function_counts()
    # The physics core alone has some 200: fewer found means the count misses modules.
    assert total > 300, f'only {total} public functions found: the count counts too little'
    assert not missing, f'{len(missing)} of {total} not annotated:\n' + '\n'.join(missing)


def test_the_public_function_count_sees_a_missing_annotation(tmp_path):
    copy = tmp_path / 'rigid_body_sim'
    (copy / 'physics').mkdir(parents=True)
    (copy / 'physics' / 'example.py').write_text(
        'def annotated(x: float) -> float:\n    return x\n\n\n'
        'def no_return(x: float):\n    return x\n\n\n'
        'def _private(x):\n    return x\n\n\n'
        'class Body:\n'
        '    def mass(self) -> float:\n        return 1.0\n\n'
        '    def scaled(self, factor) -> float:\n        return factor\n')

    annotated, total, missing = public_function_counts(copy)

    assert (annotated, total) == (2, 4)
    assert missing == ['rigid_body_sim/physics/example.py: no_return',
                       'rigid_body_sim/physics/example.py: Body.scaled']


def test_the_package_ships_the_py_typed_marker():
    assert (PACKAGE / 'py.typed').is_file()
    assert "package_data={package_name: ['py.typed']" in (PACKAGE_ROOT / 'setup.py').read_text()


if __name__ == '__main__':
    package = Path(sys.argv[1]) / 'rigid_body_sim' if len(sys.argv) > 1 else PACKAGE
    public_annotated, public_total, _ = public_function_counts(package)
    every_annotated, every_total = all_function_counts(package)
    print(f'annotated public functions ({", ".join(CHECKED)}): '
          f'{public_annotated} of {public_total}')
    print(f'functions of rigid_body_sim/ with an annotation: {every_annotated} of {every_total}')
