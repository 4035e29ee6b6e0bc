"""
Text from a peer, made fit to echo: long strings cut, control characters escaped.

A frame id, a parameter name or a value that a DDS peer sends can be megabytes long or hold
terminal control sequences; every warning, log line and service reply that quotes one
quotes :func:`shortened` of it.
"""

__all__ = ['MAX_ECHOED', 'shortened']

MAX_ECHOED = 200
"""Most characters of a peer's string that a message quotes (the rest is counted)."""


def shortened(text, limit=MAX_ECHOED):
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
