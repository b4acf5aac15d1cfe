"""Cylinder on a conical hopper (thesis ch. 7, the Danish silo): gmsh script and template.

    python meshes/bin_hopper.py             # abrupt transition: meshes/bin_hopper.msh
    python meshes/bin_hopper.py 1.0         # filleted, radius 1 m: meshes/bin_hopper_fillet1.msh

The transition is a mesh node (abrupt) or a circular arc whose ends are mesh nodes
(filleted); cells are refined towards it. See meshes/hopper.py for how to adapt.
"""

import sys
from pathlib import Path

from silo_dolfinx.geometry.mesher import mesh_geometry

GEOMETRY = {
    "shape": "bin_hopper",
    "radius": 0.35,  # m
    "bin_height": 4.313,  # m, vertical wall above the transition (5 m in all)
    "hopper_half_angle": 20.0,  # degrees from the vertical
    "outlet_radius": 0.1,  # m
    "fillet_radius": 0.0,  # m, 0 = abrupt
    "element_size": 0.025,  # m
    "transition_size_factor": 0.4,
}

if __name__ == "__main__":
    geometry = dict(GEOMETRY)
    name = "bin_hopper"
    if len(sys.argv) > 1:
        geometry["fillet_radius"] = float(sys.argv[1])
        name += f"_fillet{geometry['fillet_radius']:g}"
    mesh_geometry(geometry, Path(__file__).with_name(name + ".msh"))
