"""A simulated clock shared by the virtual arm and its program: time passes when it sleeps.

The design, one socket pair between the two processes (:class:`VirtualSO101`'s
``sim_clock=True`` makes it, and hands the program's end out as ``arm.clock``):

- The program owns the time. :meth:`SimClock.sleep` adds ``seconds`` to it, rounded
  up to the next whole nanosecond and one more (so a loop sleeping until a deadline
  is never left a hair short of it, and its busy-wait ends: ``spin`` is 0), sends the
  new time to the emulator as 8 bytes (integer nanoseconds, little-endian) and waits
  for the emulator's answer, once it has stepped the MuJoCo arm up to the new time.
  :meth:`SimClock.clock` returns the time without asking anyone.
- The emulator (:class:`ClockFollower`, watched by its event loop beside the pty)
  first answers what is already on the bus (requests sent before the sleep act
  before it), then takes every 4 ms physics step up to the new time, however long
  that takes on the wall clock (never slipping, as the wall clock's emulator does
  when it falls more than 25 steps behind), then answers.
- Nothing else moves the time but the bus's silence: a request the emulator leaves
  unanswered (an outage, a lost reply, a missing servo) costs the program lerobot's
  timeout (:data:`LEROBOT_TIMEOUT_S`), and a late reply its lateness up to that, as
  they do on a real arm; the emulator adds it (:meth:`ClockFollower.charge`) and says
  so at once, and :meth:`SimClock.clock` takes that news first. A program that stalls
  stalls the arm with it, and the run is the same, cycle for cycle. The bus's bytes,
  the emulator's reply latency and lerobot's own waits take wall time and no other
  simulated time. The faults timed by the arm (``outage:MS``, a hand's motion) run on
  this clock too.
- Every message from the emulator is 24 bytes: the time answered (the last sent), the
  time its physics has reached, the program's time. One answering an older time than
  the sleep's (news of a charge, or an answer left unread by a signal handler that
  raised in the middle of a sleep) does not end the sleep; when the emulator has gone,
  a sleep returns at once and the time goes on in the program alone.

Example (a stand-in emulator that steps 4 ms at a time)::

    >>> import socket, threading
    >>> ours, theirs = socket.socketpair()
    >>> follower = ClockFollower(theirs.detach())
    >>> def emulator():
    ...     while follower.receive():
    ...         follower.acknowledge(follower.target_ns // 4_000_000 * 4_000_000)
    >>> thread = threading.Thread(target=emulator); thread.start()
    >>> clock = SimClock(ours)
    >>> clock.sleep(0.010)  # [s] returns when the arm is at 10 ms (its physics at 8 ms)
    >>> clock.clock(), clock.reached
    (0.010000001, 0.008)
    >>> clock.close(); thread.join(); follower.close()
"""

from __future__ import annotations

import math
import select
import socket
import struct

from so101_kinematics.errors import VirtualSO101Error

__all__ = ["CATCH_UP_TIMEOUT_S", "ClockFollower", "LEROBOT_TIMEOUT_S", "SimClock"]

CATCH_UP_TIMEOUT_S = 60.0  # [s] of wall time the emulator may take to step up to a new time
LEROBOT_TIMEOUT_S = 0.05
"""[s] lerobot waits this long for a reply before it gives up (its Feetech port handler: 50 ms
plus the bytes' time): what an unanswered request costs the program."""
_TIME = struct.Struct("<q")  # a sleep's new time: integer nanoseconds, little-endian
_NEWS = struct.Struct("<qqq")  # the emulator's: the time answered, the physics', the program's


def _receive(sock: socket.socket, shape: struct.Struct) -> tuple | None:
    """One whole message from ``sock`` (blocking), or None when the other end has gone."""
    data = b""
    while len(data) < shape.size:
        try:
            chunk = sock.recv(shape.size - len(data))
        except OSError:
            return None
        if not chunk:
            return None
        data += chunk
    return shape.unpack(data)


class SimClock:
    """The program's side: ``clock()`` and ``sleep(seconds)`` on the simulated time.

    Pass ``clock``, ``sleep`` and ``spin`` to the control loop (``hw/run.py``'s
    ``run_on_arm(time_source=arm.clock)``; ``hw/control.py``'s ``ArmSession``).

    Args:
        sock: this process's end of the socket pair; the emulator holds the other.
    """

    spin = 0.0
    """[s] the control loop busy-waits at the end of each wait: none, a sleep here is exact."""

    def __init__(self, sock: socket.socket):
        self._sock = sock
        self._ns = 0  # the program's time [ns] since the arm powered up
        self.reached_ns = 0  # the emulator's physics at the last answer [ns]

    def clock(self) -> float:
        """The simulated time [s] since the arm powered up (with the bus's silences)."""
        while self._sock is not None and select.select([self._sock], [], [], 0.0)[0]:
            self._take(_receive(self._sock, _NEWS))
        return self._ns / 1e9

    def _take(self, news: tuple | None) -> int:
        """Apply the emulator's news; returns the time it answers (-1: the emulator has gone)."""
        if news is None:
            self.close()
            return -1
        answered, reached, program = news
        self._ns = max(self._ns, program)
        self.reached_ns = max(self.reached_ns, reached)
        return answered

    @property
    def reached(self) -> float:
        """[s] where the arm's physics stood at the last answer (at most one step behind)."""
        return self.reached_ns / 1e9

    def sleep(self, seconds: float) -> None:
        """Advance the time by ``seconds`` [s] (at least), return when the arm is there."""
        if not seconds > 0.0:
            return
        self._ns += math.ceil(seconds * 1e9) + 1
        if self._sock is None:
            return
        sent = self._ns
        try:
            self._sock.sendall(_TIME.pack(sent))
            while True:
                ready, _, _ = select.select([self._sock], [], [], CATCH_UP_TIMEOUT_S)
                if not ready:
                    raise VirtualSO101Error(
                        f"The virtual arm did not reach {self.clock():.3f} s of simulated time "
                        f"within {CATCH_UP_TIMEOUT_S:g} s. Fix: check that its emulator "
                        "process runs (a debugger, SIGSTOP) or start it again.")
                answered = self._take(_receive(self._sock, _NEWS))
                if answered >= sent or answered < 0:  # else news of an earlier time
                    return
        except OSError:
            self.close()  # the emulator has gone: the time goes on here alone

    def close(self) -> None:
        """Stop talking to the emulator (idempotent); later sleeps only advance the time."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None


class ClockFollower:
    """The emulator's side: the time the program has reached, and the answer once there.

    Args:
        fd: the emulator's end of the socket pair (a file descriptor).
    """

    def __init__(self, fd: int):
        self.sock = socket.socket(fileno=fd)
        self.sock.setblocking(False)
        self.target_ns = 0  # the program's time [ns]: step the physics up to it
        self.asked_ns = 0  # the last time the program sent [ns]
        self.reached_ns = 0  # where the physics stands [ns] (the emulator's steps)
        self.pending = False  # an answer is owed
        self.open = True

    def fileno(self) -> int:
        """The descriptor to watch with ``select`` (readable: a new time)."""
        return self.sock.fileno()

    @property
    def now(self) -> float:
        """The program's time [s]: the arm's clock."""
        return self.target_ns / 1e9

    def receive(self) -> bool:
        """Take the new time(s) sent (the latest counts); False when the program has gone."""
        self.sock.setblocking(True)
        try:
            latest = _receive(self.sock, _TIME)
            while latest is not None and select.select([self.sock], [], [], 0.0)[0]:
                latest = _receive(self.sock, _TIME)  # several sleeps queued: the last is now
        finally:
            self.sock.setblocking(False)
        if latest is None:
            self.open = False
            return False
        self.asked_ns = latest[0]
        self.target_ns = max(self.target_ns, self.asked_ns)
        self.pending = True
        return True

    def acknowledge(self, reached_ns: int) -> None:
        """Tell the program the physics has reached ``reached_ns`` [ns] (if it waits)."""
        self.reached_ns = reached_ns
        if self.pending:
            self.pending = False
            self._tell()

    def charge(self, seconds: float) -> None:
        """The program waited ``seconds`` [s] on the bus for nothing: its time moves on."""
        self.target_ns += round(seconds * 1e9)
        self._tell()

    def _tell(self) -> None:
        try:
            self.sock.sendall(_NEWS.pack(self.asked_ns, self.reached_ns, self.target_ns))
        except OSError:  # the program has gone: nobody to tell
            self.open = False

    def close(self) -> None:
        """Close the emulator's end."""
        self.sock.close()
        self.open = False
