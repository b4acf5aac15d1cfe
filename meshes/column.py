"""Tapered column (thesis ch. 5): gmsh script and template.

    python meshes/column.py                 # parallel column: meshes/column.msh
    python meshes/column.py 3               # converging 3°: meshes/column_alpha3.msh

The whole base is the outlet (it is pulled down to start a rarefaction wave).
"""

import sys
from pathlib import Path

from silo_dolfinx.geometry.mesher import mesh_geometry

GEOMETRY = {
    "shape": "column",
    "base_radius": 0.5,  # m
    "height": 5.0,  # m
    "half_angle": 0.0,  # degrees: + converging (widening upwards), - diverging
    "element_size": 0.05,  # m
}

if __name__ == "__main__":
    geometry = dict(GEOMETRY)
    name = "column"
    if len(sys.argv) > 1:
        geometry["half_angle"] = float(sys.argv[1])
        name += f"_alpha{geometry['half_angle']:g}"
    mesh_geometry(geometry, Path(__file__).with_name(name + ".msh"))
