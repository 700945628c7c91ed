"""Lab-day tools that use both arms at once: the fault drills (hardware path, virtual arm)."""

__all__: list[str] = []
