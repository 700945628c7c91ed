"""The final project's throw: a ball, its flight with drag, the release the servos can reach."""

__all__: list[str] = []
