"""Triple-jump (Yoshida) weights of the fourth-order composition.

Φ_h = Ψ_{γ1 h} ∘ Ψ_{γ2 h} ∘ Ψ_{γ1 h} with 2γ1 + γ2 = 1 and 2γ1³ + γ2³ = 0. Shared by the
OpenMM step program (:mod:`~openmm_alphaprk.integrators.pieces`) and the NumPy reference
(:mod:`openmm_alphaprk.reference.composition`), so that both take the same sub-steps.
"""

GAMMA1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
GAMMA2 = -(2.0 ** (1.0 / 3.0)) / (2.0 - 2.0 ** (1.0 / 3.0))
