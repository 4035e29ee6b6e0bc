"""
The frame ids the node publishes, named in one place and checked as tf2 reads them.

Frames follow the namespace as robot_state_publisher's do: a ``frame_prefix`` is put in
front of every frame the node names, verbatim (``sat1/`` + ``body`` is ``sat1/body``, so the
prefix carries its own ``/``), and defaults to the node's namespace (:func:`default_frame_prefix`:
``/sat1`` gives ``sat1/``, the root namespace none).  Two nodes in ``/sat1`` and ``/sat2`` then
publish ``sat1/world -> sat1/body`` and ``sat2/world -> sat2/body`` on the one global ``/tf``.
A name that starts with ``/`` is absolute, as tf1's ``tf_prefix`` resolved it: no prefix is
put in front of it, so ``world_frame:=/world`` gives both nodes one ``world`` frame (``world
-> sat1/body``, ``world -> sat2/body``: one tree, both bodies in one RViz view).

tf2 drops one leading ``/`` from every frame id it is given (``/body`` is ``body``): the
frame ids are compared, and published, as it reads them (:func:`as_tf2_reads`), so at the
root ``world_frame:=/body`` is the body frame, and ``/`` is no frame at all.  Whitespace,
control characters and names longer than :data:`MAX_FRAME_ID_LENGTH` are refused too: tf2
would take some of them, but no RViz field, ``tf2_echo`` argument or log line can name them.

:func:`frame_ids` is where every frame id of the node is made: the many-bodies scenes add
theirs (``<name>``, ``<name>/imu``) to the names it is given.
"""

from ..text import shortened

__all__ = ['MAX_FRAME_ID_LENGTH', 'as_tf2_reads', 'default_frame_prefix', 'frame_id_problem',
           'frame_ids']

MAX_FRAME_ID_LENGTH = 256
"""The longest frame id accepted, in characters (after the prefix, as tf2 reads it)."""


def default_frame_prefix(namespace):
    """
    Return the frame prefix of a node in `namespace`: ``/sat1`` -> ``sat1/``, ``/`` -> ``''``.

    Nested namespaces keep their path: ``/fleet/sat1`` -> ``fleet/sat1/``.
    """
    path = namespace.strip('/')
    return f'{path}/' if path else ''


def as_tf2_reads(frame_id):
    """Return `frame_id` as tf2 stores it: without one leading ``/``."""
    return frame_id[1:] if frame_id.startswith('/') else frame_id


def frame_id_problem(frame_id):
    """
    Return why tf2 frame id `frame_id` (as tf2 reads it) cannot be used, or None.

    Refused: an empty one, one still starting with ``/`` (tf2 drops only one), whitespace,
    control and other non-printable characters, more than :data:`MAX_FRAME_ID_LENGTH`
    characters.
    """
    if not frame_id:
        return 'is empty as tf2 reads it (it drops one leading /)'
    if len(frame_id) > MAX_FRAME_ID_LENGTH:
        return (f'is {len(frame_id)} characters long; frame ids are at most '
                f'{MAX_FRAME_ID_LENGTH} here')
    if frame_id.startswith('/'):
        return 'still starts with / once tf2 dropped one (tf2 lookups refuse such an id)'
    if any(character.isspace() for character in frame_id):
        return 'holds whitespace, which no RViz field or tf2_echo argument can name'
    if not frame_id.isprintable():
        return 'holds a control character (or another non-printable one)'
    return None


def frame_ids(frame_prefix, names):
    """
    Return {parameter: frame id} of the frames `names` gives, prefixed, as tf2 reads them.

    Parameters
    ----------
    frame_prefix : str
        Put in front of every name verbatim (robot_state_publisher's rule): ``sat1/``;
        not in front of an absolute name, one that starts with ``/``.
    names : mapping
        Parameter (what a refusal names, e.g. ``world_frame``) -> the frame name given.

    Raises
    ------
    ValueError
        One line naming the parameter, the frame id tf2 would read and what is wrong with
        it: not a usable frame id (:func:`frame_id_problem`), or the same frame as another.

    """
    ids = {}
    for parameter, name in names.items():
        frame_id = as_tf2_reads(_prefixed(frame_prefix, name))
        problem = frame_id_problem(frame_id)
        if problem is not None:
            raise ValueError(f'parameter {parameter!r}: {_quoted(frame_prefix, name)} '
                             f'{problem}')
        for other, other_id in ids.items():
            if other_id == frame_id:
                raise ValueError(
                    f'parameters {other!r} and {parameter!r} name one frame: '
                    f'{_quoted(frame_prefix, names[other])} and {_quoted(frame_prefix, name)} '
                    f"are both '{shortened(frame_id)}' as tf2 reads them (it drops one leading "
                    '/); give them different names')
        ids[parameter] = frame_id
    return ids


def _prefixed(frame_prefix, name):
    """Return `name` after `frame_prefix`, or as it is if it is absolute (starts with /)."""
    return name if name.startswith('/') else frame_prefix + name


def _quoted(frame_prefix, name):
    """Return how a refusal quotes a given name: with the prefix put before it, if any."""
    if frame_prefix and _prefixed(frame_prefix, name) != name:
        return f"'{shortened(name)}' (with frame_prefix '{shortened(frame_prefix)}')"
    return f"'{shortened(name)}'"
