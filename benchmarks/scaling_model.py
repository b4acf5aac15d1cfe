"""Scaling on paper: the expected parallel efficiency at 8, 64 and 512 ranks for a large mesh,
from what this machine measures at 1 and 2 ranks.

    python benchmarks/scaling_model.py                 # 1M cells, 8/64/512 ranks
    python benchmarks/scaling_model.py --cells 2e5 --ranks 8 32 128

Measured here (the ch. 4 hopper of benchmarks/step_cost.py, the scene's default numerics):

* the serial step at two sizes (~500 and ~8,400 cells): the cost per cell t_c and the fixed
  cost per step t_0 (Python calls, assembly set-up, the Δt reduction: what does not shrink with
  the part size);
* on 2 ranks: the ghost layer (ghost nodes per rank, neighbours), the time of one ghost
  exchange of the velocity (``scatter_forward``: latency + bytes) and of the one-float
  ``Allreduce`` of the stable Δt.

The model, per step on P ranks for N cells (ALE every 10 steps adds its seven ghost exchanges
and two reductions, a tenth per step; history output is not counted):

    T(P) = t_0 + t_c N/P + (2 + 0.7) · n_nb · (α + β · 16 B · g(P)/n_nb) + (1 + 0.2) · α_r · log₂P

with g(P) = 4 k √(N/P) the ghost nodes of a compact 2-D part (four sides of a part of N/P
cells; k = g₂ / √(N₂/2), the ghost nodes per √cells of one side, from the measured 2-rank cut),
n_nb = 6 neighbours (a 2-D partition), β (per byte) from the measured exchange, α (per message)
the larger of half the measured exchange and the network's latency (``--latency``, default
3 µs), α_r the larger of the measured reduction and ``--reduction`` (default 5 µs per stage);
efficiency E = T(1) / (P T(P)).
The assumptions are the model's weak points: partitions as compact as a structured split (the
graph partitioner does about that), no load imbalance (the active layers of a fill are
imbalanced: the discharge is not), and t_0 that stays serial.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from step_cost import k0_hopper  # noqa: E402  (the model the step is timed on, in one place)

SMALL, LARGE = 0.1, 0.024  # element sizes of the ch. 4 hopper: ~500 and ~8,400 cells


def timed(f, n: int, comm) -> float:
    """Median over 5 blocks of n calls of f (s per call), all ranks in step."""
    out = []
    for _ in range(5):
        comm.barrier()
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        comm.barrier()
        out.append((time.perf_counter() - t0) / n)
    return float(np.median(out))


def measure() -> dict:
    from mpi4py import MPI

    from silo_dolfinx._mpi import reduce_scalar

    comm = MPI.COMM_WORLD
    res = {"ranks": comm.size}
    for name, size in (("small", SMALL), ("large", LARGE)):
        s = k0_hopper(size).solver
        for _ in range(100):
            s.step()
        res[name] = {"cells": comm.allreduce(s.n_cells_owned, op=MPI.SUM), "step": timed(s.step, 100, comm)}
        if name == "large":
            imap = s.V.dofmap.index_map
            res["ghost_nodes"] = comm.allreduce(imap.num_ghosts, op=MPI.MAX)
            res["owned_nodes"] = comm.allreduce(imap.size_local, op=MPI.MAX)
            res["neighbours"] = comm.allreduce(len(set(imap.owners)) if imap.num_ghosts else 0, op=MPI.MAX)
            res["exchange"] = timed(s._vvec.scatter_forward, 2000, comm)
            res["reduction"] = timed(lambda: reduce_scalar(comm, 1.0, MPI.MIN), 2000, comm)
    return res


def predict(serial: dict, two: dict, cells: float, ranks: int, latency: float, reduction: float) -> dict:
    """The model's step time and efficiency at ``ranks`` for ``cells`` (docstring)."""
    n1, t1 = serial["small"]["cells"], serial["small"]["step"]
    n2, t2 = serial["large"]["cells"], serial["large"]["step"]
    tc = (t2 - t1) / (n2 - n1)
    t0 = max(t1 - tc * n1, 0.0)
    # the measured 2-rank cut: g2 ghost nodes for a part of n2/2 cells with one cut side
    g2 = two["ghost_nodes"]
    per_side = g2 / math.sqrt(n2 / 2.0)  # ghost nodes per √(cells) of one side
    part = cells / ranks
    ghosts = 4.0 * per_side * math.sqrt(part) if ranks > 1 else 0.0
    nb = min(6, ranks - 1)
    # β from the measured exchange (one neighbour, g2 nodes × 2 components × 8 B), α the larger of
    # what was measured and the network's latency
    alpha = max(two["exchange"] * 0.5, latency)
    beta = max(two["exchange"] - two["exchange"] * 0.5, 0.0) / (16.0 * g2)
    exchanges = 2.0 + 0.7  # velocity forward + force reverse per step, ALE's seven every 10 steps
    comm = exchanges * (nb * alpha + beta * 16.0 * ghosts) if ranks > 1 else 0.0
    red = (1.0 + 0.2) * max(two["reduction"], reduction) * math.log2(ranks) if ranks > 1 else 0.0
    step = t0 + tc * part + comm + red
    serial_step = t0 + tc * cells
    return {"ranks": ranks, "cells_per_rank": part, "ghosts": ghosts, "t0": t0, "compute": tc * part, "comm": comm,
            "reduction": red, "step": step, "efficiency": serial_step / (ranks * step)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cells", type=float, default=1.0e6)
    ap.add_argument("--ranks", type=int, nargs="+", default=[8, 64, 512])
    ap.add_argument("--latency", type=float, default=3e-6, help="network latency per message (s)")
    ap.add_argument("--reduction", type=float, default=5e-6, help="network latency per reduction stage (s)")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        r = measure()
        from mpi4py import MPI

        if MPI.COMM_WORLD.rank == 0:
            print("JSON" + json.dumps(r))
        return
    serial = measure()
    mpirun = Path(sys.executable).with_name("mpirun")
    out = subprocess.run([str(mpirun) if mpirun.exists() else "mpirun", "-n", "2", sys.executable, __file__,
                          "--worker"], capture_output=True, text=True, env=os.environ.copy(), check=True).stdout
    two = json.loads(next(line for line in out.splitlines() if line.startswith("JSON"))[4:])
    tc = (serial["large"]["step"] - serial["small"]["step"]) / (serial["large"]["cells"] - serial["small"]["cells"])
    eff2 = serial["large"]["step"] / (2 * two["large"]["step"])
    print(f"Measured (ch. 4 hopper): serial step {1e3 * serial['small']['step']:.3f} ms at {serial['small']['cells']} "
          f"cells, {1e3 * serial['large']['step']:.3f} ms at {serial['large']['cells']} cells -> t_c "
          f"{1e6 * tc:.3f} µs/cell, t_0 {1e6 * max(serial['small']['step'] - tc * serial['small']['cells'], 0):.0f} "
          f"µs; 2 ranks at {two['large']['cells']} cells: {1e3 * two['large']['step']:.3f} ms "
          f"(efficiency {100 * eff2:.0f} %), "
          f"ghost nodes {two['ghost_nodes']} of {two['owned_nodes']} owned, {two['neighbours']} neighbour(s), "
          f"exchange {1e6 * two['exchange']:.1f} µs, reduction {1e6 * two['reduction']:.1f} µs")
    print(f"\nModel for {args.cells:.3g} cells (network latency {1e6 * args.latency:g} µs/message, "
          f"{1e6 * args.reduction:g} µs/reduction stage):\n")
    print("| ranks | cells/rank | ghost nodes/rank | t_0 µs | compute µs | exchange µs | reduction µs | step ms "
          "| efficiency |")
    print("|---|---|---|---|---|---|---|---|---|")
    for p in args.ranks:
        m = predict(serial, two, args.cells, p, args.latency, args.reduction)
        print(f"| {p} | {m['cells_per_rank']:,.0f} | {m['ghosts']:,.0f} | {1e6 * m['t0']:.0f} "
              f"| {1e6 * m['compute']:.0f} | {1e6 * m['comm']:.0f} | {1e6 * m['reduction']:.0f} | {1e3 * m['step']:.3f} "
              f"| {100 * m['efficiency']:.0f} % |")


if __name__ == "__main__":
    main()
