"""How conservative is the stable-Δt estimate? The critical time-step scale, by bisection.

    python benchmarks/stable_dt.py [--hoop 0.1 0.25]

For each mesh (structured and unstructured column and hopper) and Poisson ratio, an
undamped elastic body (frictionless wall contact, outlet on a roller, no gravity) starts
from small random velocities and is stepped 3,000 times at Δt = scale × estimate. It is
*unstable* if its total energy more than doubles or an element collapses. The table gives
the bracket of the critical scale: above 1 the estimate is conservative; the default scale
0.8 (and 0.9) must stay below every entry, and 1.5 above every entry for the guard test.
The hoop coefficient (kernels.HOOP) is the one free constant of the estimate; pass several
values to see how it trades safety for step size.
"""

from __future__ import annotations

import argparse

import numpy as np

import silo_dolfinx  # noqa: F401

GEOMETRIES = {
    "column, structured": {"shape": "column", "base_radius": 0.2, "height": 0.5, "element_size": 0.04},
    "column, unstructured": {"shape": "column", "base_radius": 0.2, "height": 0.5, "element_size": 0.04,
                             "mesh": "unstructured"},
    "hopper, structured": {"shape": "hopper", "height": 1.0, "top_radius": 0.5, "outlet_radius": 0.05,
                           "element_size": 0.05},
    "hopper, unstructured": {"shape": "hopper", "height": 1.0, "top_radius": 0.5, "outlet_radius": 0.05,
                             "element_size": 0.05, "mesh": "unstructured"},
}


def stable(geometry: dict, scale: float, nu: float, hoop: float, steps: int = 3000) -> bool:
    from mpi4py import MPI

    from silo_dolfinx import kernels
    from silo_dolfinx.geometry.mesher import mesh_scene
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import SiloModel
    from silo_dolfinx.solver import InstabilityError, VelocityConstraint

    kernels.HOOP = hoop
    scene = load_scene({"geometry": geometry, "wall": {"friction": "none"},
                        "material": {"model": "elastic", "density": 1000.0, "youngs_modulus": 1e6,
                                     "poisson_ratio": nu},
                        "numerics": {"time_step_scale": scale, "bulk_viscosity": [0.0, 0.0]}})
    model = SiloModel(scene, mesh_scene(scene, MPI.COMM_SELF))
    s = model.solver
    s.constraints.append(VelocityConstraint(model.outlet_dofs_all, 1))
    model.remove_gate()
    rng = np.random.default_rng(0)
    s.v[:] = 1e-6 * rng.standard_normal(s.v.shape)
    s.v[model.axis_dofs, 0] = 0.0
    s.v[model.outlet_dofs_all, 1] = 0.0
    e0 = None
    try:
        for i in range(steps):
            s.step()
            if i == 10:
                e = s.global_energy()
                e0 = e.kinetic + e.elastic
    except InstabilityError:
        return False
    e = s.global_energy()
    return bool(np.isfinite(e.kinetic) and e.kinetic + e.elastic < 2.0 * e0)


def critical(geometry, nu, hoop, lo=0.8, hi=2.5, iterations=7):
    if not stable(geometry, lo, nu, hoop):
        return (0.0, lo)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if stable(geometry, mid, nu, hoop):
            lo = mid
        else:
            hi = mid
    return lo, hi


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    from silo_dolfinx import kernels

    ap.add_argument("--hoop", type=float, nargs="+", default=[kernels.HOOP])
    ap.add_argument("--nu", type=float, nargs="+", default=[0.3, 0.45])
    args = ap.parse_args()
    print("critical Δt scale (stable below the first number, unstable above the second)")
    print(f"{'mesh':24s} {'ν':>5s} " + " ".join(f"{'hoop ' + format(h, 'g'):>15s}" for h in args.hoop))
    for name, g in GEOMETRIES.items():
        for nu in args.nu:
            cells = [critical(g, nu, h) for h in args.hoop]
            print(f"{name:24s} {nu:5.2f} " + " ".join(f"{lo:6.3f} – {hi:6.3f}" for lo, hi in cells))


if __name__ == "__main__":
    main()
