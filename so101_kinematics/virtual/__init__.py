"""A virtual SO-101 on a pseudo-terminal: the Feetech protocol, a servo, the emulator, faults."""

__all__: list[str] = []
