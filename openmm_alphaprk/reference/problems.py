"""Ready-made constrained test problems for the NumPy reference.

Analytic problems are in dimensionless units; molecular problems
(rigid molecules in vacuum, no cutoff, no periodic boundaries) are in OpenMM's
units (nm, ps, amu, kJ/mol, elementary charge) and can be turned into an
``openmm.System`` with :func:`to_openmm_system` for step-for-step comparisons.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ellipk

from .step import Array, ConstrainedProblem, project_velocities

COULOMB_CONSTANT = 138.935457644382  # kJ/mol nm / e², OpenMM 8's ONE_4PI_EPS0


# ----------------------------------------------------------------- pendulums
def planar_pendulum(kappa: float = 0.0) -> ConstrainedProblem:
    """Planar pendulum in Cartesian coordinates: H = ½|p|² + q₂ + ½κ q₁², g = |q|² − 1.

    ``kappa`` adds a horizontal spring, a position-dependent force through which α
    acts (with κ = 0 the force is constant and α changes nothing).
    """
    return ConstrainedProblem(
        masses=np.ones(2),
        potential=lambda q: q[1] + 0.5 * kappa * q[0] ** 2,
        force=lambda q: np.array([-kappa * q[0], -1.0]),
        constraints=lambda q: np.array([q @ q - 1.0]),
        constraint_jacobian=lambda q: 2.0 * q[None, :],
        name=f"planar pendulum (kappa={kappa})",
        metadata={"kappa": kappa},
    )


def planar_pendulum_start(theta0: float) -> tuple[Array, Array]:
    """Start at rest at angle θ₀ from the downward vertical."""
    return np.array([np.sin(theta0), -np.cos(theta0)]), np.zeros(2)


def planar_pendulum_period(theta0: float) -> float:
    """Exact period T = 4 K(sin²(θ₀/2)) of the unit pendulum (g = l = 1)."""
    return 4.0 * float(ellipk(np.sin(theta0 / 2.0) ** 2))


def spherical_pendulum(kappa: float = 0.0) -> ConstrainedProblem:
    """Spherical pendulum: H = ½|p|² + q₃ + ½κ q₃², g = |q|² − 1 (Hairer–Lubich–Wanner §VII.1).

    L₃ = q₁p₂ − q₂p₁ is a quadratic invariant for every κ.
    """
    return ConstrainedProblem(
        masses=np.ones(3),
        potential=lambda q: q[2] + 0.5 * kappa * q[2] ** 2,
        force=lambda q: np.array([0.0, 0.0, -1.0 - kappa * q[2]]),
        constraints=lambda q: np.array([q @ q - 1.0]),
        constraint_jacobian=lambda q: 2.0 * q[None, :],
        name=f"spherical pendulum (kappa={kappa})",
        metadata={"kappa": kappa},
    )


def spherical_pendulum_start() -> tuple[Array, Array]:
    """Return the standard start: H₀ = 25.8924988…, L₃ = 6.2631282….

    q₀ = (sin 1.3, 0, cos 1.3), p₀ = (3 cos 1.3, 6.5, −3 sin 1.3).
    """
    return (
        np.array([np.sin(1.3), 0.0, np.cos(1.3)]),
        np.array([3 * np.cos(1.3), 6.5, -3 * np.sin(1.3)]),
    )


def harmonic_oscillator(omega: float = 1.0) -> ConstrainedProblem:
    """One unconstrained harmonic degree of freedom, U = ½ω²q² (linear stability tests)."""
    return ConstrainedProblem(
        masses=np.ones(1),
        potential=lambda q: 0.5 * omega**2 * float(q[0] ** 2),
        force=lambda q: -(omega**2) * q,
        name=f"harmonic oscillator (omega={omega})",
        metadata={"omega": omega},
    )


# ----------------------------------------------------- rigid molecules in vacuum
@dataclass(frozen=True)
class MolecularModel:
    """Point charges + Lennard-Jones between molecules, rigid bonds, in vacuum."""

    masses: Array  # (N,)
    charges: Array  # (N,)
    sigmas: Array  # (N,)
    epsilons: Array  # (N,)
    molecule: Array  # (N,) molecule index of each atom
    constraints: tuple[tuple[int, int, float], ...]


def molecular_problem(model: MolecularModel, name: str) -> ConstrainedProblem:
    """Build the constrained problem (flat coordinates) of a :class:`MolecularModel`."""
    n_atoms = len(model.masses)
    i_idx, j_idx = np.triu_indices(n_atoms, k=1)
    inter = model.molecule[i_idx] != model.molecule[j_idx]
    i_idx, j_idx = i_idx[inter], j_idx[inter]
    qq = COULOMB_CONSTANT * model.charges[i_idx] * model.charges[j_idx]
    sig = 0.5 * (model.sigmas[i_idx] + model.sigmas[j_idx])
    eps = np.sqrt(model.epsilons[i_idx] * model.epsilons[j_idx])
    ci = np.array([c[0] for c in model.constraints], dtype=int)
    cj = np.array([c[1] for c in model.constraints], dtype=int)
    d2 = np.array([c[2] ** 2 for c in model.constraints])

    def pair_terms(q: Array) -> tuple[Array, Array, Array]:
        x = q.reshape(n_atoms, 3)
        rij = x[j_idx] - x[i_idx]
        r2 = np.einsum("ij,ij->i", rij, rij)
        return rij, r2, np.sqrt(r2)

    def potential(q: Array) -> float:
        _, r2, r = pair_terms(q)
        s6 = (sig * sig / r2) ** 3
        return float(np.sum(qq / r + 4 * eps * (s6 * s6 - s6)))

    def force(q: Array) -> Array:
        rij, r2, r = pair_terms(q)
        s6 = (sig * sig / r2) ** 3
        # dU/dr / r  for U = qq/r + 4ε(s¹² − s⁶)
        du_over_r = -qq / (r2 * r) + 4 * eps * (-12 * s6 * s6 + 6 * s6) / r2
        fij = du_over_r[:, None] * rij  # force on i
        f = np.zeros((n_atoms, 3))
        np.add.at(f, i_idx, fij)
        np.add.at(f, j_idx, -fij)
        return f.ravel()

    def g(q: Array) -> Array:
        x = q.reshape(n_atoms, 3)
        d = x[ci] - x[cj]
        return np.einsum("ij,ij->i", d, d) - d2

    def jac(q: Array) -> Array:
        x = q.reshape(n_atoms, 3)
        d = x[ci] - x[cj]
        out = np.zeros((len(ci), n_atoms, 3))
        rows = np.arange(len(ci))
        out[rows, ci] = 2 * d
        out[rows, cj] = -2 * d
        return out.reshape(len(ci), 3 * n_atoms)

    return ConstrainedProblem(
        masses=np.repeat(model.masses, 3),
        potential=potential,
        force=force,
        constraints=g,
        constraint_jacobian=jac,
        name=name,
        metadata={"model": model},
    )


# TIP3P water geometry and parameters (OpenMM's tip3p.xml)
_WATER_OH = 0.09572
_WATER_HH = 0.15139
_WATER_MASSES = (15.99943, 1.007947, 1.007947)
_WATER_CHARGES = (-0.834, 0.417, 0.417)
_WATER_SIGMAS = (0.31507524065751241, 1.0, 1.0)
_WATER_EPSILONS = (0.635968, 0.0, 0.0)


def _water_geometry() -> Array:
    half_angle = np.arcsin(0.5 * _WATER_HH / _WATER_OH)
    return np.array(
        [
            [0.0, 0.0, 0.0],
            [_WATER_OH * np.sin(half_angle), _WATER_OH * np.cos(half_angle), 0.0],
            [-_WATER_OH * np.sin(half_angle), _WATER_OH * np.cos(half_angle), 0.0],
        ]
    )


def _random_rotation(rng: np.random.Generator) -> Array:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


def _thermal_velocities(problem: ConstrainedProblem, x: Array, temperature: float, rng) -> Array:
    kT = 0.0083144626 * temperature  # kJ/mol
    v = rng.normal(size=problem.n_dof) * np.sqrt(kT / problem.masses)
    v = project_velocities(problem, x, v)
    m3 = problem.masses.reshape(-1, 3)
    vcm = np.sum(m3 * v.reshape(-1, 3), axis=0) / np.sum(m3[:, 0])
    return project_velocities(problem, x, (v.reshape(-1, 3) - vcm).ravel())


def water_cluster(
    n_waters: int = 3, spacing: float = 0.31, temperature: float = 300.0, seed: int = 0
) -> tuple[ConstrainedProblem, Array, Array]:
    """Rigid TIP3P waters on a small cubic lattice in vacuum, with thermal velocities.

    Returns the problem and a consistent starting state (zero total momentum).
    """
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n_waters ** (1 / 3)))
    sites = np.array([(i, j, k) for i in range(side) for j in range(side) for k in range(side)])[:n_waters]
    positions = []
    for site in sites:
        positions.append(_water_geometry() @ _random_rotation(rng).T + spacing * site)
    n_atoms = 3 * n_waters
    constraints = []
    for w in range(n_waters):
        o, h1, h2 = 3 * w, 3 * w + 1, 3 * w + 2
        constraints += [(o, h1, _WATER_OH), (o, h2, _WATER_OH), (h1, h2, _WATER_HH)]
    model = MolecularModel(
        masses=np.tile(_WATER_MASSES, n_waters),
        charges=np.tile(_WATER_CHARGES, n_waters),
        sigmas=np.tile(_WATER_SIGMAS, n_waters),
        epsilons=np.tile(_WATER_EPSILONS, n_waters),
        molecule=np.repeat(np.arange(n_waters), 3),
        constraints=tuple(constraints),
    )
    problem = molecular_problem(model, f"{n_waters} rigid TIP3P waters in vacuum")
    x = np.concatenate(positions).ravel()
    assert x.size == 3 * n_atoms
    return problem, x, _thermal_velocities(problem, x, temperature, rng)


def rigid_diatomics(
    n_molecules: int = 4, bond: float = 0.11, spacing: float = 0.4, temperature: float = 300.0, seed: int = 0
) -> tuple[ConstrainedProblem, Array, Array]:
    """Rigid polar diatomics (charges ±0.3 e, LJ) in vacuum, with thermal velocities."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n_molecules ** (1 / 3)))
    sites = np.array([(i, j, k) for i in range(side) for j in range(side) for k in range(side)])[:n_molecules]
    positions, constraints = [], []
    for k, site in enumerate(sites):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        centre = spacing * site
        positions += [centre - 0.5 * bond * axis, centre + 0.5 * bond * axis]
        constraints.append((2 * k, 2 * k + 1, bond))
    model = MolecularModel(
        masses=np.tile([14.007, 15.999], n_molecules),
        charges=np.tile([0.3, -0.3], n_molecules),
        sigmas=np.tile([0.32, 0.30], n_molecules),
        epsilons=np.tile([0.7, 0.8], n_molecules),
        molecule=np.repeat(np.arange(n_molecules), 2),
        constraints=tuple(constraints),
    )
    problem = molecular_problem(model, f"{n_molecules} rigid diatomics in vacuum")
    x = np.array(positions).ravel()
    return problem, x, _thermal_velocities(problem, x, temperature, rng)


def angular_momentum(problem: ConstrainedProblem, x: Array, v: Array) -> Array:
    """Total angular momentum Σ mᵢ rᵢ × vᵢ of a molecular problem."""
    m = problem.masses.reshape(-1, 3)[:, 0]
    return np.sum(m[:, None] * np.cross(x.reshape(-1, 3), v.reshape(-1, 3)), axis=0)


def linear_momentum(problem: ConstrainedProblem, v: Array) -> Array:
    """Total linear momentum Σ mᵢ vᵢ of a molecular problem."""
    return np.sum((problem.masses * v).reshape(-1, 3), axis=0)


def to_openmm_system(problem: ConstrainedProblem):
    """Build the ``openmm.System`` of a molecular problem: NoCutoff nonbonded force, constraints."""
    import openmm as mm

    model: MolecularModel = problem.metadata["model"]
    system = mm.System()
    nonbonded = mm.NonbondedForce()
    nonbonded.setNonbondedMethod(mm.NonbondedForce.NoCutoff)
    nonbonded.setUseDispersionCorrection(False)
    for mass, charge, sigma, epsilon in zip(model.masses, model.charges, model.sigmas, model.epsilons):
        system.addParticle(float(mass))
        nonbonded.addParticle(float(charge), float(sigma), float(epsilon))
    n_atoms = len(model.masses)
    for i in range(n_atoms):
        for j in range(i + 1, n_atoms):
            if model.molecule[i] == model.molecule[j]:
                nonbonded.addException(i, j, 0.0, 1.0, 0.0)
    for i, j, d in model.constraints:
        system.addConstraint(i, j, d)
    system.addForce(nonbonded)
    return system
