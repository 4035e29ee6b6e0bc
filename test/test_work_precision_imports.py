"""
The benchmark's modules import one another without a circle, and none is also a script.

The modules are those of rigid_body_sim/work_precision/ as they are on disk, each import read with
:mod:`ast`: at module level or inside a function (a deferred import only moves a circle to
the moment of the call), absolute or relative.  The committed reference values are data the
package reads; what recomputes them, benchmarks/regenerate_references.py, is outside it.
"""

import ast
from pathlib import Path

import rigid_body_sim.work_precision

PACKAGE = rigid_body_sim.work_precision.__name__
DIRECTORY = Path(rigid_body_sim.work_precision.__file__).parent


def package_modules(directory, package):
    """Return {module name: source path} of every .py file of the package, subpackages too."""
    modules = {}
    for path in sorted(directory.rglob('*.py')):
        parts = path.relative_to(directory).with_suffix('').parts
        modules['.'.join((package, *parts[:-1 if parts[-1] == '__init__' else None]))] = path
    return modules


def imported_modules(path, module, modules):
    """Return the modules of `modules` that an import statement of the file loads."""
    own_package = module if path.stem == '__init__' else module.rpartition('.')[0]
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            anchor = own_package.rsplit('.', node.level - 1)[0] if node.level else ''
            base = '.'.join(part for part in (anchor, node.module) if part)
            # `from package import module` loads that module; `from module import name`, or
            # a name the package's __init__ defines, loads `base` itself.
            for alias in node.names:
                submodule = f'{base}.{alias.name}'
                names.add(submodule if submodule in modules else base)
    return names & set(modules) - {module}


def import_graph(directory, package):
    """Return {module: set of the package's modules it imports}."""
    modules = package_modules(directory, package)
    return {module: imported_modules(path, module, modules) for module, path in modules.items()}


def find_cycle(graph):
    """Return one import circle as a list of modules (first == last), or None."""
    state = {}  # module -> 'open' while on the current path, 'done' once fully explored

    def visit(module, path):
        state[module] = 'open'
        for imported in sorted(graph[module]):
            if state.get(imported) == 'open':
                return path[path.index(imported):] + [module, imported]
            if imported not in state:
                cycle = visit(imported, path + [module])
                if cycle:
                    return cycle
        state[module] = 'done'
        return None

    for module in sorted(graph):
        if module not in state:
            cycle = visit(module, [])
            if cycle:
                return cycle
    return None


def test_benchmark_modules_import_each_other_without_a_circle():
    graph = import_graph(DIRECTORY, PACKAGE)
    # The graph is read, not assumed: the modules that read the reference are in it.
    assert f'{PACKAGE}.extended_reference' in graph[f'{PACKAGE}.reference']
    assert f'{PACKAGE}.reference' in graph[f'{PACKAGE}.measure']

    cycle = find_cycle(graph)

    assert cycle is None, 'import circle: ' + ' -> '.join(cycle)


def test_the_cycle_finder_reports_a_circle_through_a_deferred_import(tmp_path):
    """The shape main had: extended_reference imports measure inside main(), measure it."""
    (tmp_path / '__init__.py').write_text('')
    (tmp_path / 'extended_reference.py').write_text(
        'def main():\n    from .measure import FULL\n')
    (tmp_path / 'measure.py').write_text('from .extended_reference import key_string\n')
    (tmp_path / 'report.py').write_text('from pkg import measure\nimport pkg.extended_reference\n')

    graph = import_graph(tmp_path, 'pkg')

    assert graph['pkg.report'] == {'pkg.measure', 'pkg.extended_reference'}
    assert find_cycle(graph) in (
        ['pkg.extended_reference', 'pkg.measure', 'pkg.extended_reference'],
        ['pkg.measure', 'pkg.extended_reference', 'pkg.measure'])


def test_no_benchmark_module_is_also_a_script():
    """What regenerates the package's data runs from benchmarks/, never as a module of it."""
    for module, path in package_modules(DIRECTORY, PACKAGE).items():
        assert "__name__ == '__main__'" not in path.read_text(encoding='utf-8'), module
