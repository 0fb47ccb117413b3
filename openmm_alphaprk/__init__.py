"""α-RATTLE: energy- and invariant-preserving constrained integrators for OpenMM."""

from .integrators import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    EnergyHoldWarning,
    IncompatibleSystemError,
    MidpointConvergenceError,
    RattleIntegrator,
    RattleRescaleIntegrator,
    SplittingRattleIntegrator,
    SystemSizeError,
    TimestepUnitWarning,
    UncheckedContextWarning,
    VelocityRescaleError,
    restore_integrator,
)
from .nve import StateChangingForceWarning, prepare_for_nve, state_changing_forces
from .smooth_forces import NonSmoothForcesWarning, make_smooth, smoothness_problems
from .start_blowup import StartBlowUpError

__all__ = [
    "AlphaRattleEnergyIntegrator",
    "AlphaRattleIntegrator",
    "EnergyHoldWarning",
    "IncompatibleSystemError",
    "MidpointConvergenceError",
    "NonSmoothForcesWarning",
    "RattleIntegrator",
    "RattleRescaleIntegrator",
    "SplittingRattleIntegrator",
    "StartBlowUpError",
    "StateChangingForceWarning",
    "SystemSizeError",
    "TimestepUnitWarning",
    "UncheckedContextWarning",
    "VelocityRescaleError",
    "make_smooth",
    "prepare_for_nve",
    "restore_integrator",
    "smoothness_problems",
    "state_changing_forces",
]
#: The package's version; pyproject.toml reads it from here (``[tool.setuptools.dynamic]``).
__version__ = "0.1.0"
