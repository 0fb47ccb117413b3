"""Build a system from its definition with OpenMM's ForceField and Modeller, then equilibrate it."""

from __future__ import annotations

import gzip
import sys
from pathlib import Path

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit
from tqdm import tqdm

from ..smooth_forces import apply_build_settings
from .definitions import DefinitionError, SystemDefinition

#: Constraint tolerance of the final projection of the equilibrated state (relative).
FINAL_CONSTRAINT_TOLERANCE = 1e-12
#: Bumped when the build code changes what a definition produces (part of the cache and shipped keys).
BUILDER_VERSION = "1"


def build_model(definition: SystemDefinition) -> tuple[app.Topology, list, app.ForceField]:
    """Topology and positions (nm) of a definition, and its force field (no equilibration)."""
    build = definition.build
    forcefield = app.ForceField(*build["forcefield"])
    kind = build["kind"]
    if kind == "water_box":
        edge = float(build["box_edge_nm"])
        modeller = app.Modeller(app.Topology(), [])
        modeller.addSolvent(
            forcefield, model=build["water_model"], boxSize=mm.Vec3(edge, edge, edge) * unit.nanometers
        )
    elif kind == "water_cluster":
        modeller = _water_cluster(forcefield, build["water_model"], float(build["radius_nm"]))
    else:
        pdb = read_pdb(_resolve_pdb(build["pdb"], definition.name))
        modeller = app.Modeller(pdb.topology, pdb.positions)
    positions = modeller.positions.value_in_unit(unit.nanometers)
    return modeller.topology, positions, forcefield


def create_system(definition: SystemDefinition, topology: app.Topology, forcefield: app.ForceField):
    """``ForceField.createSystem`` with the definition's settings and ``removeCMMotion=False`` (NVE)."""
    build = definition.build
    kwargs = {
        "constraints": app.HBonds if build["constraints"] == "HBonds" else None,
        "rigidWater": True,
        "removeCMMotion": False,
    }
    if build.get("hydrogen_mass_amu") is not None:
        kwargs["hydrogenMass"] = float(build["hydrogen_mass_amu"]) * unit.amu
    if build["nonbonded_method"] != "PME":
        return forcefield.createSystem(topology, nonbondedMethod=app.NoCutoff, **kwargs)
    cutoff = float(build["cutoff_nm"])
    system = forcefield.createSystem(
        topology, nonbondedMethod=app.PME, nonbondedCutoff=cutoff * unit.nanometers, **kwargs
    )
    # smooth forces at the cutoff (make_smooth; see systems.water_box): otherwise
    # the energy error of any integrator is dominated by pairs crossing the cutoff
    switch, ewald = build.get("switch_distance_nm"), build.get("ewald_error_tolerance")
    apply_build_settings(
        system, cutoff, None if switch is None else float(switch), None if ewald is None else float(ewald)
    )
    return system


def equilibrate(
    definition: SystemDefinition,
    system: mm.System,
    positions,
    *,
    velocities=None,
    progress: bool = False,
) -> mm.State:
    """Minimize, draw velocities and run seeded Langevin dynamics; return a consistent state.

    ``velocities`` (nm/ps, e.g. from a user's restart file) are kept instead of drawn
    where the protocol has no minimization and no Langevin steps.

    The protocol is the ``[equilibration]`` table: ``LocalEnergyMinimizer`` to
    ``minimize_tolerance_kJ_per_mol_nm`` (at most ``minimize_max_iterations``),
    Maxwell–Boltzmann velocities at ``temperature_K`` with ``seed``,
    ``langevin_steps`` of ``LangevinMiddleIntegrator`` (same seed), then positions
    and velocities constrained to 1e-12 so that NVE runs start on the constraint
    manifold. With ``zero_momentum`` the centre-of-mass velocity and the rigid
    rotation are removed (isolated clusters).
    """
    eq = definition.equilibration
    kelvin = float(eq["temperature_K"])
    integrator = mm.LangevinMiddleIntegrator(
        kelvin, float(eq["langevin_friction_per_ps"]), float(eq["langevin_timestep_fs"]) / 1000.0
    )
    integrator.setRandomNumberSeed(int(eq["seed"]))
    integrator.setConstraintTolerance(1e-10)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName(eq["platform"]))
    as_read = eq["minimize_max_iterations"] == 0 and eq["langevin_steps"] == 0  # a user's start, unchanged
    context.setPeriodicBoxVectors(*system.getDefaultPeriodicBoxVectors())
    context.setPositions(positions)
    if eq["minimize_max_iterations"] > 0:
        mm.LocalEnergyMinimizer.minimize(
            context, float(eq["minimize_tolerance_kJ_per_mol_nm"]), int(eq["minimize_max_iterations"])
        )
    if velocities is not None and as_read:
        context.setVelocities(velocities)
    else:
        context.setVelocitiesToTemperature(kelvin, int(eq["seed"]))
    _step_in_chunks(integrator, int(eq["langevin_steps"]), f"equilibrating {definition.name}", progress)
    context.applyConstraints(FINAL_CONSTRAINT_TOLERANCE)
    context.applyVelocityConstraints(FINAL_CONSTRAINT_TOLERANCE)
    if eq.get("zero_momentum"):
        state = context.getState(getPositions=True, getVelocities=True)
        velocities = _remove_rigid_motion(
            system,
            state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
            state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
        )
        context.setVelocities(velocities)
        context.applyVelocityConstraints(FINAL_CONSTRAINT_TOLERANCE)
    context.setTime(0.0)
    context.setStepCount(0)
    state = context.getState(getPositions=True, getVelocities=True, getEnergy=True, getParameters=True)
    energy = (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(unit.kilojoules_per_mole)
    if not np.isfinite(energy) and as_read:
        raise DefinitionError(
            f"the start of {definition.name!r} as read has a non-finite energy ({energy}): atoms on top of "
            "each other, or coordinates that do not belong to this topology; check the coordinates."
        )
    if not np.isfinite(energy):
        raise FloatingPointError(
            f"equilibration of {definition.name!r} ended with a non-finite energy ({energy}); "
            "check the structure or shorten langevin_timestep_fs."
        )
    return state


def _step_in_chunks(integrator: mm.Integrator, steps: int, description: str, progress: bool) -> None:
    """Take ``steps`` steps in chunks of 100, with a progress bar on stderr if asked."""
    with tqdm(total=steps, desc=description, unit="step", disable=not progress, file=sys.stderr) as bar:
        done = 0
        while done < steps:
            chunk = min(100, steps - done)
            integrator.step(chunk)
            done += chunk
            bar.update(chunk)


def _water_cluster(forcefield: app.ForceField, model: str, radius: float) -> app.Modeller:
    """Waters of a solvent box whose oxygen lies within ``radius`` nm of the box centre, no PBC."""
    edge = 2.0 * radius + 0.6
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, model=model, boxSize=mm.Vec3(edge, edge, edge) * unit.nanometers)
    positions = np.asarray(modeller.positions.value_in_unit(unit.nanometers))
    centre = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
    outside = []
    for residue in modeller.topology.residues():
        oxygen = next(
            atom for atom in residue.atoms() if atom.element is not None and atom.element.symbol == "O"
        )
        if np.linalg.norm(np.asarray(positions[oxygen.index]) - centre) > radius:
            outside.append(residue)
    modeller.delete(outside)
    modeller.topology.setPeriodicBoxVectors(None)
    if modeller.topology.getNumResidues() == 0:
        raise DefinitionError(f"water cluster of radius {radius} nm holds no water; use a larger radius_nm.")
    return modeller


def _remove_rigid_motion(system: mm.System, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Subtract the centre-of-mass velocity and the rigid rotation ω × r (massive particles)."""
    m = np.array([system.getParticleMass(i).value_in_unit(unit.dalton) for i in range(len(x))])
    massive = m > 0
    mm_, xm, vm = m[massive, None], x[massive], v[massive]
    centre = (mm_ * xm).sum(0) / mm_.sum()
    vm = vm - (mm_ * vm).sum(0) / mm_.sum()
    r = xm - centre
    angular = (mm_ * np.cross(r, vm)).sum(0)
    inertia = (
        mm_[:, 0, None, None] * ((r * r).sum(1)[:, None, None] * np.eye(3) - r[:, :, None] * r[:, None, :])
    ).sum(0)
    omega = np.linalg.solve(inertia, angular)
    out = v.copy()
    out[massive] = vm - np.cross(omega, r)
    return out


def read_pdb(path: Path) -> app.PDBFile:
    """Read a PDB file with OpenMM's ``PDBFile``; a ``.pdb.gz`` is read through gzip."""
    if path.name.endswith(".gz"):
        with gzip.open(path, "rt", encoding="utf-8") as handle:
            return app.PDBFile(handle)
    return app.PDBFile(str(path))


def _resolve_pdb(spec: str, name: str) -> Path:
    if spec.startswith("openmm:"):
        path = Path(app.__file__).parent / spec.removeprefix("openmm:")
    else:
        path = Path(spec)
        if not path.is_absolute():
            from .definitions import DEFINITIONS_DIR

            path = DEFINITIONS_DIR / path
    if not path.is_file():
        raise DefinitionError(f"system {name!r}: PDB file {path} not found.")
    return path
