"""Material laws behind one interface (:class:`~silo_dolfinx.materials.base.Material`).

``make_material(scene.material)`` builds the law a scene selects; each law lives in its
own module and is compiled with numba.
"""

from silo_dolfinx.materials.base import Material
from silo_dolfinx.materials.drucker_prager import DruckerPrager
from silo_dolfinx.materials.elastic import Elastic
from silo_dolfinx.materials.mohr_coulomb import MohrCoulomb
from silo_dolfinx.materials.non_coaxial import NonCoaxial
from silo_dolfinx.materials.viscoplastic import Viscoplastic
from silo_dolfinx.theory import drucker_prager_cone


def make_material(m) -> Material:
    """The material of a resolved [material] section; for the cone laws its Mohr-Coulomb angles
    become the Drucker-Prager slopes by ``m["cone"]`` (:func:`silo_dolfinx.theory.drucker_prager_cone`).
    A plastic law with ``relaxation_time`` > 0 comes wrapped in :class:`Viscoplastic`."""
    law = _law(m)
    tau = m.get("relaxation_time", 0.0)
    return Viscoplastic(law, tau) if tau > 0.0 else law


def _law(m) -> Material:
    if m["model"] == "elastic":
        return Elastic(m["youngs_modulus"], m["poisson_ratio"], m["density"])
    if m["model"] == "mohr_coulomb":  # φ, ψ are its own angles: nothing to map
        return MohrCoulomb(m["youngs_modulus"], m["poisson_ratio"], m["density"], m["friction_angle"],
                           m["dilation_angle"], m["cohesion"], m["max_dilation"], m["recompaction"])
    beta, psi = drucker_prager_cone(m["friction_angle"], m["dilation_angle"], m["cone"])
    if m["model"] == "drucker_prager":
        return DruckerPrager(m["youngs_modulus"], m["poisson_ratio"], m["density"], beta, psi, m["cohesion"],
                             m["max_dilation"], m["recompaction"])
    if m["model"] == "non_coaxial":
        return NonCoaxial(m["youngs_modulus"], m["poisson_ratio"], m["density"], beta, psi, m["cohesion"],
                          m["noncoaxial_modulus"], max_dilation=m["max_dilation"], recompaction=m["recompaction"])
    raise ValueError(f"[material] model = {m['model']!r}: unknown")  # the scene schema prevents this


__all__ = ["DruckerPrager", "Elastic", "Material", "MohrCoulomb", "NonCoaxial", "Viscoplastic", "make_material"]
