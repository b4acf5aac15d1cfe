"""Material-point driver: any material law along a mixed stress/strain path.

The thesis' simple shear test (ch. 8.3, Fig. 8-2) in plane strain: the sample's sides stay
parallel (ε_x = 0), plane strain (ε_z = 0), the shear strain γ_xy is prescribed and the
vertical stress σ_y is held at its initial value by solving, at every increment, for the
vertical strain increment that keeps it (a scalar root, bracketed and solved by Brent's
method). The material's own kernel does the stress update, so what is verified here is
exactly what runs in a silo.

Component map: the laws work on (rr, zz, θθ, rz); here (x, y, z, xy) — the same algebra,
θθ playing the out-of-plane normal. Stresses tension positive; the driver reports
compression-positive ratios as the thesis does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from silo_dolfinx import analysis
from silo_dolfinx.materials.base import Material


@dataclass
class ShearPath:
    gamma: np.ndarray  # engineering shear strain γ_xy
    sigma: np.ndarray  # (n, 4) stresses (x, y, z, xy), tension positive
    eps_y: np.ndarray  # vertical strain (negative: compaction, positive: dilation)
    plastic_rate: np.ndarray  # (n, 4) plastic strain increment of each step (engineering shear)

    @property
    def stress_ratio(self) -> np.ndarray:
        """τ_xy / σ_y, compression positive (the thesis' shear stress ratio)."""
        return self.sigma[:, 3] / -self.sigma[:, 1]

    @property
    def sx_over_sy(self) -> np.ndarray:
        return self.sigma[:, 0] / self.sigma[:, 1]

    @property
    def stress_angle(self) -> np.ndarray:
        """Rotation of the major (most compressive) principal stress from the vertical, degrees
        (0 at the start; positive in the sense the shear drives it)."""
        a = analysis.principal_angle(self.sigma[:, 0], self.sigma[:, 1], self.sigma[:, 3], "compressive")
        return _from_vertical(a)

    @property
    def strain_rate_angle(self) -> np.ndarray:
        """The same for the major (most compressive) principal plastic strain rate; nan where
        the step was elastic."""
        d = self.plastic_rate
        a = analysis.principal_angle(d[:, 0], d[:, 1], 0.5 * d[:, 3], "compressive")
        out = _from_vertical(a)
        out[np.linalg.norm(d, axis=1) < 1e-14] = np.nan
        return out

    def at(self, gamma: float) -> int:
        return int(np.argmin(np.abs(self.gamma - gamma)))


def _from_vertical(a):
    """Angle from the horizontal (−90, 90] -> rotation away from the vertical, [0, 90]."""
    b = np.mod(90.0 - a, 180.0)
    return np.minimum(b, 180.0 - b)


def simple_shear(material: Material, sigma_v: float = 1.0e5, k: float = 0.4, gamma_max: float = 0.1,
                 steps: int = 2000) -> ShearPath:
    """Simple shear at constant vertical stress σ_v (compression, Pa) from σ_x = σ_z = k σ_v."""
    if sigma_v <= 0 or k <= 0:
        raise ValueError("sigma_v and k must be positive (compression)")
    state = {name: np.zeros(1) for name in material.state_fields}
    new_state = {name: np.zeros(1) for name in material.state_fields}
    sig = np.array([[-k * sigma_v, -sigma_v, -k * sigma_v, 0.0]])
    out = np.zeros((1, 4))
    dV = np.ones(1)
    dg = gamma_max / steps
    M = material.wave_modulus

    def vertical(dey: float) -> float:
        material.update(sig, np.array([[0.0, dey, 0.0, dg]]), state, out, new_state, dV)
        return out[0, 1] + sigma_v

    gammas, sigmas, ey, rates = [0.0], [sig[0].copy()], [0.0], [np.zeros(4)]
    lam = material.K - 2.0 * material.G / 3.0
    c = lam / (3.0 * lam + 2.0 * material.G)
    eps_y = 0.0
    for n in range(steps):
        guess = 10.0 * dg * material.G / M + 1e-12
        lo, hi = -guess, guess
        while vertical(lo) > 0:
            lo *= 4.0
        while vertical(hi) < 0:
            hi *= 4.0
        dey = brentq(vertical, lo, hi, xtol=1e-18, rtol=1e-14, maxiter=200)
        de = np.array([0.0, dey, 0.0, dg])
        material.update(sig, de[None, :], state, out, new_state, dV)
        # plastic increment Δε − C⁻¹ Δσ
        ds = out[0] - sig[0]
        tr = ds[:3].sum()
        dp = de.copy()
        dp[:3] -= (ds[:3] - c * tr) / (2.0 * material.G)
        dp[3] -= ds[3] / material.G
        sig = out.copy()
        state, new_state = new_state, state
        eps_y += dey
        gammas.append((n + 1) * dg)
        sigmas.append(sig[0].copy())
        ey.append(eps_y)
        rates.append(dp)
    return ShearPath(np.array(gammas), np.array(sigmas), np.array(ey), np.array(rates))


# ---------------------------------------------------------------------------- the thesis' study
# Table 8-1 (φ, ψ in degrees, E in kPa, k) and Table 8-2 (ρ 1.5e3 kg/m³, G 3.8e4 kPa,
# c0 1 Pa, H_nc 1.0e4 kPa). G with E = 10e4 kPa gives ν = E/(2G) − 1 = 0.316, kept for all cases.
TABLE_8_1 = {
    1: (30.0, 0.0, 10e4, 0.4),
    2: (30.0, 30.0, 10e4, 0.4),
    3: (30.0, 0.0, 0.4e4, 0.4),
    4: (30.0, 0.0, 2e4, 0.4),
    5: (30.0, 0.0, 50e4, 0.4),
    6: (30.0, 0.0, 10e4, 2.0),
    7: (30.0, 0.0, 10e4, 1.0),
    8: (30.0, 0.0, 10e4, 0.8),
}
NU_CH8 = 10e4 / (2 * 3.8e4) - 1.0
H_NC = 1.0e4 * 1e3  # Pa
COHESION = 1.0  # Pa


def case_materials(case: int, cone: str = "plane_strain"):
    """(coaxial, non-coaxial) materials of a Table 8-1 case, φ and ψ mapped to the
    Drucker–Prager cone by ``cone`` (:data:`silo_dolfinx.theory.CONES`; the scenes'
    ``material.cone``). 'plane_strain' (the default here: the ch. 8 closed forms are plane-strain
    ones) gives Mohr–Coulomb's simple-shear ultimate states, σx/σy = (1 + sin²φ)/(1 − sin²φ),
    τ/σy = tan φ (associated) and σx = σy, τ/σy = sin φ (ψ = 0). 'thesis' is the thesis'
    apparent choice, 'plane_strain_zero_dilation' (tan β = √3 sin φ for both flow rules): it
    reproduces its ultimate states (ψ = 0: σx = σy, τ/σy = 0.5; associated: σx/σy = 1.75,
    τ/σy = 0.61, the thesis reports 1.8 and 0.6), since the associated ultimate state of a DP
    cone of slope t = tan β is σx/σy = (1 + 2t²/9)/(1 − 4t²/9), τ/σy = t/√(3(1 − 4t²/9))."""
    from silo_dolfinx.materials import DruckerPrager, NonCoaxial
    from silo_dolfinx.theory import drucker_prager_cone

    phi, psi, e_kpa, k = TABLE_8_1[case]
    beta, psi_dp = drucker_prager_cone(phi, psi, "plane_strain_zero_dilation" if cone == "thesis" else cone)
    E = e_kpa * 1e3
    co = DruckerPrager(E, NU_CH8, 1500.0, beta, psi_dp, COHESION)
    nc = NonCoaxial(E, NU_CH8, 1500.0, beta, psi_dp, COHESION, H_NC)
    return co, nc, k


def run_study(out: str, cone: str = "plane_strain", gamma_max: float = 0.1, steps: int = 2000) -> list[dict]:
    """Table 8-1 cases 1-8, coaxial and non-coaxial: CSV per case, Figs. 8-3 to 8-7 as PNG,
    and a summary list (also summary.csv). Returns the summary rows."""
    import csv
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths, rows = {}, []
    for case in TABLE_8_1:
        co, nc, k = case_materials(case, cone)
        a = simple_shear(co, k=k, gamma_max=gamma_max, steps=steps)
        b = simple_shear(nc, k=k, gamma_max=gamma_max, steps=steps)
        paths[case] = (a, b)
        diff = a.stress_ratio - b.stress_ratio
        ipk = int(np.argmax(np.abs(diff)))
        with open(folder / f"case{case}.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["gamma", "tau_over_sy_coaxial", "tau_over_sy_noncoaxial", "sx_over_sy_coaxial",
                        "sx_over_sy_noncoaxial", "stress_angle_coaxial", "stress_angle_noncoaxial",
                        "strain_rate_angle_coaxial", "strain_rate_angle_noncoaxial", "difference"])
            for i in range(a.gamma.size):
                w.writerow([a.gamma[i], a.stress_ratio[i], b.stress_ratio[i], a.sx_over_sy[i], b.sx_over_sy[i],
                            a.stress_angle[i], b.stress_angle[i], a.strain_rate_angle[i], b.strain_rate_angle[i],
                            diff[i]])
        phi, psi, e_kpa, _ = TABLE_8_1[case]
        rows.append({"case": case, "phi": phi, "psi": psi, "E_kPa": e_kpa, "k": k, "beta_dp": co.friction_angle,
                     "psi_dp": co.dilation_angle, "ultimate_sx_over_sy": a.sx_over_sy[-1],
                     "ultimate_tau_over_sy": a.stress_ratio[-1], "peak_difference": diff[ipk],
                     "gamma_at_peak": a.gamma[ipk], "final_stress_angle": a.stress_angle[-1]})
    with open(folder / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

    def figure(cases, name, title):
        fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
        for c in cases:
            a, b = paths[c]
            g = 100 * a.gamma
            lab = f"case {c}"
            l0, = ax[0].plot(g, a.stress_ratio, "-", lw=1.2, label=f"{lab} coaxial")
            ax[0].plot(g, b.stress_ratio, "--", lw=1.2, color=l0.get_color(), label=f"{lab} non-coaxial")
            ax[1].plot(g, a.stress_angle, "-", lw=1.2, color=l0.get_color(), label=f"{lab} σ1 coaxial")
            ax[1].plot(g, b.stress_angle, "--", lw=1.2, color=l0.get_color(), label=f"{lab} σ1 non-coaxial")
            ax[1].plot(g, b.strain_rate_angle, ":", lw=1.2, color=l0.get_color(), label=f"{lab} ε̇p non-coaxial")
            ax[2].plot(g, a.stress_ratio - b.stress_ratio, "-", lw=1.2, color=l0.get_color(), label=lab)
        ax[0].set_ylabel("τxy / σy")
        ax[1].set_ylabel("rotation from vertical (°)")
        ax[2].set_ylabel("coaxial − non-coaxial τxy/σy")
        for a_ in ax:
            a_.set_xlabel("shear strain γ (%)")
            a_.grid(alpha=0.3)
            a_.legend(fontsize=6)
        fig.suptitle(title)
        fig.tight_layout()
        fig.savefig(folder / name, dpi=110)
        plt.close(fig)

    figure([1, 2], "fig8-3_flow_rule.png", "Fig. 8-3: flow rule (k = 0.4, E = 1e5 kPa)")
    figure([3, 4, 1, 5], "fig8-4_youngs_modulus.png", "Fig. 8-4: Young's modulus (k = 0.4, ψ = 0)")
    figure([1, 8, 7, 6], "fig8-6_lateral_ratio.png", "Fig. 8-6: lateral pressure ratio k (ψ = 0)")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    es = sorted((r for r in rows if r["case"] in (3, 4, 1, 5)), key=lambda r: r["E_kPa"])
    ax[0].semilogx([r["E_kPa"] for r in es], [r["peak_difference"] for r in es], "ko-")
    ax[0].set_xlabel("E (kPa)")
    ax[0].set_ylabel("peak coaxial − non-coaxial τ/σy")
    ax[0].set_title("Fig. 8-5")
    ks = sorted((r for r in rows if r["case"] in (1, 8, 7, 6)), key=lambda r: r["k"])
    ax[1].plot([r["k"] for r in ks], [r["peak_difference"] for r in ks], "ko-")
    ax[1].axhline(0, color="0.5", lw=0.6)
    ax[1].set_xlabel("lateral pressure ratio k")
    ax[1].set_title("Fig. 8-7")
    for a_ in ax:
        a_.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(folder / "fig8-5_8-7_peak_difference.png", dpi=110)
    plt.close(fig)
    return rows
