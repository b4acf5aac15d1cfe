"""What the outputs cost: each history stream's sample, timed in a ch. 4 discharge, against the
steps it is taken between.

    mpirun -n 2 python benchmarks/output_cost.py           # ≈ 20 s
    python benchmarks/output_cost.py --samples 100

The ch. 4 scene (~7,300 cells, its nine wall stations and five interior points) starts from a
K0 state, stores 0.3 s and discharges for ``--discharge`` s at its own history rate (200 Hz).
Then, before the results are closed (the run's ``_finish`` is wrapped), the discharge goes on
for ``--samples`` history intervals - the scene's steps between two samples, with the loop's
hooks (ALE, the interval means) - and after each, every stream of the scene's output (energy
record, wall history, point history, discharge monitor) and the solver's finite check are
sampled in turn, each after a barrier so that no rank's wait for another is booked to it (in a
run, the first reduction of a sample also absorbs the step's imbalance). A stream's time is
the slowest rank's: rank 0 alone writes the CSV rows. Printed: the median per sample, its
share of the sample, and the whole sample's share of the steps between two (timed in the same
loop).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import silo_dolfinx  # noqa: F401  (imports dolfinx_solver first where it exists)

HERE = Path(__file__).resolve().parents[1]
SCENE = HERE / "demos" / "scenes" / "hopper_ch4.toml"


def main():
    from mpi4py import MPI

    import silo_dolfinx.simulation as sim
    from silo_dolfinx.scene import load_scene

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--discharge", type=float, default=0.5, help="simulated discharge seconds before the timing")
    ap.add_argument("--samples", type=int, default=200, help="samples of each stream")
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    timings: dict[str, float] = {}
    steps: dict[str, float] = {}

    def stream_costs(model, results, stages):
        """Go on stepping from the run's last state (the results still open) and time every
        stream at each of ``--samples`` samples, the scene's steps between two."""
        s = model.solver
        probes = [(type(st).__name__, lambda st=st: st.sample("discharge")) for st in model.outputs.history]
        probes.append(("finite check", s.check_finite))
        times = {name: [] for name, _ in probes}
        per_sample = max(1, round(1.0 / (model.scene.output.history_rate * s.dt)))
        stepping = 0.0
        for _ in range(args.samples):
            comm.Barrier()
            t0 = time.perf_counter()
            for _ in range(per_sample):  # the loop's step with its hooks (ALE, interval means)
                for hook in model.hooks:
                    hook.before_step()
                s.step()
                for hook in model.hooks:
                    hook.after_step()
            stepping += comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
            for name, sample in probes:
                comm.Barrier()
                t0 = time.perf_counter()
                sample()
                times[name].append(comm.allreduce(time.perf_counter() - t0, op=MPI.MAX))
        timings.update({name: statistics.median(ts) for name, ts in times.items()})
        steps.update(per_sample=per_sample, ms=1e3 * stepping / (args.samples * per_sample))
        return finish(model, results, stages)

    finish = sim._finish
    sim._finish = stream_costs
    out = Path(comm.bcast(tempfile.mkdtemp(prefix="output_cost_") if comm.rank == 0 else None, root=0))
    scene = load_scene(SCENE, ['fill.method="k0"', "store.duration=0.3", f"discharge.duration={args.discharge}",
                               "output.field_interval=1000.0"])
    summary = sim.run(scene, out, comm, progress_every=1e9)
    if comm.rank:
        return
    shutil.rmtree(out, ignore_errors=True)
    total = sum(timings.values())
    print(f"Output cost, {SCENE.name} ({summary['cells']} cells), {comm.size} rank(s), history rate "
          f"{scene.output.history_rate:g} Hz; median of {args.samples} samples per stream")
    print(f"{'stream':>18} {'ms/sample':>9} {'share':>6}")
    for name, t in timings.items():
        print(f"{name:>18} {1e3 * t:9.3f} {100 * t / total:5.0f}%")
    print(f"{'whole sample':>18} {1e3 * total:9.3f}")
    ms, n = steps["ms"], steps["per_sample"]
    print(f"the discharge step (its hooks and ALE included) {ms:.3f} ms, {n} steps per sample: a sample costs "
          f"{100 * 1e3 * total / (ms * n):.1f} % of the steps between two")


if __name__ == "__main__":
    main()
