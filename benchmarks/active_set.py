"""What an active-set remap would have to touch: a what-if, not a feature of the library.

    mpirun -n 2 python benchmarks/active_set.py                # ε 0, 0.01, 0.03; ≈ 1.5 min
    mpirun -n 2 python benchmarks/active_set.py --eps 0.02 --discharge 5

The remap sweeps every edge and limits every cell, however little the smoothing moved them. For
each ε this script runs the ch. 4 scene (K0 start, 0.3 s of storage, ``--discharge`` s) with
the smoothing wrapped (``Smoother.smooth`` patched here, nowhere else): an interior node whose
smoothed target is within ε h of where the material took it stays there (h: the scene's element
size); the next smoothing starts from the smoothed mesh (``--anchor smoothed``: a node's lag is
measured against where the smoothing would have it, and stays under ε h) or from where the
nodes were left (``--anchor material``: lags accumulate). At every remap it counts the edges
whose swept volume is more than round-off (10⁻¹² of the median cell volume: an edge whose two
nodes both stay sweeps a degenerate quadrilateral, whose moments are round-off, not zero), the
owned cells such edges touch, and those with their edge neighbours (the gradients and bounds
read them) - what a remap over active lists would update; the others' totals cannot change.
Printed per ε: the share of interior nodes left where they were, of edges swept, of cells
touched (over the run and over its last third), and the discharge's flow, outlet velocity,
energy error and largest aspect ratio at the end, which say what the lagging mesh did to the
physics. Results: docs/performance.md.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "demos" / "scenes" / "hopper_ch4.toml"


def one_run(eps: float, discharge: float, comm, anchor: str) -> dict:
    import silo_dolfinx.simulation as sim
    from silo_dolfinx.ale.remap import Remapper
    from silo_dolfinx.ale.smoothing import Smoother
    from silo_dolfinx.scene import load_scene

    scene = load_scene(SCENE, ['fill.method="k0"', "store.duration=0.3", f"discharge.duration={discharge}",
                               "output.field_interval=1000.0"])
    h = scene.geometry.element_size
    rec = {"left": [], "edges": [], "cells": [], "cells_nb": []}
    smooth, remap = Smoother.smooth, Remapper.remap

    def lazy_smooth(self, xL):
        xs = smooth(self, xL)
        if eps > 0.0:
            xL2 = np.ascontiguousarray(xL[:, :2])
            i = self.interior  # owned interior nodes; the ghosts follow their owners
            left = i[((xs[i] - xL2[i]) ** 2).sum(axis=1) < (eps * h) ** 2]
            rec["left"].append(comm.allreduce(left.size, op=sum_op) / max(comm.allreduce(i.size, op=sum_op), 1))
            xs = xs.copy()
            xs[left] = xL2[left]
            self._sync(xs)
            if anchor == "material":  # the next smoothing starts from where the nodes were left
                np.copyto(self.x_prev, xs)
            # "smoothed": it starts from the smoothed mesh (left untouched by smooth() above), so a
            # node's lag is measured against where the smoothing would have it and cannot drift
        return xs

    def counting_remap(self, x0, x1, *args, **kwargs):
        rep = remap(self, x0, x1, *args, **kwargs)
        no = self.n_owned
        swept = np.abs(self._swept[:, 0]) > 1e-12 * np.median(self._vol0[:no])
        touched = np.zeros(self.n_all, bool)
        for side in (self.fleft[swept], self.fright[swept]):
            touched[side[side >= 0]] = True
        t = touched[:no]
        inner = (self.nbr >= 0) & (self.nbr < no)
        with_nb = t | np.any(t[np.where(inner, self.nbr, 0)] & inner, axis=1)
        fl, fr = self.fleft, self.fright  # each edge counted once: on the rank owning its left cell
        mine = ((fl >= 0) & (fl < no)) | ((fl < 0) & (fr >= 0) & (fr < no))
        for key, num, den in (("edges", np.sum(swept & mine), np.sum(mine)), ("cells", t.sum(), no),
                              ("cells_nb", with_nb.sum(), no)):
            rec[key].append(comm.allreduce(int(num), op=sum_op) / comm.allreduce(int(den), op=sum_op))
        return rep

    from mpi4py import MPI

    sum_op = MPI.SUM
    Smoother.smooth, Remapper.remap = lazy_smooth, counting_remap
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="active_set_") if comm.rank == 0 else None, root=0))
    try:
        summary = sim.run(scene, out, comm, progress_every=1e9)
    finally:
        Smoother.smooth, Remapper.remap = smooth, remap
        if comm.rank == 0:
            shutil.rmtree(out, ignore_errors=True)
    d = next(st for st in summary["stages"] if st["name"] == "discharge")
    return {"rec": rec, "flow": d["mean_mass_flow_rate_second_half"], "v": d["mean_outlet_velocity_second_half"],
            "energy": summary["energy_balance_error_max"], "aspect": d["final_max_aspect_ratio"]}


def main():
    from mpi4py import MPI

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--eps", type=float, nargs="+", default=[0.0, 0.01, 0.03])
    ap.add_argument("--discharge", type=float, default=3.0, help="simulated discharge seconds per run")
    ap.add_argument("--anchor", choices=("smoothed", "material"), default="smoothed",
                    help="what the next smoothing starts from: the smoothed mesh (a bounded lag) or the nodes "
                         "where they were left (their lags accumulate)")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    runs = {eps: one_run(eps, args.discharge, comm, args.anchor) for eps in args.eps}
    if comm.rank:
        return

    def share(v):
        v = np.asarray(v, float)
        return f"{100 * v.mean():3.0f} / {100 * v[2 * v.size // 3:].mean():3.0f} %" if v.size else "    - / -  "

    print(f"What an active-set remap would touch, {SCENE.name}, {comm.size} rank(s), {args.discharge:g} s of "
          f"discharge, the next smoothing from the {args.anchor} places (every remap; shares over the run / its "
          "last third)")
    print(f"{'ε':>5} {'interior left':>13} {'edges swept':>12} {'cells':>12} {'+ neighbours':>12} {'flow kg/s':>9} "
          f"{'outlet m/s':>10} {'E err':>6} {'aspect':>6}")
    for eps, r in runs.items():
        rec = r["rec"]
        print(f"{eps:5.3g} {share(rec['left']):>13} {share(rec['edges']):>12} {share(rec['cells']):>12} "
              f"{share(rec['cells_nb']):>12} {r['flow']:9.3f} {r['v']:10.4f} {100 * r['energy']:5.2f}% "
              f"{r['aspect']:6.2f}")


if __name__ == "__main__":
    main()
