"""The results folder: one run, everything it produced, written as it goes.

    results/NAME/
      scene.toml              the resolved scene (every default filled in)
      summary.json            status (running | completed | failed), key numbers, stages
      energy.csv              t, stage, energy terms, balance error
      wall_history.csv        t, station, s, r, z, p_n, p_s, slip_velocity (at the history rate)
      wall_profile_<stage>.csv  s, r, z, p_n, p_s, slip_velocity, in_contact (end of each stage)
      outlet.csv              t, discharged_mass, mass_flow_rate, mean_outlet_velocity, ... (discharge)
      mesh_quality.csv        t, top_drop, min_scaled_jacobian, max_aspect_ratio (discharge)
      tracers.csv             id, row, r0, z0, r, z, discharged_at (discharge with tracers)
      fields/nodes.bp, fields/cells.bp   VTX (ParaView): velocity, displacement; stress, p, q, q/p, ...
      checkpoint/             while running: the state to resume from (silo_dolfinx.checkpoint)
      mesh.png, *.png         pictures

Rank 0 writes the CSV and JSON files; every row is flushed when written and summary.json is
replaced atomically, so a crash leaves a readable partial result. Pressures are in Pa,
heights in m, times in s, energies in J. The columns of every CSV are in :mod:`.schema`.
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np


class CsvSeries:
    """A CSV file written row by row (rank 0 only), flushed after each row; ``append``: continue
    an existing file (a resumed run, the file already cut back to its checkpoint length)."""

    def __init__(self, path: Path, columns: list[str], active: bool, append: bool = False):
        self.path, self.columns, self.active = path, columns, active
        self._f = None
        if active:
            self._f = open(path, "a" if append else "w", newline="")  # noqa: SIM115 - kept open for incremental rows
            self._w = csv.writer(self._f)
            if not append:
                self._w.writerow(columns)
            self._f.flush()

    def write(self, *rows) -> None:
        if not self.active:
            return
        self._w.writerows([_fmt(x) for x in row] for row in rows)
        self._f.flush()

    @property
    def is_open(self) -> bool:
        return self._f is not None

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None


def _fmt(x):
    """A CSV cell: a float as its shortest round-trip repr (the csv module's own), a non-finite
    one empty; numpy scalars as Python ones (np.float64's repr is "np.float64(...)": not CSV)."""
    if type(x) is float:  # the common case first: rows built with .tolist()
        return x if x - x == 0.0 else ""  # inf - inf and nan - nan are nan
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else ""
    if isinstance(x, np.integer):
        return int(x)
    return x


class ResultsFolderBusy(RuntimeError):
    """A fresh run was started in a folder another run is still writing into."""


class Results:
    """Writer of one results folder (collective: create on every rank).

    ``resume``: the checkpoint a killed run continues from (:mod:`silo_dolfinx.checkpoint`):
    the summary so far is kept (status back to ``running``, the resumption listed under
    ``resumed``), every CSV the checkpoint recorded is cut back to its length then and appended
    to, and the wall-clock counts on from the checkpoint's. A fresh run into the folder of an
    earlier run first removes what that run wrote (:meth:`clear_earlier_run`), so that no file of
    it is read as this run's."""

    def __init__(self, folder: str | Path, scene, comm, resume: dict | None = None):
        self.folder = Path(folder)
        self.comm = comm
        self.root = comm.rank == 0
        self.scene = scene
        self._series: dict[str, CsvSeries] = {}
        self._last_beat = time.time()
        self._append: set[str] = set()
        self.resumed = 0  # how many times this run was resumed
        if resume is not None:
            self._resume(resume)
            return
        busy = comm.bcast(self.live_run(self.folder) if self.root else None, root=0)
        if busy:  # refused on every rank, before anything is touched
            raise ResultsFolderBusy(busy)
        if self.root:
            self.clear_earlier_run(self.folder)
            self.folder.mkdir(parents=True, exist_ok=True)
            (self.folder / "scene.toml").write_text(scene.to_toml())
        comm.barrier()
        self.started = time.time()
        self.summary: dict[str, Any] = {
            "status": "running",
            "title": scene.title,
            "scene": str(scene.source) if scene.source else None,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
            "ranks": comm.size,
            "material_angles": scene.cone,
            "stages": [],
            "warnings": list(scene.warnings),
        }
        self.write_summary()

    @classmethod
    def live_run(cls, folder: Path) -> str | None:
        """Why ``folder`` must not be started afresh: a run is still writing into it (its
        summary says "running" and was rewritten within LIVE heartbeats); None if it may."""
        path = folder / "summary.json"
        try:
            status = json.loads(path.read_text()).get("status")
            age = time.time() - path.stat().st_mtime
        except (OSError, ValueError):
            return None
        if status != "running" or age > cls.LIVE * cls.HEARTBEAT:
            return None
        return (f"{folder}: a run is still writing into this folder (its summary.json says \"running\", "
                f"updated {age:.0f} s ago; a run records its progress every {cls.HEARTBEAT:.0f} s). Fix: give this "
                f"run another --out, or stop that one first; a run killed outright frees the folder "
                f"{cls.LIVE * cls.HEARTBEAT:.0f} s after its last record.")

    @staticmethod
    def clear_earlier_run(folder: Path) -> list[str]:
        """Remove the results of an earlier run in ``folder`` (one holding a ``summary.json``):
        its CSV files (those :mod:`.schema` names), field output, checkpoint, figures, report,
        summary and scene. Otherwise a shorter run would leave the longer one's later field
        snapshots, or a run without a discharge its outlet.csv, beside its own. Files of other
        names are left alone, and so is a folder that is not a results folder. Returns what was
        removed (rank 0 only)."""
        import shutil

        from silo_dolfinx.output.schema import for_file

        if not (folder / "summary.json").is_file():
            return []
        ours = {"summary.json", "scene.toml", "report.md", "fields", "checkpoint"}
        gone = sorted(f.name for f in folder.iterdir()
                      if f.name in ours or f.suffix == ".png" or (f.suffix == ".csv" and for_file(f.name)))
        for name in gone:
            path = folder / name
            if path.is_dir():
                shutil.rmtree(path)
            else:
                path.unlink()
        print(f"silo: {folder} held an earlier run: its {len(gone)} results (CSV files, fields, figures, "
              "summary) are replaced by this run's", flush=True)
        return gone

    def _resume(self, ck: dict) -> None:
        self.summary = json.loads((self.folder / "summary.json").read_text())
        self.summary.pop("error", None)
        resumed = self.summary.setdefault("resumed", [])
        resumed.append({"from_t": ck["t"], "from_steps": ck["steps"], "at": time.strftime("%Y-%m-%dT%H:%M:%S")})
        self.resumed = len(resumed)
        self.summary.update(status="running", t_reached=ck["t"], steps=ck["steps"])
        self.started = time.time() - ck["wall_clock_s"]
        self._append = set(ck["csv_sizes"])
        if self.root:
            for name, size in ck["csv_sizes"].items():
                os.truncate(self.folder / name, size)  # rows after the checkpoint are written again
        self.comm.barrier()
        self.write_summary()

    def csv_sizes(self) -> dict[str, int]:
        """Byte length of every open CSV series (rank 0; all flushed): what a checkpoint records."""
        return {name: os.path.getsize(s.path) for name, s in self._series.items() if s.is_open} if self.root else {}

    def path(self, name: str) -> Path:
        return self.folder / name

    def series(self, name: str, columns: list[str]) -> CsvSeries:
        if name not in self._series:
            self._series[name] = CsvSeries(self.folder / name, columns, self.root, append=name in self._append)
        return self._series[name]

    def table(self, schema, **parts) -> CsvSeries:
        """The CSV series of a results file by its schema (:mod:`.schema`)."""
        return self.series(schema.name(**parts), schema.names)

    def write_table(self, schema, rows, **parts) -> None:
        """A whole small CSV at once, by its schema (a wall profile, the tracers)."""
        self.write_rows(schema.name(**parts), schema.names, rows)

    def write_rows(self, name: str, columns: list[str], rows) -> None:
        """A whole small CSV at once (e.g. a wall profile)."""
        s = CsvSeries(self.folder / name, columns, self.root)
        s.write(*rows)
        s.close()

    def update(self, **items) -> None:
        self.summary.update(items)
        self.write_summary()

    HEARTBEAT = 10.0  # s of wall-clock between the progress records in summary.json
    LIVE = 6  # a "running" summary rewritten within this many heartbeats belongs to a live run

    def heartbeat(self, **progress) -> None:
        """Record how far the run has come (stage, t_reached, steps) in summary.json, at most every
        HEARTBEAT s: a run killed outright leaves status "running" and where it was. Rank 0 only
        (no collective: it is called where only rank 0 may have the clock past the interval)."""
        if self.root and time.time() - self._last_beat >= self.HEARTBEAT:
            self._last_beat = time.time()
            self.update(**progress)

    def write_summary(self) -> None:
        if not self.root:
            return
        self.summary["wall_clock_s"] = round(time.time() - self.started, 3)
        tmp = self.folder / ".summary.json.tmp"
        tmp.write_text(json.dumps(self.summary, indent=2, default=_json_default))
        os.replace(tmp, self.folder / "summary.json")

    def finish(self, status: str, error: str | None = None) -> None:
        self.summary["status"] = status
        if error:
            self.summary["error"] = error
        for s in self._series.values():
            s.close()
        self.write_summary()


def _json_default(o):
    try:
        import numpy as np

        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:  # pragma: no cover
        pass
    return str(o)


class Progress:
    """Progress lines on rank 0: stage, simulated time, steps/s, ETA (every ``every`` seconds).

    Rates are those of the recent past (an exponential average over the last few lines, half
    weight to the newest interval), not since the start: a run's pace changes between stages
    (a discharge's Δt is smaller than the fill's), and an ETA from the average since the start
    would promise the fill's pace for the discharge."""

    SMOOTHING = 0.5  # weight of the newest interval in the running rates

    def __init__(self, comm, total_time: float, every: float = 5.0, stream=None):
        import sys

        self.root = comm.rank == 0
        self.total = total_time
        self.every = every
        self.stream = stream or sys.stderr
        self._last = time.time()
        self._sim_last = None
        self._steps_last = 0
        self._rates = None  # (steps/s, simulated s per wall-clock s)

    def __call__(self, stage: str, t: float, steps: int, dt: float, force: bool = False) -> None:
        now = time.time()
        if self._sim_last is None:
            self._sim_last, self._steps_last = t, steps
        if not self.root or (not force and now - self._last < self.every):
            return
        span = max(now - self._last, 1e-9)
        new = ((steps - self._steps_last) / span, (t - self._sim_last) / span)
        w = self.SMOOTHING
        self._rates = new if self._rates is None else tuple(w * a + (1 - w) * b for a, b in zip(new, self._rates))
        self._last, self._sim_last, self._steps_last = now, t, steps
        rate, sim_rate = self._rates
        eta = (self.total - t) / sim_rate if sim_rate > 0 else float("inf")
        print(f"[{stage}] t = {t:.4g} / {self.total:.4g} s | step {steps:,} | Δt {dt:.3g} s | "
              f"{rate:,.0f} steps/s | ETA {_hms(eta)}", file=self.stream, flush=True)


def _hms(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    s = int(s)
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"
