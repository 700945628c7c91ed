"""Two SO-101s in one scene: the board game both arms play (issue 38)."""

__all__: list[str] = []
