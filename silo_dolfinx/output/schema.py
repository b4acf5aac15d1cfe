"""One schema per results file: its columns, their units and meaning.

The writers (:mod:`silo_dolfinx.output.streams`), the reader (:mod:`silo_dolfinx.output.reader`),
``silo report`` and the tests all take the columns from here, so a column is named, typed
and documented once. ``docs/results.md`` is :func:`markdown` verbatim (``silo schema --results``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Column:
    name: str
    unit: str
    doc: str
    text: bool = False  # read as strings (the others as floats, empty cells NaN)


@dataclass(frozen=True)
class CsvFile:
    pattern: str  # file name; "<stage>" stands for a stage name
    doc: str
    columns: tuple[Column, ...]

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.columns]

    def name(self, **parts) -> str:
        out = self.pattern
        for k, v in parts.items():
            out = out.replace(f"<{k}>", str(v))
        return out


C = Column
T = C("t", "s", "simulated time")

ENERGY = CsvFile("energy.csv", "The energy ledger (J, full 360°), at the history rate.", (
    T, C("stage", "-", "fill | store | discharge", text=True),
    C("kinetic", "J", "½ Σ M |v|² at the half step"),
    C("elastic", "J", "stored elastic energy ½ σ:C⁻¹:σ"),
    C("plastic", "J", "plastic dissipation so far"),
    C("viscous", "J", "bulk-viscous dissipation so far"),
    C("damping", "J", "dissipation of the fill damping so far"),
    C("remap", "J", "kinetic + elastic energy lost by ALE remaps (upwinding)"),
    C("outflow", "J", "kinetic + elastic energy carried out through the outlet"),
    C("initial", "J", "energy of a prescribed initial (K0) stress field"),
    C("hourglass", "J", "work against the hourglass control (numerics.integration = \"reduced\"; Abaqus' "
      "ALLAE): read it against elastic + plastic"),
    C("gravity_work", "J", "work of gravity"),
    C("external_work", "J", "work of gravity, surcharge, prescribed velocities and contact"),
    C("contact_work", "J", "work of the wall and gate contact forces (and prescribed velocities)"),
    C("balance", "J", "kinetic + elastic + dissipated + remap + outflow + hourglass − external − initial"),
    C("relative_error", "-", "|balance| over the largest energy scale so far"),
))

WALL_HISTORY = CsvFile("wall_history.csv", "Wall stations at the history rate (interpolated along the wall); "
                       "pressures and slip are means over the interval since the previous sample (instants with "
                       "output.history_sampling = \"instant\").", (
    T, C("station", "-", "station index (output.stations order)"),
    C("s", "m", "arclength along the wall from the outlet edge"),
    C("r", "m", "radius of the station now"), C("z", "m", "height of the station now"),
    C("p_n", "Pa", "normal wall pressure"), C("p_s", "Pa", "wall shear stress (signed along the tangent)"),
    C("slip_velocity", "m/s", "slip velocity along the wall tangent (negative: down the wall)"),
))

WALL_PROFILE = CsvFile("wall_profile_<stage>.csv", "Every wall node at the end of a stage, sorted by s.", (
    C("s", "m", "arclength from the outlet edge"), C("r", "m", "radius"), C("z", "m", "height"),
    C("p_n", "Pa", "normal wall pressure"), C("p_s", "Pa", "wall shear stress"),
    C("slip_velocity", "m/s", "slip velocity along the tangent"),
    C("in_contact", "-", "1 if the node touches the wall, else 0"),
))

POINT_HISTORY = CsvFile("point_history.csv", "Stress and velocity at the interior points (output.points; fixed in space or, "
                        "with output.point_motion = \"material\", moving with the solid from the opening) at "
                        "the history rate: the means over the cell containing each point (empty while it is in no "
                        "active cell), averaged over the interval since the previous sample (instants with "
                        "output.history_sampling = \"instant\").", (
    T, C("point", "-", "point index (output.points order)"),
    C("r", "m", "radius of the point (material points: where it is now)"), C("z", "m", "height of the point"),
    C("stress_rr", "Pa", "radial stress (tension +)"), C("stress_zz", "Pa", "vertical stress"),
    C("stress_tt", "Pa", "hoop stress"), C("stress_rz", "Pa", "shear stress"),
    C("p", "Pa", "mean pressure −tr σ/3 (compression +)"), C("q", "Pa", "√(3 J2)"),
    C("q_over_p", "-", "stress ratio q/p"),
    C("v_r", "m/s", "radial velocity: the mean of the cell's four nodes"),
    C("v_z", "m/s", "vertical velocity (up +): the mean of the cell's four nodes"),
))

SHEAR_ZONES = CsvFile("shear_zones.csv", "Where the solid is failing, per height band (output.zone_bands equal "
                      "bands from the silo's bottom to the fill height; a quadrature point counts in the band of its "
                      "cell's centroid), at the history rate: instants, summed over the ranks. A point is separated "
                      "where its mean pressure is below the stress-free level (the weight of a thousandth of the "
                      "fill) or it is at the apex; the others are loaded.", (
    T, C("band", "-", "band index (0 = lowest)"),
    C("z_low", "m", "bottom of the band"), C("z_high", "m", "top of the band"),
    C("volume", "m³", "volume of solid in the band (full 360°; 0: the band is empty)"),
    C("separated_fraction", "-", "share of that volume separated (stress-free: a free-fall zone, the loose "
      "solid under an arch)"),
    C("yielded_fraction", "-", "share of the loaded volume at yield (mobilised strength ≥ 0.99): the thesis' "
      "shear failure zone (q/p at its limit, eq. 4-11)"),
    C("mobilised_strength", "-", "volume mean over the loaded solid of the share of its strength mobilised (q / "
      "(p tan β + d) on a cone, the pyramid's own on Mohr–Coulomb; above 1: a viscoplastic overstress)"),
))

OUTLET = CsvFile("outlet.csv", "The outlet during the discharge, at the history rate.", (
    T, C("discharged_mass", "kg", "mass that left (counted by the remap as it crosses the Eulerian outlet; "
         "Lagrangian: the mass of cells below the outlet plane)"),
    C("mass_in_silo", "kg", "mass above the outlet plane"),
    C("mass_flow_rate", "kg/s", "the mass actually leaving: discharged mass over the last 0.05 s"),
    C("mean_outlet_velocity", "m/s", "downward, area-weighted over the outlet"),
    C("mass_balance_error", "-", "(mass at opening − inside − discharged) / mass at opening"),
    C("nominal_mass_flow_rate", "kg/s", "the thesis' definition ρ0 · A · v (above the real one where the "
      "outlet material is looser than ρ0)"),
    C("dt", "s", "the current stable time step"),
))

MESH_QUALITY = CsvFile("mesh_quality.csv", "Mesh quality during the discharge (the Fig. 3-18 quantities).", (
    T, C("top_drop", "m", "drop of the free surface on the axis"),
    C("min_scaled_jacobian", "-", "smallest scaled Jacobian of any cell"),
    C("max_aspect_ratio", "-", "largest aspect ratio of any cell"),
))

TRACERS = CsvFile("tracers.csv", "One row per tracer at the end of the discharge.", (
    C("id", "-", "tracer id"), C("row", "-", "seeding row (0 = lowest)"),
    C("r0", "m", "seed radius"), C("z0", "m", "seed height"),
    C("r", "m", "radius now (empty once discharged)"), C("z", "m", "height now (empty once discharged)"),
    C("discharged_at", "s", "when it left (empty while inside)"),
))

DISCHARGE_PRESSURES = CsvFile("discharge_pressures.csv", "Written by `silo report`: time-averaged wall pressures "
                              "(eq. 4-9) over the first 2 s and the first 10 s of the discharge (or as much of "
                              "them as was run) against the end of filling, per station.", (
    C("station", "-", "station index"), C("z", "m", "mean height of the station over the window"),
    C("p_fill", "Pa", "end-of-fill wall pressure (the fill profile interpolated at z)"),
    C("p_discharge_2s", "Pa", "mean p_n over the first 2 s after opening"),
    C("p_discharge_10s", "Pa", "mean p_n over the first 10 s after opening"),
    C("overpressure_2s", "-", "p_discharge_2s / p_fill"), C("overpressure_10s", "-", "p_discharge_10s / p_fill"),
))

DESIGN_PRESSURES = CsvFile("design_pressures.csv", "Written by `silo report`: what the wall carried in the "
                           "discharge against EN 1991-4 (2006)'s symmetrical loads with the scene's own solid (K = "
                           "1.1 (1 − sin φ), its μ; no property factors a_K, a_μ; no patch load), per station. Empty "
                           "EN columns: no rule there (a floor, a fillet, a retaining silo (flat bottom, h_c/d_c ≤ "
                           "0.4), a surcharged silo below h_c/d_c 2, a wall rougher than the solid under a hopper).", (
    C("station", "-", "station index"), C("z", "m", "mean height of the station over the discharge"),
    C("p_opening", "Pa", "wall pressure at the opening (the profile at the end of the stage before the discharge, "
      "interpolated at z)"),
    C("p_en_filling", "Pa", "EN 1991-4 filling load at z"),
    C("p_en_discharge", "Pa", "EN 1991-4 fixed discharge load at z (vertical wall: C_h × filling, 1.15 in slender silos, "
      "1 + 0.15 (h_c/d_c − 1) in intermediate ones, 1 in squat ones; hopper: F_e)"),
    C("p_en", "Pa", "the larger of the two: the load the code designs the wall for (near a hopper's outlet F_e < "
      "F_f and filling governs)"),
    C("p_mean", "Pa", "mean p_n over the first 10 s after the opening (or the whole discharge if shorter), while "
      "the silo is still nearly full: the code's loads are the full silo's"),
    C("p_99", "Pa", "99th percentile of p_n over the discharge (the pulses, without the single highest samples)"),
    C("p_max", "Pa", "largest p_n over the discharge (a history sample: the mean over its interval at "
      "output.history_sampling = \"mean\")"),
    C("t_max", "s", "when it occurred, after the opening"),
    C("mean_over_en", "-", "p_mean / p_en"), C("p99_over_en", "-", "p_99 / p_en"),
    C("max_over_en", "-", "p_max / p_en"),
))

WALL_DYNAMICS = CsvFile("wall_dynamics.csv", "Written by `silo report`: what makes the discharge pressure pulse, "
                        "per station, over the discharge after its start-up (2 s, and 1 s after the station's "
                        "switch from the filled to the flowing state, whichever is later; all of it if the "
                        "discharge is shorter than 4 s).", (
    C("station", "-", "station index"), C("z", "m", "mean height of the station"),
    C("t_from", "s", "start of the measured window, after the opening"),
    C("p_mean", "Pa", "mean p_n over the discharge"),
    C("low_rms", "Pa", "RMS of p_n below 1 Hz (window mean and linear trend removed; zero-phase 4th-order "
      "Butterworth)"),
    C("low_frequency", "Hz", "dominant frequency of that < 1 Hz part"),
    C("fast_rms", "Pa", "RMS of p_n above 1 Hz (the detrended signal minus its < 1 Hz part)"),
    C("wave_frequency", "Hz", "largest peak above 1 Hz of the Welch-averaged spectrum of p_n (six half-overlapping "
      "windows: the stress wave, eq. 4-12, which drifts as the fill drains)"),
    C("mobilised_friction", "-", "mean |p_s|/p_n while loaded"),
    C("slip_fraction", "-", "fraction of the samples in which the station slides (|v_slip| > 0.1 mm/s)"),
    C("windowed_low_rms", "Pa", "RMS of p_n below 1 Hz within consecutive 10-s windows (Fig. 4-12's), each with its "
      "own mean and linear trend removed: a drift slower than a window, such as the station's recovery after its "
      "switch, is left out"),
))

PULSE_TRAVEL = CsvFile("pulse_travel.csv", "Written by `silo report`: whether the wall pressure's pulses run "
                       "along the wall, per pair of neighbouring stations, over the first 10 s of the discharge after "
                       "its start-up (as wall_dynamics.csv; stations pressed by less than 5 % of the most pressed "
                       "one left out): p_n detrended and its part below 1 Hz removed, the lag of the upper "
                       "station's pulses behind the lower one's that maximises their normalised cross-correlation, "
                       "searched within half a period of the pulses' dominant frequency.", (
    C("z_low", "m", "height of the pair's lower station"), C("z_high", "m", "height of its upper station"),
    C("ds", "m", "their distance along the wall"),
    C("lag", "s", "how long the upper station's pulses follow the lower one's (negative: they come first)"),
    C("correlation", "-", "the normalised cross-correlation at that lag (1: the same pulse at both)"),
    C("speed", "m/s", "ds / lag: the pulses' speed up the wall between the two (negative: down it)"),
))

ZONE_FOLLOWING = CsvFile("zone_following.csv", "Written by `silo report`: whether each wall station's slow "
                         "pressure follows where the solid fails, over the discharge after the station's switch (as "
                         "wall_dynamics.csv) and between re-meshes: the parts below 1 Hz of p_n and of every "
                         "height band's yielded and separated shares (shear_zones.csv) - detrended, zero-phase filtered, thinned to 1/8 s - "
                         "and the band and share whose normalised cross-correlation with p_n is largest in magnitude "
                         "within ± 1 s, against what the same search finds by chance.", (
    C("z", "m", "height of the station"), C("t_from", "s", "measured from this long after the opening"),
    C("t_to", "s", "to this long after it (the longest stretch without a re-mesh: a re-mesh steps both signals)"),
    C("low_rms", "Pa", "RMS of the station's p_n below 1 Hz"),
    C("separated", "-", "1: the separated share of the band (stress-free pockets), 0: the share at yield"),
    C("z_low", "m", "the band's lower edge"), C("z_high", "m", "its upper edge"),
    C("lag", "s", "how long the band's share follows the pressure (negative: it comes first)"),
    C("correlation", "-", "the normalised cross-correlation at that lag (negative: the pressure rises as the share "
      "falls)"),
    C("chance", "-", "the 95 % quantile of the same search's best |r| with the pressure record circularly shifted "
      "in time (at least a tenth of it): a |correlation| below it is what unrelated slow signals give"),
    C("bands_above", "-", "how many band records correlate beyond chance"),
    C("bands", "-", "how many band records were searched (shares with a whole record that varies)"),
))

REMESH_STEPS = CsvFile("remesh_steps.csv", "Written by `silo report` for a discharge that was meshed again "
                       "(ale.rezone_*): whether each re-mesh stepped each station's wall pressure more than the "
                       "pressure steps anyway (analysis.event_steps: the mean over 0.5 s after the re-mesh minus the "
                       "mean over 0.5 s before it, against the same at every instant of the discharge after its "
                       "start-up that is at least 1 s from a re-mesh).", (
    C("t", "s", "the re-mesh, this long after the opening"), C("z", "m", "height of the station"),
    C("step", "Pa", "p_n's mean over 0.5 s after the re-mesh minus its mean over 0.5 s before"),
    C("typical", "Pa", "the median |step| of the station's p_n at the instants away from every re-mesh"),
    C("exceedance", "-", "the share of those instants whose |step| is at least as large: below 0.01, the re-mesh "
      "stepped the pressure"),
))

ENSEMBLE_SPECTRA = CsvFile("ensemble_spectra.csv", "Written by `silo report FOLDER --ensemble OTHER ...` into "
                           "FOLDER: per wall station, the spectrum of p_n over several realisations of one scene "
                           "(analysis.ensemble_peak: the mean of their Welch spectra over the window wall_dynamics.csv "
                           "measures on, the latest start among them).", (
    C("station", "-", "station index"), C("z", "m", "height of the station"),
    C("frequency", "Hz", "the mean spectrum's largest peak above 1 Hz"),
    C("low", "Hz", "its 90 % bootstrap interval over the realisations: lower end"), C("high", "Hz", "upper end"),
    C("each_min", "Hz", "the lowest of the realisations' own peaks (each found as wall_dynamics.csv's wave_frequency, "
      "over the same window)"),
    C("each_max", "Hz", "the highest of them"), C("realisations", "-", "how many folders"),
))

RAREFACTION = CsvFile("rarefaction.csv", "Written by `silo report` for a controlled discharge of a column "
                      "(thesis ch. 5): the rarefaction wave launched by the pull, per interior point (output.points; "
                      "the axis in the ch. 5 scenes), before the top's reflection reaches it.", (
    C("point", "-", "point index"), C("z", "m", "height = distance the wave has travelled"),
    C("sigma_plus", "Pa", "σ⁺: the largest drop of −σ_zz below its value at the pull"),
    C("normalised", "-", "σ⁺/σ⁺0, σ⁺0 = ρ c u0 (the boundary's magnitude)"),
    C("predicted", "-", "eq. 5-1 / 5-14 / 5-15 for the scene's D, μ and half-angle and the k = σ_rr/σ_zz the run "
      "reached on the axis"),
    C("predicted_taper", "-", "the same 1-D model keeping the lateral strain the taper imposes "
      "(theory.taper_wave_growth: G^(k μ/tan α − 1)); equals `predicted` for a parallel column"),
))

FLOW_CHANNEL = CsvFile("flow_channel.csv", "Written by `silo report` for a discharge with field snapshots: the "
                       "flow-channel boundary (v_z = 0.001 × the centreline v_z at the same height, ch. 6.4.3) at the "
                       "snapshots nearest to V_dis = 0.1, 3, 6, 10 % and at the last one.", (
    C("v_dis", "%", "discharged volume at the snapshot (eq. 6-2, in mass)"), T,
    C("z", "m", "height"),
    C("r_fcb", "m", "radius of the boundary (empty: the whole section flows)"),
))

FILES: tuple[CsvFile, ...] = (ENERGY, WALL_HISTORY, WALL_PROFILE, POINT_HISTORY, SHEAR_ZONES, OUTLET, MESH_QUALITY,
                              TRACERS, DISCHARGE_PRESSURES, DESIGN_PRESSURES, WALL_DYNAMICS, PULSE_TRAVEL,
                              ZONE_FOLLOWING, REMESH_STEPS, ENSEMBLE_SPECTRA, RAREFACTION,
                              FLOW_CHANNEL)


def for_file(filename: str) -> CsvFile | None:
    """The schema of a results file by its name (None for a file without one)."""
    for f in FILES:
        head, _, tail = f.pattern.partition("<")
        if filename == f.pattern or ("<" in f.pattern and filename.startswith(head)
                                     and filename.endswith(tail.partition(">")[2])):
            return f
    return None


def markdown() -> str:
    """The results-file reference as Markdown."""
    out = ["# Results files", "", "<!-- generated by `silo schema --results > docs/results.md`; do not edit -->", "",
           "Each run writes one folder: `scene.toml` (the resolved scene), `summary.json` (status, key numbers, "
           "stages; while the run goes, `status = \"running\"` and, every 10 s of wall-clock, the `stage`, "
           "`t_reached` and `steps` so far, and `checkpoint` (t, steps, when) of the last checkpoint: a run killed "
           "outright says how far it got; `resumed` lists the checkpoints a run was resumed from; each stage's record "
           "has its steps, wall-clock, last Δt, lowest cell density and `dt_limit`, the cell with the smallest stable "
           "Δt at its end: centroid `r`, `z` (m), `length` (m, the Δt length), `density` (kg/m³), `dt` (s, before "
           "numerics.time_step_scale); a discharge's `mass_flow_quarters` (kg/s left in each quarter of it: an arch "
           "shows as a last one near 0); a discharge that was meshed again (`ale.rezone_dt_fall`, "
           "`ale.rezone_min_quality`) lists its `rezones`: time `t`, solver `step`, `cells_before`/`cells_after`, stable "
           "`dt_before`/`dt_after` (s, before the scale), `mass_before`/`mass_after` (kg), `uncovered_mass` (kg of "
           "old cells no new cell overlapped: lost), `gap_volume` (m³ of new cells no old cell covered: the mass "
           "around spreads into it), `kinetic_before`/`kinetic_after` and `energy_removed` (J, booked as remap "
           "dissipation), `seconds`), the CSV files "
           "below (rank 0, one flushed row at a time, so a crash leaves a readable partial result), `fields/` (VTX "
           "for ParaView - `nodes.bp`, `cells.bp`, and `nodes_resumedN.bp`, `cells_resumedN.bp` for the part after "
           "the N-th resumption, `nodes_rezoneN.bp`, `cells_rezoneN.bp` on the mesh of the N-th rezone - and `snapshot_NNNN.npz` for `silo report`, each with its mesh's number `mesh`), `checkpoint/` while the run goes "
           "(per-rank state every `output.checkpoint_interval` s of wall-clock, for `silo run --resume FOLDER`; "
           "removed when the run completes), PNG figures and `report.md`. A fresh run into the folder of an earlier "
           "run (one with a `summary.json`) first removes that run's results - the files named here, `fields/`, "
           "`checkpoint/`, PNG figures, `report.md` - so that none of them is read as the new run's; files of other "
           "names are left alone. It is refused while another run is still writing into the folder (its summary "
           "says `running` and was rewritten within the last minute). Read any CSV with `silo_dolfinx.output.read_csv(path)`.", ""]
    for f in FILES:
        out += [f"## `{f.pattern}`", "", f.doc, "", "| column | unit | meaning |", "|---|---|---|"]
        out += [f"| `{c.name}` | {c.unit} | {c.doc.replace('|', chr(92) + '|')} |" for c in f.columns]
        out.append("")
    return "\n".join(out)
