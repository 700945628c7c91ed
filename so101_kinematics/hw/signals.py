"""Stopping the real arm's loop: every stop signal at a cycle boundary, and no garbage collection.

Ctrl-C, SIGTERM and SIGHUP all ask for the same controlled stop
(:func:`stop_on_signals`); outside the motion they interrupt like Ctrl-C
(:func:`signals_as_interrupt`). :func:`gc_frozen` keeps Python's full
garbage collection out of the control loop.
"""

from __future__ import annotations

import gc
import signal
import sys
import threading
from contextlib import contextmanager
from typing import TYPE_CHECKING

from so101_kinematics.errors import FreezeRequested

if TYPE_CHECKING:
    from so101_kinematics.hw.control import ArmSession

__all__ = ["gc_frozen", "signals_as_interrupt", "stop_on_signals"]


@contextmanager
def gc_frozen():
    """Collect garbage once, then freeze: no 0.2 s full collection in the middle of a motion.

    With lerobot (and PyTorch) imported, a full collection of the cyclic
    garbage collector walks about 250 000 objects: about 0.2 s on this
    machine, long enough to stall the arm mid-move. Frozen objects are
    skipped; reference counting still frees everything the loop creates.
    """
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()



STOP_SIGNALS = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}
"""Every signal that asks a program to stop, and how the messages name it."""


@contextmanager
def stop_on_signals(session: ArmSession, freeze_at_once: bool = False):
    """Turn every stop signal (Ctrl-C, SIGTERM, SIGHUP) into a stop at the next cycle boundary.

    The first signal sets ``session.stop_reason`` (the loop raises
    StopRequested at its next cycle, never inside a bus transaction); a second
    one raises :class:`FreezeRequested` at once. With ``freeze_at_once`` (during
    the return after an abort) the first signal already freezes. Only in the
    main thread; the previous handlers are restored on exit.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        name = STOP_SIGNALS.get(signum, f"signal {signum}")
        if session.stop_reason is None and not freeze_at_once:
            session.stop_reason = name
            print(f"\nStopping ({name}): the arm returns slowly to its start (a cube in the "
                  f"jaws is put down first). {name} again freezes it where it is, torque on.",
                  file=sys.stderr, flush=True)
        else:
            raise FreezeRequested(name)

    previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextmanager
def signals_as_interrupt():
    """SIGTERM and SIGHUP raise KeyboardInterrupt, as Ctrl-C does (before and after the motion)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise KeyboardInterrupt(STOP_SIGNALS.get(signum, str(signum)))

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


