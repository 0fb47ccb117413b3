r"""Numerical validation of the α-RATTLE family: every number and figure of docs/validation.md.

Run from the repository root::

    python -m tools.reports.validation           # the full page (about 10 minutes on 2 cores)
    python -m tools.reports.validation --quick   # smaller runs, to check the report (1 minute)

It computes

1. convergence orders on the plain pendulum (error after one exact period), on the
   pendulum with a spring and on a cluster of three rigid waters (error at a fixed
   time against a fine-step reference), with the NumPy reference
   (:mod:`.validation_convergence`);
2. symplecticity defects of fixed α, the energy modes and the one-pass variant
   (:mod:`.validation_symplecticity`);
3. α* against h for both energy modes (NumPy reference), and α* distributions of
   the OpenMM energy modes on the 774-atom ``tip3p-2nm`` box (:mod:`.validation_openmm`);
4. long OpenMM runs on the 222-atom ``water-cluster`` (Reference and CPU platforms):
   angular and linear momentum, constraints and H − E_ref against time
   (:mod:`.validation_openmm`, :mod:`.validation_reporter`).

It writes ``docs/data/validation/validation.json`` (all numbers), ``docs/figures/validation_*.png``
(:mod:`.validation_figures`), rewrites the generated tables of ``docs/validation.md``
(:mod:`.validation_tables`, between ``<!-- generated: NAME -->`` and
``<!-- end generated: NAME -->``; the prose is left alone) and prints the tables.
OpenMM runs use one CPU thread. ``--quick`` writes to a scratch directory unless
paths are given, so that it never overwrites the page's numbers.
"""

from __future__ import annotations

import argparse
import json
import platform as python_platform
import re
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from tools.reports.markdown import update_page
from tools.reports.validation_convergence import convergence
from tools.reports.validation_figures import write_figures
from tools.reports.validation_openmm import long_runs, openmm_alpha_star
from tools.reports.validation_symplecticity import symplecticity
from tools.reports.validation_tables import render_tables

DOCS = Path(__file__).resolve().parents[2] / "docs"
COMMAND = "python -m tools.reports.validation"


def dump_json(data: dict) -> str:
    """Return indented JSON with every list of plain numbers on one line."""
    text = json.dumps(data, indent=1)
    numbers = re.compile(r"\[\s*([-0-9.eE+]+(?:,\s*[-0-9.eE+]+)*)\s*\]")
    return numbers.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]", text) + "\n"


def compute(quick: bool, workdir: Path) -> dict:
    """Run every study; return the page's data (what ``docs/data/validation/validation.json`` holds)."""
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


def build_parser() -> argparse.ArgumentParser:
    """Return the command line's parser."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small runs, to check the script")
    parser.add_argument(
        "--json", type=Path, help="output JSON (default docs/data/validation/validation.json)"
    )
    parser.add_argument("--figures", type=Path, help="figure folder (default docs/figures)")
    parser.add_argument(
        "--page", type=Path, help="page whose tables are rewritten (default docs/validation.md)"
    )
    parser.add_argument(
        "--workdir", type=Path, help="run directories of the OpenMM runs (default: temporary)"
    )
    parser.add_argument(
        "--from-json",
        action="store_true",
        help="compute nothing: redraw the figures and rewrite the tables from the existing JSON",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Compute everything, write the JSON, the figures and the page's tables; print the tables."""
    args = build_parser().parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="alphaprk-validation-"))
    if args.quick:
        json_path = args.json or scratch / "validation.json"
        figures = args.figures or scratch / "figures"
        page = args.page
    else:
        json_path = args.json or DOCS / "data" / "validation" / "validation.json"
        figures = args.figures or DOCS / "figures"
        page = args.page or DOCS / "validation.md"
    if args.from_json:
        data = json.loads(json_path.read_text(encoding="utf-8"))
    else:
        data = compute(args.quick, args.workdir or scratch / "runs")
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(dump_json(data), encoding="utf-8")
    write_figures(data, figures)
    tables = render_tables(data)
    for name, table in tables.items():
        print(f"\n## {name}\n{table}")
    if page is not None:
        missing = update_page(page, tables)
        if missing:
            print(f"\n{page} has no place for the tables {', '.join(missing)}", file=sys.stderr)
    print(f"\nJSON: {json_path}\nfigures: {figures}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
