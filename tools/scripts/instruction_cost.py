"""Instructions per step of each integrator against the first's, counted by valgrind: no timing noise.

On a shared 2-core machine the step times of two identical RATTLE Contexts differ by
2–6 % from run to run (wall clock or process time), so a cost of about 1 % cannot be
timed there. Instructions can be counted: each integrator runs in a process of its own
under ``valgrind --tool=callgrind`` on the CPU platform with one thread, once for
``--warm`` steps and once for ``--warm`` + ``--steps``; the difference of the two counts,
over ``--steps``, is the instructions per step with the start-up (imports, the Context,
the first steps) cancelled. With ``--steps`` a multiple of every N, each ``@N`` row counts
its rescaling steps in their share. Instructions are not time (memory traffic is not in
them): the script measures the work a program adds, for the cost tables' noise to be read
against. Prints a row per integrator with its ratio to the first row of the same run;
``--json`` writes them.

    python tools/scripts/instruction_cost.py --system tip3p-2nm \
        --integrators rattle rattle+rescale rattle+rescale@10 rattle+rescale@100 --json out.json

Needs valgrind on PATH (not a dependency of the package).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from datetime import date
from pathlib import Path

#: What each counted process runs: the system's start, the integrator, ``steps`` steps.
_STEPPER = """
import sys
import openmm as mm
from openmm_alphaprk.runs.integrator_names import make_integrator
from openmm_alphaprk.systems import prepare_system
system, name, steps, timestep = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
prepared = prepare_system(system)
integrator = make_integrator(name, timestep)
platform = mm.Platform.getPlatformByName("CPU")
context = mm.Context(prepared.system, integrator, platform, {"Threads": "1"})
context.setState(prepared.state)
if hasattr(integrator, "check_context"):
    integrator.check_context(context)
integrator.step(steps)
"""

_COLLECTED = re.compile(r"Collected\s*:\s*(\d+)")


def collected_instructions(valgrind_output: str) -> int:
    """Return the instruction count callgrind printed ("Collected : N")."""
    found = _COLLECTED.findall(valgrind_output)
    if not found:
        raise RuntimeError(f"no instruction count in valgrind's output:\n{valgrind_output[-2000:]}")
    return int(found[-1])


def count(system: str, name: str, steps: int, timestep_ps: float, folder: Path) -> int:
    """Instructions of one process that takes ``steps`` steps of ``name`` on ``system``."""
    stepper = folder / "stepper.py"
    command = [
        "valgrind",
        "--tool=callgrind",
        f"--callgrind-out-file={folder / 'callgrind.%p.out'}",
        sys.executable,
        str(stepper),
        system,
        name,
        str(steps),
        str(timestep_ps),
    ]
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{result.stderr[-2000:]}")
    return collected_instructions(result.stderr)


def instructions_per_step(short: int, long: int, steps: int) -> float:
    """Instructions per step from the counts of a short and a longer run ``steps`` steps apart."""
    if long <= short:
        raise RuntimeError(f"the longer run counted {long} instructions, not more than the shorter's {short}")
    return (long - short) / steps


def parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--system", default="tip3p-2nm", help="a system of `alphaprk systems`")
    parser.add_argument(
        "--integrators", nargs="+", default=["rattle", "rattle+rescale@10", "rattle+rescale@100"]
    )
    parser.add_argument("--steps", type=int, default=200, help="counted steps (default 200)")
    parser.add_argument("--warm", type=int, default=20, help="steps of the shorter run (default 20)")
    parser.add_argument("--timestep", type=float, default=2.0, help="step in fs (default 2)")
    parser.add_argument("--workers", type=int, default=2, help="valgrind processes at once (default 2)")
    parser.add_argument("--json", help="also write the rows to this JSON file")
    parser.add_argument("--note", default="", help="a note to keep in the JSON (e.g. which program)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.steps <= 0 or args.warm <= 0:
        parser().error("--steps and --warm must be positive")
    timestep_ps = args.timestep / 1000
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        (folder / "stepper.py").write_text(_STEPPER, encoding="utf-8")
        runs = [(name, steps) for name in args.integrators for steps in (args.warm, args.warm + args.steps)]
        with ThreadPoolExecutor(max_workers=args.workers) as pool:
            counts = list(pool.map(lambda run: count(args.system, *run, timestep_ps, folder), runs))
    by_run = dict(zip(runs, counts))
    rows = []
    for name in args.integrators:
        short, long = by_run[(name, args.warm)], by_run[(name, args.warm + args.steps)]
        per_step = instructions_per_step(short, long, args.steps)
        rows.append({"integrator": name, "instructions_per_step": per_step})
    for row in rows:
        row["ratio"] = row["instructions_per_step"] / rows[0]["instructions_per_step"]
    header = (
        f"system {args.system}, {args.timestep:g} fs, CPU platform, one thread, under valgrind's callgrind; "
        f"instructions per step: (count after {args.warm + args.steps} steps - count after {args.warm}) "
        f"/ {args.steps}; ratio against {args.integrators[0]} in the same run"
    )
    print(header)
    print(f"{'integrator':28s} {'M instructions/step':>20s} {'ratio':>8s}")
    for row in rows:
        print(f"{row['integrator']:28s} {row['instructions_per_step'] / 1e6:20.3f} {row['ratio']:8.4f}")
    if args.json:
        data = {"header": header, "day": date.today().isoformat(), "system": args.system, "rows": rows}
        if args.note:
            data["note"] = args.note
        Path(args.json).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
