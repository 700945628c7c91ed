"""The ``so101`` command: the tools beside the course's files (compare, sheet, the checkers)."""

__all__: list[str] = []
