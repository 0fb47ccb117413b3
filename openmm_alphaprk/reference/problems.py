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

    Parameters
    ----------
    kappa : float, default 0.0
        Stiffness of the horizontal spring.

    Returns
    -------
    ConstrainedProblem

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum, planar_pendulum_start
    >>> pendulum = planar_pendulum(kappa=1.0)
    >>> pendulum.name, pendulum.n_dof
    ('planar pendulum (kappa=1.0)', 2)
    >>> round(pendulum.energy(*planar_pendulum_start(0.5)), 6)  # at rest: −cos θ₀ + ½κ sin²θ₀
    -0.762658
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
    """Start at rest at angle θ₀ from the downward vertical.

    Parameters
    ----------
    theta0 : float
        The angle (rad).

    Returns
    -------
    x, v : numpy.ndarray
        Positions (sin θ₀, −cos θ₀) and zero velocities.

    Examples
    --------
    >>> from openmm_alphaprk.reference import planar_pendulum_start
    >>> x, v = planar_pendulum_start(0.5)
    >>> x.round(6).tolist(), v.tolist()
    ([0.479426, -0.877583], [0.0, 0.0])
    """
    return np.array([np.sin(theta0), -np.cos(theta0)]), np.zeros(2)


def planar_pendulum_period(theta0: float) -> float:
    """Exact period T = 4 K(sin²(θ₀/2)) of the unit pendulum (g = l = 1).

    Parameters
    ----------
    theta0 : float
        The amplitude (rad).

    Returns
    -------
    float

    Examples
    --------
    >>> import math
    >>> from openmm_alphaprk.reference import planar_pendulum_period
    >>> round(planar_pendulum_period(0.5), 6)
    6.38279
    >>> math.isclose(planar_pendulum_period(1e-8), 2 * math.pi)  # small swings: 2π
    True
    """
    return 4.0 * float(ellipk(np.sin(theta0 / 2.0) ** 2))


def spherical_pendulum(kappa: float = 0.0) -> ConstrainedProblem:
    """Spherical pendulum: H = ½|p|² + q₃ + ½κ q₃², g = |q|² − 1 (Hairer–Lubich–Wanner §VII.1).

    L₃ = q₁p₂ − q₂p₁ is a quadratic invariant for every κ.

    Parameters
    ----------
    kappa : float, default 0.0
        Stiffness of a vertical spring.

    Returns
    -------
    ConstrainedProblem

    Examples
    --------
    α-RATTLE keeps the quadratic invariant L₃ to round-off:

    >>> from openmm_alphaprk.reference import integrate, spherical_pendulum, spherical_pendulum_start
    >>> pendulum = spherical_pendulum()
    >>> x0, v0 = spherical_pendulum_start()
    >>> x, v = integrate(pendulum, x0, v0, 0.01, 100, alpha=0.3)
    >>> bool(abs((x[0] * v[1] - x[1] * v[0]) - (x0[0] * v0[1] - x0[1] * v0[0])) < 1e-12)
    True
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

    Returns
    -------
    x, v : numpy.ndarray

    Examples
    --------
    >>> from openmm_alphaprk.reference import spherical_pendulum, spherical_pendulum_start
    >>> x, v = spherical_pendulum_start()
    >>> round(spherical_pendulum().energy(x, v), 7), round(float(x[0] * v[1] - x[1] * v[0]), 7)
    (25.8924988, 6.2631282)
    """
    return (
        np.array([np.sin(1.3), 0.0, np.cos(1.3)]),
        np.array([3 * np.cos(1.3), 6.5, -3 * np.sin(1.3)]),
    )


def harmonic_oscillator(omega: float = 1.0) -> ConstrainedProblem:
    """One unconstrained harmonic degree of freedom, U = ½ω²q² (linear stability tests).

    Parameters
    ----------
    omega : float, default 1.0
        Angular frequency.

    Returns
    -------
    ConstrainedProblem

    Examples
    --------
    >>> import numpy as np
    >>> from openmm_alphaprk.reference import harmonic_oscillator, integrate
    >>> oscillator = harmonic_oscillator(omega=2.0)
    >>> x, v = integrate(oscillator, np.array([1.0]), np.array([0.0]), 0.1, 10)
    >>> round(oscillator.energy(x, v), 2)  # ½ω² = 2 at the start, kept near it (hω = 0.2)
    1.98
    """
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

    Parameters
    ----------
    n_waters : int, default 3
        Number of waters.
    spacing : float, default 0.31
        Lattice spacing (nm).
    temperature : float, default 300.0
        Temperature of the velocities (K).
    seed : int, default 0
        Seed of the orientations and velocities.

    Returns
    -------
    problem : ConstrainedProblem
        In OpenMM's units; its metadata hold the model for :func:`to_openmm_system`.
    x, v : numpy.ndarray
        The start (nm, nm/ps).

    Examples
    --------
    >>> import numpy as np
    >>> from openmm_alphaprk.reference import linear_momentum, water_cluster
    >>> problem, x, v = water_cluster(n_waters=3)
    >>> problem.name, problem.n_dof
    ('3 rigid TIP3P waters in vacuum', 27)
    >>> bool(np.abs(problem.g(x)).max() < 1e-12), bool(np.abs(linear_momentum(problem, v)).max() < 1e-12)
    (True, True)
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
    """Rigid polar diatomics (charges ±0.3 e, LJ) in vacuum, with thermal velocities.

    Parameters
    ----------
    n_molecules : int, default 4
        Number of molecules.
    bond : float, default 0.11
        Bond length (nm).
    spacing : float, default 0.4
        Lattice spacing (nm).
    temperature : float, default 300.0
        Temperature of the velocities (K).
    seed : int, default 0
        Seed of the orientations and velocities.

    Returns
    -------
    problem : ConstrainedProblem
    x, v : numpy.ndarray
        A consistent start with zero total momentum (nm, nm/ps).

    Examples
    --------
    >>> from openmm_alphaprk.reference import rigid_diatomics
    >>> problem, x, v = rigid_diatomics(n_molecules=4)
    >>> problem.name, problem.n_dof, problem.g(x).shape  # one constraint per molecule
    ('4 rigid diatomics in vacuum', 24, (4,))
    """
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
    """Total angular momentum Σ mᵢ rᵢ × vᵢ of a molecular problem.

    Parameters
    ----------
    problem : ConstrainedProblem
        A molecular problem (three degrees of freedom per atom).
    x, v : numpy.ndarray
        Positions and velocities.

    Returns
    -------
    numpy.ndarray
        The three components.

    Examples
    --------
    Kept by α-RATTLE (in vacuum):

    >>> import numpy as np
    >>> from openmm_alphaprk.reference import angular_momentum, integrate, water_cluster
    >>> problem, x0, v0 = water_cluster(n_waters=3)
    >>> x, v = integrate(problem, x0, v0, 0.002, 10, alpha=0.2)
    >>> change = angular_momentum(problem, x, v) - angular_momentum(problem, x0, v0)
    >>> bool(np.abs(change).max() < 1e-10)
    True
    """
    m = problem.masses.reshape(-1, 3)[:, 0]
    return np.sum(m[:, None] * np.cross(x.reshape(-1, 3), v.reshape(-1, 3)), axis=0)


def linear_momentum(problem: ConstrainedProblem, v: Array) -> Array:
    """Total linear momentum Σ mᵢ vᵢ of a molecular problem.

    Parameters
    ----------
    problem : ConstrainedProblem
        A molecular problem (three degrees of freedom per atom).
    v : numpy.ndarray
        Velocities.

    Returns
    -------
    numpy.ndarray
        The three components.

    Examples
    --------
    >>> import numpy as np
    >>> from openmm_alphaprk.reference import linear_momentum, rigid_diatomics
    >>> problem, x, v = rigid_diatomics()
    >>> bool(np.abs(linear_momentum(problem, v)).max() < 1e-12)  # the start has none
    True
    """
    return np.sum((problem.masses * v).reshape(-1, 3), axis=0)


def to_openmm_system(problem: ConstrainedProblem):
    """Build the ``openmm.System`` of a molecular problem: NoCutoff nonbonded force, constraints.

    Parameters
    ----------
    problem : ConstrainedProblem
        A problem of :func:`water_cluster` or :func:`rigid_diatomics`.

    Returns
    -------
    openmm.System

    Examples
    --------
    The same potential energy in OpenMM:

    >>> import openmm
    >>> from openmm_alphaprk.reference import to_openmm_system, water_cluster
    >>> problem, x, v = water_cluster(n_waters=3)
    >>> system = to_openmm_system(problem)
    >>> system.getNumParticles(), system.getNumConstraints()
    (9, 9)
    >>> context = openmm.Context(system, openmm.VerletIntegrator(0.001),
    ...                          openmm.Platform.getPlatformByName("Reference"))
    >>> context.setPositions(x.reshape(-1, 3))
    >>> energy = context.getState(getEnergy=True).getPotentialEnergy()._value  # kJ/mol
    >>> abs(energy - problem.potential(x)) < 1e-8
    True
    """
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
