"""What the critical-state limit does to a discharge: one table over material.max_dilation.

    mpirun -n 2 python benchmarks/critical_state.py                  # 0, 0.02, 0.05, 0.10 (≈ 4 min)
    mpirun -n 2 python benchmarks/critical_state.py --values 0.05 --discharge 10

The ch. 4 hopper (default reading: φ 30° → β 50.19°, ψ 10° → ψ_DP 20.24°) on a 0.03 m mesh,
started from a K0 state and discharged freely. For each limit ε_c on the plastic volumetric
strain (0 = dilation never stops, the thesis' Drucker–Prager):

* v: mean outlet velocity over 1-2 s after opening and over the last 2 s;
* W: the mass actually leaving (discharged mass over the window / its length), same windows,
  and the thesis' nominal ρ0·A·v over the last 2 s, both against Beverloo (32.5 kg/s);
* ρ_min: the lowest cell density at the end; Δt at opening and at the end; wall-clock.

Reading: with ε_c = 0 the outlet material keeps loosening, the real mass flow decays and Δt
falls with the density; a critical state holds both.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

import silo_dolfinx  # noqa: F401

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "demos" / "scenes" / "hopper_ch4.toml"


def run_case(max_dilation: float, discharge: float, size: float, comm) -> dict:
    from silo_dolfinx import theory
    from silo_dolfinx.output import read_csv
    from silo_dolfinx.scene import load_scene
    from silo_dolfinx.simulation import run

    sc = load_scene(SCENE, ['fill.method="k0"', "store.duration=0.0", f"discharge.duration={discharge}",
                            f"geometry.element_size={size}", "ale.tracer_rows=0", "output.history_rate=50.0",
                            "output.field_interval=1000.0", f"material.max_dilation={max_dilation}"])
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="crit_") if comm.rank == 0 else None, root=0))
    t0 = time.perf_counter()
    summary = run(sc, out, comm, progress_every=1e9)
    wall = time.perf_counter() - t0
    comm.barrier()
    o = read_csv(out / "outlet.csv")
    t = o["t"] - o["t"][0]

    def window(a, b):
        sel = (t >= a) & (t <= b)
        i, j = np.argmax(sel), len(sel) - 1 - np.argmax(sel[::-1])
        return (o["mean_outlet_velocity"][sel].mean(),
                (o["discharged_mass"][j] - o["discharged_mass"][i]) / (t[j] - t[i]),
                o["nominal_mass_flow_rate"][sel].mean())

    g = sc.geometry
    dts = o["dt"]
    return {"max_dilation": max_dilation, "early": window(1.0, 2.0), "late": window(discharge - 2.0, discharge),
            "rho_min": summary["stages"][-1]["density_min"], "dt0": float(dts[0]), "dt1": float(dts[-1]), "wall": wall,
            "energy": summary["energy_balance_error_max"], "mass": summary["stages"][-1]["mass_balance_error_max"],
            "beverloo": theory.beverloo(sc.material.density, 2 * g.outlet_radius)}


def main() -> None:
    from mpi4py import MPI

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--values", type=float, nargs="+", default=[0.0, 0.02, 0.05, 0.10])
    ap.add_argument("--discharge", type=float, default=6.0, help="seconds of free discharge (default 6)")
    ap.add_argument("--size", type=float, default=0.03, help="element size (m, default 0.03)")
    ap.add_argument("--json", help="also write the rows here")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    rows = [run_case(v, args.discharge, args.size, comm) for v in args.values]
    if comm.rank:
        return
    wb = rows[0]["beverloo"]
    print(f"\nch. 4 hopper, {args.size} m mesh, K0 start, {args.discharge:g} s free discharge, {comm.size} rank(s); "
          f"Beverloo {wb:.1f} kg/s")
    print("| max_dilation | v 1-2 s | v last 2 s | W 1-2 s | W last 2 s (vs Beverloo) | ρ0·A·v last 2 s "
          "| ρ_min kg/m³ | Δt open → end (ms) | energy | wall-clock |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        (v0, w0, _), (v1, w1, n1) = r["early"], r["late"]
        print(f"| {r['max_dilation']:g}{' (unbounded)' if r['max_dilation'] == 0 else ''} | {v0:.3f} | {v1:.3f} "
              f"| {w0:.1f} | {w1:.1f} ({100 * (w1 / wb - 1):+.0f} %) | {n1:.1f} | {r['rho_min']:.0f} "
              f"| {1e3 * r['dt0']:.3f} → {1e3 * r['dt1']:.3f} | {100 * r['energy']:.2f} % | {r['wall']:.0f} s |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1, default=float))


if __name__ == "__main__":
    main()
