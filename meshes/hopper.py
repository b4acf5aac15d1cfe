"""Conical hopper (thesis ch. 4, Fig. 4-1): gmsh script and template for your own hopper.

    python meshes/hopper.py                 # writes meshes/hopper.msh and meshes/hopper.png
    mpirun -n 2 python meshes/hopper.py     # the same, meshed on rank 0 and distributed

Change GEOMETRY for your silo: it takes any key of a scene's [geometry] section
(docs/scene.md); bad values are refused with a message naming the key. A scene uses the
mesh with `mesh_file = "meshes/hopper.msh"` (the other [geometry] keys must describe the
same wall: the mesh is checked against it).
"""

from pathlib import Path

from silo_dolfinx.geometry.mesher import mesh_geometry

GEOMETRY = {
    "shape": "hopper",
    "height": 2.64,  # m, outlet to top
    "top_radius": 1.2,  # m
    "outlet_radius": 0.1,  # m  -> half-angle atan(1.1/2.64) = 22.6°
    "element_size": 0.05,  # m
    "outlet_size_factor": 0.5,  # cells at the outlet edge half as big
}

if __name__ == "__main__":
    mesh_geometry(GEOMETRY, Path(__file__).with_suffix(".msh"))
