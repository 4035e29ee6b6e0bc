"""
The compiled kernels' cache: a changed source never runs a stale kernel; compiles are known.

numba caches each kernel beside its source and checks only that file's own time stamp, not the
helpers it calls from other files; kernels/__init__.py keeps a fingerprint of the whole
core's sources and drops every cached kernel when it changes.  These tests run that on a
directory of their own (the package's cache is left alone).
"""

import subprocess
import sys

from rigid_body_sim import cli
from rigid_body_sim.physics import kernels
from rigid_body_sim.physics import warm_up


def _tree(tmp_path):
    """Return a small source tree with cached kernels beside two sources."""
    root = tmp_path / 'physics'
    (root / 'kernels' / '__pycache__').mkdir(parents=True)
    (root / '__pycache__' / 'compiled').mkdir(parents=True)
    (root / 'algebra.py').write_text('x = 1\n')
    (root / 'kernels' / 'loop.py').write_text('y = 2\n')
    return root


def _cache_files(root):
    for name in ('kernels/__pycache__/loop.run-30.py311.nbi',
                 'kernels/__pycache__/loop.run-30.py311.1.nbc',
                 '__pycache__/compiled/buss.0123456789abcdef'):
        (root / name).write_bytes(b'cached')


def test_a_changed_helper_in_another_file_drops_every_cached_kernel(tmp_path):
    root = _tree(tmp_path)
    _cache_files(root)
    # The first look records the fingerprint (and, knowing none, drops what was cached).
    assert kernels.ensure_fresh_cache(root) == 3
    _cache_files(root)
    assert kernels.ensure_fresh_cache(root) == 0
    assert len(kernels.cached_kernel_files(root)) == 3
    # An edit of algebra.py, which loop.py's kernel calls: numba would not see it.
    (root / 'algebra.py').write_text('x = 2\n')
    assert kernels.ensure_fresh_cache(root) == 3
    assert kernels.cached_kernel_files(root) == []


def test_a_new_or_renamed_source_changes_the_fingerprint(tmp_path):
    root = _tree(tmp_path)
    before = kernels.source_fingerprint(root)
    (root / 'kernels' / 'loop.py').rename(root / 'kernels' / 'steps.py')
    renamed = kernels.source_fingerprint(root)
    (root / 'extra.py').write_text('')
    assert len({before, renamed, kernels.source_fingerprint(root)}) == 3


def test_a_new_or_edited_effect_keeps_every_integrators_compiled_kernels(tmp_path):
    # The kernels call effects through a Model's pointers and never inline them; numba
    # watches an effect's own file for its own functions.
    root = _tree(tmp_path)
    (root / 'effects').mkdir()
    (root / 'effects' / 'drag.py').write_text('z = 3\n')
    kernels.ensure_fresh_cache(root)
    _cache_files(root)
    (root / 'effects' / 'spring.py').write_text('k = 1\n')
    (root / 'effects' / 'drag.py').write_text('z = 4\n')
    assert kernels.ensure_fresh_cache(root) == 0
    assert len(kernels.cached_kernel_files(root)) == 3
    # The toolkit an effect's code inlines is in the fingerprint: an edit drops everything.
    (root / 'kernels' / 'loop.py').write_text('y = 3\n')
    assert kernels.ensure_fresh_cache(root) == 3


def test_a_compiled_integrator_is_marked_for_these_sources_only():
    # The set-up compiled everything: every integrator is marked, under this fingerprint.
    assert warm_up.missing() == []
    marker = kernels.compiled_marker('buss')
    assert marker.exists() and kernels.FINGERPRINT[:16] in marker.name
    assert warm_up.compile_estimate(['buss', 'rk4']) == 0.0


def test_the_compile_command_refuses_an_unknown_integrator_in_one_line(capsys):
    assert cli.main(['compile', 'rk5']) == 2
    out = capsys.readouterr().out.strip()
    assert out.startswith('rigid-body-sim compile: error: unknown integrator(s) rk5; valid: ')
    assert '\n' not in out


def test_the_compile_command_says_what_is_compiled_already():
    result = subprocess.run([sys.executable, '-m', 'rigid_body_sim.cli', 'compile', 'buss'],
                            capture_output=True, text=True, timeout=600, check=False)
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
                           'first use (about ')
    assert '\n' not in line and 'rigid-body-sim compile' in line
