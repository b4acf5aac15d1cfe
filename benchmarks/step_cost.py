"""Cost of one explicit elastic-plastic step, per element and per phase.

    python benchmarks/step_cost.py            # 8k and 32k cells, 1 and 2 ranks, prints a table
    python benchmarks/step_cost.py --against /path/to/other/checkout --rounds 5
                                              # this tree against another, serial, interleaved

The ch. 4 hopper (Drucker-Prager, wall friction 0.267) starts from a geostatic stress state
under full gravity, so the return map, the wall contact and the bulk viscosity all work as in
a real run. After a warm-up (JIT compilation, first-touch), blocks of steps are timed and
the median block is reported: µs per element-step per core (wall-clock × ranks / (cells ×
steps)), the split into the phases of the step, and the parallel efficiency
(T1 / (2 T2)). The 2-rank numbers come from this script relaunched under mpirun.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401

PHASES = ("update", "strain", "constitutive", "dt", "assembly")
SIZES = {"8k": 0.024, "32k": 0.012}  # element sizes of the ch. 4 hopper giving ~8.4k / ~33k cells


def k0_hopper(element_size: float, integration: str = "full"):
    """The ch. 4 hopper at ``element_size`` (structured: the meshes SIZES were chosen for),
    every cell active, in its K0 state under full gravity: the model the step is timed on."""
    from mpi4py import MPI

    from silo_dolfinx.geometry.mesher import mesh_scene
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import SiloModel

    here = Path(__file__).resolve().parents[1]
    scene = load_scene(here / "demos" / "scenes" / "hopper_ch4.toml",
                       [f"geometry.element_size={element_size}", 'fill.method="k0"', 'geometry.mesh="structured"',
                        f'numerics.integration="{integration}"'])
    model = SiloModel(scene, mesh_scene(scene, MPI.COMM_WORLD))
    model.activate(np.arange(model.solver.n_cells_owned, dtype=np.int32), None, 0.0, 0.0, last=True)
    model.set_geostatic_stress(0.4)
    return model


def measure(element_size: float, blocks: int, steps: int, integration: str = "full", floor: bool = True) -> dict:
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    s = k0_hopper(element_size, integration).solver
    for _ in range(steps):  # warm-up
        s.step()
    cells = comm.allreduce(s.n_cells_owned, op=MPI.SUM)
    per_block, phases = [], []
    for _ in range(blocks):
        s.profile(True)
        comm.barrier()
        t0 = time.perf_counter()
        for _ in range(steps):
            s.step()
        comm.barrier()
        per_block.append(time.perf_counter() - t0)
        local = np.array([s.timings[k] for k in PHASES])
        worst = np.empty_like(local)
        comm.Allreduce(local, worst, op=MPI.MAX)
        phases.append(worst)
    k = int(np.argsort(per_block)[len(per_block) // 2])
    plastic = comm.allreduce(int(np.count_nonzero(s.state["eqps"] > 0)), op=MPI.SUM)
    out = {"cells": cells, "ranks": comm.size, "seconds_per_step": per_block[k] / steps,
           "phases": (phases[k] / steps).tolist(), "plastic_points": plastic, "quadrature_points": cells * s.nq,
           "peak_rss_mb": peak_rss_mb()}
    if comm.size == 1 and floor:
        out |= measure_floor(s, blocks, steps)
    return out


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MB; Linux reports kB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure_floor(s, blocks: int, steps: int) -> dict:
    """The hand-written fused step (benchmarks/floor.py) on the solver's mesh and state: checked
    first (its stable Δt equals the solver's to 1 %), then timed like the solver (median block)."""
    sys.path.insert(0, str(Path(__file__).parent))
    import floor

    arrays, law = floor.from_solver(s)
    dt = s.dt
    dt_floor = floor.step(arrays, law, dt)  # also compiles
    if abs(dt_floor - s.dt_crit) > 0.01 * s.dt_crit:
        raise RuntimeError(f"the floor's stable Δt {dt_floor:.4g} differs from the solver's {s.dt_crit:.4g}")
    per_block = []
    for _ in range(blocks):  # each block from the solver's state: the floor's frictionless walls, fixed Δt
        arrays, _ = floor.from_solver(s)  # and no ALE let its mesh drift until a cell collapses (~600 steps)
        t0 = time.perf_counter()
        for _ in range(steps):
            floor.step(arrays, law, dt)
        per_block.append(time.perf_counter() - t0)
    return {"floor_seconds_per_step": float(np.median(per_block)) / steps}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--blocks", type=int, default=5)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--sizes", nargs="+", default=list(SIZES))
    ap.add_argument("--integrations", nargs="+", default=["full", "reduced"], choices=["full", "reduced"])
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--no-floor", action="store_true", help="skip the hand-written floor (--against runs skip it)")
    ap.add_argument("--against", type=Path, help="another checkout of the package: steps/s of both, interleaved")
    ap.add_argument("--rounds", type=int, default=5, help="with --against: alternating measurements of each")
    args = ap.parse_args()
    if args.against:
        return compare(args)
    results = [measure(SIZES[n], args.blocks, args.steps, i, not args.no_floor) | {"case": f"{n} {i}"}
               for n in args.sizes for i in args.integrations]
    from mpi4py import MPI

    if args.worker:
        if MPI.COMM_WORLD.rank == 0:
            print("JSON" + json.dumps(results))
        return
    mpirun = Path(sys.executable).with_name("mpirun")
    cmd = [str(mpirun) if mpirun.exists() else "mpirun", "-n", "2", sys.executable, __file__, "--worker",
           "--blocks", str(args.blocks), "--steps", str(args.steps), "--sizes", *args.sizes,
           "--integrations", *args.integrations]
    out = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy(), check=True).stdout
    results += json.loads(next(line for line in out.splitlines() if line.startswith("JSON"))[4:])

    print(f"Explicit elastic-plastic step, ch. 4 hopper, Q1 (full: 2×2 points, reduced: 1 + hourglass control); "
          f"median of {args.blocks} blocks "
          f"of {args.steps} steps")
    head = f"{'case':>12} {'cells':>7} {'ranks':>5} {'steps/s':>8} {'µs/elem-step/core':>18} " + \
        " ".join(f"{p:>12}" for p in PHASES) + f" {'efficiency':>10}"
    print(head)
    serial = {r["case"]: r for r in results if r["ranks"] == 1}
    for r in results:
        us = r["seconds_per_step"] * r["ranks"] / r["cells"] * 1e6
        split = " ".join(f"{ph * r['ranks'] / r['cells'] * 1e6:12.3f}" for ph in r["phases"])
        eff = serial[r["case"]]["seconds_per_step"] / (r["ranks"] * r["seconds_per_step"])
        print(f"{r['case']:>12} {r['cells']:7d} {r['ranks']:5d} {1 / r['seconds_per_step']:8.0f} {us:18.3f} {split} "
              f"{100 * eff:9.0f}%")
    print("\nThe floor (benchmarks/floor.py: the same step hand-written in one numba kernel, serial):")
    print(f"{'case':>12} {'ours µs':>8} {'floor µs':>9} {'ours/floor':>10} {'peak MB/kcell':>14}")
    for r in results:
        if "floor_seconds_per_step" in r:
            us = r["seconds_per_step"] / r["cells"] * 1e6
            fl = r["floor_seconds_per_step"] / r["cells"] * 1e6
            print(f"{r['case']:>12} {us:8.3f} {fl:9.3f} {us / fl:10.2f} {1000 * r['peak_rss_mb'] / r['cells']:14.1f}")
    print("phases in µs per element-step per core; plastic points at the end: "
          + ", ".join(f"{r['case']}/{r['ranks']}: {r['plastic_points']}/{r['quadrature_points']}" for r in results))


def compare(args) -> None:
    """Serial steps/s of this tree and of ``--against`` (the same script, the other package on
    PYTHONPATH), alternating so that the machine's drift hits both alike; medians and ratio."""
    here = Path(__file__).resolve().parents[1]
    trees = {"this tree": here, "against": args.against.resolve()}
    rates = {k: [] for k in trees}
    for _ in range(args.rounds):
        for name, root in trees.items():
            env = os.environ | {"PYTHONPATH": str(root)}
            cmd = [sys.executable, __file__, "--worker", "--blocks", str(args.blocks), "--steps", str(args.steps),
                   "--sizes", *args.sizes, "--integrations", *args.integrations, "--no-floor"]
            out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True).stdout
            r = json.loads(next(line for line in out.splitlines() if line.startswith("JSON"))[4:])
            rates[name].append([1.0 / c["seconds_per_step"] for c in r])
    print(f"serial steps/s, median of {args.rounds} alternating rounds ({args.blocks} blocks of {args.steps} steps)")
    print(f"{'case':>12} {'this tree':>10} {'against':>10} {'ratio':>7}")
    cases = [f"{n} {i}" for n in args.sizes for i in args.integrations]  # the worker's order
    for i, case in enumerate(cases):
        a, b = (float(np.median([r[i] for r in rates[k]])) for k in trees)
        print(f"{case:>12} {a:10.1f} {b:10.1f} {a / b:7.3f}")
    print(f"against: {args.against}")


if __name__ == "__main__":
    main()
