"""
The ranges of the options that set how ``run`` and ``simulate`` step.

They are checked before anything is simulated, each refusal one line naming the option (a
ValueError for the command line).

They are the node's: a rate of 0.1 to 10000 Hz (a step of 0.1 ms to 10 s), 1 to 100000
substeps, a tolerance of 0 (off) to 1 rad/s; and a duration above 0 s and at most 2^31 s (a
bag's stamps hold int32 seconds).  Within them every run ends: at most 2.1e13 steps, a count
that int64 and a float's 53 bits hold exactly, and a simulated clock that resolves each
step.  Outside them a step of 1e15 s advanced nothing (1 s of it is below what
Simulator.run takes), one of 5e-324 s overflowed the step count, a NaN duration ran nothing
and exited 0.
"""

from __future__ import annotations

import math
from typing import TypeVar

from ..scenes import RATE_RANGE
from ..scenes import SUBSTEPS_RANGE
from ..scenes import TOLERANCE_RANGE

__all__ = ['MAX_DURATION', 'check_duration', 'check_rate', 'check_step', 'check_substeps',
           'check_tolerance', 'check_every']

MAX_DURATION = 2.0 ** 31
"""The longest simulated time (s) the commands take: a bag's stamps hold int32 seconds."""

STEP_RANGE = (1.0 / RATE_RANGE[1], 1.0 / RATE_RANGE[0])
"""The steps (s) ``run --dt`` takes: the periods of the node's rates."""

# A checked value keeps its type: a count stays an int, a time a float.
_Number = TypeVar('_Number', int, float)


def _within(value: _Number, option: str, low: float, high: float, allowed: str,
            above: bool = False) -> _Number:
    """Return `value` if low <= value <= high (low < value if `above`), else ValueError."""
    # Written so that NaN, which compares False, is refused too.
    if not ((low < value if above else low <= value) and value <= high):
        shown = f'{value:g}' if isinstance(value, float) else value
        raise ValueError(f'{option} must be {allowed}; got {shown}')
    return value


def check_duration(duration: float, option: str = '--duration') -> float:
    """Return `duration` (s) if it is above 0 and at most MAX_DURATION, else ValueError."""
    return _within(duration, option, 0.0, MAX_DURATION,
                   'above 0 and at most 2^31 s (68 years)', above=True)


def check_rate(rate: float, option: str = '--rate') -> float:
    """Return `rate` (Hz) if it is one the node takes, else ValueError."""
    return _within(rate, option, *RATE_RANGE,
                   f"{RATE_RANGE[0]:g} to {RATE_RANGE[1]:g} Hz, as the node's rate")


def check_step(step: float, option: str = '--dt') -> float:
    """Return `step` (s) if it is the period of a rate the node takes, else ValueError."""
    return _within(step, option, *STEP_RANGE,
                   f"{STEP_RANGE[0]:g} to {STEP_RANGE[1]:g} s (the node's rates, "
                   f'{RATE_RANGE[0]:g} to {RATE_RANGE[1]:g} Hz)')


def check_substeps(substeps: int, option: str = '--substeps') -> int:
    """Return `substeps` if it is a number of substeps the node takes, else ValueError."""
    return _within(substeps, option, *SUBSTEPS_RANGE,
                   f"{SUBSTEPS_RANGE[0]} to {SUBSTEPS_RANGE[1]}, as the node's substeps")


def check_tolerance(tolerance: float, option: str = '--tolerance') -> float:
    """Return `tolerance` (rad/s, 0: off) if the node takes it, else ValueError."""
    return _within(tolerance, option, *TOLERANCE_RANGE,
                   f'{TOLERANCE_RANGE[0]:g} (off) to {TOLERANCE_RANGE[1]:g} rad/s, as the '
                   "node's tolerance")


def check_every(every: float, step: float, option: str = '--every') -> float:
    """
    Return `every` (s between printed rows) if it is at least one `step` (s), else ValueError.

    A row between two steps would cut the step short, silently a shorter step than asked.
    """
    if math.isnan(every) or every < step:
        raise ValueError(f'{option} must be at least one step, {step:g} s (or give a shorter '
                         f'--dt); got {every:g}')
    return every
