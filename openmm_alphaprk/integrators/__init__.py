"""RATTLE and α-RATTLE as OpenMM ``CustomIntegrator`` step programs.

The α-RATTLE step from a consistent state (x0, v0) with F0 = F(x0) (Li & Wang, J. Comput. Math. 41, 2023)::

    x1 = x0 + h v0 + h² M⁻¹[(½−α) F0 + α F(x_m)] − M⁻¹ G(x0)ᵀ λ,   g(x1) = 0,   x_m = (x0+x1)/2
    v1 = (x1 − x0)/h + h M⁻¹[α F(x_m) + (½−α) F(x1)] − M⁻¹ G(x1)ᵀ μ,  G(x1) v1 = 0

The implicit midpoint force is found by fixed-point iteration started from the RATTLE
predictor and iterated to a tolerance (a single pass is not symplectic). The programs
are built from ``_add_*`` pieces whose ordering rules (:mod:`~.base`) make the same
program correct on the Reference, CPU and common (CUDA, OpenCL, HIP) platforms.
``integrator.program_listing()`` (every integrator of this package) prints the program
OpenMM runs, one computation per line, indented by block.

Modules, each class building on the one before:

- :mod:`~.binding`: ``SystemCheckedProgram``, what a program knows of its Context
  (the system check at each ``step()`` call, ``check_context()``);
- :mod:`~.base`: :class:`StepProgram`, the base (counters, the frame of every
  program, the RATTLE pieces, ``program_listing()``);
- :mod:`~.midpoint`: ``MidpointProgram``, α and the midpoint iteration, α-RATTLE-4's
  sub-steps (:mod:`~.triple_jump`: their weights);
- :mod:`~.controller`: ``EnergyControllerProgram``, the α* controller's step programs,
  and the names of the global variables that reporters read;
- :mod:`~.energy_mode`: ``EnergyModeProgram``, the energy mode's settings and reporting;
- :mod:`~.rattle`, :mod:`~.alpha_rattle`: the public :class:`RattleIntegrator` and
  :class:`AlphaRattleIntegrator`; :mod:`~.restore`: :func:`restore_integrator`;
- :mod:`~.names`: integrators by name for the driver and command line.
"""

from .alpha_rattle import AlphaRattleIntegrator
from .base import KIND_VARIABLE, StepProgram, TimestepUnitWarning
from .binding import IncompatibleSystemError, SystemSizeError, check_context
from .midpoint import MidpointConvergenceError
from .rattle import RattleIntegrator
from .restore import restore_integrator

__all__ = [
    "KIND_VARIABLE",
    "AlphaRattleIntegrator",
    "IncompatibleSystemError",
    "MidpointConvergenceError",
    "RattleIntegrator",
    "StepProgram",
    "SystemSizeError",
    "TimestepUnitWarning",
    "check_context",
    "restore_integrator",
]
