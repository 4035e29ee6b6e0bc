"""
Outside text made fit to echo: one line of printable text of bounded length.

A scene file, a path on the command line, a parameter value or a string a DDS peer sends
(a frame id, a parameter name) can be megabytes long or hold terminal control sequences; a
message, log line or service reply that quotes it must neither flood the terminal or the
log nor let an escape sequence through.

- :func:`one_line` escapes what is not printable (as Python's repr does: a newline becomes
  backslash n, ESC backslash x1b) and cuts a long text in its middle, keeping the beginning
  (the file and the key) and the end (what to do): for error messages the package writes.
- :func:`one_line_errors` does it for every ValueError of a function: a public function
  that reads outside input wears it once, and every message it raises is then such a line.
- :func:`shortened` cuts a peer's string at its end, saying how many characters were left
  out, and escapes it: for the node's warnings and replies that quote what a peer sent.
"""

from __future__ import annotations

from collections.abc import Callable
import functools
from typing import ParamSpec
from typing import TypeVar

__all__ = ['MAX_ECHOED', 'MESSAGE_LIMIT', 'one_line', 'one_line_errors', 'shortened']

MESSAGE_LIMIT = 500
"""The most characters :func:`one_line` returns: room for every message the project writes
itself (the longest are ~300), not for a value quoted whole."""

MAX_ECHOED = 200
"""Most characters of a peer's string that :func:`shortened` quotes (the rest is counted)."""

_TAIL = 120
# A decorated function keeps its parameters and result (one_line_errors).
_Parameters = ParamSpec('_Parameters')
_Result = TypeVar('_Result')


def one_line(text: object, limit: int = MESSAGE_LIMIT) -> str:
    """
    Return `text` as one line of at most `limit` printable characters.

    Characters that are not printable are escaped; a text still longer than `limit` keeps
    its beginning and its last ~`limit`/4 characters around a note of its whole length.
    A text that is already such a line is returned unchanged.
    """
    text = str(text)
    if len(text) <= limit and text.isprintable():
        return text
    # Each part is escaped after it is cut: a megabyte of control characters is never
    # escaped whole (an escape is up to 10 characters).
    head = _escaped(text[:limit])
    if len(text) <= limit and len(head) <= limit:
        return head
    tail_size = min(_TAIL, limit // 4)
    note = f' [...{len(text)} characters in all...] '
    head_size = max(0, limit - tail_size - len(note))
    return head[:head_size] + note + _escaped(text[-tail_size:])[-tail_size:]


def _escaped(text: str) -> str:
    if text.isprintable():
        return text
    return ''.join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def one_line_errors(function: Callable[_Parameters, _Result]) -> Callable[_Parameters, _Result]:
    """
    Return `function` with every ValueError it raises made :func:`one_line`.

    An error that already is such a line is raised as it is (its type and traceback kept).
    """
    @functools.wraps(function)
    def checked(*args: _Parameters.args, **kwargs: _Parameters.kwargs) -> _Result:
        try:
            return function(*args, **kwargs)
        except ValueError as error:
            message = str(error)
            shown = one_line(message)
            if shown == message:
                raise
            raise ValueError(shown) from None
    return checked


def shortened(text: object, limit: int = MAX_ECHOED) -> str:
    """
    Return `text` cut to `limit` characters, saying how many were left out, and escaped.

    Control characters (and other non-printable ones) come out as Python escapes, so one
    log line stays one line and the terminal shows what came.
    """
    text = str(text)
    cut = len(text) - limit
    if cut > 0:
        text = text[:limit]
    if not text.isprintable():
        text = text.encode('unicode_escape').decode('ascii')
    return text + (f'... ({cut} more characters)' if cut > 0 else '')
