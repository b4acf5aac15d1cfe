"""`silo report results/NAME`: figures and a report.md from a results folder.

Every figure uses the thesis' axes and shows the matching theory beside the simulation:

* ``wall_pressure_<stage>.png`` — p_n and p_s against height at the end of each stage, with
  Janssen (cylindrical walls), Walker κ = −1 / +1 and McLean (hoppers), EN 1991-4;
* ``wall_history.png`` — p_n(t) at the wall stations;
* ``spectra.png`` — amplitude spectra at the stations, eq. 4-12's frequency marked;
* ``discharge_pressures.png`` (+ ``discharge_pressures.csv``) — eq. 4-9 means over the first
  2 s and 10 s of the discharge against filling, and the overpressure (Figs. 4-6, 4-8);
* ``design_pressures.png`` (+ ``design_pressures.csv``) — the discharge's mean over its first
  10 s, its 99th percentile and largest wall pressure per station against EN 1991-4's filling
  and fixed discharge loads;
* ``wall_dynamics.png`` (+ ``wall_dynamics.csv`` for every station) — windowed spectra
  (Fig. 4-12) and mobilised friction (Figs. 4-13/4-14) at the station nearest h/4; the < 1 Hz
  RMS and frequency, the wave peak, the slip fraction per station;
* ``wall_spacetime.png`` (+ ``pulse_travel.csv``) — the pulses above 1 Hz against height and
  time, and whether they run along the wall: their lag from station to station and its speed
  against the solid's elastic waves;
* ``remesh_steps.csv`` — for a discharge that was meshed again, whether each re-mesh stepped
  each station's wall pressure beyond the discharge's own steps;
* ``outlet.png`` — outlet velocity and mass flow rate against Beverloo (eq. 4-6/4-8);
* ``flow_channel.png`` — the flow-channel boundary (v_z = 0.001 × centreline, ch. 6.4.3);
* ``mesh_quality.png`` — aspect ratio against top-surface drop (Fig. 3-18), scaled Jacobian;
* ``flow_pattern.png`` — tracer rows at four times (ALE discharges);
* ``energy.png`` — energy terms and the balance error;
* ``field_q_over_p.png``, ``field_velocity.png`` — the last field snapshot over the whole silo
  (section and mirror image, metres, the time in the title; :mod:`silo_dolfinx.render`);
* ``discharge.gif`` — with ``--movie``: speed, tracers and q/p through the discharge;

and ``report.md`` tying them together with a table of the key numbers. A partial results
folder (a run still going, or one that stopped) gives whatever its files allow; what is
missing is named in the report.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from silo_dolfinx import analysis, theory
from silo_dolfinx.geometry.shapes import bin_hopper_cone_height, hopper_half_angle
from silo_dolfinx.output.reader import read_csv, read_summary


class Report:
    def __init__(self, folder: str | Path, times: list[float] | None = None, movie: bool = False):
        self.folder = Path(folder)
        self.times = times  # of the stress-field figures (None: the stages' ends, 2 s into the discharge)
        self.with_movie = movie  # discharge.gif (silo report --movie)
        if not self.folder.is_dir():
            raise FileNotFoundError(f"{self.folder}: no such results folder")
        from silo_dolfinx.scene import load_scene

        self.scene = load_scene(self.folder / "scene.toml") if (self.folder / "scene.toml").is_file() else None
        self.summary = read_summary(self.folder)
        self.missing: list[str] = []
        self.figures: list[tuple[str, str]] = []
        self.numbers: list[tuple[str, str]] = []
        import matplotlib

        matplotlib.use("Agg")

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def _low_frequency(f: float, span: float) -> str:
        """The < 1 Hz part's dominant frequency, or why there is none (a record too short for a
        peak below 1 Hz: its spectrum's first bins are the window's own)."""
        return f"at {f:.3g} Hz" if np.isfinite(f) else f"with no peak below 1 Hz in its {span:.3g}-s record"

    def _station(self, k, z: float) -> str:
        """How station ``k`` (its index in output.stations) at height ``z`` is named in figures and
        numbers: "z = 0.66 m", or with output.station_labels "D (z = 0.69 m)"."""
        labels = self.scene.output.station_labels if self.scene is not None else []
        name = labels[int(k)] if int(k) < len(labels) else ""
        return f"{name} (z = {z:.2f} m)" if name else f"z = {z:.2f} m"

    def _save(self, fig, name: str, caption: str) -> None:
        import matplotlib.pyplot as plt

        if fig.get_layout_engine() is None:
            fig.tight_layout()
        fig.savefig(self.folder / name, dpi=120)
        plt.close(fig)
        self.figures.append((name, caption))

    def _stage_times(self) -> dict[str, tuple[float, float]]:
        return {st["name"]: (st.get("t_start", 0.0), st.get("t_end", 0.0)) for st in self.summary.get("stages", [])}

    # ------------------------------------------------------------------ theory beside the walls
    def wall_theory(self, z: np.ndarray, stage: str) -> list[tuple[str, np.ndarray]]:
        """Theory curves of p_n at heights z for this scene and stage, each drawn only in the
        state it describes (filling: Janssen, EN 1991-4 filling, Walker's active solution;
        discharge: EN 1991-4 discharge, Walker's passive solution, McLean's radial-field m)
        and labelled with the K, F and m it uses. Janssen's K comes from the scene: EN 1991-4's
        1.1 (1 − sin φ) and the simulated solid's own (measured at the end of the stage where
        a field snapshot allows, else the larger of ν/(1 − ν) and the cone's active ratio: a fill
        in uniaxial strain is elastic unless it yields); the thesis' K is
        drawn only for the thesis' own scenes."""
        sc = self.scene
        if sc is None:
            return []
        g, m, w = sc.geometry, sc.material, sc.wall
        gamma = m.density * sc.loads.gravity
        mu = w.get("mu", w.get("mu_static", 0.0))
        cone = sc.cone
        phi = cone["phi_mohr_coulomb"] if cone else None  # Mohr-Coulomb φ of the simulated solid
        discharge = stage == "discharge"
        out = []
        if g.shape in ("flat_bottom", "column", "bin_hopper") and mu > 0 and not discharge:
            R = {"flat_bottom": "radius", "bin_hopper": "radius", "column": "base_radius"}[g.shape]
            curves = self._janssen(z, g[R], mu, gamma, stage)
            if g.shape == "bin_hopper":  # Janssen holds on the vertical wall, above the transition
                below = z < self._vertical_wall_base(z)
                curves = [(label, np.where(below, np.nan, p)) for label, p in curves]
            out += curves
        if g.shape == "hopper" and mu > 0:
            alpha = hopper_half_angle(g)
            zz = np.clip(z, 0, g.height)
            kappa = 1 if discharge else -1
            if phi and math.atan(mu) < math.radians(phi):
                F, m_w = theory.walker_parameters(phi, mu, alpha, kappa)
                pn, _ = theory.walker_hopper(zz, phi, mu, alpha, g.outlet_radius, g.height, gamma, kappa)
                out.append((f"Walker κ = {kappa:+d} ({'passive' if discharge else 'active'}), φ = {phi:.1f}°: "
                            f"F {F:.2f}, m {m_w:.2f}", pn))
                if discharge:  # McLean's m belongs to the radial stress field of a flowing hopper
                    m_mc = theory.mclean_m(mu, alpha)
                    sv = theory.hopper_vertical_stress(zz, m_mc, alpha, g.outlet_radius, g.height, gamma)
                    out.append((f"McLean (eq. 4-4): m = 2μ/tan α = {m_mc:.2f}, Walker's passive F {F:.2f}", F * sv))
        label, pn = self.en1991(z, stage)
        if pn is not None and g.shape != "hopper" and not discharge:  # the vertical wall's is a Janssen K above
            pn = np.where(z >= self._vertical_wall_base(z) - 1e-9 * g.fill_height, np.nan, pn)
        if pn is not None and np.any(np.isfinite(pn)):
            out.append((label, pn))
        return out

    def en1991(self, z: np.ndarray, stage: str) -> tuple[str, np.ndarray | None]:
        """EN 1991-4 (2006)'s symmetrical wall pressure p_n at heights z in this stage's state
        (filling, or the fixed discharge load), with the scene's own solid: (label, p_n), NaN
        where the code has no rule (a floor, a fillet above the cone's end); or (why not, None).
        Vertical walls: K = 1.1 (1 − sin φ), Janssen in slender silos and §5.3's profile in
        squat and intermediate ones, × C_h in discharge (theory.en1991_vertical_wall); conical
        hoppers: F_f or F_e on eq. 4-2's vertical stress (theory.en1991_hopper), under a bin
        with the bin's filling load at the transition (C_b = 1)."""
        sc = self.scene
        if sc is None:
            return "no scene.toml", None
        g, w = sc.geometry, sc.wall
        gamma = sc.material.density * sc.loads.gravity
        mu = w.get("mu", w.get("mu_static", 0.0))
        phi = sc.cone["phi_mohr_coulomb"] if sc.cone else None
        discharge = stage == "discharge"
        hf = g.fill_height
        if g.shape not in ("hopper", "flat_bottom", "bin_hopper"):
            return f"EN 1991-4: no rule for a `{g.shape}` wall", None
        if not mu > 0:
            return "EN 1991-4: a frictionless wall", None
        if phi is None and (discharge or g.shape != "hopper"):
            return "EN 1991-4: needs a Mohr-Coulomb friction angle (a frictional solid)", None
        if discharge and math.atan(mu) >= math.radians(phi) and g.shape != "flat_bottom":
            return "EN 1991-4: a hopper wall rougher than the solid (atan μ ≥ φ) has no F_e", None
        z = np.asarray(z, float)
        name = "EN 1991-4 " + ("discharge" if discharge else "filling")
        if g.shape == "hopper":
            pn, _ = theory.en1991_hopper(np.clip(z, 0, g.height), mu, hopper_half_angle(g), g.outlet_radius,
                                         g.height, gamma, discharge=discharge, friction_angle=phi)
            return name, pn
        K = theory.janssen_k_en1991(phi)
        base = 0.0 if g.shape == "flat_bottom" else self._vertical_wall_base(z)
        slender = (hf - base) / (2 * g.radius)
        p = np.full(z.shape, np.nan)
        wall = z > base + 1e-9 * hf if g.shape == "flat_bottom" else z >= base - 1e-9 * hf

        if g.shape == "flat_bottom" and slender <= theory.EN1991_RETAINING:
            return (f"EN 1991-4: h_c/d_c = {slender:.2f}: a flat-bottomed silo with h_c/d_c ≤ "
                    f"{theory.EN1991_RETAINING:g} is a retaining silo (§5.4, not implemented)"), None

        def code(depth, discharge):
            return theory.en1991_vertical_wall(np.clip(depth, 0, None), g.radius, mu, phi, gamma, slender, discharge,
                                               sc.loads.top_surcharge)
        try:
            p[wall], _, _ = code(hf - z[wall], discharge)
        except ValueError as err:  # a surcharged squat or intermediate silo: no rule
            return f"EN 1991-4: {err}", None
        c_h = theory.en1991_discharge_factors(slender)[0]
        label = f"{name} (K = {K:.2f}" + (f", C_h {c_h:.3g}" if discharge else "") + (
            "" if slender >= theory.EN1991_SLENDER else f"; h_c/d_c {slender:.2f}: §5.3's profile, φ_r = φ")
        if g.shape == "bin_hopper":
            hh = bin_hopper_cone_height(g)
            pv_t = float(code(hf - hh, False)[2])  # the bin's filling load at the cone's top
            cone = z <= hh
            p[cone], _ = theory.en1991_hopper(np.clip(z[cone], 0, hh), mu, g.hopper_half_angle, g.outlet_radius, hh,
                                              gamma, surcharge=pv_t, discharge=discharge, friction_angle=phi)
            label += "; the hopper under the bin's load"
        return label + ")", p

    # Janssen's K as the thesis gives it, for its own scenes only (by title)
    THESIS_K = {"flat_bottom_ch6": 0.38, "bin_hopper_ch7": 0.38}

    def _janssen(self, z, R: float, mu: float, gamma: float, stage: str) -> list[tuple[str, np.ndarray]]:
        sc = self.scene
        m, cone = sc.material, sc.cone
        depth = np.clip(sc.geometry.fill_height - z, 0, None)
        ks = []
        if cone:
            ks.append((theory.janssen_k_en1991(cone["phi_mohr_coulomb"]),
                       f"EN 1991-4 K = 1.1(1 − sin φ), φ {cone['phi_mohr_coulomb']:.1f}°"))
        own = self.measured_k(stage, mu, R)
        k0 = m.poisson_ratio / (1 - m.poisson_ratio)
        if own is not None:
            ks.append((own, "the simulated solid's own K, measured"))
        elif cone is None:
            ks.append((k0, "ν/(1−ν), elastic"))
        elif cone["beta"] < 71.5:  # without a snapshot: a fill in uniaxial strain, elastic unless it yields
            ka = theory.drucker_prager_active_k(cone["beta"])
            ks.append((max(k0, ka), "the solid's own: ν/(1−ν) or its cone's active ratio, the larger"))
        thesis = next((k for name, k in self.THESIS_K.items() if sc.title.startswith(name)), None)
        if thesis is not None:
            ks.append((thesis, "the thesis'"))
        return [(f"Janssen K = {K:.3g} ({why})", theory.janssen(depth, R, mu, K, gamma, sc.loads.top_surcharge)[0])
                for K, why in ks]

    def _vertical_wall_base(self, z: np.ndarray) -> float:
        """Where the vertical wall starts: a bin-hopper's transition (a fillet's upper tangent
        point), else the bottom of the wall profile ``z``."""
        sc = self.scene
        if sc.geometry.shape == "bin_hopper":
            return float(np.max(sc.outline.transition_points[:, 1]))
        return float(np.min(z))

    def measured_k(self, stage: str, mu: float, R: float) -> float | None:
        """The solid's own lateral pressure ratio at the end of ``stage``: the median over the
        depths from one Janssen depth (with that K; at most half the vertical wall) down to
        0.1 m above the floor, or one radius above a bin-hopper's transition, of wall p_n over
        the section-mean vertical stress (analysis.lateral_pressure_ratio), from the last field
        snapshot of the stage; None without one."""
        t_end = self._stage_times().get(stage, (0.0, None))[1]
        wall = read_csv(self.folder / f"wall_profile_{stage}.csv")
        snap = self._snapshot(t_end) if t_end is not None else None
        if wall is None or snap is None or "cell_stress_zz" not in snap:
            return None
        from silo_dolfinx import analysis

        z = wall["z"]
        z_top = self.scene.geometry.fill_height
        # the vertical wall from 0.1 m above the floor, or one radius above a bin-hopper's
        # transition (its switch stress spreads about a radius up the bin, ch. 7)
        base = self._vertical_wall_base(z)
        z_lo = base + (R if self.scene.geometry.shape == "bin_hopper" else 0.1)
        k = 0.5
        for _ in range(3):  # the window starts one Janssen depth down: iterate K and z0 = R/(2 K μ)
            # (a bin shorter than that: its upper half is left out instead)
            sel = (z > z_lo) & (z < z_top - min(R / (2 * k * mu), 0.5 * (z_top - z_lo)))
            if not np.any(sel):
                return None
            k = float(np.nanmedian(analysis.lateral_pressure_ratio(snap, wall, z[sel])))
            if not (np.isfinite(k) and k > 0):
                return None
        return k

    # ------------------------------------------------------------------ figures
    def wall_profiles(self) -> None:
        import matplotlib.pyplot as plt

        profiles = sorted(self.folder.glob("wall_profile_*.csv"))
        if not profiles:
            self.missing.append("wall profiles (wall_profile_<stage>.csv)")
            return
        for path in profiles:
            stage = path.stem.removeprefix("wall_profile_")
            d = read_csv(path)
            if d is None:
                continue
            fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 6), sharey=True)
            a1.plot(d["p_n"] / 1e3, d["z"], "k.-", ms=3, lw=1, label="simulation")
            for label, pn in self.wall_theory(d["z"], stage):
                a1.plot(pn / 1e3, d["z"], "--", lw=1.3, label=label)
            a1.set_xlabel("wall normal pressure p_n (kPa)")
            a1.set_ylabel("height above outlet z (m)")
            a1.legend(fontsize=8)
            a1.grid(alpha=0.3)
            a2.plot(d["p_s"] / 1e3, d["z"], "k.-", ms=3, lw=1, label="p_s")
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(d["p_n"] > 0, d["p_s"] / d["p_n"], np.nan)
            a2b = a2.twiny()
            a2b.plot(ratio, d["z"], "r-", lw=0.8, alpha=0.7)
            a2b.set_xlabel("mobilised friction p_s/p_n", color="r")
            a2.set_xlabel("wall shear p_s (kPa)")
            a2.grid(alpha=0.3)
            fig.suptitle(f"{self._title()} — wall pressures, end of {stage}")
            self._save(fig, f"wall_pressure_{stage}.png", f"Wall pressures at the end of {stage}, with theory.")
            self.numbers.append((f"max p_n, end of {stage}", f"{np.nanmax(d['p_n']) / 1e3:.3f} kPa at z = "
                                 f"{d['z'][int(np.nanargmax(d['p_n']))]:.3f} m"))
            loaded = (d["p_n"] > 0.05 * np.nanmax(d["p_n"])) & (d["z"] > d["z"].min())  # not the outlet-edge node
            if np.any(loaded):
                self.numbers.append((f"mobilised p_s/p_n, end of {stage} (nodes with p_n > 5 % of max)",
                                     f"mean {np.nanmean(ratio[loaded]):.4f}, median {np.nanmedian(ratio[loaded]):.4f}"))
            if stage != "discharge":
                self._janssen_fit(d, stage)

    def _janssen_fit(self, d: dict, stage: str) -> None:
        """Janssen fitted to a vertical wall's pressures (K and μ free, analysis.janssen_fit):
        the ratio and the wall friction the fill developed, as the depth scale z0 and the level
        p∞ they give - from one radius above the floor or the transition to the surface."""
        sc = self.scene
        if sc is None or sc.geometry.shape not in ("flat_bottom", "bin_hopper"):
            return
        from silo_dolfinx import analysis

        R = sc.geometry.radius
        vertical = d["r"] > R * (1 - 1e-9)
        base = self._vertical_wall_base(d["z"])
        try:
            f = analysis.janssen_fit(d["z"][vertical], d["p_n"][vertical], fill_height=sc.geometry.fill_height,
                                     radius=R, unit_weight=sc.material.density * sc.loads.gravity, z_min=base + R)
        except ValueError:  # too short a wall above the window's start
            return
        self.numbers.append((f"Janssen fitted to the vertical wall, end of {stage} (K, μ free; z ≥ {base + R:.2f} m)",
                             f"K {f.k:.3f}, μ {f.mu:.3f}: z0 = R/(2μK) {f.z0:.3f} m, level γR/(2μ) {f.p_inf / 1e3:.3f} "
                             f"kPa (rms {f.rms:.3g} Pa)"))

    def _history(self):
        h = read_csv(self.folder / "wall_history.csv")
        if h is None:
            self.missing.append("wall pressure histories (wall_history.csv)")
            return None
        return h

    def wall_histories(self) -> None:
        import matplotlib.pyplot as plt

        h = self._history()
        if h is None:
            return
        fig, ax = plt.subplots(figsize=(10, 5))
        for k in np.unique(h["station"]).astype(int):
            sel = h["station"] == k
            ax.plot(h["t"][sel], h["p_n"][sel] / 1e3, lw=0.8, label=self._station(k, np.nanmean(h["z"][sel])))
        for name, (t0, t1) in self._stage_times().items():
            ax.axvline(t1, color="0.6", lw=0.6, ls=":")
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("wall normal pressure p_n (kPa)")
        ax.legend(fontsize=7, ncol=2)
        ax.grid(alpha=0.3)
        self._save(fig, "wall_history.png", "Wall normal pressure at the stations (dotted: stage ends).")

    def point_histories(self) -> None:
        """σ_rr, σ_zz and q/p at the interior points (output.points) against time (Figs. 4-16 to
        4-18), with each point's < 1 Hz RMS of σ_rr over the discharge."""
        import matplotlib.pyplot as plt

        h = read_csv(self.folder / "point_history.csv")
        if h is None:
            return  # no interior points asked for: nothing is missing
        fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
        t0, t1 = self._stage_times().get("discharge", (np.inf, np.inf))
        for k in np.unique(h["point"]).astype(int):
            sel = h["point"] == k
            t = h["t"][sel]
            label = f"({h['r'][sel][0]:.2f}, {h['z'][sel][0]:.2f}) m"
            for ax, col, scale in zip(axes, ("stress_rr", "stress_zz", "q_over_p"), (-1e-3, -1e-3, 1.0)):
                ax.plot(t, h[col][sel] * scale, lw=0.7, label=label)
            during = sel & (h["t"] >= self._settled(t0, t1)) & (h["t"] <= t1) & np.isfinite(h["stress_rr"])
            if during.sum() >= 16:
                rms, f = analysis.low_frequency_fluctuation(h["t"][during], h["stress_rr"][during])
                self.numbers.append((f"point {label}: < 1 Hz RMS of σ_rr over the discharge, its frequency",
                                     f"{rms:.3g} Pa at {f:.3g} Hz"))
        for ax, name in zip(axes, ("−σ_rr (kPa)", "−σ_zz (kPa)", "q/p")):
            ax.set_ylabel(name)
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7, ncol=3)
        axes[-1].set_xlabel("time t (s)")
        self._save(fig, "point_histories.png", "Stress at the interior points (the mean of the cell holding each; "
                   "Figs. 4-16 to 4-18).")

    def spectra(self) -> None:
        import matplotlib.pyplot as plt

        h = self._history()
        if h is None:
            return
        stages = self._stage_times()
        t0, t1 = stages.get("discharge", (None, None))
        window = "discharge" if t0 is not None and t1 > t0 else "whole record"
        if window == "whole record":
            t0, t1 = float(np.nanmin(h["t"])), float(np.nanmax(h["t"]))
        sc = self.scene
        f_theory = f_radial = None
        if sc is not None:
            m = sc.material
            f_theory = theory.longitudinal_frequency(m.youngs_modulus, m.poisson_ratio, m.density,
                                                     sc.geometry.fill_height)
            if sc.geometry.shape in ("flat_bottom", "bin_hopper"):  # a vertical wall: the fill's breathing mode
                f_radial = theory.radial_frequency(m.youngs_modulus, m.poisson_ratio, m.density, sc.geometry.radius)
        fig, ax = plt.subplots(figsize=(10, 5))
        rows = []
        for k in np.unique(h["station"]).astype(int):
            sel = (h["station"] == k) & (h["t"] >= t0) & (h["t"] <= t1)
            if sel.sum() < 16:
                continue
            sp = analysis.spectrum(h["t"][sel], h["p_n"][sel])
            ax.plot(sp.frequency, sp.amplitude, lw=0.8, label=self._station(k, np.nanmean(h["z"][sel])))
            pk = sp.peaks(2, min_frequency=sp.resolution)
            rows.append((self._station(k, np.nanmean(h["z"][sel])), pk, sp.resolution))
        if not rows:
            plt.close(fig)
            self.missing.append("spectra (too few samples)")
            return
        if f_theory:
            ax.axvline(f_theory, color="r", ls="--", lw=1, label=f"eq. 4-12: {f_theory:.2f} Hz")
        if f_radial:
            ax.axvline(f_radial, color="m", ls=":", lw=1, label=f"radial mode (rigid wall): {f_radial:.3g} Hz")
        ax.set_xscale("log")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("amplitude of p_n (Pa)")
        ax.legend(fontsize=7, ncol=2)
        ax.grid(alpha=0.3, which="both")
        self._save(fig, "spectra.png", f"Amplitude spectra of p_n ({window}); dashed: eq. 4-12; dotted: the "
                   "radial mode inside a vertical wall.")
        name, pk, res = rows[len(rows) // 2]
        self.numbers.append((f"spectral peaks at {name} ({window})",
                             ", ".join(f"{p:.3g} Hz" for p in pk) + f" (resolution {res:.3g} Hz)"))
        if f_theory:
            self.numbers.append(("eq. 4-12 longitudinal frequency", f"{f_theory:.3g} Hz"))
        if f_radial:
            self.numbers.append(("radial (breathing) frequency of the fill inside the vertical wall, "
                                 "3.832 √(M/ρ)/(2πR)", f"{f_radial:.3g} Hz"))

    def _table(self, f, rows) -> None:
        from silo_dolfinx.output.writer import CsvSeries

        csv = CsvSeries(self.folder / f.pattern, f.names, True)
        csv.write(*rows)
        csv.close()

    def _discharge_history(self):
        """(wall history, opening time, end) when there is a discharge to analyse, else None."""
        h = self._history()
        t0, t1 = self._stage_times().get("discharge", (None, None))
        if h is None or t0 is None or not t1 > t0:
            return None
        return h, t0, t1

    @staticmethod
    def _pressure_and_ratio(a1, a2, ratio_label: str) -> None:
        """Finish a two-panel profile figure: p_n against height, and a ratio against height
        with 1 marked."""
        a2.axvline(1.0, color="0.5", lw=0.8)
        a1.set_xlabel("wall normal pressure p_n (kPa)")
        a1.set_ylabel("height z (m)")
        a2.set_xlabel(ratio_label)
        for a in (a1, a2):
            a.legend(fontsize=7)
            a.grid(alpha=0.3)

    def discharge_pressures(self) -> None:
        """Eq. 4-9 means over the first 2 s and 10 s of the discharge against the end of
        filling (Figs. 4-6, 4-8): discharge_pressures.csv and a figure."""
        import matplotlib.pyplot as plt

        from silo_dolfinx.output.schema import DISCHARGE_PRESSURES

        d = self._discharge_history()
        fill = read_csv(self.folder / "wall_profile_fill.csv")
        if d is None or fill is None:
            self.missing.append("discharge pressures (needs a discharge, wall_history.csv, wall_profile_fill.csv)")
            return
        h, t0, t1 = d
        means = {w: analysis.station_means(h, t0, min(t0 + w, t1)) for w in (2.0, 10.0)}
        z = means[2.0][0]
        p_fill = analysis.profile_at(z, fill["z"], fill["p_n"])
        ratio = {w: analysis.overpressure(z, means[w][1], fill["z"], fill["p_n"]) for w in means}
        self._table(DISCHARGE_PRESSURES, [[k, z[k], p_fill[k], means[2.0][1][k], means[10.0][1][k], ratio[2.0][k],
                                           ratio[10.0][k]] for k in range(z.size)])
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 5), sharey=True)
        a1.plot(fill["p_n"] / 1e3, fill["z"], "k-", lw=1, label="end of filling")
        for w, style in ((2.0, "bo-"), (10.0, "rs-")):
            span = min(w, t1 - t0)
            a1.plot(means[w][1] / 1e3, z, style, ms=4, label=f"discharge mean, first {span:g} s")
            a2.plot(ratio[w], z, style, ms=4, label=f"first {span:g} s")
        self._pressure_and_ratio(a1, a2, "discharge / filling pressure")
        self._save(fig, "discharge_pressures.png", "Time-averaged discharge pressures (eq. 4-9) against filling, "
                   "and the overpressure (Figs. 4-6, 4-8).")
        r = ratio[10.0]
        if np.any(np.isfinite(r)):
            k = int(np.nanargmax(r))
            self.numbers.append((f"discharge overpressure, first {min(10.0, t1 - t0):g} s (max, where)",
                                 f"{r[k]:.3g} at z = {z[k]:.2f} m; above filling at {np.sum(r > 1)}/{r.size} stations"))
            # the ratio peaks where the fill presses least (near the surface); a design checks the rise
            rise = means[10.0][1] - p_fill
            k = int(np.nanargmax(rise))
            self.numbers.append((f"largest rise of the discharge mean over filling, first {min(10.0, t1 - t0):g} s",
                                 f"{rise[k] / 1e3:+.3g} kPa at {self._station(k, z[k])} (× {r[k]:.3g}; "
                                 f"the mean there {means[10.0][1][k] / 1e3:.3g} kPa)"))

    MEAN_WINDOW = 10.0  # s after opening over which design_pressures takes the mean

    def design_pressures(self) -> None:
        """What the wall carried in the discharge - its mean over the first 10 s, its 99th
        percentile and largest p_n over the whole discharge, per station - against EN 1991-4's
        symmetrical filling and fixed discharge loads with the scene's own solid
        (:meth:`en1991`): design_pressures.csv, a figure, and where the discharge exceeded the
        larger of the two."""
        import matplotlib.pyplot as plt

        from silo_dolfinx.output.schema import DESIGN_PRESSURES

        d = self._discharge_history()
        before = [st["name"] for st in self.summary.get("stages", []) if st["name"] != "discharge"]
        rest = read_csv(self.folder / f"wall_profile_{before[-1]}.csv") if before else None
        if d is None or rest is None:
            self.missing.append("design pressures (needs a discharge, wall_history.csv and the wall profile "
                                "at the opening)")
            return
        h, t0, t1 = d
        st = np.asarray(h["station"], float)
        stations = np.unique(st)
        # the mean while the silo is still nearly full (the code's loads are the full silo's);
        # the pulses over the whole discharge (the envelope)
        mean_span = min(self.MEAN_WINDOW, t1 - t0)
        z, p_mean = analysis.station_means(h, t0, t0 + mean_span)
        p99, pmax, tmax = (np.full(stations.size, np.nan) for _ in range(3))
        for k, s in enumerate(stations):
            m = (st == s) & (h["t"] >= t0) & (h["t"] <= t1)
            if np.any(m):
                p = h["p_n"][m]
                i = int(np.nanargmax(p))
                p99[k], pmax[k], tmax[k] = np.nanpercentile(p, 99), p[i], h["t"][m][i] - t0
        p_open = analysis.profile_at(z, rest["z"], rest["p_n"])
        en = {stage: self.en1991(z, stage) for stage in ("fill", "discharge")}
        if en["discharge"][1] is None:
            self.numbers.append(("EN 1991-4 discharge load", en["discharge"][0]))
        p_ef, p_ed = (np.full(z.shape, np.nan) if p is None else p for _, p in en.values())
        # a wall is designed for the larger of the code's two load cases (near a hopper's outlet
        # F_e < F_f: there the filling load governs)
        p_en = np.where(np.isnan(p_ed), np.nan, np.fmax(p_ef, p_ed))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = {k: np.where(p_en > 0, v / p_en, np.nan) for k, v in (("mean", p_mean), ("99", p99), ("max", pmax))}
        self._table(DESIGN_PRESSURES, [[k, z[k], p_open[k], p_ef[k], p_ed[k], p_en[k], p_mean[k], p99[k], pmax[k],
                                        tmax[k], ratio["mean"][k], ratio["99"][k], ratio["max"][k]]
                                       for k in range(z.size)])
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 5.5), sharey=True)
        a1.plot(p_open / 1e3, z, "k-", lw=1, label=f"at the opening (end of {before[-1]})")
        a1.plot(p_mean / 1e3, z, "bo-", ms=4, lw=1, label=f"discharge mean, first {mean_span:.3g} s")
        a1.plot(p99 / 1e3, z, "^-", color="darkorange", ms=4, lw=1, label="discharge, 99th percentile")
        a1.plot(pmax / 1e3, z, "rx", ms=6, label="discharge, largest")
        zz = np.linspace(np.nanmin(z), np.nanmax(z), 200)  # the code's loads as curves
        for stage, style in (("fill", "--"), ("discharge", "-.")):
            label, p = self.en1991(zz, stage)
            if p is not None:
                a1.plot(p / 1e3, zz, style, color="0.3", lw=1.2, label=label)
        for k, label, fmt, colour in (("mean", "mean", "o-", "b"), ("99", "99th percentile", "^-", "darkorange"),
                                      ("max", "largest", "x", "r")):
            a2.plot(ratio[k], z, fmt, color=colour, ms=4, label=label)
        self._pressure_and_ratio(a1, a2, "over EN 1991-4's load (the larger of filling and discharge)")
        fig.suptitle(f"{self._title()} — the discharge against EN 1991-4 (the scene's own solid, no property factors)")
        self._save(fig, "design_pressures.png", "What the wall carried over the discharge (mean, 99th percentile, "
                   "largest) against EN 1991-4's filling and fixed discharge loads with the scene's solid.")
        # the ratio is largest where the code's load is small (near the surface): the excess in
        # kPa says where the wall carries most beyond it
        for k, p, what in (("mean", p_mean, f"the discharge mean (first {mean_span:.3g} s)"),
                           ("99", p99, "the discharge's 99th percentile"), ("max", pmax, "the largest discharge pressure")):
            r = ratio[k]
            if not np.any(np.isfinite(r)):
                continue
            i, j = int(np.nanargmax(r)), int(np.nanargmax(p - p_en))
            when = (lambda n: f", {tmax[n]:.3g} s after the opening" if k == "max" else "")
            self.numbers.append((f"{what} over EN 1991-4's load (the larger of filling and discharge)",
                                 f"largest × {r[i]:.3g} at {self._station(i, z[i])}{when(i)}; the largest excess "
                                 f"{(p[j] - p_en[j]) / 1e3:+.3g} kPa at {self._station(j, z[j])}{when(j)}; above it "
                                 f"at {int(np.sum(r > 1))}/{int(np.sum(np.isfinite(r)))} stations"))

    START_UP = 2.0  # s after opening left out of the dynamics (the thesis' flow is steady after ≈ 2 s)

    def _settled(self, t_open: float, t_end: float) -> float:
        """Where the dynamics are measured from: START_UP s after the opening, when the
        discharge is at least twice as long."""
        return t_open + self.START_UP if t_end - t_open >= 2 * self.START_UP else t_open

    def _after_switch(self, h, k, times) -> tuple[np.ndarray | None, float] | None:
        """(the samples of station ``k`` to measure the discharge's dynamics on, from when):
        ``times`` = (opening, start-up's end, end); from the start-up's end or 1 s after the
        station's switch from the filled to the flowing state (:func:`analysis.switch_time`),
        whichever is later. None if the discharge has fewer than 16 samples at the station; no
        samples (None, from when) if less than a quarter of the discharge is left after it."""
        t_open, t0, t1 = times
        sel = (h["station"] == k) & (h["t"] >= t_open) & (h["t"] <= t1)
        if sel.sum() < 16:
            return None
        ts = analysis.switch_time(h["t"][sel], h["p_n"][sel], t_open)
        tk = max(t0, ts + 1.0 / analysis.LOW_CUTOFF) if np.isfinite(ts) and t0 > t_open else t0
        sel &= h["t"] >= tk
        return (None if sel.sum() < 16 or t1 - tk < 0.25 * (t1 - t_open) else sel), tk

    def wall_dynamics(self) -> None:
        """Why the pressure pulses, per station over the discharge after its start-up
        (``START_UP`` s, when the discharge is at least twice as long, and 1 s after the
        station's switch from the filled to the flowing state, :func:`analysis.switch_time`,
        whichever is later: a slow controlled discharge switches late): the < 1 Hz fluctuation
        (RMS, frequency), the stress-wave peak, the mobilised friction and the slip fraction
        (wall_dynamics.csv); windowed spectra (Fig. 4-12) and the mobilised friction (Figs.
        4-13/4-14) at the station nearest a quarter of the fill height (the thesis' point e)."""
        import matplotlib.pyplot as plt

        from silo_dolfinx.output.schema import WALL_DYNAMICS

        d = self._discharge_history()
        if d is None:
            self.missing.append("wall dynamics (needs a discharge and wall_history.csv)")
            return
        h, t_open, t1 = d
        t0 = self._settled(t_open, t1)
        rows = []
        for k in np.unique(h["station"]):
            window = self._after_switch(h, k, (t_open, t0, t1))
            if window is None:
                continue
            sel, tk = window
            if sel is None:  # too little after the switch to measure
                rows.append([int(k), float(np.mean(h["z"][h["station"] == k])), tk - t_open]
                            + [np.nan] * (len(WALL_DYNAMICS.columns) - 3))  # every measured column NaN
                continue
            t, p = h["t"][sel], h["p_n"][sel]
            rms, f_low = analysis.low_frequency_fluctuation(t, p)
            fast = analysis.fast_fluctuation(t, p)
            wave = analysis.averaged_spectrum(t, p).peaks(1, min_frequency=analysis.LOW_CUTOFF)
            mob = analysis.mobilised_friction(p, h["p_s"][sel])
            rows.append([int(k), float(np.mean(h["z"][sel])), tk - t_open, float(np.mean(p)), rms, f_low, fast,
                         float(wave[0]) if wave.size else np.nan,
                         float(np.nanmean(mob)) if np.any(np.isfinite(mob)) else np.nan,
                         analysis.slip_fraction(h["slip_velocity"][sel]), analysis.windowed_low_fluctuation(t, p)])
        if not rows:
            self.missing.append("wall dynamics (too few discharge samples)")
            return
        self._table(WALL_DYNAMICS, rows)
        hf = self.scene.geometry.fill_height if self.scene is not None else max(r[1] for r in rows) * 2
        e = min(rows, key=lambda r: abs(r[1] - 0.25 * hf))
        if not np.isfinite(e[4]):
            self.missing.append(f"wall dynamics at z = {e[1]:.2f} m (the discharge ends too soon after its switch, "
                                f"{e[2]:.3g} s after opening)")
            return
        name = self._station(e[0], e[1])
        self.numbers.append((f"station {name}: RMS of p_n above 1 Hz", f"{e[6]:.3g} Pa"))
        self.numbers.append((f"station {name} (≈ h/4, point e): < 1 Hz RMS, its frequency (in 10-s windows); "
                             "wave peak",
                             f"{e[4]:.3g} Pa {self._low_frequency(e[5], t1 - t_open - e[2])} ({e[10]:.3g} Pa); "
                             f"{e[7]:.3g} Hz (from {e[2]:.3g} s after opening)"))
        self.numbers.append((f"station {name}: mobilised |p_s|/p_n, time sliding",
                             f"{e[8]:.4f}; {100 * e[9]:.0f} % of the discharge"))
        t0 = t_open + e[2]
        sel = (h["station"] == e[0]) & (h["t"] >= t0) & (h["t"] <= t1)
        t, p = h["t"][sel], h["p_n"][sel]
        span = (t1 - t0) / 6.0
        spectra = analysis.windowed_spectra(t, p, t0, span, 6)
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
        for i, sp in enumerate(spectra):
            a1.plot(sp.frequency, sp.amplitude, lw=0.8,
                    label=f"{t0 + i * span - t_open:.3g}–{t0 + (i + 1) * span - t_open:.3g} s")
        if self.scene is not None:
            m = self.scene.material
            f4 = theory.longitudinal_frequency(m.youngs_modulus, m.poisson_ratio, m.density, hf)
            a1.axvline(f4, color="r", ls="--", lw=1, label=f"eq. 4-12 (H = {hf:g} m): {f4:.2f} Hz")
        a1.set_xscale("log")
        a1.set_xlabel("frequency (Hz)")
        a1.set_ylabel("amplitude of p_n (Pa)")
        a1.legend(fontsize=6, title="after opening", title_fontsize=7)
        ratio = analysis.mobilised_friction(p, h["p_s"][sel])
        a2.plot(t - t_open, ratio, "k-", lw=0.6)
        top = float(np.nanmax(ratio, initial=0.0))
        if self.scene is not None and self.scene.wall.friction == "coulomb":
            a2.axhline(self.scene.wall.mu, color="r", ls="--", lw=1, label=f"μ = {self.scene.wall.mu:g}")
            a2.legend(fontsize=7)
            top = max(top, self.scene.wall.mu)
        # from zero, no offset: a wall sliding throughout sits at μ to round-off, which an
        # autoscaled axis would draw as a band 1e-13 wide about "+2.67e-1"
        a2.set_ylim(0.0, 1.25 * top if top > 0.0 else 1.0)
        a2.ticklabel_format(axis="y", useOffset=False)
        a2.set_xlabel("time after opening (s)")
        a2.set_ylabel("mobilised friction |p_s| / p_n")
        for a in (a1, a2):
            a.grid(alpha=0.3)
        self._save(fig, "wall_dynamics.png", f"At z = {e[1]:.2f} m: spectra of six consecutive windows (Fig. 4-12) "
                   "and the mobilised friction (Figs. 4-13/4-14).")

    PULSE_WINDOW = 10.0  # s after the start-up over which pulse_travel follows the pulses
    PULSE_MIN_LOAD = 0.05  # stations pressed by less than this fraction of the most pressed one are left out

    def pulse_travel(self) -> None:
        """Whether the discharge's pulses run along the wall, and how fast: per pair of
        neighbouring stations the lag of the upper one's pulses above 1 Hz behind the lower
        one's (:func:`analysis.pulse_travel`) over the first ``PULSE_WINDOW`` s after the
        start-up (pulse_travel.csv), their speed against the solid's elastic wave speeds, and
        a space-time picture of the pulses (wall_spacetime.png)."""
        import matplotlib.pyplot as plt

        from silo_dolfinx.output.schema import PULSE_TRAVEL

        d = self._discharge_history()
        if d is None:
            self.missing.append("pulse travel (needs a discharge and wall_history.csv)")
            return
        h, t_open, t1 = d
        t0 = self._settled(t_open, t1)
        t, z, p = analysis.station_matrix(h, "station", "p_n")
        s = analysis.station_matrix(h, "station", "s")[2][:, -1]
        win = (t >= t0) & (t <= min(t1, t0 + self.PULSE_WINDOW))
        mean = p[:, win].mean(axis=1) if win.any() else np.zeros(z.size)
        keep = mean >= self.PULSE_MIN_LOAD * mean.max() if mean.size and mean.max() > 0 else np.zeros(z.size, bool)
        order = np.argsort(s)
        keep[order[1:]] &= np.diff(s[order]) > 0  # one of two stations at the same place
        if win.sum() < 16 or keep.sum() < 2:
            self.missing.append("pulse travel (fewer than two loaded stations or 16 samples after the start-up)")
            return
        t, z, s, p = t[win], z[keep], s[keep], p[keep][:, win]
        r = analysis.pulse_travel(t, s, p)
        z_of = dict(zip(s, z))
        zl, zh = np.array([z_of[x] for x in r.s_low]), np.array([z_of[x] for x in r.s_high])
        ds = r.s_high - r.s_low
        with np.errstate(divide="ignore"):
            speed = np.where(r.lag != 0, ds / np.where(r.lag != 0, r.lag, 1.0), np.inf)
        self._table(PULSE_TRAVEL, [[zl[i], zh[i], ds[i], r.lag[i], r.correlation[i], speed[i]] for i in range(ds.size)])
        m = self.scene.material if self.scene is not None else None
        c_p = theory.confined_wave_speed(m.youngs_modulus, m.poisson_ratio, m.density) if m is not None else np.nan
        c_s = theory.shear_wave_speed(m.youngs_modulus, m.poisson_ratio, m.density) if m is not None else np.nan
        tracked = r.tracked
        span = (f"{t0 - t_open:.3g}–{t[-1] - t_open:.3g} s after the opening, dominant {r.frequency:.3g} Hz")
        if not tracked.any():
            text = (f"no pair of neighbouring stations correlated ≥ {r.min_correlation:g}: the pulses are local "
                    f"(slip-stick of a stretch of wall, chatter), not a wave along it ({span})")
        else:
            v = r.speed
            where = f"z {zl[tracked].min():.2f}–{zh[tracked].max():.2f} m"
            how = ("in phase (lags below a sample: a motion of the whole fill, or a standing mode)" if not np.isfinite(v)
                   else f"{'up' if v > 0 else 'down'} the wall at {abs(v):.3g} m/s")
            text = (f"{how} over {where} ({int(tracked.sum())} of {tracked.size} station pairs correlated ≥ "
                    f"{r.min_correlation:g}, median {np.median(r.correlation[tracked]):.2f}); the solid's elastic "
                    f"waves: √(M/ρ) {c_p:.3g} m/s, √(G/ρ) {c_s:.3g} m/s ({span})"
                    + self._pulse_growth(t, s, p, r.frequency))
        self.numbers.append(("the pulses above 1 Hz along the wall", text))
        # the picture: the pulses (p_n less its part below 1 Hz) against height and time over a
        # few periods, with the measured speed and the elastic waves' drawn from the lowest station
        from scipy import signal as sps

        show = t <= t[0] + min(8.0 / r.frequency, t[-1] - t[0]) if np.isfinite(r.frequency) else t <= t[-1]
        x = sps.detrend(p, axis=1, type="linear")
        x = np.array([row - analysis.low_pass(t, row) for row in x])[:, show]
        fig, ax = plt.subplots(figsize=(10, 5))
        lim = float(np.max(np.abs(x))) / 1e3 or 1.0
        mesh = ax.pcolormesh(t[show] - t_open, z, x / 1e3, cmap="RdBu_r", vmin=-lim, vmax=lim, shading="nearest")
        fig.colorbar(mesh, ax=ax, label="p_n above 1 Hz (kPa)")
        ta = t[show][0] - t_open
        dz_ds = (z.max() - z.min()) / (s.max() - s.min())  # the wall's rise per length along it
        for speed_s, style, label in ((r.speed, "k-", "measured"), (c_p, "k--", "√(M/ρ)"), (c_s, "k:", "√(G/ρ)")):
            if np.isfinite(speed_s) and speed_s != 0:
                ax.plot([ta, ta + (s.max() - s.min()) / abs(speed_s)],
                        [z.min(), z.max()] if speed_s > 0 else [z.max(), z.min()], style, lw=1.2,
                        label=f"{label}: {abs(speed_s):.3g} m/s along the wall")
        ax.set_ylim(z.min() - 0.02 * dz_ds, z.max() + 0.02 * dz_ds)
        ax.set_xlabel("time after opening (s)")
        ax.set_ylabel("station height z (m)")
        ax.legend(fontsize=7, loc="upper right")
        self._save(fig, "wall_spacetime.png", "The wall pressure's pulses (above 1 Hz) against height and time: a wave "
                   "runs along the wall as slanted stripes (the lines: the measured speed and the solid's elastic "
                   "waves), a motion of the whole fill as vertical ones, slip-stick as patches.")

    ZONE_LAG = 1.0  # s: how far apart in time a band's failing and the wall's slow pulse are looked for

    def shear_zones(self) -> None:
        """Where the solid fails during the discharge, and whether the wall's slow pulses follow
        it (shear_zones.csv): the share of each height band's loaded solid at yield mapped in
        height and time - the thesis' contours of q/p (Figs. 4-19, 8-13) as one picture, where a
        zone that moves is seen moving - and the share separated beside it; after the start-up,
        the band whose failing swings most below 1 Hz, and (:meth:`_zone_following`) whether
        the < 1 Hz part of p_n follows any band's failing: the thesis' account of the slow
        fluctuation, "each slip corresponds to a reduced stress ratio in the arching shear
        zone", as a number with its chance level."""
        import matplotlib.pyplot as plt

        zones = read_csv(self.folder / "shear_zones.csv")
        t_open, t1 = self._stage_times().get("discharge", (None, None))
        if zones is None or t_open is None or not t1 > t_open:
            self.missing.append("shear zones (needs a discharge and shear_zones.csv: output.zone_bands > 0 and a "
                                "plastic solid)")
            return
        n = int(zones["band"].max()) + 1
        grid = {k: zones[k].reshape(-1, n).T for k in ("t", "volume", "separated_fraction", "yielded_fraction")}
        t = grid["t"][0]
        win = (t >= t_open) & (t <= t1)
        if win.sum() < 16:
            self.missing.append("shear zones (fewer than 16 discharge samples)")
            return
        edges = np.append(zones["z_low"][:n], zones["z_high"][n - 1])
        zc = 0.5 * (edges[:-1] + edges[1:])
        t, yielded, separated = t[win], grid["yielded_fraction"][:, win], grid["separated_fraction"][:, win]
        loaded = grid["volume"][:, win] * (1.0 - separated)
        share = np.nansum(yielded * loaded) / np.nansum(np.where(np.isfinite(yielded), loaded, 0.0))
        per_band = np.nanmean(yielded, axis=1) if np.any(np.isfinite(yielded)) else np.full(n, np.nan)
        self.numbers.append(("shear zones: the loaded solid at yield over the discharge (the band mean ranging)",
                             f"{100 * share:.0f} % ({100 * np.nanmin(per_band):.0f} % at z "
                             f"{zc[np.nanargmin(per_band)]:.2f} m to {100 * np.nanmax(per_band):.0f} % at z "
                             f"{zc[np.nanargmax(per_band)]:.2f} m)"))
        front = self._failure_front(t - t_open, edges, yielded)
        calm = self._calm_stretch(self._settled(t_open, t1), t1)
        settled = (t >= calm[0]) & (t <= calm[1])
        whole = np.all(np.isfinite(yielded[:, settled]), axis=1) & (np.ptp(yielded[:, settled], axis=1) > 0)
        follow = None
        if settled.sum() >= 16 and t[settled][-1] - t[settled][0] >= 4.0 / analysis.LOW_CUTOFF and whole.any():
            ts = t[settled]
            swing = np.array([analysis.low_frequency_fluctuation(ts, yielded[k, settled]) if whole[k]
                              else (np.nan, np.nan) for k in range(n)])
            k = int(np.nanargmax(swing[:, 0]))
            self.numbers.append(("shear zones: the band failing most intermittently below 1 Hz",
                                 f"z {edges[k]:.2f}–{edges[k + 1]:.2f} m, its yielded share swinging by RMS "
                                 f"{100 * swing[k, 0]:.1f} % {self._low_frequency(swing[k, 1], ts[-1] - ts[0])} "
                                 f"({calm[0] - t_open:.3g}–{calm[1] - t_open:.3g} s after the opening"
                                 + (", the longest stretch without a re-mesh)"
                                    if calm != (self._settled(t_open, t1), t1) else ")")))
            follow = self._zone_following(t, edges, {"yielded": yielded, "separated": separated},
                                          (t_open, self._settled(t_open, t1), t1))
        else:
            self.missing.append("shear zones below 1 Hz (needs 4 s of discharge after the start-up)")
        fig, axes = plt.subplots(3 if follow else 2, 1, figsize=(10, 9 if follow else 6.5), sharex=True)
        t_edges = np.concatenate([[t[0]], 0.5 * (t[1:] + t[:-1]), [t[-1]]]) - t_open  # each sample's span
        for ax, values, label in ((axes[0], yielded, "share of the loaded solid at yield"),
                                  (axes[1], separated, "share separated (stress-free)")):
            mesh = ax.pcolormesh(t_edges, edges, values, cmap="magma", vmin=0.0, vmax=1.0, shading="flat")
            fig.colorbar(mesh, ax=ax, label=label)
            ax.set_ylabel("height z (m)")
        if front is not None:
            axes[0].plot(front[0], front[1], "o", color="c", ms=3,
                         label=f"failure front ({100 * analysis.FRONT_ONSET:.0f} % of a band at yield)")
            axes[0].legend(fontsize=7, loc="lower right")
        if follow:
            ax, (name, z_station, kind, k, lag, r, chance, slow) = axes[2], follow
            ax.plot(slow[0] - t_open, slow[1] / 1e3, "k-", lw=0.9, label=f"p_n at {name}, < 1 Hz")
            ax.set_ylabel("p_n below 1 Hz (kPa)")
            twin = ax.twinx()
            twin.plot(slow[0] - t_open, 100 * slow[2], "C1-", lw=0.9,
                      label=f"{kind} share, z {edges[k]:.2f}–{edges[k + 1]:.2f} m, < 1 Hz (r {r:+.2f} at lag "
                      f"{lag:+.2f} s; chance {chance:.2f})")
            twin.set_ylabel(f"{kind} share below 1 Hz (%)")
            for a in (ax, twin):
                a.legend(fontsize=7, loc="upper left" if a is ax else "upper right")
            axes[0].axhline(z_station, color="w", lw=0.8, ls="--")
        axes[-1].set_xlabel("time after opening (s)")
        self._save(fig, "shear_zones.png", "Where the solid fails, against height and time: the share of each band's "
                   "loaded solid at yield (the thesis' shear failure zone, q/p at its limit) and the share separated; "
                   + ("below: the slow part of the wall pressure where it is largest (dashed line above) beside the "
                      "band share it follows most closely, with the chance level of that search (zone_following.csv: "
                      "every station)." if follow else ""))

    def _remeshes(self) -> list[float]:
        """When the discharge was re-meshed (summary.json's rezones)."""
        return [r["t"] for st in self.summary.get("stages", []) if st["name"] == "discharge"
                for r in st.get("rezones", [])]

    STEP_WINDOW = 0.5  # s: a re-mesh's step is the change of the 0.5-s means either side (2.5 periods of a 5-Hz wave)

    def remesh_steps(self) -> None:
        """Whether the re-meshes of the discharge stepped the wall pressure (remesh_steps.csv,
        :func:`analysis.event_steps` per station and re-mesh, over the discharge after its
        start-up): a re-mesh carries the state onto a new mesh by overlaps, first-order, and
        where a steep state meets a new mesh - the outlet zone's stress-free pockets - it can
        change what the wall carries. The key number counts the station-re-meshes that stepped
        beyond what one instant in a hundred does without one."""
        from silo_dolfinx.output.schema import REMESH_STEPS

        d = self._discharge_history()
        if d is None or not self._remeshes():
            return  # nothing was re-meshed: nothing to measure, nothing missing
        h, t_open, t1 = d
        t0 = self._settled(t_open, t1)
        rows = []
        for k in np.unique(h["station"]):
            sel = (h["station"] == k) & (h["t"] >= t_open)
            if sel.sum() < 16:
                continue
            st = analysis.event_steps(h["t"][sel], h["p_n"][sel], self._remeshes(), self.STEP_WINDOW, t0, t1)
            z = float(np.mean(h["z"][sel]))
            rows += [[tr - t_open, z, s, st.typical, e] for tr, s, e in zip(self._remeshes(), st.step, st.exceedance)
                     if np.isfinite(s)]
        if not rows:
            self.missing.append("re-mesh steps (no re-mesh at least 0.5 s inside the measured discharge)")
            return
        self._table(REMESH_STEPS, rows)
        stepped = [r for r in rows if r[4] < 0.01]
        text = f"{len(stepped)} of {len(rows)} station-re-meshes beyond 1 % exceedance (chance alone: 1 in 100)"
        if stepped:
            worst = max(stepped, key=lambda r: abs(r[2]) / r[3])
            text += (f"; the largest {worst[2]:+.3g} Pa ({abs(worst[2]) / worst[3]:.1f} × the typical step) at "
                     f"z = {worst[1]:.2f} m, {worst[0]:.3g} s after opening; at z "
                     + ", ".join(f"{z:.2f}" for z in sorted({r[1] for r in stepped})) + " m")
        self.numbers.append((f"re-meshes ({len(self._remeshes())}): the wall pressure stepped by them "
                             f"(0.5-s means either side, against the discharge's own steps)", text))

    def _calm_stretch(self, t0: float, t1: float) -> tuple[float, float]:
        """The longest stretch of [t0, t1] without a re-mesh. A re-mesh steps the stress field -
        the outlet zone's stress-free pockets most (ch. 4's 60-s run: the pocket 0.13-0.40 m above
        the outlet switched on or off at four of its five) - and the pressures with it: a step in
        two records at once, which no measure of their slow parts should read as their dynamics
        (the lowest station's r -0.89 with that band's share was the steps)."""
        cuts = np.array([t0, *[x for x in self._remeshes() if t0 < x < t1], t1])
        i = int(np.argmax(np.diff(cuts)))
        return float(cuts[i]), float(cuts[i + 1])

    def _failure_front(self, t, edges, yielded):
        """How the failure that starts at the outlet climbs the fill after the opening - the
        thesis' "switch of the stress state propagated from the bottom to the top" (§4.3.1):
        :func:`analysis.failure_front` of the bands' yielded shares (times after the opening,
        ``t``), with the number for report.md (its speed fitted over all of it and over its
        first and last thirds, against the solid's confined wave speed: a front carried by the
        opening's stress wave would climb at it; how its height grows with time,
        :func:`analysis.front_growth`); (times, band centres) for the figure, or None
        where fewer than three bands are reached."""
        ta, za, fresh = analysis.failure_front(t, 0.5 * (edges[:-1] + edges[1:]), yielded)
        if ta.size < 3:
            return None
        third = max(2, za.size // 3)
        speeds = [analysis.front_speed(ta[part], za[part])
                  for part in (slice(None), slice(third), slice(-third, None))]
        exponent, diffusing = analysis.front_growth(ta, za - edges[0])
        m = self.scene.material if self.scene is not None else None
        c_p = theory.confined_wave_speed(m.youngs_modulus, m.poisson_ratio, m.density) if m is not None else np.nan
        self.numbers.append((f"shear zones: the failure front after the opening ({100 * analysis.FRONT_ONSET:.0f} % "
                             "of a band at yield)",
                             f"reaches z {za[0]:.2f} m at {ta[0]:.3g} s and z {za[-1]:.2f} m at {ta[-1]:.3g} s "
                             f"({ta.size} of {fresh} bands elastic at the opening; passed once every band below has "
                             f"failed): climbing at {speeds[0]:.3g} m/s over all, {speeds[1]:.3g} m/s in its lowest "
                             f"third and {speeds[2]:.3g} m/s in its highest (the confined wave speed √(M/ρ): "
                             f"{c_p:.3g} m/s)" + (f"; its height above the outlet grows as t^{exponent:.2f} (½: a "
                                                  f"diffusing front, height²/t {diffusing:.3g} m²/s; 1: a constant speed)"
                                                  if np.isfinite(exponent) else "; its bands failing at once")))
        return ta, za

    def _zone_following(self, t, edges, shares: dict, times):
        """Whether the < 1 Hz part of p_n at each wall station, after its switch
        (:meth:`_after_switch`) and between re-meshes (the longest stretch), follows the slow part
        of a band's failing or separating (the ``shares`` of each band with a whole record
        there): the best |r| of
        :func:`analysis.best_lag` within ± ``ZONE_LAG`` s over the bands and both shares, against
        its chance level (:func:`analysis.chance_correlation`) - zone_following.csv, and the
        numbers for report.md (the station where the slow part is largest, the thesis' concern,
        and the stations whose link beats chance). For the figure: (station's name, height,
        share, band, lag, r, chance level, (times, the two slow parts)) of the station where the
        slow part is largest; None without a station with a long enough record."""
        from silo_dolfinx.output.schema import ZONE_FOLLOWING

        h = read_csv(self.folder / "wall_history.csv")
        if h is None:
            return None
        found = []
        for k in np.unique(h["station"]):
            window = self._after_switch(h, k, times)
            if window is None or window[0] is None:
                continue
            tk, tz = self._calm_stretch(window[1], times[2])
            sel = window[0] & (h["t"] >= tk) & (h["t"] <= tz)
            inside = (t >= tk) & (t <= tz)
            rows = [(kind, b) for kind, v in shares.items() for b in range(v.shape[0])
                    if np.all(np.isfinite(v[b, inside])) and np.ptp(v[b, inside]) > 0]
            if inside.sum() < 16 or t[inside][-1] - tk < 4.0 / analysis.LOW_CUTOFF or not rows:
                continue
            tw = t[inside]
            ts, slow_p = analysis.slow_part(tw, np.interp(tw, h["t"][sel], h["p_n"][sel]))
            slow = np.array([analysis.slow_part(tw, shares[kind][b, inside])[1] for kind, b in rows])
            m = max(1, int(round(self.ZONE_LAG * (ts.size - 1) / (ts[-1] - ts[0]))))
            pairs = [analysis.best_lag(slow_p, row, m) for row in slow]
            j = int(np.nanargmax([abs(r) for _, r in pairs]))
            chance = analysis.chance_correlation(slow_p, slow, m)
            z_k = float(np.mean(h["z"][sel]))
            found.append(dict(z=z_k, name=self._station(k, z_k), start=tk - times[0], end=tz - times[0],
                              cut=(tk, tz) != (window[1], times[2]),
                              rms=analysis.low_frequency_fluctuation(h["t"][sel], h["p_n"][sel])[0], kind=rows[j][0],
                              band=rows[j][1], lag=pairs[j][0] * (ts[-1] - ts[0]) / (ts.size - 1),
                              edge=abs(pairs[j][0]) >= m, r=pairs[j][1], chance=chance, rows=len(rows),
                              above=sum(1 for _, x in pairs if abs(x) > chance), slow=(ts, slow_p, slow[j])))
        if not found:
            return None
        self._table(ZONE_FOLLOWING, [[f["z"], f["start"], f["end"], f["rms"], int(f["kind"] == "separated"),
                                      edges[f["band"]], edges[f["band"] + 1], f["lag"], f["r"], f["chance"],
                                      f["above"], f["rows"]] for f in found])

        def link(f, named: bool = True) -> str:
            edge = " - at the search's edge: no peak within it" if f["edge"] else ""
            order = "in step" if f["lag"] == 0 else "the band follows" if f["lag"] > 0 else "the band leads"
            return ((f"{f['name']}: " if named else "") + f"the {f['kind']} share of z {edges[f['band']]:.2f}–"
                    f"{edges[f['band'] + 1]:.2f} m: r {f['r']:+.2f} at a lag of {f['lag']:+.2f} s{edge} ({order}); "
                    f"chance level |r| {f['chance']:.2f}")

        largest = max(found, key=lambda f: f["rms"])
        self.numbers.append((f"shear zones: the < 1 Hz part of p_n where it is largest, at {largest['name']} "
                             f"(RMS {largest['rms']:.3g} Pa {largest['start']:.3g}–{largest['end']:.3g} s after the "
                             "opening"
                             + (", the longest stretch without a re-mesh" if largest["cut"] else "")
                             + "), follows most closely",
                             f"{link(largest, named=False)} (95 % of the same search against the wall's record shifted "
                             f"in time), exceeded at {largest['above']} of {largest['rows']} band records"))
        beaten = [f for f in found if abs(f["r"]) > f["chance"]]
        widest = (f"; by the widest margin {link(max(beaten, key=lambda f: abs(f['r']) - f['chance']))}"
                  if beaten else "")
        self.numbers.append(("shear zones: wall stations whose < 1 Hz pressure follows a band's failing or "
                             "separating beyond chance (r < 0: the pressure rises as the share falls)",
                             f"{len(beaten)} of {len(found)} (chance alone: 1 in 20){widest}"))
        return (largest["name"], largest["z"], largest["kind"], largest["band"], largest["lag"], largest["r"],
                largest["chance"], largest["slow"])

    WAVE_RESIDUAL = 20.0  # degrees: a phase residual above this is no travelling wave (tests: 0.02° clean,
    #                       88° standing; the ch. 7 wave 4-13°)

    def _pulse_growth(self, t, s, p, frequency: float) -> str:
        """How the pulses' amplitude changes along the wall at their dominant frequency (± 20 %,
        :func:`analysis.mode_shape` against the highest station, :func:`analysis.travelling_wave`
        along the wall), beside eq. 5-1's 2μk/D for a vertical wall (k = ν/(1 − ν), the elastic
        fill's ratio of increments): a wave the sliding wall feeds grows as it climbs (thesis
        ch. 5). Empty where the window is too short for it."""
        try:
            m = analysis.mode_shape(t, p, (0.8 * frequency, 1.2 * frequency), reference=int(np.argmax(s)))
            w = analysis.travelling_wave(s, m.ratio, frequency)
        except ValueError:
            return ""
        residual = np.degrees(w.phase_residual)
        phases = (f"phase speed {w.speed:.3g} m/s, phase residual {residual:.0f}°"
                  if residual <= self.WAVE_RESIDUAL else
                  f"the phases fit no one travelling wave, residual {residual:.0f}°: a standing wave, or stations "
                  f"too far apart for its wavelength")
        text = (f"; at {frequency:.3g} Hz ± 20 % its amplitude changes by {w.growth:+.2f} /m along the wall "
                f"(×{np.exp(w.growth * (s.max() - s.min())):.2g} over the stations; {phases}")
        sc = self.scene
        mu = sc.wall.get("mu", sc.wall.get("mu_static", 0.0)) if sc is not None else 0.0
        if mu > 0 and sc.geometry.shape in ("flat_bottom", "bin_hopper"):
            k = sc.material.poisson_ratio / (1.0 - sc.material.poisson_ratio)
            growth = theory.wensrich_exponent(2 * sc.geometry.radius, mu, k)
            text += f"; eq. 5-1 for the bin, 2μk/D with k = ν/(1 − ν): {growth:.2f} /m"
        return text + ")"

    RISE = 0.01  # s a rarefaction front takes to pass a point (eq. 5-17's 5-ms pull and its smearing)
    SATURATED = 0.8  # σ⁺ / the pre-wave stress beyond which the wave is no longer small (rarefaction)

    def rarefaction(self) -> dict | None:
        """Thesis ch. 5: the rarefaction wave a controlled pull of a column's base launches, at
        the interior points (rarefaction.csv): σ⁺ before the top's reflection, σ⁺/σ⁺0 with
        σ⁺0 = ρ c u0, eq. 5-1/5-14/5-15 beside it; the growth exponent fitted both through σ⁺0
        and with a free intercept (Figs. 5-6, 5-11/5-12), and S0 of eq. 5-18 against the theory;
        returns them (None for a run that is not a column pulled at its base)."""
        sc = self.scene
        h = read_csv(self.folder / "point_history.csv")
        if sc is None or sc.geometry.shape != "column" or sc.discharge.mode != "controlled" or h is None:
            return None  # not a ch. 5 column: nothing is missing
        h = {k: v[h["r"] == 0.0] for k, v in h.items()}  # the axis points (others: profiles)
        import matplotlib.pyplot as plt

        from silo_dolfinx.output.schema import RAREFACTION

        m, g = sc.material, sc.geometry
        c = theory.confined_wave_speed(m.youngs_modulus, m.poisson_ratio, m.density)
        t_pull = self._stage_times()["discharge"][0]
        sigma0 = m.density * c * sc.discharge.velocity
        t, z, s = analysis.station_matrix(h, "point", "stress_zz", -1.0)
        pull = analysis.Pull(t_pull, c, g.height, self.RISE)
        # the theory is for a wave small against the stress it relieves: the fit stops below the
        # first point where σ⁺ has taken SATURATED of the stress there (a rarefaction cannot
        # relieve more than all of it; FE-2's 10.5 kPa is 2.5 σ⁺0)
        pre = s[:, np.searchsorted(t, t_pull, side="right") - 1]
        every = analysis.rarefaction_growth(t, z, s, pull, (0.5, None))
        saturated = np.nonzero((every.amplitude > self.SATURATED * pre) & (z >= 0.5))[0]
        fit = (0.5, float(z[saturated[0]]) - 1e-9 if saturated.size else None)
        through = analysis.rarefaction_growth(t, z, s, pull, fit, sigma0)
        free = analysis.rarefaction_growth(t, z, s, pull, fit)
        # the theory with the k the run reached (as the thesis evaluates k from its own runs)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = h["stress_rr"] / h["stress_zz"]
        k_axis = float(np.nanmedian([ratio[(h["point"] == i) & (h["t"] <= t_pull)][-1]
                                     for i, zi in zip(np.unique(h["point"]), z) if zi > 0.5]))
        k = m.poisson_ratio / (1.0 - m.poisson_ratio)
        D, alpha = 2.0 * g.base_radius, g.half_angle
        ok = np.isfinite(through.amplitude)
        predicted, taper = np.full(z.size, np.nan), np.full(z.size, np.nan)
        predicted[ok] = theory.wave_growth(z[ok], D, sc.wall.mu, k_axis, alpha)
        taper[ok] = theory.taper_wave_growth(z[ok], D, sc.wall.mu, k_axis, alpha)
        self._table(RAREFACTION, [[i, z[i], through.amplitude[i], through.normalised[i], predicted[i], taper[i]]
                                  for i in range(z.size)])
        s0 = analysis.representative_deviation(through.amplitude[ok], sigma0 * predicted[ok], sigma0)
        s0_taper = analysis.representative_deviation(through.amplitude[ok], sigma0 * taper[ok], sigma0)
        eq51 = theory.wensrich_exponent(D, sc.wall.mu, k_axis)
        # the theory starts from a sliding wall (τ = μ p_n); a wall below that first re-mobilises
        # under the wave instead of sliding, and the wave grows less
        mobilised = self._mobilised(t_pull, fit)
        self.numbers += [
            ("k = σ_rr/σ_zz on the axis at the pull (median above 0.5 m); intended ν/(1 − ν)", f"{k_axis:.3f}; {k:.3f}"),
            ("wall friction mobilised at the pull, p_s/(μ p_n) over the fit window: mean, least",
             f"{np.mean(mobilised):.3f}, {np.min(mobilised):.3f}"),
            ("rarefaction growth exponent, through σ⁺0 = ρ c u0 / free intercept (1/m)",
             f"{through.exponent:.3f} ± {through.stderr:.3f} / {free.exponent:.3f} ± {free.stderr:.3f} "
             f"(x {through.window[0]:.2f}–{through.window[1]:.2f} m; eq. 5-1 with that k, α = 0: {eq51:.3f})"),
            ("S0 (eq. 5-18) against eq. 5-1/5-14/5-15; against the 1-D model with the taper's lateral strain",
             f"{s0:.3f}; {s0_taper:.3f}"),
        ]
        fig, ax = plt.subplots(figsize=(7, 5))
        ax.plot(z[ok], through.normalised[ok], "ko", ms=4, label="σ⁺/σ⁺0 on the axis (ours)")
        xs = np.linspace(0.0, z[ok].max(), 100)
        ax.plot(xs, theory.wave_growth(xs, D, sc.wall.mu, k_axis, alpha), "r-",
                label=f"eq. 5-{'1' if alpha == 0 else ('14' if alpha > 0 else '15')} (α = {alpha:g}°)")
        if alpha != 0.0:
            ax.plot(xs, theory.taper_wave_growth(xs, D, sc.wall.mu, k_axis, alpha), "b-",
                    label="1-D model with the taper's lateral strain (G^(kμ/tan α − 1))")
        ax.plot(xs, np.exp(through.exponent * xs), "k--", lw=0.8, label=f"fit: exp({through.exponent:.3f} x)")
        ax.set_xlabel("distance travelled x (m)")
        ax.set_ylabel("σ⁺ / σ⁺0")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        self._save(fig, "rarefaction.png", f"Growth of the rarefaction wave up the column, σ⁺0 = ρ c u0 = "
                   f"{sigma0:.0f} Pa (Figs. 5-6, 5-12).")
        return {"k_axis": k_axis, "k": k, "through": through, "free": free, "s0": s0, "s0_taper": s0_taper,
                "eq51": eq51,  # eq51: with k_axis
                "mobilised": float(np.mean(mobilised)), "mobilised_least": float(np.min(mobilised))}

    def _mobilised(self, t: float, window: tuple) -> np.ndarray:
        """p_s/(μ p_n) at time t at the wall stations whose height lies in window (lo, hi|None)."""
        wall = read_csv(self.folder / "wall_history.csv")
        if wall is None:
            return np.array([np.nan])
        times, z, pn = analysis.station_matrix(wall, "station", "p_n")
        _, _, ps = analysis.station_matrix(wall, "station", "p_s")
        i = np.searchsorted(times, t, side="right") - 1
        inside = (z >= window[0]) & (z <= (np.inf if window[1] is None else window[1]))
        return ps[inside, i] / (self.scene.wall.mu * pn[inside, i])

    def outlet(self) -> None:
        import matplotlib.pyplot as plt

        d = read_csv(self.folder / "outlet.csv")
        if d is None or d["t"].size < 2:
            self.missing.append("outlet flow (outlet.csv: written during discharge)")
            return
        fig, (a1, a2, a3) = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
        a1.plot(d["t"], d["mean_outlet_velocity"], "k-", lw=0.8)
        a1.set_ylabel("mean outlet velocity (m/s)")
        a1.grid(alpha=0.3)
        a3.set_ylabel("V_dis (%, eq. 6-2)")
        a3.grid(alpha=0.3)
        if (v := self._v_dis()) is not None:
            t, vd = v
            a3.plot(t, vd, "k-", lw=1)
            # steady: every later 1-s window's mass flow within 10 % of their mean
            ts = analysis.steady_flow_start(t, d["discharged_mass"], self.STEADY_WINDOW, self.STEADY_TOLERANCE)
            self.numbers.append(("discharged V_dis (eq. 6-2, in mass) at the end", f"{vd[-1]:.3g} %"))
            self.numbers.append((f"steady flow from (every later {self.STEADY_WINDOW:g}-s window's mass flow "
                                 f"within {100 * self.STEADY_TOLERANCE:g} % of their mean)",
                                 "not reached" if np.isnan(ts) else
                                 f"t = {ts:.3g} s, V_dis {np.interp(ts, t, vd):.3g} %"))
            if np.isfinite(ts):
                for a in (a2, a3):
                    a.axvline(ts, color="g", ls=":", lw=1)
        a2.plot(d["t"], d["mass_flow_rate"], "k-", lw=0.8, label="mass leaving (simulation)")
        if "nominal_mass_flow_rate" in d:
            a2.plot(d["t"], d["nominal_mass_flow_rate"], "b-", lw=0.6, alpha=0.6,
                    label="nominal ρ0·A·v (the thesis' definition)")
        sc = self.scene
        if sc is not None and sc.geometry.shape != "column":
            D0 = 2 * sc.geometry.outlet_radius
            Wb = theory.beverloo(sc.material.density, D0, gravity=sc.loads.gravity)
            a2.axhline(Wb, color="r", ls="--", label=f"Beverloo {Wb:.3g} kg/s")
            steady = d["t"] > d["t"][0] + 0.5 * (d["t"][-1] - d["t"][0])
            if np.any(steady):
                mean = float(np.nanmean(d["mass_flow_rate"][steady]))
                self.numbers.append(("mean mass flow (mass leaving), second half of discharge",
                                     f"{mean:.4g} kg/s (Beverloo {Wb:.4g} kg/s, {100 * (mean - Wb) / Wb:+.1f} %)"))
                if "nominal_mass_flow_rate" in d:
                    nom = float(np.nanmean(d["nominal_mass_flow_rate"][steady]))
                    self.numbers.append(("nominal mass flow ρ0·A·v (the thesis' definition), second half",
                                         f"{nom:.4g} kg/s ({100 * (nom - Wb) / Wb:+.1f} % from Beverloo)"))
                    if mean > self.DENSER_OUTFLOW * nom:
                        self.numbers.append(("the solid leaves denser than it was placed", self._denser_outflow(mean, nom)))
        a3.set_xlabel("time t (s)")
        a2.set_ylabel("mass flow rate (kg/s)")
        a2.legend(fontsize=8)
        a2.grid(alpha=0.3)
        self._save(fig, "outlet.png", "Outlet velocity, mass flow rate against Beverloo, and the discharged "
                   "volume V_dis (dotted: steady flow from there).")

    DENSER_OUTFLOW = 1.1  # mass leaving over ρ0·A·v beyond which the outlet's solid is compacted

    @staticmethod
    def _denser_outflow(mean: float, nominal: float) -> str:
        """Why a mass leaving well above ρ0·A·v is not to be trusted, and what to change: a
        flowing solid at an outlet is looser than placed, so the excess is compaction without
        the stress that would go with it. Its known cause - one-point cells whose volumetric
        strain was the centre's, not the cell's volume change (+25 to +41 % density at 0-500 Pa
        on coarse unstructured meshes around a small outlet) - is fixed since 2026-12-07
        (kernels.mean_gradients_q1; docs/validation/ch6.md); the check stays for older results
        and causes not yet seen."""
        return (f"**check the outlet's cells**: the mass leaving ({mean:.4g} kg/s) is {100 * (mean / nominal - 1):.0f} % "
                "above ρ0·A·v - the outlet's cells carry more density than any stress in them accounts for (a flowing "
                "solid leaves looser than placed). One-point cells did this before 2026-12-07 (their strain missed part "
                "of the cell's volume change; fixed: re-run such results); otherwise look at the density field by the "
                "outlet and refine geometry.element_size there (docs/validation/ch6.md). Read the flow from ρ0·A·v "
                "meanwhile.")

    def mesh_quality(self) -> None:
        """Critical-element aspect ratio against the fall of the top surface (Fig. 3-18)."""
        import matplotlib.pyplot as plt

        d = read_csv(self.folder / "mesh_quality.csv")
        if d is None:
            return  # no discharge: nothing to show, nothing missing
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
        a1.plot(1e3 * d["top_drop"], d["max_aspect_ratio"], "k-", lw=1)
        a1.set_xlabel("top-surface drop on the axis (mm)")
        a1.set_ylabel("max element aspect ratio")
        a1.grid(alpha=0.3)
        a2.plot(d["t"], d["min_scaled_jacobian"], "k-", lw=1)
        a2.set_xlabel("time t (s)")
        a2.set_ylabel("min scaled Jacobian (> 0: no inverted cell)")
        a2.grid(alpha=0.3)
        self.numbers.append(("max aspect ratio, start → worst", f"{d['max_aspect_ratio'][0]:.3g} → "
                             f"{np.nanmax(d['max_aspect_ratio']):.3g}"))
        self.numbers.append(("min scaled Jacobian during discharge", f"{np.nanmin(d['min_scaled_jacobian']):.3g}"))
        self._save(fig, "mesh_quality.png", "Mesh quality in the discharge: aspect ratio of the critical element "
                   "against the top-surface drop (thesis Fig. 3-18) and the worst scaled Jacobian.")

    def flow_pattern(self) -> None:
        """Tracer rows (coloured layers) at a few snapshot times: the flow pattern."""
        import matplotlib.pyplot as plt

        snaps = [np.load(f) for f in sorted((self.folder / "fields").glob("snapshot_*.npz"))]
        snaps = [s for s in snaps if "tracer_xy" in s.files]
        if not snaps:
            return  # no ALE discharge with tracers
        pick = [snaps[i] for i in sorted({0, len(snaps) // 3, (2 * len(snaps)) // 3, len(snaps) - 1})]
        fig, axes = plt.subplots(1, len(pick), figsize=(3.2 * len(pick), 4.5), sharey=True)
        axes = np.atleast_1d(axes)
        rows = int(max(s["tracer_row"].max(initial=0) for s in pick)) + 1
        cmap = plt.get_cmap("tab10")
        for ax, snap in zip(axes, pick):
            c = snap["corners"]
            edges = np.concatenate([c, c[:, :1]], axis=1)
            ax.plot(edges[..., 0].T, edges[..., 1].T, color="0.85", lw=0.3)
            xy, row = snap["tracer_xy"], snap["tracer_row"]
            ax.scatter(xy[:, 0], xy[:, 1], c=[cmap(int(r) % 10) for r in row], s=8)
            ax.set_title(f"t = {float(snap['t']):.3g} s ({len(snap['tracer_out_id'])} out)", fontsize=9)
            ax.set_aspect("equal")
            ax.set_xlabel("r (m)")
        axes[0].set_ylabel("z (m)")
        self.numbers.append(("tracers discharged by the last snapshot",
                             f"{len(pick[-1]['tracer_out_id'])} of {len(pick[-1]['tracer_out_id']) + len(pick[-1]['tracer_id'])}"
                             f" ({rows} rows)"))
        self._save(fig, "flow_pattern.png", "Flow pattern: tracer rows seeded at the opening, at four times "
                   "(mass flow: the rows stay flat; funnel flow: they dip at the centre).")

    def energy(self) -> None:
        import matplotlib.pyplot as plt

        d = read_csv(self.folder / "energy.csv")
        if d is None:
            self.missing.append("energy history (energy.csv)")
            return
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
        for k in ("kinetic", "elastic", "plastic", "viscous", "damping", "hourglass", "gravity_work",
                  "external_work", "contact_work"):
            if k in d and np.nanmax(np.abs(d[k])) > 0:
                a1.plot(d["t"], d[k], lw=1, label=k)
        a1.set_ylabel("energy (J)")
        a1.legend(fontsize=7, ncol=2)
        a1.grid(alpha=0.3)
        a2.semilogy(d["t"], np.maximum(d["relative_error"], 1e-12), "k-", lw=0.8)
        a2.set_ylabel("|balance| / energy scale")
        a2.set_xlabel("time t (s)")
        a2.grid(alpha=0.3, which="both")
        self._save(fig, "energy.png", "Energy terms and the balance error.")

    def _snapshot(self, t_max: float | None = None):
        """The last field snapshot (written at or before ``t_max``, if given); None if none."""
        snaps = sorted((self.folder / "fields").glob("snapshot_*.npz"))
        if t_max is not None:
            snaps = [f for f in snaps if float(np.load(f)["t"]) <= t_max + 1e-9]
        if not snaps:
            return None
        return dict(np.load(snaps[-1]))

    V_DIS = (0.1, 3.0, 6.0, 10.0)  # % discharged at which the thesis draws the FCB (Fig. 6-11)
    STEADY_WINDOW, STEADY_TOLERANCE = 1.0, 0.1  # s, fraction: the steady-flow criterion

    def _v_dis(self):
        """(t, V_dis %) of the discharge (eq. 6-2 in mass), or None."""
        d = read_csv(self.folder / "outlet.csv")
        if d is None or d["t"].size == 0 or "mass_in_silo" not in d:
            return None  # an old results folder: no V_dis
        m0 = float(d["mass_in_silo"][0] + d["discharged_mass"][0])
        return d["t"], analysis.discharged_percentage(d["discharged_mass"], m0)

    def flow_snapshots(self) -> list[tuple[float, Path]]:
        """(t, file) of the snapshots written during the discharge, in time order."""
        t0, t1 = self._stage_times().get("discharge", (np.inf, np.inf))
        out = [(float(np.load(f)["t"]), f) for f in sorted((self.folder / "fields").glob("snapshot_*.npz"))]
        return [(t, f) for t, f in out if t0 < t <= t1 + 1e-9]

    FCB_WINDOW = 5.0  # s: v_z of the flow-channel boundary averaged over the snapshots this far back

    def flow_channel(self) -> None:
        """The flow-channel boundary (v_z = 0.001 × centreline v_z at the same height, ch. 6.4.3)
        at the snapshots nearest to V_dis = 0.1, 3, 6, 10 % (Fig. 6-11) and at the last one,
        from v_z averaged over the snapshots of the FCB_WINDOW seconds up to each (one snapshot
        carries the stress waves), and its effective transition at each (meeting the wall to
        within one element; flow_channel.csv)."""
        import matplotlib.pyplot as plt

        from silo_dolfinx.output.schema import FLOW_CHANNEL

        snaps = self.flow_snapshots()
        if self.scene is None or not snaps:
            self.missing.append("flow-channel boundary (needs a field snapshot during discharge)")
            return
        vd = self._v_dis()
        times = np.array([t for t, _ in snaps])
        picks = []
        if vd is not None:
            for target in self.V_DIS:
                tt = analysis.first_time_reaching(*vd, target)
                if np.isfinite(tt):
                    picks.append(int(np.argmin(np.abs(times - tt))))
        picks = sorted(set(picks) | {len(snaps) - 1})  # and the last: a short run's most developed channel
        wall = self.scene.outline.wall
        fig, ax = plt.subplots(figsize=(5, 8))
        sw = wall.point_at(np.linspace(0, wall.length, 300))
        ax.plot(sw[:, 0], sw[:, 1], "k-", lw=1.5, label="wall")
        rows = []
        h = self.scene.geometry.element_size
        for i in picks:
            t = times[i]
            xy, v = analysis.time_averaged_velocity(f for tt, f in snaps if t - self.FCB_WINDOW < tt <= t)
            if np.nanmax(np.abs(v[:, 1])) == 0:
                continue
            z_rows, r_fcb, rw = analysis.flow_channel_from_nodes(xy, v[:, 1], wall.radius_at)
            v_here = float(np.interp(t, *vd)) if vd is not None else np.nan
            et = analysis.effective_transition(z_rows, r_fcb, rw, tolerance=h)
            rows += [[v_here, t, z, r] for z, r in zip(z_rows, r_fcb)]
            at = "" if vd is None else f" at V_dis {v_here:.2g} %"
            ax.plot(np.where(np.isnan(r_fcb), rw, r_fcb), z_rows, ".-", ms=3, label=f"t = {t:.3g} s{at}")
            self.numbers.append((f"effective transition (FCB meets the wall){at}",
                                 "none (mass flow at every height)" if np.all(np.isnan(r_fcb)) else
                                 ("does not meet the wall" if np.isnan(et) else f"{et:.3g} m")))
        if not rows:
            plt.close(fig)
            self.missing.append("flow-channel boundary (no flow in the discharge snapshots)")
            return
        self._transition_spread(snaps, wall, h)
        self._table(FLOW_CHANNEL, rows)
        ax.set_xlabel("r (m)")
        ax.set_ylabel("z (m)")
        ax.set_aspect("equal")
        ax.legend(fontsize=7)
        self._save(fig, "flow_channel.png", "Flow-channel boundary (v_z = 0.001 × centreline, ch. 6.4.3; v_z "
                   f"averaged over {self.FCB_WINDOW:g} s of snapshots) at successive discharged volumes (Fig. 6-11).")

    def _transition_spread(self, snaps, wall, h: float) -> None:
        """The effective transition of each FCB_WINDOW-s window of the discharge, as a key
        number: median and range. One window's is one sample of a boundary that wanders with
        the flow (docs/validation/ch6.md); the range over one run is what a single value can
        be trusted to."""
        t_open = self._stage_times()["discharge"][0]
        _, et = analysis.windowed_transitions(snaps, self.FCB_WINDOW, wall.radius_at, t_open, tolerance=h)
        if et.size < 2:
            return
        median, lo, hi, met = analysis.finite_spread(et)
        spread = f"median {median:.3g} m, {lo:.3g}–{hi:.3g} m" if met else "none meets the wall"
        self.numbers.append((f"effective transition over {et.size} windows of {self.FCB_WINDOW:g} s",
                             f"{spread} ({met} of {et.size} windows meet the wall)"))

    def _snapshot_times(self) -> list[float]:
        """The default times of the stress-field figures: the end of filling, the opening, 2 s
        into the discharge and its end (those the run has)."""
        st = self._stage_times()
        times = [st[k][1] for k in ("fill", "store") if k in st]
        if "discharge" in st:
            t0, t1 = st["discharge"]
            times += [t for t in (t0 + 2.0, t1) if t <= t1 + 1e-9]
        return sorted(set(times))

    def stress_fields(self, times: list[float] | None = None) -> None:
        """q/p (eq. 4-11) and the direction of the major principal stress at chosen times
        (Figs. 4-5, 4-19; default: the report's ``times``, else the stages' ends and 2 s into the
        discharge): one panel per time, from the field snapshot nearest each; the share
        of the fill whose major principal stress is within 45° of the vertical (the active,
        filling state; discharge turns the hopper's towards the horizontal, passive)."""
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection, PolyCollection

        snaps = sorted((self.folder / "fields").glob("snapshot_*.npz"))
        if not snaps or "cell_stress_rr" not in np.load(snaps[0]):
            self.missing.append("stress fields (no field snapshot with the stress components)")
            return
        t_snap = np.array([float(np.load(f)["t"]) for f in snaps])
        times = times or self.times or self._snapshot_times()
        chosen = sorted({int(np.argmin(np.abs(t_snap - t))) for t in times})
        fig, axes = plt.subplots(1, len(chosen), figsize=(3.4 * len(chosen) + 1, 6), squeeze=False, sharey=True,
                                 layout="constrained")
        for ax, i in zip(axes[0], chosen):
            d = np.load(snaps[i])
            c = d["corners"]
            sig = np.column_stack([d[f"cell_stress_{k}"] for k in ("rr", "zz", "tt", "rz")])
            cmap = plt.get_cmap("viridis").with_extremes(bad="lightgrey")  # stress-free cells: q/p undefined
            poly = PolyCollection(c, array=analysis.stress_ratio(sig, self._stress_free()), cmap=cmap, clim=(0.0, 1.5))
            ax.add_collection(poly)
            angle = np.radians(analysis.stress_orientation(sig))
            area = analysis.cell_areas(c)
            ctr = c.mean(axis=1)
            spacing = 0.04 * np.ptp(ctr[:, 1])
            pick = _spread(ctr, spacing)
            half = 0.35 * spacing * np.column_stack([np.cos(angle[pick]), np.sin(angle[pick])])
            ax.add_collection(LineCollection(np.stack([ctr[pick] - half, ctr[pick] + half], axis=1), colors="w", lw=0.8))
            active = float(np.sum(area * (np.abs(angle) > np.pi / 4)) / np.sum(area))
            ax.set_title(f"t = {t_snap[i]:.3g} s\nactive (σ1 within 45° of vertical): {100 * active:.0f} %", fontsize=8)
            self.numbers.append((f"t = {t_snap[i]:.3g} s: share of the fill in the active state (σ1 within 45° of "
                                 "vertical)", f"{100 * active:.0f} %"))
            ax.set_aspect("equal")
            ax.autoscale_view()
            ax.set_xlabel("r (m)")
        axes[0][0].set_ylabel("z (m)")
        fig.colorbar(poly, ax=axes[0].tolist(), shrink=0.7, label="q/p")
        self._save(fig, "stress_fields.png", "Stress ratio q/p (colour, eq. 4-11; grey: stress-free, separated at the "
                   "cone's apex) and the major principal stress direction (white; Figs. 4-5, 4-19) at " + ", ".join(f"{t_snap[i]:.3g}" for i in chosen) + " s.")

    def _stress_free(self) -> float:
        """Mean pressure below which a cell is stress-free (its q/p undefined)."""
        from silo_dolfinx.invariants import stress_free_pressure

        sc = self.scene
        return stress_free_pressure(sc.material.density, sc.loads.gravity, sc.geometry.fill_height) if sc else 0.0

    def renders(self) -> None:
        """The last snapshot's q/p and speed over the whole silo (:mod:`silo_dolfinx.render`)."""
        from silo_dolfinx import render

        snap = self._snapshot()
        if snap is None:
            self.missing.append("field renders (no field snapshot)")
            return
        t = float(snap["t"])
        if "cell_q_over_p" in snap:
            render.picture(snap, "q_over_p", self.folder / "field_q_over_p.png")
            self.figures.append(("field_q_over_p.png", f"Stress ratio q/p (eq. 4-11) at t = {t:.3g} s, the section and "
                                 "its mirror image (grey: stress-free cells, separated at the cone's apex, where q/p is "
                                 "undefined)."))
        render.picture(snap, "speed", self.folder / "field_velocity.png")
        self.figures.append(("field_velocity.png", f"Speed at t = {t:.3g} s (cell means of the corner nodes' |v|)"
                             + (", tracers in white" if "tracer_xy" in snap else "") + "."))

    def movie(self) -> None:
        """discharge.gif: speed and q/p through the discharge, one frame per field snapshot."""
        from silo_dolfinx import render

        t0 = self._stage_times().get("discharge", (None, None))[0]
        snaps = sorted((self.folder / "fields").glob("snapshot_*.npz"))
        if t0 is not None:
            snaps = [f for f in snaps if float(np.load(f)["t"]) >= t0 - 1e-9]
        if len(snaps) < 2:
            self.missing.append("discharge movie (fewer than two field snapshots in the discharge)")
            return
        n = render.movie(snaps, self.folder / "discharge.gif")
        self.figures.append(("discharge.gif", f"The discharge: speed (tracers in white) and q/p, {n} frames, one per "
                             "field snapshot (output.field_interval)."))

    # ------------------------------------------------------------------ text
    def _title(self) -> str:
        return (self.scene.title if self.scene else None) or self.summary.get("title") or self.folder.name

    def key_numbers(self) -> None:
        s = self.summary
        pairs = [("status", s.get("status", "unknown") + (f" — {s['error']}" if s.get("error") else "")),
                 ("cells", s.get("cells")), ("outlet resolution", self._outlet_resolution()), ("steps", s.get("steps")),
                 ("simulated time", f"{s['simulated_time']:.6g} s" if "simulated_time" in s else None),
                 ("wall-clock", f"{s['wall_clock_s']:.1f} s" if "wall_clock_s" in s else None),
                 ("steps per second", f"{s['steps_per_second']:.0f}" if "steps_per_second" in s else None),
                 ("ranks", s.get("ranks")),
                 ("initial stable Δt", f"{s['stable_dt_initial']:.3g} s" if "stable_dt_initial" in s else None),
                 ("stable Δt at the end, set by", self._dt_limit()),
                 ("energy balance error (max)", f"{100 * s['energy_balance_error_max']:.3f} %"
                  if "energy_balance_error_max" in s else None)]
        self.numbers = [(k, str(v)) for k, v in pairs if v is not None] + self.numbers

    def _outlet_resolution(self) -> str | None:
        """Cells across the outlet radius (the mass flow depends on it: docs/guide/your-silo.md)."""
        n = (self.summary.get("mesh_quality") or {}).get("outlet_cells")
        if not n or self.scene is None:
            return None
        r0 = self.scene.outline.outlet_radius
        return f"{n} cells across the outlet radius ({1e3 * r0 / n:.3g} mm each on average)"

    def _dt_limit(self) -> str | None:
        """The cell that set the stable Δt at the end of the last stage (its summary record)."""
        stages = self.summary.get("stages") or [{}]
        c = stages[-1].get("dt_limit")
        if not c or not np.isfinite(c.get("dt", np.nan)):
            return None
        return (f"{c['dt']:.3g} s ({stages[-1]['name']}): the cell at r {c['r']:.3g} m, z {c['z']:.3g} m, "
                f"{1e3 * c['length']:.2g} mm across, {c['density']:.4g} kg/m³")

    def write(self) -> Path:
        for part in (self.wall_profiles, self.wall_histories, self.point_histories, self.spectra, self.discharge_pressures,
                     self.design_pressures,
                     self.wall_dynamics, self.pulse_travel, self.shear_zones, self.remesh_steps, self.rarefaction,
                     self.outlet, self.flow_channel,
                     self.mesh_quality, self.flow_pattern, self.energy, self.renders, self.stress_fields,
                     *([self.movie] if self.with_movie else [])):
            try:
                part()
            except Exception as e:  # a broken part must not lose the others
                self.missing.append(f"{part.__name__}: {type(e).__name__}: {e}")
        self.key_numbers()
        sc = self.scene
        lines = [f"# {self._title()}", ""]
        if sc is not None:
            if sc.description:
                lines += [sc.description, ""]
            g, m = sc.geometry, sc.material
            lines += [f"Geometry: `{g.shape}`, fill height {g.fill_height:g} m. Material: `{m.model}`, "
                      f"ρ {m.density:g} kg/m³, E {m.youngs_modulus:g} Pa, ν {m.poisson_ratio:g}"
                      + (f"; {sc.cone_text()}" if sc.cone else "")
                      + f". Wall: `{sc.wall.friction}`.", ""]
        lines += ["## Key numbers", "", "| quantity | value |", "|---|---|"]
        lines += [f"| {k} | {v} |" for k, v in self.numbers]
        lines += ["", "## Figures", ""]
        for name, caption in self.figures:
            lines += [f"![{caption}]({name})", "", caption, ""]
        if self.summary.get("warnings"):
            lines += ["## Warnings", ""] + [f"- {w}" for w in self.summary["warnings"]] + [""]
        if self.missing:
            lines += ["## Not available", ""] + [f"- {m}" for m in self.missing] + [""]
        path = self.folder / "report.md"
        path.write_text("\n".join(lines))
        return path


def _spread(points: np.ndarray, spacing: float) -> np.ndarray:
    """Indices of one point per ``spacing``-sized square (the first found): an even subsample
    for arrows on a graded mesh."""
    key = np.floor(points / spacing).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    return np.sort(first)


def ensemble_spectra(folders: list[str | Path]) -> Path:
    """`silo report FOLDER --ensemble OTHER ...`: the wall pressure's spectrum at every station
    over several realisations of one scene (the same run with an immaterial change - Δt × 0.99,
    another rank count - whose instants differ, a chaotic discharge's peaks with them), by
    :func:`analysis.ensemble_peak`: the mean of their Welch spectra over the window each
    station's dynamics are measured on (as wall_dynamics.csv: after the start-up and the
    station's switch, the latest start among the realisations), its largest peak above 1 Hz
    with a 90 % interval, and the spread of each realisation's own. Writes ensemble_spectra.csv
    and .png into the first folder; returns the CSV's path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from silo_dolfinx.output.schema import ENSEMBLE_SPECTRA

    reports = [Report(f) for f in folders]
    histories = []
    for r in reports:
        d = r._discharge_history()
        if d is None:
            raise FileNotFoundError(f"{r.folder}: no discharge in its wall_history.csv: an ensemble needs one in each")
        histories.append((d[0], (d[1], r._settled(d[1], d[2]), d[2])))
    rows, spectra = [], []
    for k in np.unique(histories[0][0]["station"]):
        windows = [r._after_switch(h, k, times) for r, (h, times) in zip(reports, histories)]
        if any(w is None or w[0] is None for w in windows):
            continue
        records = [(h["t"][w[0]], h["p_n"][w[0]]) for (h, _), w in zip(histories, windows)]
        ens = analysis.ensemble_peak(records, t_start=max(w[1] for w in windows))
        z = float(np.mean(histories[0][0]["z"][histories[0][0]["station"] == k]))
        rows.append([int(k), z, ens.frequency, *ens.interval, float(np.nanmin(ens.each)), float(np.nanmax(ens.each)),
                     len(records)])
        spectra.append((z, ens.spectrum))
    if not rows:
        raise FileNotFoundError("no station has a long enough discharge record in every folder")
    first = reports[0]
    first._table(ENSEMBLE_SPECTRA, rows)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for z, sp in spectra:
        ax.plot(sp.frequency, sp.amplitude, lw=1, label=f"z = {z:.2f} m")
    if first.scene is not None:
        m, hf = first.scene.material, first.scene.geometry.fill_height
        ax.axvline(theory.longitudinal_frequency(m.youngs_modulus, m.poisson_ratio, m.density, hf), color="r",
                   ls="--", lw=1, label=f"eq. 4-12 (H = {hf:g} m)")
    ax.set_xscale("log")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("amplitude of p_n (Pa)")
    ax.set_title(f"The mean spectrum of {len(reports)} realisations at each wall station", fontsize=9)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(first.folder / "ensemble_spectra.png", dpi=120)
    plt.close(fig)
    return first.folder / ENSEMBLE_SPECTRA.pattern


def make_report(folder: str | Path, times: list[float] | None = None, movie: bool = False) -> Path:
    """Write every figure the folder's files allow and report.md (the stress fields at
    ``times``, default: see :meth:`Report.stress_fields`; with ``movie``, discharge.gif);
    returns its path."""
    return Report(folder, times, movie).write()


if __name__ == "__main__":  # pragma: no cover
    print(make_report(sys.argv[1]))
