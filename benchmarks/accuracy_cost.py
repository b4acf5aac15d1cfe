"""What accuracy costs in time: one table per accuracy knob.

    python benchmarks/accuracy_cost.py                 # every knob (≈ 5 min on one core)
    python benchmarks/accuracy_cost.py --knobs time_step_scale remap_order

The test problem is the ch. 3 hopper (Fig. 3-17, 645 cells at the default size) started from
a K0 state, stored 0.3 s and discharged freely for ``--discharge`` s with ALE. The quantities
a silo designer reads off such a run are compared with those of the most accurate setting of
the knob (the reference row, marked *):

* p̄_w: the wall normal pressure at the output stations, averaged over the second half of the
  discharge; error = mean over stations of |p̄ − p̄_ref| / mean p̄_ref;
* W: the mean mass flow rate over the second half; error = |W − W_ref| / W_ref;
* E: the energy balance error of the run itself (the scheme's own bookkeeping).

Wall-clock is the whole run (meshing excluded), serial, median of ``--repeat`` runs. Knobs:
time-step scale, mesh size, smoothing (ALE) frequency, remap order and mass scaling. Mass
scaling changes the physics it speeds up (inertia): its error column says by how much.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "demos" / "scenes" / "hopper_ch3_ale.toml"

# knob -> (scene key, values, reference value); the reference is the most accurate setting
KNOBS = {
    "time_step_scale": ("numerics.time_step_scale", [0.9, 0.8, 0.6, 0.4], 0.2),
    "mesh_size": ("geometry.element_size", [0.12, 0.08, 0.06], 0.04),
    "smoothing_frequency": ("ale.frequency", [50, 20, 10, 5], 1),
    "remap_order": ("ale.remap_order", [1], 2),
    "mass_scaling": ("numerics.mass_scaling", [100.0, 25.0, 4.0], 1.0),
}


def run_case(key: str, value, discharge: float) -> dict:
    from mpi4py import MPI

    from silo_dolfinx.output import read_csv
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    scene = load_scene(SCENE, ['fill.method="k0"', "store.duration=0.3", f"discharge.duration={discharge}",
                               "output.field_interval=1000.0", "output.history_rate=100.0", f"{key}={value}"])
    out = Path(tempfile.mkdtemp(prefix="acc_"))
    t0 = time.perf_counter()
    summary = run(scene, out, MPI.COMM_SELF, progress_every=1e9)
    wall = time.perf_counter() - t0
    h = read_csv(out / "wall_history.csv")
    t_open = next(st["t_start"] for st in summary["stages"] if st["name"] == "discharge")
    late = h["t"] >= t_open + 0.5 * discharge
    stations = sorted(set(h["station"]))
    p = np.array([h["p_n"][late & (h["station"] == k)].mean() for k in stations])
    d = next(st for st in summary["stages"] if st["name"] == "discharge")
    return {"wall": wall, "p": p, "flow": d.get("mean_mass_flow_rate_second_half", float("nan")),
            "energy": summary["energy_balance_error_max"], "steps": summary["steps"], "cells": summary["cells"]}


def table(name: str, discharge: float, repeat: int) -> None:
    key, values, ref = KNOBS[name]
    results = {}
    for v in [ref] + values:
        runs = [run_case(key, v, discharge) for _ in range(repeat)]
        results[v] = runs[0] | {"wall": statistics.median(r["wall"] for r in runs)}
    r0 = results[ref]
    print(f"\n{name} ({key}); reference {ref}*")
    print(f"{'value':>10} {'cells':>6} {'steps':>7} {'wall s':>7} {'speed-up':>8} {'p_w error':>9} "
          f"{'W kg/s':>8} {'W error':>8} {'E error':>8}")
    for v in [ref] + values:
        r = results[v]
        ep = float(np.mean(np.abs(r["p"] - r0["p"])) / np.mean(np.abs(r0["p"])))
        ew = abs(r["flow"] - r0["flow"]) / abs(r0["flow"])
        mark = "*" if v == ref else " "
        print(f"{str(v) + mark:>10} {r['cells']:6d} {r['steps']:7d} {r['wall']:7.2f} {r0['wall'] / r['wall']:7.2f}x "
              f"{100 * ep:8.2f}% {r['flow']:8.2f} {100 * ew:7.2f}% {100 * r['energy']:7.2f}%")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--knobs", nargs="+", default=list(KNOBS), choices=list(KNOBS))
    ap.add_argument("--discharge", type=float, default=2.0)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    print(f"Accuracy against wall-clock, {SCENE.name}: K0 start, {args.discharge:g} s of free discharge, serial")
    for k in args.knobs:
        table(k, args.discharge, args.repeat)


if __name__ == "__main__":
    main()
