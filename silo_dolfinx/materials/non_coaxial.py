"""Non-coaxial (yield-vertex) Drucker-Prager, thesis ch. 8 (eqs. 8-1 to 8-13).

The plastic strain rate has a coaxial part from the Drucker-Prager flow rule and a
non-coaxial part proportional to the deviatoric stress rate tangential to the yield
surface (Rudnicki & Rice 1975; Yang & Yu 2006):

    ε̇ᵖⁿ = ṡⁿ / H_nc,   ṡⁿ = ṡ − (s ⊗ s / s:s) : ṡ                      (8-9, 8-10)
        = (2G/(H_nc + 2G)) T : ε̇                                          (8-11)

so the tangent loses (4G²/(H_nc + 2G)) T (8-13). In an increment this lowers the trial
deviator of a point loading plastically by c_nc Δe_t with c_nc = 4G²/(H_nc + 2G) and
Δe_t the deviatoric strain increment tangential to the current deviator; the return to the
Drucker-Prager surface then proceeds as for the coaxial law. As H_nc → ∞, c_nc → 0 and the
law is coaxial Drucker-Prager; the non-coaxial plastic strain is orthogonal to s, so it
dissipates nothing to first order.
"""

from __future__ import annotations

from silo_dolfinx.materials.drucker_prager import DruckerPrager


class NonCoaxial(DruckerPrager):
    name = "non_coaxial"

    def __init__(self, youngs_modulus, poisson_ratio, density, friction_angle, dilation_angle, cohesion,
                 noncoaxial_modulus, **flow):
        """``flow``: the Drucker-Prager law's max_dilation and recompaction."""
        super().__init__(youngs_modulus, poisson_ratio, density, friction_angle, dilation_angle, cohesion, **flow)
        if not noncoaxial_modulus > 0:
            raise ValueError("noncoaxial_modulus must be positive")
        self.noncoaxial_modulus = noncoaxial_modulus
        self.noncoaxial = 4.0 * self.G**2 / (noncoaxial_modulus + 2.0 * self.G)
