"""The quantities every room measures, each in one place: energy, drift, DOF, constraints, momenta, α*.

Runs, analyses, benchmarks, reports and tests import these; nothing here imports
anything of the package above it (integrators, runs, workflows).
"""

from __future__ import annotations

import numpy as np
import openmm as mm
import openmm.unit as unit

#: Percentiles of α* reported by runs, benchmarks and reports (as ``p1`` … ``p99``).
ALPHA_PERCENTILES = (1, 5, 25, 50, 75, 95, 99)

#: Why ``openmm.VerletIntegrator``'s H − E_ref is not comparable step for step.
VERLET_IS_LEAPFROG = (
    "openmm.VerletIntegrator is leapfrog: its State kinetic energy is a half-step estimate, so its "
    "H - E_ref is not comparable step for step with the velocity-Verlet integrators; its drift is."
)


def total_energy(source: mm.Context | mm.State) -> float:
    """Potential + kinetic energy (kJ/mol) of a context's current state or of a State with energies."""
    state = source.getState(getEnergy=True) if isinstance(source, mm.Context) else source
    return (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(unit.kilojoules_per_mole)


def degrees_of_freedom(system: mm.System) -> int:
    """3 N − constraints − 3 if the system removes centre-of-mass motion (massive particles only)."""
    massive = sum(
        system.getParticleMass(i).value_in_unit(unit.dalton) > 0 for i in range(system.getNumParticles())
    )
    removes_cm = any(isinstance(system.getForce(i), mm.CMMotionRemover) for i in range(system.getNumForces()))
    return 3 * massive - system.getNumConstraints() - (3 if removes_cm else 0)


def drift_per_dof(times_ps: np.ndarray, residuals: np.ndarray, dof: int) -> float:
    """Slope of a least-squares line through H(t), in kJ/mol/ns per degree of freedom."""
    slope_per_ps = np.polyfit(times_ps, residuals, 1)[0]
    return float(slope_per_ps * 1000.0 / dof)


def masses(system: mm.System) -> np.ndarray:
    """Particle masses (amu), shape (N,)."""
    return np.array(
        [system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(system.getNumParticles())]
    )


def system_constraints(system: mm.System) -> tuple[np.ndarray, np.ndarray]:
    """Constrained pairs (k, 2) and their lengths (nm) from an OpenMM System."""
    n = system.getNumConstraints()
    pairs = np.empty((n, 2), dtype=np.intp)
    lengths = np.empty(n)
    for k in range(n):
        i, j, d = system.getConstraintParameters(k)
        pairs[k] = i, j
        lengths[k] = d.value_in_unit(unit.nanometers)
    return pairs, lengths


def constraint_errors(
    pairs: np.ndarray, lengths: np.ndarray, x: np.ndarray, v: np.ndarray
) -> tuple[float, float]:
    """Max relative bond-length error |r − d|/d and max |relative velocity along the bond| (nm/ps).

    ``x`` in nm and ``v`` in nm/ps, shape (N, 3); no minimum image (constrained pairs
    are within one molecule, which OpenMM keeps whole). (0, 0) without constraints.
    """
    if len(pairs) == 0:
        return 0.0, 0.0
    r = x[pairs[:, 1]] - x[pairs[:, 0]]
    norm = np.linalg.norm(r, axis=1)
    dv = v[pairs[:, 1]] - v[pairs[:, 0]]
    return (
        float(np.max(np.abs(norm - lengths) / lengths)),
        float(np.max(np.abs(np.einsum("ij,ij->i", dv, r)) / norm)),
    )


def system_constraint_errors(system: mm.System, x: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """:func:`constraint_errors` for the constraints of ``system``."""
    return constraint_errors(*system_constraints(system), x, v)


def momenta(particle_masses: np.ndarray, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total linear (amu nm/ps) and angular momentum about the origin (amu nm²/ps)."""
    m = np.asarray(particle_masses)[:, None]
    return (m * v).sum(0), (m * np.cross(x, v)).sum(0)


def alpha_percentiles(alphas: np.ndarray) -> dict[str, float]:
    """α* percentiles :data:`ALPHA_PERCENTILES` as ``{"p1": …, "p99": …}``, NaN ignored (all NaN if none)."""
    alphas = np.asarray(alphas, dtype=float)
    finite = alphas[np.isfinite(alphas)]
    if finite.size == 0:
        return {f"p{p}": float("nan") for p in ALPHA_PERCENTILES}
    return {f"p{p}": float(v) for p, v in zip(ALPHA_PERCENTILES, np.percentile(finite, ALPHA_PERCENTILES))}


def positive_int(value: object, name: str) -> int:
    """Validate a positive integer argument (integral floats accepted); raise ``ValueError`` naming it."""
    numeric = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not numeric or not np.isfinite(value) or value != int(value) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}.")
    return int(value)
