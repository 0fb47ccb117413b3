"""RATTLE + rescaling holding U + K + K_a instead of U + K, measured against the h → 0 limit of ⟨U⟩.

K_a = ½ Σ m |P(½ h F/m)|², P RATTLE's velocity projection: the kinetic energy of the half
kick. K + K_a is the mean of the kinetic energies of the half-step velocities v ± ½hF/m
(projected) around the on-step v, which for velocity Verlet on a harmonic oscillator is
unbiased where the on-step K is low by (1 − h²ω²/4); held at E_ref it puts ⟨U⟩ at E/2 there.

With the weight 2/3 (``U + K + 2/3 K_a``) it holds, in the mean, the kinetic energy that
Tolman's generalized equipartition gives on velocity Verlet's O(h²) shadow Hamiltonian
H̃ = H + h²(vᵀ∇²U v/12 − Fᵀ M⁻¹ F/24), the idea of Eastwood et al. (JCTC 6 (2010) 2045):
½⟨p·∂H̃/∂p⟩ = ⟨K⟩ + h²⟨vᵀ∇²U v⟩/12, and the canonical mean of vᵀ∇²U v is that of Fᵀ M⁻¹ F,
so the correction's mean is (2/3)⟨K_a⟩. Only the mean: the instantaneous Hessian term (a
Hessian–vector product per step) is not computed.
The question (docs/physics.md): does it bring ⟨U⟩ at the start's energy closer to the
h → 0 limit than the plain rescaling?

Reads the starts and the RATTLE runs of ``alphaprk bench physics segments`` (``--physics``,
its output folder): from each start, 10 ps of NVE of both rescalings at each ``--timesteps``,
H read every 0.02 ps; the h → 0 limit is Richardson's from RATTLE at 1 and 0.5 fs of the same
segments. CPU platform, one thread. Prints a line per run; ``--json`` writes them.

    python tools/scripts/half_kick_estimator.py --physics /work/physics/water --json out.json
"""

from __future__ import annotations

import argparse
import json
from functools import partial
from pathlib import Path

import numpy as np
import openmm as mm

from openmm_alphaprk import RattleRescaleIntegrator
from openmm_alphaprk.integrators.rescale import VELOCITY_SCALE


class HalfKickRescaleIntegrator(RattleRescaleIntegrator):
    """RATTLE + rescaling that holds U + K + w K_a = E_ref (a prototype: every step, RATTLE's step).

    ``half_kick_weight`` w: 1 holds the mean of the half-step kinetic energies; 2/3 the
    generalized-equipartition kinetic energy of velocity Verlet's O(h²) shadow Hamiltonian
    with its Hessian term replaced by its canonical mean (see the module docstring).
    """

    def __init__(self, *args, half_kick_weight: float = 1.0, **kwargs) -> None:
        self._half_kick_weight = float(half_kick_weight)
        super().__init__(*args, **kwargs)

    def _add_rescale_variables(self) -> None:
        super()._add_rescale_variables()
        self.addPerDofVariable("kept_velocity", 0)
        self.addGlobalVariable("half_kick_energy", 0)

    def _add_scale_factor(self) -> None:
        self.addComputePerDof("kept_velocity", "v")
        self.addComputePerDof("v", "0.5*dt*f/m")
        self.addConstrainVelocities()
        self._add_sum("half_kick_energy", "0.5*m*v*v")
        self.addComputePerDof("v", "kept_velocity")
        super()._add_scale_factor()
        self.addComputeGlobal(
            "scale_squared",
            f"(reference_energy - {self._half_kick_weight!r}*half_kick_energy - potential_energy"
            " - rigid_kinetic_energy)"
            "/(kinetic_energy - rigid_kinetic_energy)",
        )
        self.addComputeGlobal(VELOCITY_SCALE, "select(no_factor, 1, sqrt(max(scale_squared, 0)))")


ROWS = {
    "rattle+rescale": RattleRescaleIntegrator,
    "rattle+rescale, U + K + K_a": HalfKickRescaleIntegrator,
    "rattle+rescale, U + K + 2/3 K_a": partial(HalfKickRescaleIntegrator, half_kick_weight=2 / 3),
}


def mean_potential(physics: Path, row: str, start: int) -> float:
    """⟨U⟩ (kJ/mol) of a segment of ``alphaprk bench physics`` from its energies.csv."""
    table = np.genfromtxt(
        physics / "segments" / row / f"start_{start}" / "energies.csv", delimiter=",", skip_header=1
    )
    return float(table[:, 2].mean())


def run(
    system: mm.System, state: mm.State, integrator: mm.Integrator, timestep_fs: float, length_ps: float
) -> dict:
    """Run ``integrator`` from ``state``; ⟨U⟩, ⟨K⟩ and the last H (kJ/mol), H read every 0.02 ps."""
    context = mm.Context(system, integrator, mm.Platform.getPlatformByName("CPU"), {"Threads": "1"})
    context.setState(state)
    context.applyConstraints(1e-12)  # a start written before bench physics projected its starts
    context.applyVelocityConstraints(1e-12)
    every = round(0.02 / (timestep_fs / 1000.0))
    energies = []
    for i in range(round(length_ps / 0.02) + 1):
        if i:
            integrator.step(every)
        read = context.getState(getEnergy=True)
        energies.append((read.getPotentialEnergy()._value, read.getKineticEnergy()._value))
    u, k = np.array(energies).T
    held = isinstance(integrator, HalfKickRescaleIntegrator)
    half_kick = integrator.getGlobalVariableByName("half_kick_energy") if held else 0.0
    return {"U": float(u.mean()), "K": float(k.mean()), "H_last": float(u[-1] + k[-1]), "K_a_last": half_kick}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--physics", type=Path, required=True, help="output folder of bench physics segments")
    parser.add_argument("--timesteps", type=float, nargs="+", default=[4.0, 2.0], help="fs")
    parser.add_argument("--length", type=float, default=10.0, help="ps of NVE from each start")
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--rows", nargs="+", choices=list(ROWS), default=list(ROWS), help="which rescalings")
    parser.add_argument("--json", type=Path, help="write the runs (runs in it are kept)")
    args = parser.parse_args(argv)
    limit = [
        (4 * mean_potential(args.physics, "rattle@0.5fs", s) - mean_potential(args.physics, "rattle@1fs", s))
        / 3
        for s in range(args.starts)
    ]
    runs = []
    if args.json and args.json.is_file():
        runs = json.loads(args.json.read_text(encoding="utf-8"))["runs"]
    done = {(r["row"], r["timestep_fs"], r["start"]) for r in runs}
    for timestep in args.timesteps:
        for start in range(args.starts):
            folder = args.physics / "segments" / f"rattle@{timestep:g}fs" / f"start_{start}"
            system = mm.XmlSerializer.deserialize((folder / "system.xml").read_text(encoding="utf-8"))
            state = mm.XmlSerializer.deserialize(
                (args.physics / "starts" / f"start_{start}.xml").read_text(encoding="utf-8")
            )
            for name in args.rows:
                if (name, timestep, start) in done:
                    continue
                make = ROWS[name]
                result = run(system, state, make(timestep / 1000.0), timestep, args.length)
                result.update(
                    row=name, timestep_fs=timestep, start=start, U_minus_limit=result["U"] - limit[start]
                )
                runs.append(result)
                print(json.dumps(result), flush=True)
                if args.json:  # after every run: an interrupted run loses at most the one going
                    write(args.json, args.length, runs)


def write(path: Path, length_ps: float, runs: list[dict]) -> None:
    """Write the runs so far to ``path`` (JSON)."""
    document = {
        "system": "tip3p-2nm (the starts of bench physics segments)",
        "length_ps": length_ps,
        "limit": "Richardson from RATTLE at 1 and 0.5 fs of the same segments, per start",
        "openmm": mm.__version__,
        "runs": runs,
    }
    path.write_text(json.dumps(document, indent=1), encoding="utf-8")


if __name__ == "__main__":
    main()
