"""α-RATTLE: energy- and invariant-preserving constrained integrators for OpenMM."""

from .integrators import (
    AlphaRattleIntegrator,
    MasslessParticleError,
    MidpointConvergenceError,
    RattleIntegrator,
    restore_integrator,
)

__all__ = [
    "AlphaRattleIntegrator",
    "MasslessParticleError",
    "MidpointConvergenceError",
    "RattleIntegrator",
    "restore_integrator",
]
__version__ = "0.1.0"
