"""
Every shell and Python example of the README and docs/ runs as written, so no page goes stale.

The examples are the ```sh and ```python blocks of README.md and docs/*.md, taken from the
pages at test time, and the file blocks: a ```python, ```yaml or ```toml block whose first
line is ``# file: PATH`` is a file the page has the reader write (a plugin, a scene), written
to PATH in the working directory before each later block of its page runs, and checked to
parse.  Each shell command runs verbatim with bash in a scratch copy of the
places the pages write to (the working directory: a fresh clone's root with .venv, config,
benchmarks and a copy of docs/), after the one activation step the README states
(``. .venv/bin/activate``); each Python block runs whole.  A command that cannot run here
says why and is checked as far as it can be:

- ``ros2``, ``rviz2``: skipped with a reason where the ros2 CLI is absent (the pip-only
  venv has none), run where it is (only their ``--help`` side is safe: they talk to a node);
- ``make run`` / ``make test``: the node until Ctrl-C, and this very suite: not run;
- ``rigid_body_node``, ``angular_momentum_arrow`` (but their ``--help``): they run until
  Ctrl-C: not run (test_launch.py starts both, and runs the pages' ``ros2 launch`` lines
  in a scratch ROS 2 launch environment);
- a ROS 2 workspace (``colcon build`` in ~/ros2_ws): test_colcon_build.py builds it;
- ``rigid-body-sim bench`` without ``--quick`` (tens of minutes), ``record`` and ``watch`` (until
  Ctrl-C, with a node): their arguments are parsed by the real parser (an option that no
  longer exists fails), not run; their ``--help`` runs.

Also here: the help texts and lists the pages promise (the table of every integrator on
docs/physics_api.md, as registered; imu in ``rigid_body_node --help``, the README's figures as
docs/benchmark.md has them) and every script in benchmarks/ answering ``--help``.
"""

from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys

import pytest
from rigid_body_sim.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
VENV = ROOT / '.venv'
_BLOCK = re.compile(r'```(sh|python|yaml|toml)\n(.*?)```', re.S)
_FILE = re.compile(r'# file: (\S+)\n')
# Shell commands of the pages whose run would take too long, need a running node or would
# never end; their arguments are parsed instead, by the tool's own parser.
_PARSED_ONLY = {
    'bench': 'the full benchmark takes tens of minutes (--quick runs in test_bench.py)',
    'record': 'records a running node until Ctrl-C (test_recorder.py runs it)',
    'watch': 'shows a running node until Ctrl-C (test_watch.py runs it)',
}


def _examples():
    """Yield (page, index, language, text) of every example block (yaml, toml: files only)."""
    for page in PAGES:
        for index, match in enumerate(_BLOCK.finditer(page.read_text()), 1):
            language, text = match.group(1), match.group(2)
            if language in ('sh', 'python') or _FILE.match(text):
                yield page.relative_to(ROOT), index, language, text


def _write_files(directory, page, before):
    """Write the file blocks of `page` that come before block `before` into `directory`."""
    for other, index, _, text in EXAMPLES:
        found = _FILE.match(text)
        if other == page and index < before and found:
            path = directory / found.group(1)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)


def _check_file_block(language, name, text):
    """Fail unless a file block parses as its language."""
    if language == 'python':
        compile(text, name, 'exec')
    elif language == 'yaml':
        import yaml
        assert isinstance(yaml.safe_load(text), dict), name
    else:
        import tomllib
        tomllib.loads(text)


EXAMPLES = list(_examples())


def _commands(text):
    """Return the block's commands: continuation lines joined, comment lines dropped."""
    commands = []
    for line in text.replace('\\\n', ' ').splitlines():
        if line.strip() and not line.lstrip().startswith('#'):
            commands.append(line.strip())
    return commands


def _words(command):
    """Return the command's words without its trailing comment."""
    return shlex.split(command, comments=True)


def _reason_not_run(command):
    """Return why a command is not run (None: run it), and whether to parse it instead."""
    words = _words(command)
    if not words:
        return None, False
    program = words[0]
    if program == 'ros2' and words[1:2] == ['launch']:
        return ('test_launch.py runs every ros2 launch line of the pages as written, in a '
                'scratch ROS 2 launch environment'), False
    if program in ('ros2', 'rviz2'):
        if shutil.which('ros2') is None:
            return 'the ros2 CLI is not installed here (the pip-only venv has none)', False
        return 'talks to a running node (the ros2 CLI is here, no node is)', False
    if program == 'make':
        return 'make run starts the node until Ctrl-C; make test is this suite', False
    if Path(program).name in ('rigid_body_node', 'angular_momentum_arrow') \
            and '--help' not in words:
        return 'runs until Ctrl-C (test_launch.py starts it)', False
    if program in ('mkdir', 'cd', 'colcon', 'source', 'git') or '~/ros2_ws' in command:
        return 'sets up a ROS 2 workspace (test_colcon_build.py builds the package)', False
    if program.endswith('rigid-body-sim') and len(words) > 1:
        tool = words[1]
        if tool in _PARSED_ONLY and not (tool == 'bench' and '--quick' in words) \
                and '--help' not in words:
            return _PARSED_ONLY[tool], True
    return None, False


@pytest.fixture(scope='module')
def scratch(tmp_path_factory):
    """Return a working directory laid out as a fresh clone's root for the examples."""
    if not (VENV / 'bin' / 'activate').exists():
        pytest.skip('no .venv in the package root (make venv builds it)')
    directory = tmp_path_factory.mktemp('docs_examples')
    for name in ('.venv', 'config', 'benchmarks', 'rigid_body_sim', 'test'):
        (directory / name).symlink_to(ROOT / name)
    # The pages write into docs/ (an animation): a copy, so the committed files stay.
    shutil.copytree(ROOT / 'docs', directory / 'docs')
    return directory


@pytest.mark.parametrize('page, index, language, text', EXAMPLES,
                         ids=[f'{page}#{index}' for page, index, _, _ in EXAMPLES])
def test_every_example_of_the_pages_runs_as_written(scratch, page, index, language, text):
    _write_files(scratch, page, index)
    found = _FILE.match(text)
    if found:
        _check_file_block(language, found.group(1), text)
        return
    if language == 'python':
        result = subprocess.run([str(VENV / 'bin' / 'python'), '-c', text], cwd=scratch,
                                capture_output=True, text=True, timeout=600)
        assert result.returncode == 0, f'{page} block {index}:\n{text}\n{result.stderr}'
        return
    skipped = []
    for command in _commands(text):
        reason, parse = _reason_not_run(command)
        if parse:
            # The tool's own parser: an option the pages name that no longer exists fails.
            try:
                build_parser().parse_args(_words(command)[1:])
            except SystemExit as error:
                pytest.fail(f'{page}: {command!r} does not parse ({error})')
            continue
        if reason is not None:
            skipped.append(f'{command!r}: {reason}')
            continue
        result = subprocess.run(['bash', '-c', f'set -e; . .venv/bin/activate; {command}'],
                                cwd=scratch, capture_output=True, text=True, timeout=900)
        assert result.returncode == 0, (f'{page} block {index}: {command!r} exited '
                                        f'{result.returncode}:\n{result.stdout}\n'
                                        f'{result.stderr}')
    if skipped:
        pytest.skip('; '.join(skipped))


def test_the_pages_have_examples_to_run():
    # A change of the block syntax must not silently leave nothing to check.
    assert len(EXAMPLES) >= 12
    assert any(language == 'python' for _, _, language, _ in EXAMPLES)


_CONSERVED = {'angular_momentum': 'world L', 'rotational_energy': 'energy'}
_TABLE = re.compile(r'<!-- integrators: .*? -->\n(.*?)\n<!-- end of integrators -->', re.S)


def integrator_table():
    """Return docs/physics_api.md's table of the integrators, from their registrations."""
    from rigid_body_sim.physics import INTEGRATORS
    rows = ['| integrator | order | with drag | wrench evaluations a step | kick-drift-kick '
            'stages | torque-free, keeps exactly | compile job, est. CPU s | what it is |',
            '|---|---|---|---|---|---|---|---|']
    for name, integrator in sorted(INTEGRATORS.items()):
        kept = ', '.join(_CONSERVED[q] for q in integrator.conserves) or '-'
        if integrator.exact_torque_free:
            kept += ' (the exact flow)'
        rows.append(f'| `{name}` | {integrator.order} | {integrator.momentum_dependent_order} '
                    f'| {integrator.stages} | {len(integrator.kicks) or "-"} | {kept} '
                    f'| `{integrator.compile_job}`, {integrator.compile_seconds:g} '
                    f'| {integrator.summary} |')
    return '\n'.join(rows)


def test_physics_api_tables_every_integrator_as_registered():
    # The table is the registry's: a registration changed or added and the page not is a
    # failure that prints the table to paste.
    text = (ROOT / 'docs' / 'physics_api.md').read_text()
    found = _TABLE.search(text)
    assert found, 'docs/physics_api.md has no generated table of the integrators'
    assert found.group(1) == integrator_table(), (
        'docs/physics_api.md: replace the table of the integrators with\n'
        + integrator_table())


def test_the_node_help_lists_every_published_topic():
    from rigid_body_sim.node.help_text import help_text
    text = help_text()
    for topic in ('pose', 'twist', 'angular_momentum', 'odom', 'marker', 'imu',
                  '/tf', '/diagnostics', '/clock'):
        assert re.search(rf'^  {re.escape(topic)} ', text, re.M), topic


def test_the_readme_quotes_the_benchmark_page_figures():
    # Ranges the README gives as "within A-Bx of MuJoCo RK4's error" must be the page's.
    readme = (ROOT / 'README.md').read_text()
    benchmark = (ROOT / 'docs' / 'benchmark.md').read_text()
    ranges = re.findall(r'within (\d+(?:\.\d+)?-\d+(?:\.\d+)?x) of\s+MuJoCo', readme)
    assert ranges, 'the README no longer quotes the rk4 range'
    for figure in ranges:
        assert figure in benchmark, f'README says {figure}; docs/benchmark.md does not'


@pytest.mark.parametrize('script', sorted(p.name for p in (ROOT / 'benchmarks').glob('*.py')))
def test_every_benchmark_script_answers_help(script):
    result = subprocess.run([sys.executable, str(ROOT / 'benchmarks' / script), '--help'],
                            capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert result.returncode == 0 and result.stdout.startswith('usage:'), result.stderr


def test_scene_theory_runs_and_every_check_holds():
    result = subprocess.run([sys.executable, str(ROOT / 'benchmarks' / 'scene_theory.py')],
                            capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr
    assert result.stdout.rstrip().endswith(' 0 failing')


# -- the traps a newcomer met (issue 23)


def test_a_quick_bench_refuses_to_overwrite_a_full_runs_results(tmp_path, capsys):
    from rigid_body_sim.cli import main
    # The committed full run's results, in a copy (a failing guard must not overwrite them).
    shutil.copy(ROOT / 'docs' / 'benchmark' / 'results.json', tmp_path / 'results.json')
    assert main(['bench', '--quick', '--no-mujoco', '--out', str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert 'holds the results of a full run' in error and error.count('\n') == 1


def test_simulate_overwrite_replaces_a_bag_and_never_another_directory(tmp_path, capsys):
    from rigid_body_sim.cli import main
    bag = tmp_path / 'runs' / 'flip'
    arguments = ['simulate', '--duration', '0.05', '--quiet', '--bag', str(bag)]
    assert main(arguments) == 0
    assert main(arguments) == 2 and '--overwrite' in capsys.readouterr().err
    assert main(arguments + ['--overwrite']) == 0
    other = tmp_path / 'notes'
    other.mkdir()
    (other / 'keep.txt').write_text('mine')
    arguments[-1] = str(other)
    assert main(arguments + ['--overwrite']) == 2
    assert (other / 'keep.txt').read_text() == 'mine'


def test_scenes_prints_round_off_as_zero(capsys):
    from rigid_body_sim.cli import main
    assert main(['scenes', 'heavy_top']) == 0
    out = capsys.readouterr().out
    omega = next(line for line in out.splitlines() if 'omega body' in line)
    assert 'e-' not in omega and '150' in omega, omega


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_simulate_overwrite_removes_only_what_the_bags_metadata_names(tmp_path, capsys,
                                                                      storage):
    """
    A folder with a metadata.yaml that is not a bag's keeps every file; a bag goes whole.

    Before: any folder with a metadata.yaml and plain files counted as a bag, so a photo
    album's metadata.yaml got its IMG_0001.jpg and notes.txt deleted.
    """
    from rigid_body_sim.cli import main
    album = tmp_path / 'album'
    album.mkdir()
    (album / 'metadata.yaml').write_text('title: my photo album\n')
    (album / 'IMG_0001.jpg').write_bytes(b'\xff\xd8 a photo')
    (album / 'notes.txt').write_text('mine')
    arguments = ['simulate', '--duration', '0.05', '--quiet', '--storage', storage,
                 '--bag', str(album), '--overwrite']
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and 'not that of a rosbag2 bag' in error, error
    assert sorted(path.name for path in album.iterdir()) == [
        'IMG_0001.jpg', 'metadata.yaml', 'notes.txt']
    # A real bag with a stray file of the user's beside it: kept, and named.
    bag = tmp_path / 'bag'
    arguments[-2] = str(bag)
    assert main(arguments[:-1]) == 0
    (bag / 'IMG_0002.jpg').write_bytes(b'another photo')
    assert main(arguments) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and 'IMG_0002.jpg' in error, error
    assert (bag / 'IMG_0002.jpg').exists()
    (bag / 'IMG_0002.jpg').unlink()
    assert main(arguments) == 0 and (bag / 'metadata.yaml').is_file()


def test_an_empty_bag_path_is_one_line_saying_so(capsys):
    from rigid_body_sim.cli import main
    assert main(['simulate', '--duration', '0.05', '--quiet', '--bag', '']) == 2
    error = capsys.readouterr().err
    assert error.count('\n') == 1 and '--bag is empty' in error, error


# -- the docs as a new user read them (issue 32)

def _page_file(page, name):
    """Return the text of the file block `name` of `page` (docs/scenes.md's cylinder.yaml)."""
    for other, _, _, text in EXAMPLES:
        found = _FILE.match(text)
        if other == Path(page) and found and found.group(1) == name:
            return text
    raise AssertionError(f'{page} has no file block {name}')


def test_every_params_file_the_pages_name_is_where_they_say(scratch):
    # A venv has no install/ tree: a page's --params-file is a path of the source tree, or
    # the colcon install's, found by `ros2 pkg prefix` (the share/ tree mirrors config/).
    prefix = '$(ros2 pkg prefix rigid_body_sim)/share/rigid_body_sim/'
    named = []
    for page, _, language, text in EXAMPLES:
        if language != 'sh':
            continue
        for command in _commands(text):
            for path in re.findall(r'--params-file (\$\(ros2 pkg prefix [^)]*\)\S*|\S+)',
                                   command):
                named.append(path)
                relative = path[len(prefix):] if path.startswith(prefix) else path
                assert (scratch / relative).is_file(), f'{page}: {command}'
    assert any(path.startswith(prefix) for path in named)
    assert any(not path.startswith(prefix) for path in named)


def test_record_records_by_default_every_topic_simulate_writes(tmp_path):
    from rigid_body_sim.cli import main
    from rigid_body_sim.tools.record import default_record_topics
    from rosbags.rosbag2 import Reader
    bag = tmp_path / 'bag'
    assert main(['simulate', '--duration', '0.05', '--quiet', '--bag', str(bag)]) == 0
    with Reader(bag) as reader:
        written = {connection.topic for connection in reader.connections}
    from rigid_body_sim.messages.tf import transform_message_class
    if transform_message_class()[0] is not None:
        assert {'/tf', '/tf_static'} <= written
    assert written <= set(default_record_topics('')), written - set(default_record_topics(''))


def test_scenes_effects_gives_every_built_in_parameter_its_unit(capsys):
    from rigid_body_sim.cli import main
    from rigid_body_sim.physics.effects import effect_parameters
    from rigid_body_sim.physics.effects import EFFECTS
    assert main(['scenes', '--effects']) == 0
    shown = capsys.readouterr().out
    built_in = [name for name in EFFECTS
                if EFFECTS[name].__module__.startswith('rigid_body_sim.physics.effects.')]
    assert len(built_in) >= 6
    for name in built_in:
        for key in effect_parameters(name):
            unit = EFFECTS[name].units[key]
            assert re.search(rf'^    {key} \({re.escape(unit)}; (default .*|required)\)$',
                             shown, re.M), (name, key)


def test_scenes_shows_a_cylinders_moments_about_its_own_axes(tmp_path, capsys):
    # Sorted, a cylinder's moments along z read as if its axis were x.
    from rigid_body_sim.cli import main
    path = tmp_path / 'cylinder.yaml'
    path.write_text(_page_file('docs/scenes.md', 'cylinder.yaml'))
    assert main(['scenes', str(path)]) == 0
    shown = capsys.readouterr().out
    # m = 0.4 kg, r = 0.05 m, h = 0.3 m: I_x = I_y = m (3 r^2 + h^2) / 12, I_z = m r^2 / 2.
    assert 'moments about body x, y, z [0.00325, 0.00325, 0.0005 ] kg m^2' in shown, shown
