"""Small rigid-water boxes built with OpenMM's own ForceField and Modeller."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import openmm as mm
import openmm.app as app
import openmm.unit as unit

from ._units import to_float


@dataclass
class WaterBox:
    """A water box: topology, system and an equilibrated (consistent) state."""

    topology: app.Topology
    system: mm.System
    positions: np.ndarray  # nm, (N, 3)
    velocities: np.ndarray  # nm/ps, (N, 3)

    @property
    def n_atoms(self) -> int:
        return self.system.getNumParticles()


def build_water_box(
    box_size: unit.Quantity | float = 3.0,
    *,
    model: str = "tip3p",
    cutoff: unit.Quantity | float = 0.9,
    temperature: unit.Quantity | float = 300.0,
    equilibration_steps: int = 500,
    seed: int = 2024,
    platform: str = "CPU",
) -> WaterBox:
    """Build, minimize and briefly equilibrate a cubic box of rigid water with PME.

    Parameters
    ----------
    box_size
        Edge of the cubic box (nm).
    model
        Water model known to OpenMM's ForceField and Modeller ('tip3p', 'spce', 'tip4pew').
    cutoff
        Direct-space cutoff (nm); must be below half the box edge.
    temperature
        Langevin equilibration temperature (K).
    equilibration_steps
        2 fs Langevin steps after minimization.
    seed
        Seed of the velocity initialisation and the Langevin thermostat.
    platform
        OpenMM platform used for the set-up.

    Returns
    -------
    WaterBox
        With ``removeCMMotion=False`` (NVE bookkeeping), constrained positions and
        velocities satisfying the velocity constraints.

    """
    edge = to_float(box_size, unit.nanometers, "box_size", positive=True)
    rc = to_float(cutoff, unit.nanometers, "cutoff", positive=True)
    kelvin = to_float(temperature, unit.kelvin, "temperature", positive=True)
    if rc >= edge / 2:
        raise ValueError(f"cutoff {rc} nm must be below half the box edge ({edge / 2} nm); use a larger box.")
    forcefield = app.ForceField(f"{model}.xml")
    modeller = app.Modeller(app.Topology(), [])
    modeller.addSolvent(forcefield, model=model, boxSize=mm.Vec3(edge, edge, edge) * unit.nanometers)
    system = forcefield.createSystem(
        modeller.topology,
        nonbondedMethod=app.PME,
        nonbondedCutoff=rc * unit.nanometers,
        constraints=app.HBonds,
        rigidWater=True,
        removeCMMotion=False,
    )
    integrator = mm.LangevinMiddleIntegrator(kelvin, 5.0, 0.002)
    integrator.setRandomNumberSeed(seed)
    integrator.setConstraintTolerance(1e-10)
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName(platform))
    context.setPositions(modeller.positions)
    mm.LocalEnergyMinimizer.minimize(context, 10.0, 500)
    context.setVelocitiesToTemperature(kelvin, seed)
    integrator.step(int(equilibration_steps))
    context.applyConstraints(1e-12)
    context.applyVelocityConstraints(1e-12)
    state = context.getState(getPositions=True, getVelocities=True)
    return WaterBox(
        topology=modeller.topology,
        system=system,
        positions=state.getPositions(asNumpy=True).value_in_unit(unit.nanometers),
        velocities=state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds),
    )
