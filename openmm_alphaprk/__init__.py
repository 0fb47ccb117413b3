"""α-RATTLE: energy- and invariant-preserving constrained integrators for OpenMM."""

from .integrators import (
    AlphaRattleIntegrator,
    MasslessParticleError,
    MidpointConvergenceError,
    RattleIntegrator,
    TimestepUnitWarning,
    restore_integrator,
)
from .smooth_forces import NonSmoothForcesWarning, make_smooth, prepare_for_nve, smoothness_problems
from .start_blowup import StartBlowUpError

__all__ = [
    "AlphaRattleIntegrator",
    "MasslessParticleError",
    "MidpointConvergenceError",
    "NonSmoothForcesWarning",
    "RattleIntegrator",
    "StartBlowUpError",
    "TimestepUnitWarning",
    "make_smooth",
    "prepare_for_nve",
    "restore_integrator",
    "smoothness_problems",
]
#: The package's version; pyproject.toml reads it from here (``[tool.setuptools.dynamic]``).
__version__ = "0.1.0"
