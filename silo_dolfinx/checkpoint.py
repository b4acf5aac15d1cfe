"""Checkpoints: a running model's state on disk, so that a killed run resumes where it was.

Written into ``checkpoint/`` of the results folder, at a history sample, once
``output.checkpoint_interval`` s of wall-clock have passed since the last one (rank 0's clock,
broadcast: one collective per history sample). A checkpoint holds, on every rank, every number
the next step reads - what each stateful object declares in its ``CHECKPOINT`` tuple: mesh
coordinates; the solver's clocks, nodal vectors, both time levels of the quadrature data, the
energy ledger and loads; the contact sets; ALE's counters, smoother and tracers; the output
streams' schedules and monitors; the stage in progress - and, on rank 0, ``checkpoint.json``:
where the run was (stage, segment, t, steps), the records of the stages already done and the
byte length of every CSV file then. The per-rank files are written first and the JSON last
(each atomically), alternating between two slots: a run killed while writing one still has
the other.

Resuming (``silo run --resume FOLDER``, :func:`silo_dolfinx.simulation.run` with
``resume=True``; same number of ranks) meshes the scene again (the same partition: the mesh
signature is checked), then **replays the set-up** of every stage up to the one in progress
without stepping - layer activations, stage begins (gate removed, outlet drive, ALE built),
the discharge monitor - each stage from the state it began with (saved at its start), so that
whatever a set-up reads from the state (ALE's reference mesh, the monitor's initial mass) is
what the original run read; then the checkpoint is restored over it and the loop goes on.
Each CSV is cut back to its length at the checkpoint and appended to, VTX fields go on in new
files (``fields/nodes_resumed1.bp``, ...), snapshots keep their numbering: nothing written
before the checkpoint is lost, and the run ends as an uninterrupted one would, to round-off
(tests/test_checkpoint.py: equal to the last digit).
"""

from __future__ import annotations

import json
import os
import pickle
import shutil
import time
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np

FOLDER = "checkpoint"
FORMAT = 1


class CheckpointError(RuntimeError):
    """A run cannot be resumed (the message says why and what to do)."""


# ---------------------------------------------------------------------------- the state protocol
class _Fields(dict):
    """A dataclass's fields, by name (restored into the existing instance, arrays in place)."""


def capture(obj) -> dict:
    """What ``obj`` declares (its ``CHECKPOINT`` names, or its own ``checkpoint_state()``)."""
    if hasattr(obj, "checkpoint_state"):
        return obj.checkpoint_state()
    return {name: _value(getattr(obj, name)) for name in obj.CHECKPOINT}


def _value(v):
    if is_dataclass(v) and not isinstance(v, type):
        return _Fields({f.name: _value(getattr(v, f.name)) for f in fields(v)})
    if isinstance(v, dict):
        return {k: _value(x) for k, x in v.items()}
    return v


def restore(obj, saved: dict) -> None:
    """Put ``saved`` (from :func:`capture`) back into ``obj``: arrays of the same shape are
    written in place (views that compiled forms and kernels hold stay valid), everything else
    is assigned."""
    if hasattr(obj, "restore_state"):
        obj.restore_state(saved)
        return
    for name, value in saved.items():
        _assign(obj, name, value)


def _assign(obj, name: str, value) -> None:
    cur = getattr(obj, name, None)
    if isinstance(value, _Fields) and is_dataclass(cur):
        for k, x in value.items():
            _assign(cur, k, x)
    elif isinstance(value, dict) and isinstance(cur, dict):
        for k, x in value.items():
            if _same_array(cur.get(k), x):
                cur[k][...] = x
            else:
                cur[k] = x
    elif _same_array(cur, value):
        cur[...] = value
    else:
        setattr(obj, name, value)


def _same_array(a, b) -> bool:
    return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.shape == b.shape and a.dtype == b.dtype


class _Coordinates:
    """The mesh's node coordinates (dolfinx's own array, moved in place)."""

    CHECKPOINT = ("x",)

    def __init__(self, mesh):
        self.x = mesh.geometry.x


def parts(model) -> dict:
    """Every stateful object of a running model, by a name that a replayed set-up reproduces."""
    s = model.solver
    out = {"coordinates": _Coordinates(model.sm.mesh), "solver": s}
    out.update({f"contact{k}": c for k, c in enumerate(s.contacts)})
    if model.ale is not None:
        out.update(ale=model.ale, smoother=model.ale.smoother)
        if model.ale.tracers is not None:
            out["tracers"] = model.ale.tracers
    if model.rezoner is not None:
        out["rezoner"] = model.rezoner
    o = model.outputs
    out["outputs"] = o
    out.update({f"history{k}": h for k, h in enumerate(o.history)})
    if o.fields is not None:
        out["fields"] = o.fields
    out.update({f"stage{k}": st for k, st in enumerate(model.stages)})
    return out


def signature(model) -> list:
    """(nodes, cells, Σx) of this rank's mesh as meshed: a resumed run must mesh the same."""
    s = model.solver
    return [int(s.x0.shape[0]), int(s.n_cells_owned), float(np.round(s.x0.sum(), 9))]


# ---------------------------------------------------------------------------- writing and resuming
class Checkpoints:
    """A run's checkpoints: written as it goes and, when it resumes, restored (see module doc).

    The loop (:func:`silo_dolfinx.simulation.stages.run_stages`) tells it where it is:
    :meth:`stage_start` before a stage's begin, :meth:`steps` before each segment of it (False
    while a resumed run replays the set-up of segments done before its checkpoint), and
    :meth:`maybe` after every step."""

    def __init__(self, model, results, interval: float, resume: dict | None = None):
        self.model, self.results, self.comm = model, results, model.sm.comm
        self.interval = interval
        self.folder = results.path(FOLDER)
        self.resume = resume  # checkpoint.json of the checkpoint being resumed, until restored
        self.resume_stage = resume["stage"] if resume else -1
        self.records: list[dict] = list(resume["records"]) if resume else []  # stages done (run_stages appends)
        self.slot = resume["slot"] if resume else 1
        self.position = (0, 0)
        self.clock = (0.0, 0, time.time())  # the stage in progress began at (t, steps, wall-clock)
        self.written = 0
        self._last = time.time()
        if resume is not None and resume["mesh"] != self.comm.allgather(signature(model)):
            raise CheckpointError(f"{self.folder}: the scene meshes differently now than when the checkpoint was "
                                  "written (another gmsh version, or an edited mesh file): it cannot be resumed. "
                                  "Start the run again with silo run.")
        if interval > 0.0 and self.comm.rank == 0:
            self.folder.mkdir(parents=True, exist_ok=True)
        self.comm.barrier()

    def done_before(self, i: int) -> bool:
        """Stage i ended before the checkpoint being resumed (its record is in the checkpoint)."""
        return i < self.resume_stage

    def stage_start(self, i: int) -> tuple[float, int, float]:
        """Before stage i begins: its start state saved (resuming, up to the checkpoint's
        stage: restored, the outputs muted while the set-up replays). Returns the stage's
        (t0, steps0, wall-clock at its start)."""
        s = self.model.solver
        if i <= self.resume_stage and self.resume is not None:
            self._load(self._stage_file(i))
            self.model.outputs.muted = True
        elif self.interval > 0.0:
            self._dump_or_stop(self._stage_file(i))
        if i == self.resume_stage:
            r = self.resume
            self.clock = (r["stage_t0"], r["stage_steps0"], time.time() - r["stage_wall_s"])
        else:
            self.clock = (s.t, s.steps, time.time())
        return self.clock

    def steps(self, i: int, j: int) -> bool:
        """Whether segment j of stage i is stepped: always, except in a resumed run before the
        checkpoint's segment; at that one, the checkpoint is restored first."""
        self.position = (i, j)
        if self.resume is None:
            return True
        if (i, j) < (self.resume["stage"], self.resume["segment"]):
            return False
        self._load(self.folder / f"state{self.resume['slot']}.rank{self.comm.rank}.pkl")
        self.model.outputs.muted = False
        self.resume = None
        return True

    def maybe(self) -> None:
        """After a step: a checkpoint, if a history sample was just taken and ``interval`` s of
        wall-clock have passed since the last."""
        if self.interval <= 0.0 or self.model.outputs.last_sample != self.model.solver.t:
            return
        rezoner = self.model.rezoner
        if rezoner is not None and rezoner.records:  # the mesh is no longer the scene's: a resume could not rebuild it
            self.interval = 0.0
            self.results.summary["warnings"].append(
                f"[output] checkpoints stopped at the first rezone (t = {rezoner.records[0]['t']:.6g} s): the mesh is no "
                "longer the scene's. The last checkpoint before it resumes the run, which rezones again where it did.")
            return
        due = time.time() - self._last >= self.interval
        if self.comm.size > 1:
            due = self.comm.bcast(due, root=0)
        if due:
            self.write()

    def write(self) -> None:
        """Every rank's state into the free slot, then checkpoint.json naming it (collective)."""
        s, results = self.model.solver, self.results
        slot = 1 - self.slot
        if not self._dump_or_stop(self.folder / f"state{slot}.rank{self.comm.rank}.pkl"):
            return
        mesh = self.comm.gather(signature(self.model), root=0)  # (the collective also orders the JSON last)
        self.slot = slot
        self.written += 1
        now = time.time()
        (i, j), (t0, steps0, wall0) = self.position, self.clock
        if self.comm.rank == 0:
            meta = {"format": FORMAT, "ranks": self.comm.size, "slot": slot, "stage": i, "segment": j, "t": s.t,
                    "steps": s.steps, "stage_t0": t0, "stage_steps0": steps0, "stage_wall_s": now - wall0,
                    "wall_clock_s": now - results.started, "records": self.records,
                    "csv_sizes": results.csv_sizes(), "mesh": mesh, "written": time.strftime("%Y-%m-%dT%H:%M:%S")}
            _write_json(self.folder / "checkpoint.json", meta)
            results.update(checkpoint={"t": s.t, "steps": s.steps, "written": meta["written"]})
        self._last = time.time()

    def finish(self) -> None:
        """The run completed: its checkpoints are of no more use (collective)."""
        self.comm.barrier()
        if self.comm.rank == 0 and self.folder.is_dir():
            shutil.rmtree(self.folder)

    # ------------------------------------------------------------------ files
    def _stage_file(self, i: int) -> Path:
        return self.folder / f"stage{i}.rank{self.comm.rank}.pkl"

    def _dump_or_stop(self, path: Path) -> bool:
        """Write this rank's state to ``path``; if any rank cannot (disk full, a load amplitude
        that is a closure), checkpoints stop for the rest of the run with a warning in
        summary.json - the run itself goes on (collective)."""
        try:
            self._dump(path)
            error = ""
        except (OSError, pickle.PicklingError, AttributeError, TypeError) as err:
            error = f"rank {self.comm.rank}: {type(err).__name__}: {err}"
        errors = [e for e in self.comm.allgather(error) if e]
        if not errors:
            return True
        self.interval = 0.0
        self.results.summary["warnings"].append(
            f"[output] checkpoints stopped at t = {self.model.solver.t:.6g} s, the run goes on without them: could not "
            f"write {path.name} ({errors[0]}). The last complete checkpoint, if any, can still be resumed.")
        self.results.write_summary()
        return False

    def _dump(self, path: Path) -> None:
        state = {name: capture(obj) for name, obj in parts(self.model).items()}
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as f:
            pickle.dump(state, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)

    def _load(self, path: Path) -> None:
        with open(path, "rb") as f:
            state = pickle.load(f)  # noqa: S301 - our own file, in the user's results folder
        have = parts(self.model)
        missing = sorted(set(state) - set(have))
        if missing:
            raise CheckpointError(f"{path}: the replayed run has no {', '.join(missing)} (the scene changed since "
                                  "the checkpoint?): it cannot be resumed. Start the run again with silo run.")
        for name, saved in state.items():
            restore(have[name], saved)


def load(folder: str | Path, comm) -> dict:
    """checkpoint.json of a results folder, checked (collective; raises CheckpointError)."""
    folder = Path(folder)
    meta, error = None, None
    if comm.rank == 0:
        path = folder / FOLDER / "checkpoint.json"
        summary = folder / "summary.json"
        status = json.loads(summary.read_text()).get("status") if summary.is_file() else None
        if not folder.is_dir() or not (folder / "scene.toml").is_file():
            error = f"{folder} is not a results folder written by silo run (no scene.toml)."
        elif status == "completed":
            error = f"{folder}: the run completed; there is nothing to resume."
        elif not path.is_file():
            error = (f"{folder}: no checkpoint (checkpoint/checkpoint.json): the run stopped before its first one "
                     "(output.checkpoint_interval of wall-clock), or has checkpoint_interval = 0. Start it again "
                     "with silo run.")
        else:
            meta = json.loads(path.read_text())
            if meta.get("format") != FORMAT:
                error = f"{path}: written by another version of silo_dolfinx (format {meta.get('format')})."
            elif meta["ranks"] != comm.size:
                error = (f"{path} was written by {meta['ranks']} ranks: resume it on as many (mpirun -n "
                         f"{meta['ranks']} silo run --resume {folder}).")
    meta, error = comm.bcast((meta, error), root=0)
    if error:
        raise CheckpointError(error)
    return meta


def _write_json(path: Path, data: dict) -> None:
    from silo_dolfinx.output.writer import _json_default

    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=_json_default))
    os.replace(tmp, path)
