"""
A scene file's YAML, read strictly and within bounds.

Stricter than ``yaml.safe_load``: a key given twice in one mapping is an error
(``body.size: duplicate key (lines 5 and 9)``), numbers are YAML 1.2's, so
``damping: 1e-3`` is a float, and an integer beyond a float's range is an error.  Its work is
bounded by :mod:`.limits`: size, nesting and number of values.
"""

from __future__ import annotations

import io
import re
import sys
from typing import Any
from typing import TextIO

import yaml

from .limits import MAX_SCENE_DEPTH
from .limits import MAX_SCENE_SIZE
from .limits import MAX_SCENE_VALUES
from ..text import one_line_errors

__all__ = ['is_yaml_number', 'read_scene_yaml']

# Numbers in scene files are read as YAML 1.2 (core schema) reads them, not as PyYAML's
# YAML 1.1: 1e-3, 1E+3, -.5 are floats (1.1 wants a dot and a signed exponent, so these were
# strings), 010 is ten (1.1: octal 8) and 1:30 is a string (1.1: sexagesimal 90).
_INT_TAG = 'tag:yaml.org,2002:int'
_FLOAT_TAG = 'tag:yaml.org,2002:float'
_YAML12_INT = re.compile(r'^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$')
_YAML12_FLOAT = re.compile(r'^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?'
                           r'|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$')


def is_yaml_number(text: str) -> bool:
    """Return whether `text` reads as a number in YAML 1.2 (so, in quotes, it is a string)."""
    return bool(_YAML12_INT.match(text) or _YAML12_FLOAT.match(text))


@one_line_errors
def read_scene_yaml(stream: str | TextIO, source: str = '<scene>') -> Any:
    """
    Return the data of a scene file's YAML (a str or a text stream), as the loader reads it.

    Stricter than ``yaml.safe_load``: a key given twice in one mapping is an error (safe_load
    keeps the last one silently), numbers follow YAML 1.2 (``1e-3`` is a float), and an
    integer beyond a float's range (+-1.8e308) is an error.

    Its work is bounded: a text of more than MAX_SCENE_SIZE characters, more than
    MAX_SCENE_DEPTH levels of nesting or more than MAX_SCENE_VALUES values (an alias counted
    as the values it repeats) is refused as soon as it is seen.

    Raises
    ------
    ValueError
        ``<source>: not valid YAML: ...``, ``<source>: <key path>: duplicate key ...``,
        ``<source>: <key path>: an integer of 400 digits (base 10) is beyond ...``, or
        ``<source>: line 3: more than 20 levels of nesting ...``.

    """
    if isinstance(stream, str):
        text = stream
    else:
        # One character more than the limit tells a file that is too large, however large.
        text = stream.read(MAX_SCENE_SIZE + 1)
        # Named as the stream, so that YAML's messages still say 'in "x.yaml", line 3'.
        name, stream = getattr(stream, 'name', '<file>'), io.StringIO(text)
        stream.name = name
    if len(text) > MAX_SCENE_SIZE:
        raise ValueError(f'{source}: more than {MAX_SCENE_SIZE} characters, the most a scene '
                         f'file may have ({MAX_SCENE_SIZE // 1024} KiB)')
    try:
        # The reader checks the text's characters as it is built (a control character is a
        # ReaderError here).
        loader = _SceneYamlLoader(stream)
        node = loader.get_single_node()
    except yaml.YAMLError as error:
        raise ValueError(f'{source}: not valid YAML: {_one_line(error)}') from None
    except _TooLarge as error:
        raise ValueError(f'{source}: line {error.mark.line + 1}: {error}') from None
    try:
        if node is None:
            return None
        _check_nodes(loader, node, source)
        try:
            return loader.construct_document(node)
        except (yaml.YAMLError, ValueError, TypeError, OverflowError) as error:
            # A bad explicit tag (!!float abc, !!timestamp 2024-13-45) fails in Python's own
            # conversion, with a ValueError that would not name the file.
            raise ValueError(f'{source}: not valid YAML: {_one_line(error)}') from None
    finally:
        loader.dispose()


class _TooLarge(ValueError):
    """A scene's YAML nested too deep or with too many values; `mark` says where."""

    def __init__(self, problem: str, mark: Any) -> None:
        super().__init__(problem)
        self.mark = mark


class _SceneYamlLoader(yaml.SafeLoader):
    """
    SafeLoader with YAML 1.2 numbers (see _YAML12_INT, _YAML12_FLOAT) and bounded nesting.

    The composer counts the depth and the values as it builds nodes, and stops at
    MAX_SCENE_DEPTH or MAX_SCENE_VALUES: PyYAML's composer and constructor recurse once per
    level (a deep file is a RecursionError), and each value costs time and memory, so a file
    of many values could hold the loader for long (docs/scenes.md has the figures, from
    benchmarks/scene_input_cost.py).
    """

    def __init__(self, stream: str | TextIO) -> None:
        super().__init__(stream)
        self._depth = 0
        self._values = 0
        # id(node) -> the values it holds, itself included: what an alias to it repeats.
        self._sizes: dict[int, int] = {}

    def compose_node(self, parent: yaml.Node | None, index: int) -> yaml.Node | None:
        """Compose one node, counting it (an alias: the values it repeats) and its depth."""
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            node = super().compose_node(parent, index)
            self._count(self._sizes.get(id(node), 1), event.start_mark)
            return node
        if self._depth >= MAX_SCENE_DEPTH:
            raise _TooLarge(f'more than {MAX_SCENE_DEPTH} levels of nesting; a scene needs 5',
                            event.start_mark)
        self._depth += 1
        first = self._values
        self._count(1, event.start_mark)
        node = super().compose_node(parent, index)
        self._depth -= 1
        self._sizes[id(node)] = self._values - first
        return node

    def _count(self, values: int, mark: Any) -> None:
        self._values += values
        if self._values > MAX_SCENE_VALUES:
            raise _TooLarge(f'more than {MAX_SCENE_VALUES} values (an alias counts as the '
                            'values it repeats); a built-in scene has 33 to 53', mark)

    # PyYAML's 1.1 int and float resolvers are dropped (not shadowed): the first that
    # matches a plain scalar decides its type, and 1.1's would read 010 as 8.
    yaml_implicit_resolvers = {
        first: [(tag, regexp) for tag, regexp in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}

    def construct_yaml12_int(self, node: yaml.ScalarNode) -> int:
        """Return a YAML 1.2 integer: decimal (leading zeros too), 0o octal or 0x hex."""
        text = self.construct_scalar(node)
        try:
            sign, base, digits = _integer_parts(text)
            return sign * int(digits, base)
        except ValueError:
            raise yaml.constructor.ConstructorError(
                None, None, f'{text!r} is not an integer', node.start_mark) from None

    def construct_yaml12_float(self, node: yaml.ScalarNode) -> float:
        """Return a float; a value that is none (an explicit !!float tag) is a YAML error."""
        try:
            return self.construct_yaml_float(node)
        except (ValueError, IndexError):  # IndexError: an empty one (`rate: !!float`)
            raise yaml.constructor.ConstructorError(
                None, None, f'{self.construct_scalar(node)!r} is not a number',
                node.start_mark) from None


# Resolvers are tried in the order added: int first, so that 10 stays an int.
_SceneYamlLoader.add_implicit_resolver(_INT_TAG, _YAML12_INT, list('-+0123456789'))
_SceneYamlLoader.add_implicit_resolver(_FLOAT_TAG, _YAML12_FLOAT, list('-+.0123456789'))
_SceneYamlLoader.add_constructor(_INT_TAG, _SceneYamlLoader.construct_yaml12_int)
_SceneYamlLoader.add_constructor(_FLOAT_TAG, _SceneYamlLoader.construct_yaml12_float)


def _check_nodes(loader: _SceneYamlLoader, root: yaml.Node, source: str) -> None:
    """
    Raise ValueError ``<source>: <key path>: ...`` for a key given twice or a huge integer.

    Both are found on the composed nodes, before any value is built: a mapping keeps the
    last of two equal keys silently, and an integer beyond a float's range (or beyond the
    4300 digits Python converts) would end as an OverflowError without the key path.
    """
    pending, seen = [(root, '')], set()
    while pending:
        node, path = pending.pop()
        if id(node) in seen:  # an alias: already checked where its anchor is
            continue
        seen.add(id(node))
        if isinstance(node, yaml.ScalarNode):
            _check_integer(node, path, source)
        elif isinstance(node, yaml.SequenceNode):
            pending.extend((item, f'{path}[{index}]') for index, item in enumerate(node.value))
        elif isinstance(node, yaml.MappingNode):
            marks: dict[Any, yaml.Mark] = {}
            for key_node, value_node in node.value:
                if isinstance(key_node, yaml.ScalarNode):
                    _check_integer(key_node, path, source)
                key = _mapping_key(loader, key_node)
                key_path = f'{path}.{key}' if path else str(key)
                if key is not None:
                    if key in marks:
                        raise ValueError(f'{source}: {key_path}: duplicate key '
                                         f'({_where_both(marks[key], key_node.start_mark)}); '
                                         'give each key once')
                    marks[key] = key_node.start_mark
                pending.append((value_node, key_path))


def _check_integer(node: yaml.ScalarNode, path: str, source: str) -> None:
    """Raise ValueError if `node` is an integer no float holds (beyond +-1.8e308)."""
    if node.tag != _INT_TAG or not _YAML12_INT.match(node.value):
        return
    _, base, digits = _integer_parts(node.value)
    # More than 309 digits is beyond a float in every base here; a shorter number is
    # converted exactly to tell.
    if len(digits) <= 309 and int(digits, base) <= sys.float_info.max:
        return
    where = f'{path}: ' if path else ''
    raise ValueError(f'{source}: {where}an integer of {len(digits)} digits (base {base}) is '
                     f'beyond the range of a float (+-{sys.float_info.max:.3g})')


def _integer_parts(text: str) -> tuple[int, int, str]:
    """
    Return (sign, base, digits) of a YAML 1.2 integer's text; ValueError if it has no digits.

    The digits come without leading zeros: Python converts at most 4300 digits, and
    00...01 is 1 however many zeros it has.
    """
    sign, digits = (-1, text[1:]) if text[:1] == '-' else (1, text.lstrip('+'))
    base = {'0o': 8, '0x': 16}.get(digits[:2], 10)
    digits = digits[2:] if base != 10 else digits
    if not digits:
        raise ValueError(f'{text!r} has no digits')
    return sign, base, digits.lstrip('0') or '0'


def _mapping_key(loader: _SceneYamlLoader, key_node: yaml.Node) -> Any:
    """Return a scalar mapping key as it will be constructed (None for other keys)."""
    if not isinstance(key_node, yaml.ScalarNode):
        return None  # a list or mapping as a key: construction rejects it as unhashable
    if key_node.tag == 'tag:yaml.org,2002:merge':
        return '<<'
    try:
        return loader.construct_object(key_node)
    except (yaml.YAMLError, ValueError, TypeError, OverflowError):
        return None  # construct_document reports it, as invalid YAML


def _where_both(first: yaml.Mark, second: yaml.Mark) -> str:
    """Return where two marks are: 'lines 3 and 7', or 'line 3, columns 8 and 23'."""
    if first.line == second.line:
        return f'line {first.line + 1}, columns {first.column + 1} and {second.column + 1}'
    return f'lines {first.line + 1} and {second.line + 1}'


def _one_line(error: BaseException) -> str:
    return ' '.join(str(error).split())
