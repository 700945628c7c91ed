"""The final project's drawing: strokes on a page, a pen in reach, ink in the simulator."""

__all__: list[str] = []
