"""Linear isotropic (hypo-)elasticity: Δσ = λ tr(Δε) I + 2μ Δε. No history variables."""

from __future__ import annotations

from silo_dolfinx._jit_cache import numba
from silo_dolfinx.materials.base import Material, elastic_trial


class Elastic(Material):
    name = "elastic"
    plastic = False
    state_fields: dict[str, int] = {}

    def update(self, sig, deps, state_old, sig_new, state_new, dV, dt=None) -> float:
        _update(sig, deps, self.K, self.G, sig_new)
        return 0.0


@numba.njit(cache=True)
def _update(sig, deps, K, G, sig_new):
    for i in range(sig.shape[0]):
        sig_new[i, 0], sig_new[i, 1], sig_new[i, 2], sig_new[i, 3] = elastic_trial(sig[i], deps[i], K, G)
