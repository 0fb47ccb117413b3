"""Compare integrators from the same equilibrated start with the library's ``compare``.

The same as ``alphaprk compare``, from Python:

    python examples/compare_integrators.py --system tip3p-3nm --steps 1000
"""

import argparse

from openmm_alphaprk.workflows import compare
from openmm_alphaprk.workflows.comparison import ACCURACY_STEPS

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("--system", default="tip3p-2nm", help="system name (alphaprk systems); default tip3p-2nm")
parser.add_argument("--steps", type=int, default=500, help="NVE steps of 2 fs per integrator (default 500)")
parser.add_argument("--output", default="compare-example", help="output folder")
parser.add_argument(
    "--accuracy-steps",
    type=int,
    default=ACCURACY_STEPS,
    help=f"steps after which each row's position error is measured (default {ACCURACY_STEPS}; 0: none)",
)
args = parser.parse_args()

result = compare(
    args.system,
    # the baseline (RATTLE), the recommended RATTLE-4 + rescaling, Suzuki's composition of
    # RATTLE steps without it, a fixed-α member of the family, the energy mode (the method
    # under study) and OpenMM's VerletIntegrator (leapfrog: compare its drift only)
    ["rattle", "rattle4+rescale", "alpha4=0", "alpha=1/6", "energy4", "verlet"],
    args.output,
    steps=args.steps,
    timestep=0.002,  # ps
    energy_interval=5,
    accuracy_steps=args.accuracy_steps,
)
print(result.table)
for summary in result.summaries:
    print(f"{summary.integrator}: {summary.force_evaluations_per_step:.2f} force evaluations/step")
print("figure:", result.figure)
