"""
The package uses its dependencies through their public API: no private rclpy name in it.

rclpy's pybind11 module (``_rclpy``, ``rclpy.impl``), raw ``take_message`` on a
subscription's handle, name-mangled attributes (``_GuardCondition__gc``) and a process-wide
``sys.unraisablehook`` matching them: each worked once and breaks silently with the next
rclpy.  One private read remains, documented where it is: the parameter overrides
(``Node._parameter_overrides``, in ``parameters.given_overrides``), for which rclpy has no
public accessor and whose one public route crashes the node on an empty-list override.
"""

from pathlib import Path
import re

PACKAGE = Path(__file__).resolve().parent.parent / 'rigid_body_sim'
PRIVATE = re.compile(r'_rclpy\b|take_message|unraisablehook|rclpy\.impl|_parameter_overrides'
                     r'|_[A-Z]\w*__\w+|_sigint_gc')


# (file, line): the documented exception above.
ALLOWED = {('rigid_body_sim/node/parameters.py',
            "overrides = getattr(node, '_parameter_overrides', {})")}


def test_no_source_of_the_package_uses_a_private_rclpy_name():
    found = []
    for path in sorted(PACKAGE.rglob('*.py')):
        name = str(path.relative_to(PACKAGE.parent))
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if PRIVATE.search(line) and (name, line.strip()) not in ALLOWED:
                found.append(f'{name}:{number}: {line.strip()}')
    assert not found, '\n'.join(found)


def test_recording_never_imports_the_node():
    """The offline writer and the recorder load without the node (the layers of issue 21)."""
    import json
    import subprocess
    import sys
    script = ('import importlib, json, pkgutil, sys\n'
              'import rigid_body_sim.recording as recording\n'
              'for module in pkgutil.iter_modules(recording.__path__):\n'
              "    importlib.import_module('rigid_body_sim.recording.' + module.name)\n"
              'print(json.dumps([name for name in sys.modules\n'
              "                  if name.startswith('rigid_body_sim.')]))\n")
    result = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                            cwd=PACKAGE.parent, timeout=300, check=True)
    loaded = json.loads(result.stdout.strip().splitlines()[-1])
    assert any(name.startswith('rigid_body_sim.messages.') for name in loaded), \
        'the recording modules load no message module at all: the check checks nothing'
    assert not [name for name in loaded if name.startswith('rigid_body_sim.node')]
