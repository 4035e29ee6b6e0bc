"""
A scratch ROS 2 launch environment: ``ros2 launch`` built from the public jazzy sources.

PyPI's ROS 2 wheels stop at rclpy and the message packages: there is no wheel of ros2/launch,
launch_ros or ros2cli, and this repository vendors none of their code.  This module builds
them, from checkouts a person or a CI image provides, into a prefix of their own (never
into the run venv), and says how to run its ``ros2`` with the run venv's Python:

- ros2/launch: launch, launch_xml, launch_yaml;
- ros2/launch_ros: launch_ros, ros2launch (the ``ros2 launch`` verb);
- ros2/ros2cli: ros2cli (the ``ros2`` command), ros2pkg (ros2launch imports it);
- ros2/rcl_interfaces: composition_interfaces, a message package that ``launch_ros.actions``
  imports at module level (for composable nodes); it is generated and compiled as
  interfaces/build_interfaces.sh builds tf2_msgs, with the rosidl wheels of
  requirements-tf2.txt in a build venv of its own;
- from PyPI: osrf-pycommon (launch's one dependency that is not a ROS package), pinned.

The sources: the directory ``$RIGID_BODY_SIM_ROS2_SOURCES``, else
``<cache>/ros2-sources`` (``<cache>`` is ``$XDG_CACHE_HOME/rigid_body_sim``, else
``~/.cache/rigid_body_sim``), holding one checkout per repository, as made by::

    for repo in launch launch_ros ros2cli rcl_interfaces; do
        git clone -b jazzy https://github.com/ros2/$repo ~/.cache/rigid_body_sim/ros2-sources/$repo
    done

The prefix: ``<cache>/launch-env/<key>``, the key a digest of the sources' versions, the
Python (its version and base installation: every venv of it shares the prefix) and the
pins, so that a change of any of them builds a new one; a finished build is
reused (its stamp file is written last), and a lock keeps two test runs from building it
at once.  ``python test/launch_env.py`` builds it and prints the variables to set.
"""

import fcntl
import hashlib
import json
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import xml.etree.ElementTree as ElementTree

ROOT = Path(__file__).resolve().parent.parent
SOURCES_VARIABLE = 'RIGID_BODY_SIM_ROS2_SOURCES'
# repository -> (its Python packages to pip install, the version prefix of ROS 2 Jazzy).
REPOSITORIES = {
    'launch': (('launch', 'launch_xml', 'launch_yaml'), '3.4.'),
    'launch_ros': (('launch_ros', 'ros2launch'), '0.26.'),
    'ros2cli': (('ros2cli', 'ros2pkg'), '0.32.'),
    'rcl_interfaces': ((), '2.0.'),
}
MESSAGE_PACKAGE = ('rcl_interfaces', 'composition_interfaces')
# Not ROS packages: from PyPI, pinned (psutil: ros2cli imports it; the run venv may lack it).
PYPI_PINS = ('osrf-pycommon==2.0.2', 'psutil==7.2.2')
# What the build venv adds to requirements-tf2.txt: composition_interfaces's dependency,
# pinned as requirements.txt pins it for the run venv.
BUILD_VENV_ADDS = ('ros-rcl-interfaces', 'ros-type-description-interfaces')
# A change of how the prefix is built makes a new one.
LAYOUT = 1


class Unavailable(Exception):
    """The environment cannot be built here; the message says why, in one line."""


def cache_root():
    """Return ``$XDG_CACHE_HOME/rigid_body_sim``, else ``~/.cache/rigid_body_sim``."""
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / 'rigid_body_sim'


def sources_dir():
    """Return where the checkouts are looked for."""
    given = os.environ.get(SOURCES_VARIABLE)
    return Path(given) if given else cache_root() / 'ros2-sources'


def _version(package_xml):
    return ElementTree.parse(package_xml).getroot().findtext('version').strip()


def source_versions(sources=None):
    """
    Return {repository: version} of the checkouts, each checked to be a jazzy one.

    :raises Unavailable: a checkout is missing or not of ROS 2 Jazzy.
    """
    sources = Path(sources or sources_dir())
    versions = {}
    for repository, (packages, jazzy) in REPOSITORIES.items():
        package = packages[0] if packages else MESSAGE_PACKAGE[1]
        package_xml = sources / repository / package / 'package.xml'
        if not package_xml.is_file():
            raise Unavailable(
                f'no checkout of ros2/{repository} in {sources} (PyPI has no wheels of '
                f'ros2/launch, launch_ros, ros2cli; their sources are not vendored): clone '
                f'the jazzy branches there (test/launch_env.py says how) or set '
                f'{SOURCES_VARIABLE}')
        version = _version(package_xml)
        if not version.startswith(jazzy):
            raise Unavailable(f'{package_xml} is version {version}, not one of ROS 2 Jazzy '
                              f'({jazzy}x): check out the jazzy branch')
        versions[repository] = version
    return versions


def _pins(name):
    """Return {distribution: the pinned line} of a requirements file."""
    pins = {}
    for line in (ROOT / name).read_text().splitlines():
        if line and not line.startswith(('#', '-')):
            pins[re.split(r'[=<>\[; ]', line, maxsplit=1)[0].lower()] = line
    return pins


def _key(versions):
    """Return the digest that names the prefix of these sources, Python and pins."""
    facts = {'versions': versions, 'python': sys.version, 'base': sys.base_prefix,
             'pypi': PYPI_PINS, 'build': (ROOT / 'requirements-tf2.txt').read_text(),
             'adds': [_pins('requirements.txt').get(name) for name in BUILD_VENV_ADDS],
             'layout': LAYOUT}
    return hashlib.sha256(json.dumps(facts, sort_keys=True).encode()).hexdigest()[:16]


def site_packages(prefix):
    """Return the prefix's site-packages, as ``pip install --prefix`` lays it out."""
    return Path(prefix) / 'lib' / f'python{sys.version_info[0]}.{sys.version_info[1]}' \
        / 'site-packages'


def environment(prefix, base=None):
    """
    Return the environment that runs the prefix's ``ros2`` with the run venv's Python.

    The prefix's scripts run ``python3`` from PATH: this process's interpreter's directory
    comes right after the prefix's ``bin``.

    :param prefix: the built prefix; None: a sourced ROS 2 installation's ``ros2``, as is.
    :param base: the environment to extend (default: this process's).
    """
    env = dict(os.environ if base is None else base)
    if prefix is None:
        return env

    def before(name, value):
        env[name] = str(value) + (os.pathsep + env[name] if env.get(name) else '')

    before('PATH', Path(sys.executable).parent)
    before('PATH', Path(prefix) / 'bin')
    before('PYTHONPATH', site_packages(prefix))
    before('LD_LIBRARY_PATH', Path(prefix) / 'lib')
    before('AMENT_PREFIX_PATH', prefix)
    return env


def _run(command, log, **keywords):
    """Run a build step, its output appended to `log`; raise Unavailable if it fails."""
    with open(log, 'a') as out:
        out.write('\n$ ' + ' '.join(str(word) for word in command) + '\n')
        out.flush()
        done = subprocess.run([str(word) for word in command], stdout=out,
                              stderr=subprocess.STDOUT, timeout=1800, **keywords)
    if done.returncode != 0:
        raise Unavailable(f'{Path(command[0]).name} failed (exit {done.returncode}): see {log}')


def _build_venv(venv, log):
    """Make (or reuse) the venv of the rosidl generators, colcon and rcl_interfaces."""
    python = venv / 'bin' / 'python'
    if not (venv / '.complete').is_file():
        shutil.rmtree(venv, ignore_errors=True)
        _run([sys.executable, '-m', 'venv', venv], log)
        adds = [_pins('requirements.txt')[name] for name in BUILD_VENV_ADDS]
        _run([python, '-m', 'pip', 'install', '--quiet', '-r', ROOT / 'requirements-tf2.txt',
              *adds], log)
        # The message wheels' CMake exports name the include directories of the machine
        # that built them (a manylinux image's /opt/python/...): this venv's are the same
        # files at other paths.
        include = sysconfig.get_paths()['include']
        numpy_include = subprocess.run(
            [python, '-c', 'import numpy; print(numpy.get_include())'], check=True,
            capture_output=True, text=True).stdout.strip()
        foreign = re.compile(r'/opt/python/cp\d+-cp\d+/(include/python[\d.]+|lib/python[\d.]+'
                             r'/site-packages/numpy/_core/include)')
        for path in (venv / 'share').rglob('*.cmake'):
            text = path.read_text()
            if foreign.search(text):
                path.write_text(foreign.sub(
                    lambda match: include if match.group(1).startswith('include')
                    else numpy_include, text))
        (venv / '.complete').write_text('')
    return python


def _build(sources, prefix, log):
    """Build the prefix from the checkouts (see the module's docstring)."""
    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)
        # pip builds a source tree in place: copies, so the checkouts stay clean.
        packages = []
        for repository, (names, _) in REPOSITORIES.items():
            for name in names:
                shutil.copytree(sources / repository / name, scratch / name,
                                ignore=shutil.ignore_patterns('test', 'build', '*.egg-info'))
                packages.append(scratch / name)
        _run([sys.executable, '-m', 'pip', 'install', '--quiet', '--no-deps', '--prefix', prefix,
              *PYPI_PINS, *packages], log)
        # pip wrote this venv's interpreter into the scripts (ros2); any venv of the same
        # Python and pins runs them (environment() puts its interpreter first on PATH).
        for script in (Path(prefix) / 'bin').iterdir():
            lines = script.read_text().split('\n', 1)
            if lines[0].startswith('#!') and 'python' in lines[0]:
                script.write_text('#!/usr/bin/env python3\n' + lines[1])
        digest = hashlib.sha256(json.dumps(
            [sys.version, sys.base_prefix, (ROOT / 'requirements-tf2.txt').read_text(),
             [_pins('requirements.txt').get(name) for name in BUILD_VENV_ADDS]]).encode())
        build_venv = cache_root() / 'launch-env' / f'build-venv-{digest.hexdigest()[:16]}'
        python = _build_venv(build_venv, log)
        repository, package = MESSAGE_PACKAGE
        shutil.copytree(sources / repository / package, scratch / 'msgs' / package)
        env = dict(os.environ, CMAKE_PREFIX_PATH=str(build_venv),
                   AMENT_PREFIX_PATH=str(build_venv))
        _run([build_venv / 'bin' / 'colcon', '--log-base', scratch / 'log', 'build',
              '--base-paths', scratch / 'msgs', '--build-base', scratch / 'build',
              '--install-base', prefix, '--merge-install',
              '--cmake-args', f'-DPython3_EXECUTABLE={python}', '-DBUILD_TESTING=OFF'],
             log, env=env, cwd=scratch)
    # The proof it all fits: launch_ros's actions import, composition_interfaces's C type
    # support loads into the run venv's rclpy, and ros2 has the launch verb.
    check = ('import launch_ros.actions, composition_interfaces.srv as s; '
             's.LoadNode.Request.__class__.__import_type_support__(); '
             'assert s.LoadNode.Request._TYPE_SUPPORT is not None')
    _run([sys.executable, '-c', check], log, env=environment(prefix), cwd=prefix)
    _run([Path(prefix) / 'bin' / 'ros2', 'launch', '--help'], log, env=environment(prefix),
         cwd=prefix)


def ensure_built(sources=None):
    """
    Return the prefix of a built environment, building it first if needed.

    :raises Unavailable: no jazzy checkouts, no cmake or compiler, or a step failed.
    """
    sources = Path(sources or sources_dir())
    versions = source_versions(sources)
    for tool in ('cmake', 'cc', 'c++'):
        if shutil.which(tool) is None:
            raise Unavailable(f'no {tool} on PATH: composition_interfaces cannot be built')
    base = cache_root() / 'launch-env'
    prefix = base / _key(versions)
    stamp = prefix / '.complete'
    base.mkdir(parents=True, exist_ok=True)
    with open(base / '.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not stamp.is_file():
            shutil.rmtree(prefix, ignore_errors=True)
            prefix.mkdir(parents=True)
            _build(sources, prefix, prefix.with_suffix('.log'))
            stamp.write_text(json.dumps(versions, sort_keys=True) + '\n')
    return prefix


def main():
    """Build (or find) the environment; print where it is and how to use it."""
    try:
        prefix = ensure_built()
    except Unavailable as error:
        print(f'launch environment: {error}', file=sys.stderr)
        return 1
    env = environment(prefix, base={})
    print(f'# launch environment built from {sources_dir()}: {prefix}')
    for name in ('PATH', 'PYTHONPATH', 'LD_LIBRARY_PATH', 'AMENT_PREFIX_PATH'):
        print(f'export {name}="{env[name]}${{{name}:+:${name}}}"')
    return 0


if __name__ == '__main__':
    sys.exit(main())
