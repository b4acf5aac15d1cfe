"""Stages of a run and the time loop (thesis ch. 3 and 4.2).

A stage declares what it changes — whether the fill damping acts (``damped``), what it does
when it begins, when it may stop early — and the loop applies that; no stage overwrites a
setting another one relies on.

K0 start (``fill.method = "k0"``)
    every cell active, geostatic stress σ_zz = −(ρ g (H − z) + q), σ_rr = σ_θθ = K0 σ_zz, no
    time stepping.
Layer fill (``layers``; ``ramp`` is one layer)
    layer k activated stress-free at k·T/N with its gravity ramped over ``ramp_fraction`` of
    its interval; inactive layers are not integrated at all.
Store
    closed outlet, full gravity; ends at its duration or once the kinetic energy falls below
    ``kinetic_energy_tol`` × the work of gravity.
Discharge (free or controlled)
    the gate is removed (free) or the outlet driven down (controlled); ALE, if on, starts.
"""

from __future__ import annotations

import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from silo_dolfinx._mpi import reduce_scalar
from silo_dolfinx.checkpoint import Checkpoints
from silo_dolfinx.simulation.effects import smooth_step


@dataclass
class Stage:
    """One stage: its name, how long, whether the fill damping acts during it."""

    name: str
    duration: float
    damped: bool = False
    CHECKPOINT = ()  # what a checkpoint keeps of a stage in progress (silo_dolfinx.checkpoint)

    def segments(self, model):
        """(end time, progress label) of each stretch of time stepping; set-up in between."""
        yield model.solver.t + self.duration, self.name

    def stop(self, model) -> bool:
        """Whether to end the stage early (checked after every step)."""
        return False

    def record(self, model) -> dict:
        return {}


class K0Start(Stage):
    """Every cell active with the geostatic stress of ``fill.k0``; no time stepping."""

    def __init__(self, k0: float):
        super().__init__("fill", 0.0)
        self.k0 = k0

    def segments(self, model):
        s = model.solver
        model.activate(np.arange(s.n_cells_owned, dtype=np.int32), None, 0.0, 0.0, last=True)
        model.set_geostatic_stress(self.k0)
        return iter(())

    def record(self, model) -> dict:
        return {"method": "k0"}


class LayerFill(Stage):
    """N horizontal layers, one activated every T/N, its gravity ramped in (thesis ch. 3.4.1)."""

    def __init__(self, fill):
        super().__init__("fill", fill.duration, damped=True)
        self.method, self.ramp_fraction = fill.method, fill.ramp_fraction

    def segments(self, model):
        s = model.solver
        layers = model.layers()
        n = len(layers)
        t0, T = s.t, self.duration / n
        active = np.zeros(0, np.int32)
        for k, cells in enumerate(layers):
            active = np.union1d(active, cells).astype(np.int32)
            model.activate(active, cells, s.t, self.ramp_fraction * T, last=(k == n - 1))
            model.outputs.maybe(self.name)
            yield t0 + (k + 1) * T, f"fill {k + 1}/{n}"
        self.layers = n

    def record(self, model) -> dict:
        return {"method": self.method, "layers": self.layers}


class Store(Stage):
    """Closed outlet, full gravity, until at rest or the duration is over."""

    CHECKPOINT = ("t_end",)

    def __init__(self, store):
        super().__init__("store", store.duration, damped=True)
        self.tol = store.kinetic_energy_tol
        self.t_end = store.duration  # set when the stage begins

    def segments(self, model):
        self.t_end = model.solver.t + self.duration
        yield self.t_end, self.name

    def stop(self, model) -> bool:
        """At rest: checked once the history sample due by now has been taken."""
        o = model.outputs
        if self.tol <= 0.0 or o.next_history - o.dt_history > model.solver.t:
            return False
        e = model.solver.global_energy()
        return e.kinetic < self.tol * max(e.gravity, 1e-300)

    def record(self, model) -> dict:
        at_rest = model.solver.t < self.t_end - self.duration * 1e-9
        return {"ended_on": "kinetic energy" if at_rest else "duration"}


class Discharge(Stage):
    """The outlet opens (the effects begin: gate removed, drive, ALE) and the silo drains, for
    its duration or until the mesh can no longer follow the draining fill."""

    CHECKPOINT = ("ended_early",)

    def __init__(self, discharge):
        super().__init__("discharge", discharge.duration)
        self.mode, self.min_quality = discharge.mode, discharge.min_mesh_quality
        self.ended_early = ""

    def segments(self, model):
        model.outputs.begin_discharge(model)
        yield model.solver.t + self.duration, self.name

    def stop(self, model) -> bool:
        """The worst cell of the last mesh-quality sample (the same on every rank) below the floor."""
        m = model.outputs.monitor
        if not m.flow or m.min_quality >= self.min_quality:  # no verdict before the first sample
            return False
        self.ended_early = (f"[discharge] ended at t = {model.solver.t:.4g} s, {m.flow[-1][4]:.4g} kg of "
                            f"{m.mass0:.4g} discharged: the worst cell's scaled Jacobian fell to "
                            f"{m.min_quality:.3f}, below min_mesh_quality = {self.min_quality:g} (the fill's top on the "
                            f"axis {m.axis_top_height:.3g} m above the outlet). {self._why(model)} Results up to "
                            "here are complete. (min_mesh_quality = 0 runs on until a cell turns inside out.)")
        ale = model.scene.ale
        if ale.enabled and ale.max_surface_slope == 0.0:
            self.ended_early += (" If that cell is at the free surface (a pit on the axis, a lip at a rough wall), set "
                                 "ale.max_surface_slope to about the solid's friction angle: the surface then slumps "
                                 "as grains would, and the run goes on.")
        n = model.sm.outlet_cells()
        if n < self.OUTLET_CELLS and m.flow[-1][4] < 0.1 * m.mass0:  # stopped early, not a silo drained
            self.ended_early += (f" The outlet is {n} cell(s) across its radius: through so few cells the flow can fall "
                                 "down a pipe one outlet wide to the surface, which no mesh of rows can follow (a "
                                 "flat-bottomed sand silo at 2 cells ended so after 0.9 s; at 8 its flow opened into a "
                                 f"channel and ran on: docs/guide/your-silo.md). Fix: {self._outlet_fix(model, n)}.")
        return True

    #: cells across the outlet radius below which an early end names the outlet's resolution
    OUTLET_CELLS = 8

    def _outlet_fix(self, model, n: int) -> str:
        """The key that puts OUTLET_CELLS cells across the outlet: a structured mesh without a
        floor has as many in every row as across its top (element_size), else the outlet's own
        refinement (outlet_size_factor) - on an unstructured mesh, which keeps it at the outlet."""
        g, ol = model.scene.geometry, model.outline
        if g.mesh == "structured" and not ol.has_floor:
            return (f"geometry.element_size = {ol.r_max / self.OUTLET_CELLS:.3g} m or less (a structured mesh without a "
                    "floor has as many cells across its outlet as across its top)")
        factor = f"geometry.outlet_size_factor = {g.outlet_size_factor * max(n, 1) / self.OUTLET_CELLS:.2g}"
        if g.mesh == "structured":  # with a floor: its outlet column runs the height, refined it is needles
            return (f"geometry.mesh = \"unstructured\" and {factor} (a structured mesh with a floor refines its "
                    "outlet's column over the silo's whole height: needles, which speed a discharge up)")
        return factor

    @staticmethod
    def _why(model) -> str:
        rz = model.rezoner
        if rz is None:
            return "The mesh keeps all its rows and cannot follow the fill further."
        return (f"Meshed again {len(rz.records)} time(s), the fill has become too thin for cells of the element "
                "size to follow it.")

    def record(self, model) -> dict:
        ended = {"ended_on": "mesh quality", "ended_because": self.ended_early} if self.ended_early else \
            {"ended_on": "duration"}
        rezones = {"rezones": model.rezoner.records} if model.rezoner is not None else {}
        return {"mode": self.mode, **ended, **model.outputs.discharge_summary(), **rezones}


def compose(scene) -> list[Stage]:
    """The stages ``scene`` asks for, in order."""
    f = scene.fill
    stages: list[Stage] = [K0Start(f.k0) if f.method == "k0" else LayerFill(f), Store(scene.store)]
    if scene.discharge.mode != "none":
        stages.append(Discharge(scene.discharge))
    return stages


def total_time(scene) -> float:
    """Simulated time of the whole run (s), for the progress ETA."""
    return sum(st.duration for st in compose(scene))


# ---------------------------------------------------------------------------- the loop
def run_stages(model, progress, checkpoints: Checkpoints | None = None) -> list[dict]:
    """Every stage in turn: its effects begin, it steps, its end is recorded. With
    ``checkpoints`` resuming, the stages and segments before the checkpoint only replay their
    set-up (:mod:`silo_dolfinx.checkpoint`)."""
    ck = checkpoints or Checkpoints(model, model.outputs.results, 0.0)
    records = ck.records  # a resumed run's include the stages done before its checkpoint
    for i, stage in enumerate(model.stages):
        s = model.solver
        t0, steps0, wall0 = ck.stage_start(i)
        s.damping = model.damping_alpha if stage.damped else 0.0  # the stage's declaration
        for effect in model.effects.values():
            effect.begin(stage)
        for j, (t_end, label) in enumerate(stage.segments(model)):
            if ck.steps(i, j):
                advance(model, stage, t_end, label, progress, ck)
        if ck.done_before(i):
            continue
        model.outputs.stage_end(stage.name)
        records.append(_stage_record(stage, model, t0, steps0, wall0) | stage.record(model))
    return records


def advance(model, stage: Stage, t_end: float, label: str, progress, checkpoints: Checkpoints | None = None) -> None:
    """The time loop of thesis ch. 3: a Lagrangian step (predict → contact → update →
    internal force → Δt), then the post-step hooks (every N steps: smooth + remap), a rezone
    when the scene asks for one and Δt has fallen, output, and now and then a checkpoint."""
    s = model.solver
    while s.t < t_end * (1 - 1e-12) - 1e-15:
        s.dt = min(s.dt, t_end - s.t)  # land on the stage's end
        for hook in model.hooks:
            hook.before_step()
        s.step()
        for hook in model.hooks:
            hook.after_step()
        if model.rezoner is not None and model.rezoner.due():  # Δt fell behind the draining fill
            model.rezoner.rezone()
        model.outputs.maybe(stage.name)
        _stop_if_asked(model)
        progress(label, s.t, s.steps, s.dt)
        if stage.stop(model):
            break
        if checkpoints is not None:
            checkpoints.maybe()


class RunInterrupted(KeyboardInterrupt):
    """SIGTERM or SIGINT during the time loop, acted on by every rank at the same step."""


_SIGNALS = (signal.SIGTERM, signal.SIGINT)
_asked: list[str] = []  # the signal that asked the loop to stop, once one has


def _ask_to_stop(signum, frame) -> None:
    _asked.append(signal.Signals(signum).name)
    signal.signal(signum, signal.SIG_DFL if signum == signal.SIGTERM else signal.default_int_handler)  # a second: at once


@contextmanager
def interruptible():
    """SIGTERM (a batch system's time limit, ``kill``) and SIGINT (Ctrl-C) only ask the time loop
    to stop: it stops at the next history sample, on every rank at once (a signal acted on where
    it lands would leave the other ranks in a collective for ever), by raising
    :class:`RunInterrupted`. A second signal acts at once. The previous handlers come back after
    the block. In a thread other than the main one nothing is installed."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _asked.clear()
    previous = [signal.signal(sig, _ask_to_stop) for sig in _SIGNALS]
    try:
        yield
    finally:
        for sig, handler in zip(_SIGNALS, previous):
            signal.signal(sig, handler)


def _stop_if_asked(model) -> None:
    """Raise :class:`RunInterrupted` if a signal asked the run to stop - on one rank at once, on
    several at a history sample (all ranks reach it at the same step) when any rank was asked."""
    s = model.solver
    if s.comm.size == 1:
        asked = bool(_asked)
    elif model.outputs.last_sample == s.t:
        asked = s.comm.allreduce(bool(_asked), op=MPI.LOR)
    else:
        return
    if asked:
        raise RunInterrupted(f"stopped by {_asked[0] if _asked else 'a signal to another rank'}")


def _stage_record(stage: Stage, model, t0: float, steps0: int, wall0: float) -> dict:
    s = model.solver
    return {"name": stage.name, "t_start": t0, "t_end": s.t, "steps": s.steps - steps0,
            "wall_clock_s": round(time.time() - wall0, 3), "dt_last": s.dt_prev,
            "density_min": reduce_scalar(s.comm, float(s.rho_cell.min(initial=np.inf)), MPI.MIN),
            "dt_limit": s.limiting_cell()}


__all__ = ["Discharge", "K0Start", "LayerFill", "RunInterrupted", "Stage", "Store", "advance", "compose",
           "interruptible", "run_stages", "smooth_step", "total_time"]
