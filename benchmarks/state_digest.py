"""The state of a run after N steps, to check that a refactor changed no behaviour.

    python benchmarks/state_digest.py demos/scenes/hopper_ch4.toml before.npz --steps 2000 \
        --set discharge.duration=5.0
    ... change the code ...
    python benchmarks/state_digest.py demos/scenes/hopper_ch4.toml after.npz --steps 2000 \
        --set discharge.duration=5.0
    python benchmarks/state_digest.py --compare before.npz after.npz      # worst relative difference

(also under ``mpirun -n 2``: the file then holds both ranks' parts, compared rank by rank.)
The run stops after its N-th accepted step; the file holds, per rank, the owned nodes' (r, z)
and velocities, the stress, the density and every material state variable at the quadrature
points, the time, Δt and every term of the energy ledger. Two digests agree when the largest
difference of any array, relative to that array's largest magnitude, is ≤ --tol (1e-10).

Compare digests made in fresh checkouts (``git worktree add /tmp/before <commit>``, then run
with ``PYTHONPATH=/tmp/before``): numba's on-disk cache does not track helpers inlined from
other modules, and an ulp of difference grows in a discharge (flowing granular stress states
are chaotic; a flipped step rejection changes the Δt history).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)


class _Stop(Exception):
    pass


def digest(scene_path: str, out: str, steps: int, sets: list[str]) -> None:
    from mpi4py import MPI

    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run
    from silo_dolfinx.solver import ExplicitSolver
    from silo_dolfinx.state import Energy

    comm = MPI.COMM_WORLD
    step = ExplicitSolver.step

    def counted(self):
        dt = step(self)
        if self.steps >= steps:
            e = self.global_energy()
            own = self.node_dof < self.n_owned
            d = {"x": self.mesh.geometry.x[own][:, :2], "v": self.v[self.node_dof[own]], "sig": self.sig,
                 "rho": self.rho, "t": self.t, "dt": self.dt, **{f"state_{k}": a for k, a in self.state.items()},
                 **{f"energy_{k}": getattr(e, k) for k in Energy.names()}}
            parts = self.comm.gather(d, root=0)
            if self.comm.rank == 0:
                np.savez(out, parts=np.array(parts, dtype=object))
            raise _Stop
        return dt

    ExplicitSolver.step = counted
    import tempfile

    folder = comm.bcast(tempfile.mkdtemp(prefix="digest_") if comm.rank == 0 else None, root=0)
    try:
        run(load_scene(scene_path, sets), folder, comm, progress_every=1e9)
        raise SystemExit(f"the run ended before {steps} steps: ask for fewer")
    except _Stop:
        pass
    finally:
        ExplicitSolver.step = step


def compare(a: str, b: str, tol: float) -> float:
    pa, pb = (np.load(f, allow_pickle=True)["parts"] for f in (a, b))
    if len(pa) != len(pb):
        raise SystemExit(f"{a} has {len(pa)} ranks, {b} {len(pb)}: compare digests of the same rank count")
    worst = 0.0
    for rank, (x, y) in enumerate(zip(pa, pb)):
        if set(x) != set(y):
            raise SystemExit(f"rank {rank}: different arrays {sorted(set(x) ^ set(y))}")
        for k in sorted(x):
            u, w = np.asarray(x[k], float), np.asarray(y[k], float)
            d = float(np.max(np.abs(u - w)) / max(np.max(np.abs(u)), 1e-300)) if u.size else 0.0
            worst = max(worst, d)
            if d > tol:
                print(f"rank {rank} {k}: relative difference {d:.3g} > {tol:g}")
    print(f"worst relative difference {worst:.3g} ({'equal' if worst <= tol else 'DIFFERENT'} at {tol:g})")
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?")
    ap.add_argument("out", nargs="?")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--set", dest="sets", action="append", default=[], help="scene override key=value")
    ap.add_argument("--compare", nargs=2, metavar=("A", "B"))
    ap.add_argument("--tol", type=float, default=1e-10)
    args = ap.parse_args()
    if args.compare:
        sys.exit(0 if compare(*args.compare, args.tol) <= args.tol else 1)
    if not (args.scene and args.out):
        ap.error("give SCENE and OUT (or --compare A B)")
    digest(args.scene, args.out, args.steps, args.sets)


if __name__ == "__main__":
    main()
