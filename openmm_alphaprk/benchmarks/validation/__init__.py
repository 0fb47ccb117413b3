r"""Numerical validation of the α-RATTLE family: the experiment behind the validation page's numbers.

Run from the repository root::

    python -m openmm_alphaprk.benchmarks.validation --json docs/data/validation/validation.json
    python -m openmm_alphaprk.benchmarks.validation --quick --json /tmp/v.json   # 1 minute

It computes

1. convergence orders on the plain pendulum (error after one exact period), on the
   pendulum with a spring and on a cluster of three rigid waters (error at a fixed
   time against a fine-step reference), with the NumPy reference (:mod:`.convergence`);
2. symplecticity defects of fixed α, the energy modes and the one-pass variant
   (:mod:`.symplecticity`);
3. α* against h for both energy modes (NumPy reference), and α* distributions of
   the OpenMM energy modes on the 774-atom ``tip3p-2nm`` box (:mod:`.openmm_runs`);
4. long OpenMM runs on the 222-atom ``water-cluster`` (Reference and CPU platforms):
   angular and linear momentum, constraints and H − E_ref against time
   (:mod:`.openmm_runs`, :mod:`.reporter`),

and writes every number to one JSON file (about 10 minutes on 2 cores; OpenMM runs use one
CPU thread). The documentation's tables and figures are drawn from that file by the
project's report tools, outside the package.
"""

from __future__ import annotations

import argparse
import json
import platform as python_platform
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .convergence import convergence
from .openmm_runs import long_runs, openmm_alpha_star
from .symplecticity import symplecticity

COMMAND = "python -m openmm_alphaprk.benchmarks.validation"


def dump_json(data: dict) -> str:
    """Return indented JSON with every list of plain numbers on one line."""
    text = json.dumps(data, indent=1)
    numbers = re.compile(r"\[\s*([-0-9.eE+]+(?:,\s*[-0-9.eE+]+)*)\s*\]")
    return numbers.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text) + "\n"


def compute(quick: bool, workdir: Path) -> dict:
    """Run every study; return every number of the validation (what the JSON file holds)."""
    import openmm as mm

    mm.Platform.getPlatformByName("CPU").setPropertyDefaultValue("Threads", "1")
    started = time.perf_counter()
    timings: dict[str, float] = {}

    def timed(name: str, function: Callable[[], dict]) -> dict:
        t0 = time.perf_counter()
        value = function()
        timings[name] = time.perf_counter() - t0
        print(f"[{timings[name]:6.1f} s] {name}", file=sys.stderr, flush=True)
        return value

    data: dict = {
        "command": COMMAND + (" --quick" if quick else ""),
        "quick": quick,
        "versions": {
            "python": python_platform.python_version(),
            "numpy": np.__version__,
            "openmm": mm.__version__,
        },
        "machine": f"{python_platform.machine()}, OpenMM runs on 1 CPU thread",
    }
    data["convergence"] = timed("convergence", lambda: convergence(quick))
    data["symplecticity"] = timed("symplecticity", lambda: symplecticity(quick))
    data["alpha_star_openmm"] = timed(
        "alpha* on tip3p-2nm", lambda: openmm_alpha_star(workdir, 100 if quick else 1000)
    )
    long_steps = {"Reference": 500, "CPU": 500} if quick else {"Reference": 20000, "CPU": 20000}
    data["long_runs"] = timed("long runs", lambda: long_runs(workdir, long_steps, 20 if quick else 50))
    data["timings_seconds"] = {**timings, "total": time.perf_counter() - started}
    print(f"total {data['timings_seconds']['total']:.0f} s", file=sys.stderr)
    return data


def main(argv: list[str] | None = None) -> int:
    """Run the validation and write its JSON file."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small runs, to check the experiment")
    parser.add_argument("--json", type=Path, required=True, help="the JSON file to write")
    parser.add_argument(
        "--workdir", type=Path, help="run directories of the OpenMM runs (default: beside --json)"
    )
    args = parser.parse_args(argv)
    data = compute(args.quick, args.workdir or args.json.parent / "validation_runs")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(dump_json(data), encoding="utf-8")
    print(f"wrote {args.json}", file=sys.stderr)
    return 0
