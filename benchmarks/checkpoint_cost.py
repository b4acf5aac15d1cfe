"""What checkpoints cost: the time to write one, its size, and the time a resumed run takes to be
back where it was (meshing, replaying the set-up, restoring), against the cost of a step.

    python benchmarks/checkpoint_cost.py                       # serial (≈ 2 min)
    mpirun -n 2 python benchmarks/checkpoint_cost.py

Each scene starts from K0, stores for 0.01 s and discharges for ``--discharge`` s with a
checkpoint at every history sample (``output.checkpoint_interval`` ≈ 0); the run is stopped after
its last checkpoint and resumed. Medians over the checkpoints of the run. The last column is
the share of wall-clock that checkpoints take at the default interval (300 s): one write per
300 s.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)

HERE = Path(__file__).resolve().parents[1]
SCENES = HERE / "demos" / "scenes"
CASES = {  # name: (scene, overrides)
    "ch. 3 hopper": ("hopper_ch3_ale", []),
    "ch. 4 hopper h 0.03": ("hopper_ch4", ["geometry.element_size=0.03"]),
    "ch. 6 flat bottom (thesis mesh)": ("flat_bottom_ch6", []),
}


class Stop(Exception):
    pass


def measure(scene: str, sets: list[str], discharge: float, comm) -> dict:
    from mpi4py import MPI

    from silo_dolfinx.checkpoint import Checkpoints
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    sc = load_scene(SCENES / f"{scene}.toml", ['fill.method="k0"', "store.duration=0.01",
                                                f"discharge.duration={discharge}", "output.field_interval=0.0",
                                                "output.history_rate=100.0", "output.checkpoint_interval=1e-9", *sets])
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="ck_") if comm.rank == 0 else None, root=0))
    writes, at, marks = [], [], {}  # write times; (clock, steps) at each write
    write, steps = Checkpoints.write, Checkpoints.steps

    def timed_write(self):
        t0 = time.perf_counter()
        write(self)
        writes.append(time.perf_counter() - t0)
        at.append((t0, self.model.solver.steps))
        if self.model.solver.t >= 0.01 + 0.8 * discharge:
            raise Stop()

    def timed_steps(self, i, j):
        resuming = self.resume is not None
        go = steps(self, i, j)
        if resuming and go:
            marks["back"] = time.perf_counter()
        return go

    Checkpoints.write, Checkpoints.steps = timed_write, timed_steps
    try:
        run(sc, out, comm, progress_every=1e9)
    except Stop:
        pass
    size = (out / "checkpoint" / f"state0.rank{comm.rank}.pkl").stat().st_size
    Checkpoints.write = write
    t1 = time.perf_counter()
    summary = run(load_scene(out / "scene.toml"), out, comm, progress_every=1e9, resume=True)
    back = marks["back"] - t1
    Checkpoints.steps = steps
    w = comm.allreduce(statistics.median(writes), op=MPI.MAX)
    (c0, n0), (c1, n1) = at[0], at[-1]
    step = comm.allreduce((c1 - c0 - sum(writes[:-1])) / (n1 - n0), op=MPI.MAX)  # stepping between the checkpoints
    return {"cells": summary["cells"], "step_ms": 1e3 * step, "write_ms": 1e3 * w,
            "size_mb": comm.allreduce(size, op=MPI.MAX) / 2**20, "resume_s": back,
            "share": w / 300.0}


def main() -> None:
    from mpi4py import MPI

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--discharge", type=float, default=0.05, help="simulated discharge (s)")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    rows = [(name, measure(scene, sets, args.discharge, comm)) for name, (scene, sets) in CASES.items()]
    if comm.rank == 0:
        print(f"\ncheckpoints on {comm.size} rank(s): medians over the checkpoints of {args.discharge:g} s of discharge\n")
        print("| scene | cells | step (ms) | checkpoint write (ms) | file per rank (MB) | resume: back where it was (s) "
              "| share of wall-clock at 300 s |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for name, r in rows:
            print(f"| {name} | {r['cells']} | {r['step_ms']:.2f} | {r['write_ms']:.1f} | {r['size_mb']:.2f} | "
                  f"{r['resume_s']:.1f} | {100 * r['share']:.4f} % |")


if __name__ == "__main__":
    main()
