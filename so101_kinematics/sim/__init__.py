"""The simulated arm: scene, meshes, contact pairs, rendering, the pick-and-place run."""

__all__: list[str] = []
