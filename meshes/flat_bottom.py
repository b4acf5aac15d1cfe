"""Flat-bottomed silo (thesis ch. 6, the Edinburgh silo): gmsh script and template.

    python meshes/flat_bottom.py            # writes meshes/flat_bottom.msh and .png

The floor from the outlet edge to the wall is part of the wall (contact and wall pressure
act on it); a vertical mesh line rises from the outlet edge so the outlet keeps its own
column of cells. See meshes/hopper.py for how to use and adapt these scripts.
"""

from pathlib import Path

from silo_dolfinx.geometry.mesher import mesh_geometry

GEOMETRY = {
    "shape": "flat_bottom",
    "radius": 0.35,  # m
    "height": 4.0,  # m
    "outlet_radius": 0.02,  # m
    "element_size": 0.025,  # m
    "outlet_size_factor": 0.4,
}

if __name__ == "__main__":
    mesh_geometry(GEOMETRY, Path(__file__).with_suffix(".msh"))
