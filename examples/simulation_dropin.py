"""The package's integrators as drop-in integrators in an ordinary OpenMM script.

Everything here is plain OpenMM (ForceField, Modeller, Simulation, StateDataReporter,
DCDReporter, CheckpointReporter); only the integrator lines differ from a
VerletIntegrator script: the integrator (by default the recommended one, RATTLE-4 +
velocity rescaling), and ``integrator.check_context(simulation.context)``, which shows it
the platform (the energy tolerances follow its precision) and the System (warnings about
forces that are not smooth, and about barostats, thermostats and a CMMotionRemover, which
the energy-holding integrators do not apply). Plus
``prepare_for_nve(system)``, which readies the System that ``createSystem`` gives with its
defaults for energy-conserving NVE: Lennard-Jones switched off over the last 0.1 nm of
the cutoff and PME's error tolerance tightened, so that the energy is smooth, and the
CMMotionRemover removed (the energy-holding integrators do not apply it; RATTLE and a
fixed alpha would, as VerletIntegrator does).

    python examples/simulation_dropin.py --steps 1000 --output dropin-run
    python examples/simulation_dropin.py --integrator energy4   # the method under study
"""

import argparse
import sys
from pathlib import Path

import openmm as mm
import openmm.app as app
import openmm.unit as unit

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    RattleRescaleIntegrator,
    prepare_for_nve,
)

h = 2 * unit.femtoseconds
INTEGRATORS = {  # the command-line names of each (alphaprk run NAME)
    "rattle4+rescale": lambda: RattleRescaleIntegrator(h, order=4),  # recommended
    "rattle+rescale": lambda: RattleRescaleIntegrator(h),  # RATTLE's cost
    "alpha4=0": lambda: AlphaRattleIntegrator(h, alpha=0.0, order=4),  # symplectic, no rescaling
    "energy4": lambda: AlphaRattleEnergyIntegrator(h, order=4),  # the energy mode, under study
}

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("--steps", type=int, default=1000, help="NVE steps of 2 fs (default 1000)")
parser.add_argument(
    "--integrator", default="rattle4+rescale", choices=INTEGRATORS, help="default rattle4+rescale"
)
parser.add_argument("--output", default="dropin-run", help="folder for the CSV, DCD and checkpoint")
parser.add_argument(
    "--minimize-steps", type=int, default=200, help="at most this many minimization steps (default 200)"
)
args = parser.parse_args()
out = Path(args.output)
out.mkdir(exist_ok=True)

# a 2 nm box of TIP3P water with PME, built by OpenMM
forcefield = app.ForceField("amber14/tip3p.xml")
modeller = app.Modeller(app.Topology(), [])
modeller.addSolvent(forcefield, model="tip3p", boxSize=mm.Vec3(2.0, 2.0, 2.0) * unit.nanometers)
system = forcefield.createSystem(
    modeller.topology, nonbondedMethod=app.PME, nonbondedCutoff=0.9 * unit.nanometers, constraints=app.HBonds
)
for change in prepare_for_nve(system):  # smooth forces, no CMMotionRemover: what holding the energy needs
    print(change)

integrator = INTEGRATORS[args.integrator]()  # the line that differs from a VerletIntegrator script
simulation = app.Simulation(modeller.topology, system, integrator, mm.Platform.getPlatformByName("CPU"))
integrator.check_context(simulation.context)  # the platform's precision, and the System's warnings
simulation.context.setPositions(modeller.positions)
simulation.minimizeEnergy(maxIterations=args.minimize_steps)
simulation.context.setVelocitiesToTemperature(300 * unit.kelvin, 1)
simulation.context.applyVelocityConstraints(1e-10)

simulation.reporters.append(
    app.StateDataReporter(
        str(out / "energies.csv"),
        10,
        step=True,
        time=True,
        potentialEnergy=True,
        kineticEnergy=True,
        totalEnergy=True,
        temperature=True,
    )
)
simulation.reporters.append(
    app.StateDataReporter(sys.stdout, max(args.steps // 5, 1), step=True, totalEnergy=True)
)
simulation.reporters.append(app.DCDReporter(str(out / "trajectory.dcd"), 100))
simulation.reporters.append(app.CheckpointReporter(str(out / "checkpoint.chk"), 500))
simulation.step(args.steps)

print(f"{integrator!r}: {integrator.force_evaluations_per_step:.2f} force evaluations per step")
