"""The fault grammar of the virtual SO-101 (``--faults`` / ``VirtualSO101.inject``).

The grammar and what each fault does are in :mod:`so101_kinematics.virtual.arm`'s docstring.
"""

from __future__ import annotations

from collections.abc import Mapping

from so101_kinematics.errors import FaultSpecError

__all__ = ["parse_faults"]

# --- faults -----------------------------------------------------------------------------------
FAULT_KINDS = ("drop", "corrupt", "remove", "stall", "firmware", "outage", "unplug", "latency",
               "overload", "overheat", "voltage")
MAX_FAULT_MS = 60_000  # longest outage or latency [ms]


def parse_faults(spec: str | None, calibration: Mapping[str, Mapping[str, int]]) -> list[tuple]:
    """Parse a fault specification (grammar in the module docstring).

    Returns:
        A list of (kind, servo_id, argument) tuples.

    Raises:
        FaultSpecError: naming the bad item and the grammar.
    """
    grammar = ("drop:SERVO[:N], corrupt:SERVO[:N], remove:SERVO, stall:SERVO, "
               "firmware:[SERVO:]MAJOR.MINOR, outage:MS, unplug, latency:MS[:N], "
               "overload:SERVO, overheat:SERVO, voltage:SERVO (SERVO = id or joint name, "
               f"MS in 1..{MAX_FAULT_MS}), comma-separated")
    ids = {name: int(entry["id"]) for name, entry in calibration.items()}

    def servo(token: str, item: str) -> int:
        if token in ids:
            return ids[token]
        if token.isdigit() and int(token) in ids.values():
            return int(token)
        raise FaultSpecError(f"Fault '{item}': unknown servo '{token}'; use an id in "
                             f"{sorted(ids.values())} or a joint in {list(ids)}.")

    faults = []
    for item in (s.strip() for s in (spec or "").split(",")):
        if not item:
            continue
        kind, *args = item.split(":")
        if kind not in FAULT_KINDS:
            raise FaultSpecError(f"Unknown fault '{item}'. Grammar: {grammar}.")
        try:
            if kind == "firmware":
                if len(args) == 1:
                    args = [str(min(ids.values())), args[0]]
                major, minor = (int(x) for x in args[1].split("."))
                if not (0 <= major <= 255 and 0 <= minor <= 255) or len(args) != 2:
                    raise ValueError
                faults.append((kind, servo(args[0], item), (major, minor)))
            elif kind == "unplug":
                if args:
                    raise ValueError
                faults.append((kind, None, None))
            elif kind in ("outage", "latency"):
                milliseconds = float(args[0])
                count = int(args[1]) if len(args) == 2 else 1
                if not (0 < milliseconds <= MAX_FAULT_MS) or count < 1 or len(args) > 2 \
                        or (kind == "outage" and len(args) != 1):
                    raise ValueError
                faults.append((kind, None, milliseconds if kind == "outage"
                               else (milliseconds, count)))
            elif kind in ("drop", "corrupt"):
                count = int(args[1]) if len(args) == 2 else 1
                if len(args) not in (1, 2) or count < 1:
                    raise ValueError
                faults.append((kind, servo(args[0], item), count))
            else:
                if len(args) != 1:
                    raise ValueError
                faults.append((kind, servo(args[0], item), None))
        except FaultSpecError:
            raise
        except (ValueError, IndexError):
            raise FaultSpecError(f"Bad fault '{item}'. Grammar: {grammar}.") from None
    return faults
