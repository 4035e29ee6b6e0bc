"""
Comments say why: no measured figure in a comment, docstring or help text of the package.

A timing, a size, a percentage or a ratio measured on one machine at one commit goes stale
where no run checks it; it belongs in docs/ or a benchmark's output, with the command that
produced it (issue 31).  The texts read (from the sources, nothing imported): every comment,
every docstring (any string standing as a statement: module, class, function, attribute),
the argparse texts (``help=``, ``description=``, ``epilog=``, ``usage=``), and every string
of a help-text module (``*help*.py``, e.g. ``rigid_body_node --help``).  A figure is a
number with a unit of measured time below a second or above a minute, of memory, a
percentage, a ratio (``3.2x``), a before -> after pair, or a number after "measured" or
"took".  Seconds alone are not flagged: they are the simulated time of the physics
(periods, durations, steps), which a scene sets.
"""

import ast
import io
from pathlib import Path
import re
import tokenize

PACKAGE = Path(__file__).resolve().parent.parent / 'rigid_body_sim'

_NUMBER = r'(?<![\w.^\'-])[~≈]?\d+(?:[.,]\d+)*(?:e-?\d+)?'
_KINDS = {
    'a short time': _NUMBER + r'\s?(?:ns|us|µs|μs|ms|(?:nano|micro|milli)seconds?)\b',
    'a long time': _NUMBER + r'\s?(?:min|minutes?|hours?)\b',
    'a size': _NUMBER + r'\s?(?:[kKMGT]i?B|bytes?)\b',
    'a percentage': _NUMBER + r'\s?(?:%|percent\b)',
    'a ratio': r'(?<![\w.^\'])(?!0x)[~≈]?\d+(?:\.\d+)?x\b(?!\s*[\d(.])',
    'a before -> after pair': _NUMBER + r'\s*(?:->|→)\s*[~≈]?\d',
    'a measurement': r'\bmeasured\b[:\s]+[~≈]?\d',
    'a duration taken': r'\b(?:took|takes|taking)\s+(?:about\s+|only\s+)?' + _NUMBER
                        + r'\s?(?:s|sec|seconds?)\b',
}
FIGURE = re.compile('|'.join(f'(?:{pattern})' for pattern in _KINDS.values()))

# Figures that are no measurement: a unit, a format's or a library's constant, a limit the
# code sets.  (file, the phrase around the figure).
ALLOWED = (
    ('recording/bag_writer.py', '1 MiB'),  # the MCAP chunk size, as rosbags and mcap use
    ('recording/bag_writer.py', '2^63 - 1 ns'),  # RMW_DURATION_INFINITE
    ('recording/bag_writer.py', 'page cache holds 2 MB'),  # SQLite's default page cache
    ('recording/simulate.py', 'within 1 ns'),  # a stamp's resolution
    ('tools/run_limits.py', 'a step of 0.1 ms'),  # 1 / the highest rate
    ('recording/plot.py', 'below 30% of its range to above 70%'),  # the plot's thresholds
    ('watch/listener.py', 'first 12 bytes'),  # a DDS GUID's prefix: its participant's
    ('watch/listener.py', "GID's first 12 bytes"),
)


def texts(source, help_module=False):
    """Yield (line, text) of each comment, docstring and help text of a Python source."""
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            yield token.start[0], token.string
    for node in ast.walk(ast.parse(source)):
        strings = []
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            strings = [node.value]
        elif isinstance(node, ast.keyword) and node.arg in (
                'help', 'description', 'epilog', 'usage'):
            strings = list(ast.walk(node.value))
        elif help_module and isinstance(node, ast.Constant):
            strings = [node]
        for string in strings:
            if isinstance(string, ast.Constant) and isinstance(string.value, str):
                yield string.lineno, string.value


def figures(source, help_module=False, allowed=()):
    """Return [(line, figure, the text's line)] of the measured figures in a source."""
    found = []
    for line, text in texts(source, help_module):
        for offset, text_line in enumerate(text.splitlines()):
            for match in FIGURE.finditer(text_line):
                if not any(phrase in text_line and
                           text_line.index(phrase) <= match.start() < match.end()
                           <= text_line.index(phrase) + len(phrase) for phrase in allowed):
                    found.append((line + offset, match.group(0), text_line.strip()))
    return sorted(set(found))


def test_no_comment_docstring_or_help_text_of_the_package_carries_a_measured_figure():
    sources = sorted(PACKAGE.rglob('*.py'))
    assert len(sources) > 80, 'too few sources found: the check checks nothing'
    found = []
    for path in sources:
        name = path.relative_to(PACKAGE).as_posix()
        allowed = [phrase for where, phrase in ALLOWED if where == name]
        found += [f'rigid_body_sim/{name}:{line}: {figure!r} in: {text}'
                  for line, figure, text in figures(path.read_text(), 'help' in path.name,
                                                    allowed)]
    assert not found, ('measured figures in comments or help texts (move each to docs/ with '
                       'the command that measures it, and say why here):\n' + '\n'.join(found))


def test_the_check_finds_a_planted_figure_of_each_kind():
    planted = '''
"""A module whose docstring says the step costs 0.05 us."""
import argparse

# Loading the kernels takes ~0.5 ms.
SIZE = 3  # the cache holds 3 MB of kernels
parser = argparse.ArgumentParser(description='the forced benchmark runs 7.6 min on 2 cores')
parser.add_argument('--x', help='about 3 % of a core')


def f():
    """Return it, measured 8-11x faster than before."""
    # The error fell 3.9e-9 -> 7.1e-15 with this construction.
    # The controller was measured: 2 steps too many, and the load took 35 s.
'''
    found = [figure for _, figure, _ in figures(planted)]
    assert found == ['0.05 us', '~0.5 ms', '3 MB', '7.6 min', '3 %', '11x', 'measured 8',
                     '3.9e-9 -> 7', 'measured: 2', 'took 35 s'], found
    help_module = 'TEXT = """keep-last 1000 (1 s at 1 kHz): 85 ms of the queue"""\n'
    assert [figure for _, figure, _ in figures(help_module)] == []
    assert [figure for _, figure, _ in figures(help_module, help_module=True)] == ['85 ms']


def test_the_check_leaves_alone_simulated_time_dimensions_and_allowed_constants():
    source = """
# A run of 60 s at 1 kHz, a 0.4 x 0.2 x 0.1 m box, 100 x 0.1 s, (k'^2 -> 0), 0x hex, 2^31 s.
# Chunks of 1 MiB, as rosbags does.
"""
    assert [figure for _, figure, _ in figures(source)] == ['1 MiB']
    assert figures(source, allowed=['1 MiB']) == []
