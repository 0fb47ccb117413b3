"""Analyse an NVE run with MDAnalysis: constraints, O–O RDF, diffusion, energy drift.

Makes a short run first if no run directory is given:

    python examples/analyze_run.py                 # short RATTLE run of tip3p-2nm, then analyse it
    python examples/analyze_run.py path/to/run     # analyse a folder written by `alphaprk run`
"""

import argparse
import json
from pathlib import Path

import MDAnalysis as mda
import openmm as mm

from openmm_alphaprk.analysis import ConstraintDeviation, Diffusion, energy_drift, oxygen_rdf
from openmm_alphaprk.observables import degrees_of_freedom, drift_text
from openmm_alphaprk.runs import read_energies, run_nve

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("run", nargs="?", default=None, help="a run directory (default: make one)")
parser.add_argument("--steps", type=int, default=500, help="steps of the run made when none is given")
args = parser.parse_args()

run = Path(args.run) if args.run else Path("analysis-example-run")
if args.run is None:
    run_nve("tip3p-2nm", "rattle", run, steps=args.steps, energy_interval=5, trajectory_interval=10)

system = mm.XmlSerializer.deserialize((run / "system.xml").read_text(encoding="utf-8"))
universe = mda.Universe(str(run / "topology.pdb"), str(run / "trajectory.dcd"))

deviation = ConstraintDeviation.from_system(universe, system).run()
print(f"constraints: max |r - d|/d = {deviation.results.overall_max_relative_deviation:.2e}")

rdf = oxygen_rdf(universe)  # MDAnalysis InterRDF between water oxygens
peak = rdf.results.rdf.argmax()
print(f"O-O RDF: first peak g = {rdf.results.rdf[peak]:.2f} at {rdf.results.bins[peak]:.2f} Å")

msd = Diffusion(universe, "resname HOH and name O").run()  # MDAnalysis EinsteinMSD + linear fit
d = msd.results
print(
    f"diffusion: D = {d.diffusion_coefficient:.3g} ± {d.diffusion_coefficient_standard_error:.2g} "
    "× 1e-5 cm²/s "
    f"from {d.frames} frames (± over {d.error_groups} groups of molecules; short runs: not converged)"
)

energies = read_energies(run / "energies.csv")
drift = energy_drift(energies[:, 1], energies[:, 4], degrees_of_freedom(system))  # E_ref: the start state
print(f"drift/DOF: {drift_text(drift.drift_per_dof, drift.drift_per_dof_standard_error, 'kJ/mol/ns')}")
print("energy:", json.dumps(drift.as_dict(), indent=1))
