"""
The package's folders are its layers: every import goes down a layer (docs/architecture.md).

Each top-level module or package of rigid_body_sim/ sits in one layer; a module may import
from its own package and from lower layers, never from a package of its own layer or above,
function-level imports included; and no modules import each other in a circle.  Read from
the sources (ast), so nothing is imported.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / 'rigid_body_sim'

# Bottom to top: the picture of docs/architecture.md.
LAYERS = (
    ('text', 'paths'),
    ('physics',),
    ('scenes',),
    ('messages', 'work_precision'),
    ('node', 'drawing'),
    ('recording', 'watch'),
    ('sweep',),
    ('tools', 'cli'),
)
LAYER = {part: level for level, parts in enumerate(LAYERS) for part in parts}


def _part(path):
    """Return the top-level part of rigid_body_sim/ that a source file belongs to."""
    relative = path.relative_to(PACKAGE)
    return relative.parts[0].removesuffix('.py')


def _imported_modules(path):
    """Yield every rigid_body_sim module a source imports, as a dotted name."""
    package = ['rigid_body_sim', *path.relative_to(PACKAGE).with_suffix('').parts]
    if package[-1] == '__init__':
        package.pop()
    else:
        package = package[:-1]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = '.'.join(base + ([node.module] if node.module else []))
            if node.module:
                yield module
            # A name imported from a package may be one of its modules.
            yield from (f'{module}.{alias.name}' for alias in node.names)
        elif isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)


def _imports_by_part():
    """Return [(source, importer's part, imported part)] across parts of the package."""
    found = set()
    for path in PACKAGE.rglob('*.py'):
        if path.parent == PACKAGE and path.name == '__init__.py':
            continue
        importer = _part(path)
        for module in _imported_modules(path):
            parts = module.split('.')
            if parts[0] == 'rigid_body_sim' and len(parts) > 1 and parts[1] != importer:
                found.add((str(path.relative_to(PACKAGE.parent)), importer, parts[1]))
    return sorted(found)


def test_every_part_of_the_package_has_a_layer():
    parts = {_part(path) for path in PACKAGE.rglob('*.py')} - {'__init__'}
    assert parts <= set(LAYER), f'give these a layer in LAYERS: {sorted(parts - set(LAYER))}'


def test_every_import_goes_down_a_layer():
    imports = _imports_by_part()
    assert len(imports) > 20, 'too few imports between parts found: the check checks nothing'
    upward = [f'{source}: {importer} (layer {LAYER[importer]}) imports {imported} '
              f'(layer {LAYER[imported]})' for source, importer, imported in imports
              if LAYER[imported] >= LAYER[importer]]
    assert not upward, '\n'.join(upward)


# physics/simulator.py and physics/stability.py import each other; issue 31 breaks that
# circle on a branch of its own, after which this is empty.
CIRCLES_NOT_CHECKED_IN = ('physics',)


def _module_graph():
    """Return module name -> the package's modules it imports (existing modules only)."""
    modules = {}
    for path in PACKAGE.rglob('*.py'):
        parts = ['rigid_body_sim', *path.relative_to(PACKAGE).with_suffix('').parts]
        modules['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    return {name: {module for module in _imported_modules(path)
                   if module in modules and module != name}
            for name, path in modules.items()}


def test_no_modules_import_each_other_in_a_circle():
    graph = _module_graph()
    assert sum(map(len, graph.values())) > 100, 'too few imports found: the check checks nothing'
    circles = []
    for start in sorted(graph):
        if start.split('.')[1:2] and start.split('.')[1] in CIRCLES_NOT_CHECKED_IN:
            continue
        # Depth-first from `start`: a path back to it is a circle through it.
        pending = [(start, (start,))]
        seen = set()
        while pending:
            name, path = pending.pop()
            for module in graph[name]:
                if module == start:
                    circles.append(' -> '.join(path + (start,)))
                elif module not in seen:
                    seen.add(module)
                    pending.append((module, path + (module,)))
    assert not circles, '\n'.join(circles)
