"""Scene files: TOML descriptions of a run, validated against :mod:`.schema`."""

from silo_dolfinx.scene.errors import Problem, SceneError
from silo_dolfinx.scene.loader import Scene, SceneSection, apply_overrides, load_geometry, load_scene, read_toml

__all__ = ["Problem", "Scene", "SceneError", "SceneSection", "apply_overrides", "load_geometry", "load_scene", "read_toml"]
