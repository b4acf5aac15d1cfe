"""A scene, run: mesh → model (effects, stages) → the time loop → the results folder.

:func:`build_model` composes the run from the scene: the silo model with the effects the scene
asks for (:mod:`.effects`) and its stages (:mod:`.stages`); :func:`run` adds the output
streams (:mod:`silo_dolfinx.output.streams`) and runs the stages. The loop itself is
:func:`silo_dolfinx.simulation.stages.advance`; one step is
:meth:`silo_dolfinx.solver.ExplicitSolver.step`. See docs/architecture.md.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from silo_dolfinx import checkpoint
from silo_dolfinx.checkpoint import Checkpoints
from silo_dolfinx.geometry.mesher import mesh_scene
from silo_dolfinx.output import Progress, Results
from silo_dolfinx.output.streams import Outputs
from silo_dolfinx.simulation.effects import ramp_velocity, smooth_step
from silo_dolfinx.simulation.model import SiloModel
from silo_dolfinx.simulation.stages import interruptible, run_stages, total_time
from silo_dolfinx.solver import InstabilityError


def build_model(scene, comm=None, sm=None) -> SiloModel:
    """The scene's silo with its effects and stages (meshing it unless ``sm`` is given)."""
    comm = MPI.COMM_WORLD if comm is None else comm
    return SiloModel(scene, sm if sm is not None else mesh_scene(scene, comm))


def run(scene, out: str | Path, comm=None, *, progress_every: float = 5.0, resume: bool = False) -> dict:
    """Run a scene into the results folder ``out``; returns the summary (also on disk).
    ``resume``: continue the run in ``out`` from its last checkpoint (``scene`` is then the
    folder's scene.toml, and the ranks as many as wrote it; :mod:`silo_dolfinx.checkpoint`).
    Ended by SIGINT or SIGTERM, the run's summary says "interrupted", when and where it was,
    and its last checkpoint (resumable); the exception is re-raised."""
    comm = MPI.COMM_WORLD if comm is None else comm
    saved = checkpoint.load(out, comm) if resume else None  # refused before anything is touched
    results = Results(out, scene, comm, resume=saved)
    model = None
    guard = comm.Dup()  # for the error check below: independent of any collective left hanging on comm
    try:
        sm = mesh_scene(scene, comm)
        _mesh_record(scene, sm, results)
        model = build_model(scene, comm, sm)
        s = model.solver
        results.update(material=model.material.name, stable_dt_initial=s.dt_crit,
                       time_step_scale=s.numerics.time_step_scale, effects=list(model.effects),
                       ale="on in the discharge" if "ale" in model.effects else "off (Lagrangian)")
        model.outputs = Outputs(model, results)
        checkpoints = Checkpoints(model, results, scene.output.checkpoint_interval, saved)
        with interruptible():  # armed after build_model: PETSc's initialisation resets SIGTERM to its default
            stages = run_stages(model, Progress(comm, total_time(scene), every=progress_every), checkpoints)
            _finish(model, results, stages)
            checkpoints.finish()
    except InstabilityError as err:
        _record_reach(results, model)
        results.finish("failed", str(err))
        _all_ranks_or_abort(guard, err)
        raise
    except KeyboardInterrupt as err:  # SIGINT or SIGTERM (stages.RunInterrupted), or Ctrl-C outside the loop
        t = _record_reach(results, model)
        results.finish("interrupted", f"{err or 'stopped by SIGINT'} at t = {t:.6g} s (stage "
                       f"{results.summary.get('stage', '-')}); its last checkpoint resumes it: silo run --resume {out}")
        _all_ranks_or_abort(guard, err)
        raise
    except BaseException as err:
        _record_reach(results, model)
        results.finish("failed", f"{type(err).__name__}: {err}")
        _all_ranks_or_abort(guard, err)
        raise
    finally:
        if model is not None and model.outputs is not None:
            model.outputs.close()
        guard.Free()
    return results.summary


RANK_ERROR_WAIT = 30.0  # s: how long a failed rank waits for the others before it aborts them all


def _all_ranks_or_abort(guard, err: BaseException, wait: float | None = None) -> None:
    """After an error on this rank: return if every rank reaches this point within ``wait`` s (the
    error was collective: the run stops cleanly, its outputs closed); otherwise the error was this
    rank's alone and the others wait in a collective that will never complete - print the error
    and abort every rank, rather than hang silently. (What the streams have flushed stays.)"""
    if guard.size == 1:
        return
    wait = RANK_ERROR_WAIT if wait is None else wait
    req = guard.Ibarrier()
    t0 = time.time()
    while not req.Test():
        if time.time() - t0 > wait:
            sys.stderr.write(f"[rank {guard.rank}] {type(err).__name__}: {err}\n[rank {guard.rank}] the other ranks did "
                             f"not stop within {wait:g} s (the error was this rank's alone): aborting all ranks\n")
            sys.stderr.flush()
            guard.Abort(1)
        time.sleep(0.02)


def _mesh_record(scene, sm, results: Results) -> None:
    from silo_dolfinx.geometry.plot import plot_mesh
    from silo_dolfinx.geometry.quality import quality_report

    q = quality_report(sm.mesh)
    q["outlet_cells"] = sm.outlet_cells()  # the outlet's resolution (docs/guide/your-silo.md)
    plot_mesh(sm, results.path("mesh.png"), title=f"{scene.title}: {q['cells']} cells")
    results.update(cells=q["cells"], mesh_quality=q)


def _finish(model: SiloModel, results: Results, stages: list[dict]) -> None:
    s = model.solver
    e = s.global_energy()
    results.summary["warnings"] += (_dilation_warnings(model.scene, stages) + _rezone_warnings(model.scene, stages)
                                    + _arch_warnings(model.scene, stages)
                                    + [st["ended_because"] for st in stages if "ended_because" in st])
    results.update(stages=stages, steps=s.steps, rejected_steps=s.rejected, simulated_time=s.t, t_reached=s.t,
                   energy={k: getattr(e, k) for k in ("kinetic", "elastic", "plastic", "viscous", "damping",
                                                      "gravity", "external", "contact")},
                   energy_balance_error=e.relative_error(s.energy_scale),
                   energy_balance_error_max=model.outputs.max_abs_balance / max(s.energy_scale, 1e-300),
                   steps_per_second=s.steps / max(time.time() - results.started, 1e-9))
    results.finish("completed")


def _record_reach(results: Results, model: SiloModel | None) -> float:
    """The summary's ``t_reached`` at the end of a run however it ended (between heartbeats it
    lags by up to 10 s of wall-clock); the time reached."""
    t = model.solver.t if model is not None else results.summary.get("t_reached", 0.0)
    results.summary["t_reached"] = t
    return t


DILATION_WARNING = 0.5  # a cell below this fraction of the solid's density is no granular solid
ARCH_WARNING = 0.1  # a free discharge whose last quarter flows below this fraction of its fastest has arched
REZONE_WARNING = (10, 10)  # warn after this many re-meshes of a stage, fewer than this many remaps apart (median)


def _dilation_warnings(scene, stages: list[dict]) -> list[str]:
    """A warning for each stage that ended with a cell dilated below half the solid's density,
    naming the cause: without a critical state (max_dilation = 0, ψ > 0) the cone's dilation
    never stops; with one, what remains is tensile separation at the cone's apex (a solid
    stretched at near-zero pressure: the free-fall zone above an outlet, a free-surface
    crater), which a perfectly plastic solid without a cap never recompacts."""
    m = scene.material
    rho0 = m.density
    out = []
    for st in stages:
        if st["density_min"] < DILATION_WARNING * rho0:
            head = (f"[material] by the end of the {st['name']} stage a cell had dilated to {st['density_min']:.4g} "
                    f"kg/m³ ({100 * st['density_min'] / rho0:.0f} % of density = {rho0:g}): ")
            if m.get("dilation_angle", 0.0) > 0.0 and m.get("max_dilation", 0.0) == 0.0:
                out.append(head + f"with dilation_angle = {m.dilation_angle:g} and max_dilation = 0 the solid dilates "
                           "for as long as it shears. Set material.max_dilation > 0 (the default 0.05: a critical "
                           "state) or dilation_angle = 0 if the flowing solid should keep its density.")
            else:
                fix = ("" if m.get("recompaction", False) else
                       " Set material.recompaction = true to close the opened volume again (with "
                       "ale.max_surface_slope ≈ φ if the flow channel then reaches the surface): a flat-bottomed "
                       "silo's flow otherwise decays (docs/guide/your-silo.md, section 5).")
                out.append(head + "the plastic dilation is bounded (max_dilation or ψ = 0), so this is tensile "
                           "separation at the yield surface's apex, where the solid is stretched at near-zero "
                           "pressure (the free-fall zone above an outlet, a free-surface crater); a yield surface "
                           "without a cap does not recompact it. Its stable Δt falls with its density." + fix)
    return out


def _arch_warnings(scene, stages: list[dict]) -> list[str]:
    """A warning for a free discharge whose flow stopped with the silo still full: its last
    quarter let out under ARCH_WARNING of its fastest quarter's rate while more than a tenth of
    the fill was inside. Nothing in the run fails then - Δt holds, the balances hold - so without
    this a stalled discharge reads as a slow one (the ch. 3 hopper at h 0.08 m from K0 on the
    compression-matched cone: 5.5 kg in 10 s; benchmarks/accuracy_cost.py)."""
    out = []
    if scene.discharge.mode != "free":
        return out
    for st in stages:
        q = st.get("mass_flow_quarters")
        if not q or len(q) < 4 or max(q) <= 0.0:
            continue
        inside = 1.0 - sum(q) * 0.25 * (st["t_end"] - st["t_start"]) / st["mass_at_opening"]
        if q[-1] < ARCH_WARNING * max(q) and inside > 0.1:
            out.append(f"[discharge] the flow stopped: {q[-1]:.3g} kg/s left over the last quarter of the "
                       f"{st['name']} stage against {max(q):.3g} kg/s in its fastest, with {100 * inside:.0f} % of the "
                       "fill still inside - an arch over the outlet. On the Drucker-Prager cone matched in compression "
                       "(material.cone, the default) a cohesionless arch can stand: the cone carries equal-biaxial "
                       "compression at the arch's free underside (docs/material.md); it forms most readily over an "
                       "outlet one or two cells wide and from a K0 start. Fix: a finer outlet (geometry.element_size, "
                       "geometry.outlet_size_factor), material.model = \"mohr_coulomb\" or material.cone = "
                       "\"extension\", or a fill in layers (fill.method).")
    return out


def _rezone_warnings(scene, stages: list[dict]) -> list[str]:
    """A warning for a discharge that was meshed again over and over: at least REZONE_WARNING[0]
    times, fewer than REZONE_WARNING[1] remaps apart (median). The mesh then loses what the
    re-mesh restored as fast as it is restored - usually because it follows the material
    (ale.predictor = "current": the ch. 4 hopper at h 0.04 m re-meshed 179 times in 2 s, every
    ~24 steps, 14× slower than with the default predictor; docs/performance.md)."""
    out = []
    count, apart = REZONE_WARNING
    for st in stages:
        steps = [r["step"] for r in st.get("rezones", [])]
        if len(steps) < count:
            continue
        every = float(np.median(np.diff(steps)))
        if every < apart * scene.ale.frequency:
            seconds = sum(r["seconds"] for r in st["rezones"])
            out.append(f"[ale] the {st['name']} stage was meshed again {len(steps)} times, every {every:.0f} steps "
                       f"(median; {seconds:.1f} s of wall-clock in all): the mesh falls back below "
                       "ale.rezone_min_quality (or its Δt below rezone_dt_fall) about as fast as it is re-meshed. "
                       f"With ale.predictor = \"{scene.ale.predictor}\"" + (
                           " the mesh follows the material: set ale.predictor = \"previous\" (the default)."
                           if scene.ale.predictor == "current" else
                           ": lower ale.rezone_min_quality, or remap more often (ale.frequency smaller)."))
    return out


__all__ = ["InstabilityError", "SiloModel", "build_model", "mesh_scene", "ramp_velocity", "run", "smooth_step",
           "total_time"]
