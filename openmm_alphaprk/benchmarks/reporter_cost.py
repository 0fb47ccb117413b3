"""Cost of reporting the energy mode's controller: steps/s with and without AlphaControllerReporter.

Two measurements in one process:

1. steps/s with the reporter every step, every 10 steps (the driver's default: the energy
   interval) and without it, in interleaved rounds (the median of each);
2. the time of one report by itself, as ``Simulation`` makes it: a ``getState`` (no data,
   parameters, as OpenMM asks) and the reporter's ``report`` (median of many). Where the
   machine is shared, (2) is the steadier number; steps/s follow from it as
   1 / (t_step + t_report / interval).

RATTLE has no controller to report; its rows use a reporter that reads nothing, to show what
asking ``Simulation`` for a report every step costs by itself (one step per ``integrator.step``
call and a ``getState`` after each).

    python -m openmm_alphaprk.benchmarks.reporter_cost [--system tip3p-2nm] [--platform CPU] \
        [--rounds 15] [--json FILE]

``--json`` also writes every row (the steps/s of each round, their median, the ratio to no
reporter, the time of one report) and the settings of the run, for docs/driver.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

import openmm as mm
import openmm.app as app

from openmm_alphaprk.runs import AlphaControllerReporter
from openmm_alphaprk.runs.integrator_names import make_integrator
from openmm_alphaprk.systems import prepare_system

NONE = "no reporter"
TIMESTEP_PS = 0.002


class NullReporter:
    """A reporter that asks for no State data and writes nothing: the cost of a report by itself."""

    def __init__(self, interval: int):
        self._interval = interval

    def describeNextReport(self, simulation):
        return {
            "steps": self._interval - simulation.currentStep % self._interval,
            "periodic": None,
            "include": [],
        }

    def report(self, simulation, state):
        pass


def _rows(folder: Path) -> dict:
    return {
        ("energy4", NONE): None,
        ("energy4", "AlphaControllerReporter every step"): lambda: AlphaControllerReporter(
            str(folder / "a.csv"), 1
        ),
        ("energy4", "AlphaControllerReporter every 10 steps"): lambda: AlphaControllerReporter(
            str(folder / "b.csv"), 10
        ),
        ("rattle", NONE): None,
        ("rattle", "empty reporter every step"): lambda: NullReporter(1),
        ("rattle", "empty reporter every 10 steps"): lambda: NullReporter(10),
    }


def _report_time(simulation: app.Simulation, repeats: int) -> float:
    """Median time (µs) of one report of the simulation's reporter, with OpenMM's getState."""
    (reporter,) = simulation.reporters
    groups = simulation.context.getIntegrator().getIntegrationForceGroups()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        state = simulation.context.getState(groups=groups, enforcePeriodicBox=False, parameters=True)
        reporter.report(simulation, state)
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e6


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--system", default="tip3p-2nm")
    parser.add_argument("--platform", default="CPU")
    parser.add_argument("--threads", default=None, help="CPU platform threads (default: OpenMM's)")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--energy4-steps", type=int, default=20, help="steps of energy4 per round and row")
    parser.add_argument("--rattle-steps", type=int, default=100, help="steps of RATTLE per round and row")
    parser.add_argument("--repeats", type=int, default=2000, help="reports timed by themselves")
    parser.add_argument("--json", help="also write the rows and the run's settings to this file")
    args = parser.parse_args(argv)
    prepared = prepare_system(args.system, progress=False)
    platform = mm.Platform.getPlatformByName(args.platform)
    properties = {"Threads": args.threads} if args.threads else {}
    rows = _rows(Path(tempfile.mkdtemp(prefix="reporter-cost-")))
    simulations = {}
    for (name, how), make in rows.items():
        integrator = make_integrator(name, TIMESTEP_PS)
        simulation = app.Simulation(prepared.topology, prepared.system, integrator, platform, properties)
        simulation.context.setState(prepared.state)
        if make is not None:
            simulation.reporters.append(make())
        simulation.step(10)  # first step: program set-up, E_ref
        simulations[(name, how)] = simulation
    rates: dict[tuple[str, str], list[float]] = {key: [] for key in rows}
    for _ in range(args.rounds):
        for (name, how), simulation in simulations.items():
            steps = args.energy4_steps if name == "energy4" else args.rattle_steps
            start = time.perf_counter()
            simulation.step(steps)
            rates[(name, how)].append(steps / (time.perf_counter() - start))
    threads = f", {args.threads} threads" if args.threads else ""
    print(f"{args.system} ({prepared.n_atoms} atoms), platform {args.platform}{threads}")
    print("| integrator | reporting | steps/s (median of rounds) | × no reporter | one report (µs) |")
    print("| --- | --- | ---: | ---: | ---: |")
    rows = []
    for (name, how), values in rates.items():
        median = statistics.median(values)
        base = statistics.median(rates[(name, NONE)])
        simulation = simulations[(name, how)]
        report_us = _report_time(simulation, args.repeats) if simulation.reporters else None
        report = "–" if report_us is None else f"{report_us:.0f}"
        print(f"| {name} | {how} | {median:.1f} | {median / base:.3f} | {report} |")
        rows.append(
            {
                "integrator": name,
                "reporting": how,
                "steps_per_s_rounds": values,
                "steps_per_s": median,
                "ratio_to_no_reporter": median / base,
                "report_us": report_us,
            }
        )
    if args.json:
        settings = {
            "system": args.system,
            "atoms": prepared.n_atoms,
            "platform": args.platform,
            "threads": args.threads,
            "rounds": args.rounds,
            "energy4_steps": args.energy4_steps,
            "rattle_steps": args.rattle_steps,
            "repeats": args.repeats,
            "timestep_fs": TIMESTEP_PS * 1000,
            "load": list(os.getloadavg()),
            "openmm": mm.__version__,
        }
        Path(args.json).write_text(
            json.dumps({"settings": settings, "rows": rows}, indent=1), encoding="utf-8"
        )


if __name__ == "__main__":
    main()
