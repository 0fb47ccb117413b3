"""RATTLE and α-RATTLE as OpenMM ``CustomIntegrator`` step programs.

The α-RATTLE step from a consistent state (x0, v0) with F0 = F(x0) (Li & Wang, J. Comput. Math. 41, 2023)::

    x1 = x0 + h v0 + h² M⁻¹[(½−α) F0 + α F(x_m)] − M⁻¹ G(x0)ᵀ λ,   g(x1) = 0,   x_m = (x0+x1)/2
    v1 = (x1 − x0)/h + h M⁻¹[α F(x_m) + (½−α) F(x1)] − M⁻¹ G(x1)ᵀ μ,  G(x1) v1 = 0

The implicit midpoint force is found by fixed-point iteration started from the RATTLE
predictor and iterated to a tolerance (a single pass is not symplectic).
``integrator.program_listing()`` (every integrator of this package; docs/step_programs.md
holds them all) prints the program
OpenMM runs, one computation per line, indented by block.

Modules:

- :mod:`~.pieces`: the ``_add_*`` pieces every program is built from, the ordering
  rules that make one program right on the Reference, CPU and common (CUDA, OpenCL,
  HIP) platforms, the system check, ``step()``, ``check_context()`` and
  ``program_listing()``;
- :mod:`~.rattle`: :class:`RattleIntegrator` and its program;
- :mod:`~.rescale`: :class:`RattleRescaleIntegrator`, RATTLE (or a composition of
  RATTLE steps) followed by velocity rescaling to E_ref, and its program;
- :mod:`~.reference_energy`: E_ref, when the integrators that hold it take it, and its API;
- :mod:`~.compositions`: the named compositions, their coefficients and sources;
- :mod:`~.splitting_rattle`: :class:`SplittingRattleIntegrator`, the explicit α-family (α-RATTLE's
  quadrature as a kick-drift splitting), and its program; :mod:`~.splittings`: the named
  splittings, their coefficients and sources;
- :mod:`~.alpha_rattle`: :class:`AlphaRattleIntegrator` (fixed α, one step or a
  composition) and its two programs;
- :mod:`~.energy_controller`: the energy mode's controller, a layer over any base step with a
  parameter α; :mod:`~.energy_mode`: :class:`AlphaRattleEnergyIntegrator` (the energy mode)
  and its bases' trials; :mod:`~.energy_settings`: its settings and defaults;
- :mod:`~.variables`: the names of the globals read from outside a program;
  :mod:`~.restore`: :func:`restore_integrator`.
"""

from ..errors import EnergyHoldWarning
from .alpha_rattle import AlphaRattleIntegrator
from .energy_mode import AlphaRattleEnergyIntegrator
from .energy_settings import ControllerSettings
from .pieces import (
    IncompatibleSystemError,
    MidpointConvergenceError,
    SystemSizeError,
    TimestepUnitWarning,
    check_context,
)
from .rattle import RattleIntegrator
from .rescale import RattleRescaleIntegrator, VelocityRescaleError
from .restore import (
    PACKAGE_INTEGRATORS,
    counted_force_evaluations,
    force_evaluations_per_step,
    restore_integrator,
)
from .splitting_rattle import SplittingRattleIntegrator

__all__ = [
    "PACKAGE_INTEGRATORS",
    "counted_force_evaluations",
    "force_evaluations_per_step",
    "AlphaRattleEnergyIntegrator",
    "AlphaRattleIntegrator",
    "ControllerSettings",
    "EnergyHoldWarning",
    "IncompatibleSystemError",
    "MidpointConvergenceError",
    "RattleIntegrator",
    "RattleRescaleIntegrator",
    "SplittingRattleIntegrator",
    "SystemSizeError",
    "TimestepUnitWarning",
    "VelocityRescaleError",
    "check_context",
    "restore_integrator",
]
