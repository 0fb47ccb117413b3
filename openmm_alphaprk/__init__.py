"""α-RATTLE: energy- and invariant-preserving constrained integrators for OpenMM."""

from .integrators import (
    AlphaRattleIntegrator,
    MasslessParticleError,
    MidpointConvergenceError,
    RattleIntegrator,
    SystemSizeError,
    TimestepUnitWarning,
    restore_integrator,
)
from .smooth_forces import (
    NonSmoothForcesWarning,
    StateChangingForceWarning,
    make_smooth,
    smoothness_problems,
    state_changing_forces,
)
from .start_blowup import StartBlowUpError

__all__ = [
    "AlphaRattleIntegrator",
    "MasslessParticleError",
    "MidpointConvergenceError",
    "NonSmoothForcesWarning",
    "RattleIntegrator",
    "StartBlowUpError",
    "StateChangingForceWarning",
    "SystemSizeError",
    "TimestepUnitWarning",
    "make_smooth",
    "restore_integrator",
    "smoothness_problems",
    "state_changing_forces",
]
__version__ = "0.1.0"
