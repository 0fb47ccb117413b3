r"""The MD benchmark: a sweep of integrators and steps, the dynamics of its runs, its figures.

Run from the repository root::

    python -m openmm_alphaprk.benchmarks.md_sweep docs/sweeps/md_benchmark.toml \
        --json docs/data/benchmarks/benchmarks.json --figures docs/figures --run

``--run`` first runs (or completes) the sweep with the sweep runner (``alphaprk sweep``;
finished cells are skipped); then every run directory is analysed with MDAnalysis (O–O
RDF, diffusion coefficient, H velocity-autocorrelation spectrum; cached per run in
``md_benchmark_analysis.json``), the integrators are timed in interleaved rounds, and every
number goes to the JSON file and the figures to their folder. Without ``--run`` it reports
on the cells finished so far. The pieces: :mod:`.results` (the sweep's rows),
:mod:`.analysis` (dynamics and timing), :mod:`.tables`, :mod:`.figures`.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .analysis import timing_table
from .figures import figures
from .results import REFERENCE, SYSTEMS, get, load_rows, run_label
from .tables import dynamics_table, energy_table, scan_table


def build_report(rows, no_timing: bool, previous: dict, folder: Path) -> dict:
    """Gather the numbers of every system (timing, energy, dynamics, scan) and draw the figures."""
    report = {"energy": {}, "dynamics": {}, "scan": {}, "timing": {}, "reference": run_label(*REFERENCE)}
    for system in SYSTEMS:
        if no_timing or get(rows, system, "rattle", 2.0) is None:
            report["timing"][system] = previous.get("timing", {}).get(system, {})
        else:
            print(f"timing {system} (interleaved rounds)", file=sys.stderr)
            report["timing"][system] = timing_table(system)
        report["energy"][system] = energy_table(rows, system, report["timing"][system])
        report["dynamics"][system] = dynamics_table(rows, system)
        report["scan"][system] = scan_table(rows, system)
    report["figures"] = figures(rows, report, folder)
    import openmm

    report["environment"] = {
        "openmm": openmm.__version__,
        "platform": "CPU",
        "machine": "2-core development machine",
    }
    return report


def main(argv: list[str] | None = None) -> int:
    """Run (optionally) the sweep, then write the JSON file and the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("config", type=Path, help="the sweep's TOML file")
    parser.add_argument("--json", type=Path, required=True, help="the JSON file to write")
    parser.add_argument("--figures", type=Path, required=True, help="the folder of the figures")
    parser.add_argument("--run", action="store_true", help="run the sweep first (finished cells are skipped)")
    parser.add_argument("--workers", type=int, default=None, help="local dask workers for --run")
    parser.add_argument("--no-timing", action="store_true", help="keep the JSON's last timings")
    args = parser.parse_args(argv)
    from ...workflows.sweep import load_config, run_sweep

    config = load_config(args.config)
    if args.run:
        run_sweep(config, n_workers=args.workers)
    previous = json.loads(args.json.read_text(encoding="utf-8")) if args.json.is_file() else {}
    report = build_report(load_rows(config), args.no_timing, previous, args.figures)
    args.json.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {args.json} and {len(report['figures'])} figures in {args.figures}", file=sys.stderr)
    return 0
