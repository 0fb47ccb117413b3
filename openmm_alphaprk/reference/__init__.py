"""NumPy reference implementation of α-RATTLE for small systems, and test problems.

Used by the tests to check the OpenMM integrators and the theory: the step itself
(:func:`alpha_rattle_step`), geometric checks (:func:`symplecticity_defect`) and
ready problems (pendulums, a harmonic oscillator, rigid molecules in vacuum).
"""

from .composition import (
    GAMMA1,
    GAMMA2,
    alpha_rattle4_step,
    composition_step,
    energy_preserving_step,
    integrate_energy_preserving,
)
from .geometry import symplectic_form, symplecticity_defect, tangent_vectors
from .problems import (
    angular_momentum,
    harmonic_oscillator,
    linear_momentum,
    planar_pendulum,
    planar_pendulum_period,
    planar_pendulum_start,
    rigid_diatomics,
    spherical_pendulum,
    spherical_pendulum_start,
    to_openmm_system,
    water_cluster,
)
from .splitting import splitting_step
from .step import (
    ConstrainedProblem,
    StepInfo,
    alpha_rattle_step,
    integrate,
    project_to_manifold,
    project_velocities,
    solve_positions,
)

__all__ = [
    "GAMMA1",
    "GAMMA2",
    "ConstrainedProblem",
    "alpha_rattle4_step",
    "composition_step",
    "energy_preserving_step",
    "integrate_energy_preserving",
    "StepInfo",
    "alpha_rattle_step",
    "angular_momentum",
    "harmonic_oscillator",
    "integrate",
    "linear_momentum",
    "planar_pendulum",
    "planar_pendulum_period",
    "planar_pendulum_start",
    "project_to_manifold",
    "project_velocities",
    "rigid_diatomics",
    "solve_positions",
    "splitting_step",
    "spherical_pendulum",
    "spherical_pendulum_start",
    "symplectic_form",
    "symplecticity_defect",
    "tangent_vectors",
    "to_openmm_system",
    "water_cluster",
]
