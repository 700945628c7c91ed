"""The arm's serial port for this program alone: an exclusive lock, and who else has it open."""

from __future__ import annotations

import fcntl
import os

from so101_kinematics.errors import ConnectionFailed, PortInUse

__all__ = ["FIND_PORT_HINT", "claim_port"]

FIND_PORT_HINT = "lerobot-find-port"


def _proc_links(pid: str) -> set[str]:
    try:
        folder = f"/proc/{pid}/fd"
        return {os.readlink(os.path.join(folder, fd)) for fd in os.listdir(folder)}
    except OSError:
        return set()


def _command_line(pid: str) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as handle:
            return handle.read().replace(b"\0", b" ").decode(errors="replace").strip()[:80]
    except OSError:
        return "?"


def port_users(port: str) -> list[str]:
    """Other processes with ``port`` open, as "pid N (command)" (Linux; [] elsewhere).

    A process that also holds a pseudo-terminal master (/dev/ptmx: the virtual
    arm's emulator, a terminal) is the port's other end, not a user.
    """
    if not os.path.isdir("/proc"):
        return []
    target = os.path.realpath(port)
    users = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        links = _proc_links(pid)
        if target in links and "/dev/ptmx" not in links:
            users.append(f"pid {pid} ({_command_line(pid)})")
    return users


def claim_port(port: str) -> int:
    """Open ``port`` with an exclusive lock (flock) for this program; returns the fd to close.

    Raises:
        PortInUse: another program holds the lock or has the port open.
        ConnectionFailed: the port cannot be opened.
    """
    try:
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as error:
        raise ConnectionFailed(f"Cannot open port '{port}': {error.strerror}. Find the port with "
                               f"`{FIND_PORT_HINT}`.") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        users = port_users(port)
        raise PortInUse(f"The port '{port}' is in use by another program"
                        f"{': ' + ', '.join(users) if users else ''}. Fix: stop that program "
                        "first (only one program may drive the arm).") from None
    users = port_users(port)
    if users:
        os.close(fd)
        raise PortInUse(f"The port '{port}' is in use by another program: {', '.join(users)}. "
                        "Fix: stop that program first (only one program may drive the arm).")
    return fd


# --- lerobot, imported lazily ------------------------------------------------
