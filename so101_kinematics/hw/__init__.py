"""The real arm through lerobot's Feetech bus: bus, control loop, fault policy, log, teach."""

__all__: list[str] = []
