"""Silo geometry: analytic walls (:mod:`.wall`), shapes (:mod:`.shapes`), gmsh meshes (:mod:`.mesher`)."""

from silo_dolfinx.geometry.shapes import Outline, hopper_half_angle, outline_from_geometry
from silo_dolfinx.geometry.wall import Arc, Projection, Segment, Wall

__all__ = ["Arc", "Outline", "Projection", "Segment", "Wall", "hopper_half_angle", "outline_from_geometry"]
