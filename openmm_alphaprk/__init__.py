"""α-RATTLE: energy- and invariant-preserving constrained integrators for OpenMM."""

from .errors import (
    AlphaPRKError,
    AlphaPRKWarning,
    EnergyHoldWarning,
    IncompatibleSystemError,
    MidpointConvergenceError,
    NonSmoothForcesWarning,
    StartBlowUpError,
    StateChangingForceWarning,
    SystemSizeError,
    TimestepUnitWarning,
    UnconstrainedVelocitiesWarning,
    VelocityRescaleError,
)
from .integrators import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    ControllerSettings,
    RattleIntegrator,
    RattleRescaleIntegrator,
    SplittingRattleIntegrator,
    restore_integrator,
)
from .nve import prepare_for_nve, state_changing_forces
from .smooth_forces import make_smooth, smoothness_problems

__all__ = [
    "AlphaPRKError",
    "AlphaPRKWarning",
    "AlphaRattleEnergyIntegrator",
    "AlphaRattleIntegrator",
    "ControllerSettings",
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
    "UnconstrainedVelocitiesWarning",
    "VelocityRescaleError",
    "make_smooth",
    "prepare_for_nve",
    "restore_integrator",
    "smoothness_problems",
    "state_changing_forces",
]
#: The package's version; pyproject.toml reads it from here (``[tool.setuptools.dynamic]``).
__version__ = "0.1.0"
