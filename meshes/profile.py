"""Your own silo from a wall profile: gmsh script and template.

    python meshes/profile.py                # writes meshes/profile.msh and .png

List the wall from the outlet edge (z = 0) upwards as [r, z] points in metres; z may not
decrease. Straight segments join the points. This example is a mass-flow hopper under a
short vertical section and a gently diverging top. A floor (an outlet narrower than the
first wall point) or ledges (horizontal pieces) are allowed; ledges need
"mesh": "unstructured".
"""

from pathlib import Path

from silo_dolfinx.geometry.mesher import mesh_geometry

GEOMETRY = {
    "shape": "profile",
    "wall": [[0.15, 0.0], [0.6, 0.9], [0.6, 2.0], [0.5, 3.0]],
    "outlet_radius": 0.15,  # m
    "element_size": 0.04,  # m
    "transition_size_factor": 0.5,
}

if __name__ == "__main__":
    mesh_geometry(GEOMETRY, Path(__file__).with_suffix(".msh"))
