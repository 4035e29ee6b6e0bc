"""
The ROS clock under ``use_sim_time``, followed by the node itself: no /clock can end it.

rclpy's own /clock subscription (its TimeSource) turns a message it cannot represent (a
negative ``sec``, ``nanosec`` of a second or more) into an exception in the executor, which
ends the node: any peer could stop it with one message.  The node therefore removes that
subscription and follows /clock through :class:`ClockGuard`: a message that is not a time
is refused (counted, one throttled log line, a WARN on /diagnostics) and the clock stays
where it was; a valid one sets the node's ROS clock (``ROSClock.set_ros_time_override``).

What the node does not take from the ROS clock: its tick runs on the steady clock, and so
does the expiry of inputs (``input_timeout``), so a /clock that stops, never comes, runs
backwards or jumps to 2^31 s never makes an input last forever nor the ticks stop.  What it
does take: the stamps of its messages (without ``publish_clock``); when that clock does not
advance or goes back, /diagnostics says so and what the stamps then mean.
"""

import time

__all__ = ['ClockGuard', 'STALL_SECONDS', 'NANOSECONDS_PER_SECOND']

NANOSECONDS_PER_SECOND = 1_000_000_000
STALL_SECONDS = 1.0
"""Wall-clock seconds without an advance of /clock after which it is said to stand still."""


class ClockGuard:
    """
    What the node knows of /clock: its last valid time, and what went wrong.

    Feed it every /clock message (:meth:`receive`); it returns the time in ns to set, or
    None for a message that is not a time.  :meth:`status` gives the words /diagnostics
    carries.  Times are ints of ns; `now` arguments are time.monotonic() seconds.
    """

    def __init__(self):
        self.time = None  # ns: the last valid /clock, None before the first
        self.received = 0
        self.rejected = 0
        self.went_back = 0
        self.last_rejected = None  # why the last refused message was refused
        self._advanced_at = None  # monotonic s of the last advance
        self._reported = (0, 0)  # rejected, went_back at the last status

    def receive(self, seconds, nanoseconds, now=None):
        """
        Take a /clock message's ``sec`` and ``nanosec``; return the time (ns) or None.

        None: the message is not a time (sec < 0, nanosec >= 1 s) and is refused.
        """
        now = time.monotonic() if now is None else now
        self.received += 1
        if seconds < 0 or not 0 <= nanoseconds < NANOSECONDS_PER_SECOND:
            self.rejected += 1
            self.last_rejected = f'sec {seconds}, nanosec {nanoseconds}: not a time'
            return None
        stamp = seconds * NANOSECONDS_PER_SECOND + nanoseconds
        if self.time is not None and stamp < self.time:
            self.went_back += 1
        if self.time is None or stamp != self.time:
            self._advanced_at = now
        self.time = stamp
        return stamp

    def stalled_for(self, now=None):
        """Return the wall seconds since /clock last changed (None before any)."""
        if self._advanced_at is None:
            return None
        return (time.monotonic() if now is None else now) - self._advanced_at

    def status(self, now=None):
        """
        Return (problems, [(key, value)]) for /diagnostics, and start a new period.

        problems: [(what is wrong, kind)], kind 'stamps' (the clock stands still or never
        came: it matters where the stamps come from /clock) or 'peer' (a message refused,
        the clock went back: worth a warning whatever the stamps), since the last status.
        """
        stalled = self.stalled_for(now)
        rejected = self.rejected - self._reported[0]
        went_back = self.went_back - self._reported[1]
        self._reported = (self.rejected, self.went_back)
        values = [('ros clock', 'use_sim_time: /clock'),
                  ('/clock received', str(self.received)),
                  ('/clock refused', str(self.rejected)),
                  ('/clock went back', str(self.went_back))]
        if self.time is not None:
            seconds, nanoseconds = divmod(self.time, NANOSECONDS_PER_SECOND)
            values.append(('/clock time [s]', f'{seconds}.{nanoseconds:09d}'))
            values.append(('/clock unchanged for [s]', f'{stalled:.1f}'))
        problems = []
        if self.time is None:
            problems.append(('no /clock received yet: the stamps are 0', 'stamps'))
        elif stalled > STALL_SECONDS:
            problems.append((f'/clock has not advanced for {stalled:.0f} s: the stamps stand '
                             'still (they do not tell earlier messages from later ones)',
                             'stamps'))
        if went_back:
            problems.append((f'/clock went back {went_back} time(s): the stamps follow it '
                             'back', 'peer'))
        if rejected:
            problems.append((f'{rejected} /clock message(s) refused ({self.last_rejected})',
                             'peer'))
        return problems, values

    def stamps_ordered(self, now=None):
        """Return whether stamps taken now tell later from earlier (the clock advances)."""
        stalled = self.stalled_for(now)
        return self.time is not None and stalled is not None and stalled <= STALL_SECONDS
