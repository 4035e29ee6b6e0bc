"""package.xml names every package the installed code imports (what rosdep installs)."""

import ast
from pathlib import Path
import sys
import xml.etree.ElementTree as ElementTree

ROOT = Path(__file__).resolve().parent.parent
# Top-level import -> its key in package.xml: rosdep keys where they exist, pip keys
# (python3-<name>-pip) otherwise; ROS packages are their own keys.
KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'numba': 'python3-numba', 'matplotlib': 'python3-matplotlib',
    'mpl_toolkits': 'python3-matplotlib', 'tqdm': 'python3-tqdm',
    'rosbags': 'python3-rosbags-pip', 'mcap': 'python3-mcap-pip',
    'ruamel': 'python3-ruamel.yaml', 'PIL': 'python3-pil',
}
# Imported only for an optional feature, with a clear message when missing (the MuJoCo
# rival of `rigid-body-sim bench`, setup.py's extra 'mujoco').
OPTIONAL = {'mujoco'}


def imported_top_level_modules():
    """Return the top-level modules imported anywhere in the package (absolute imports)."""
    modules = set()
    for path in (ROOT / 'rigid_body_sim').rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                modules.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split('.')[0])
    return modules - set(sys.stdlib_module_names) - {'rigid_body_sim'}


def test_package_xml_lists_every_imported_package_as_a_run_time_dependency():
    """Each third-party import has its exec_depend; none is listed that nothing imports."""
    root = ElementTree.parse(ROOT / 'package.xml').getroot()
    listed = {element.text for element in root.iter('exec_depend')}
    needed = {KEYS.get(module, module) for module in imported_top_level_modules() - OPTIONAL}
    assert needed - listed == set(), 'missing from package.xml'
    assert listed - needed == set(), 'listed in package.xml but imported nowhere'
