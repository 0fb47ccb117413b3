r"""Regenerate every table and figure of docs/benchmarks.md from the MD benchmark sweep.

Run from the repository root::

    python -m tools.reports.md_benchmark --run

``--run`` first runs (or completes) the sweep ``docs/sweeps/md_benchmark.toml`` with the
sweep runner (``alphaprk sweep``; finished cells are skipped), then analyses every run
directory with MDAnalysis (O–O RDF, diffusion coefficient, H velocity-autocorrelation
spectrum; cached per run in ``md_benchmark_analysis.json``), and writes

- ``docs/data/benchmarks/benchmarks.json``: every number of the page,
- ``docs/figures/benchmark_*.png``: the figures,
- the generated tables of ``docs/benchmarks.md`` (between ``<!-- generated: NAME -->``
  and ``<!-- end generated: NAME -->``; the prose around them is written by hand).

Without ``--run`` it reports on the cells finished so far. The pieces:
:mod:`.md_benchmark_results` (the sweep's rows), :mod:`.md_benchmark_analysis`
(dynamics and timing), :mod:`.md_benchmark_tables`, :mod:`.md_benchmark_figures`.
"""

from __future__ import annotations

import argparse
import json
import sys

from tools.reports.markdown import replace_generated
from tools.reports.md_benchmark_analysis import timing_table
from tools.reports.md_benchmark_figures import figures
from tools.reports.md_benchmark_results import (
    CONFIG,
    JSON_OUT,
    PAGE,
    REFERENCE,
    ROOT,
    SYSTEMS,
    get,
    load_rows,
    run_label,
)
from tools.reports.md_benchmark_tables import (
    dynamics_markdown,
    dynamics_table,
    energy_markdown,
    energy_table,
    scan_markdown,
    scan_table,
)


def build_parser() -> argparse.ArgumentParser:
    """Return the command line's parser."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", action="store_true", help="run the sweep first (finished cells are skipped)")
    parser.add_argument("--workers", type=int, default=None, help="local dask workers for --run")
    parser.add_argument(
        "--no-timing", action="store_true", help="skip the interleaved timing (keep the JSON's last timings)"
    )
    return parser


def build_report(rows, no_timing: bool) -> dict:
    """Gather the numbers of every system (timing, energy, dynamics, scan) and draw the figures."""
    report = {"energy": {}, "dynamics": {}, "scan": {}, "timing": {}, "reference": run_label(*REFERENCE)}
    previous = (
        json.loads(JSON_OUT.read_text(encoding="utf-8")).get("timing", {}) if JSON_OUT.is_file() else {}
    )
    for system in SYSTEMS:
        if no_timing or get(rows, system, "rattle", 2.0) is None:
            report["timing"][system] = previous.get(system, {})
        else:
            print(f"timing {system} (interleaved rounds)", file=sys.stderr)
            report["timing"][system] = timing_table(system)
        report["energy"][system] = energy_table(rows, system, report["timing"][system])
        report["dynamics"][system] = dynamics_table(rows, system)
        report["scan"][system] = scan_table(rows, system)
    report["figures"] = figures(rows, report)
    import openmm

    report["environment"] = {
        "openmm": openmm.__version__,
        "platform": "CPU",
        "machine": "2-core development machine",
    }
    return report


def render_page(page: str, report: dict) -> str:
    """Replace the generated blocks of the page's text ``page`` with the report's tables."""
    for system in SYSTEMS:
        if report["energy"][system]:
            page = replace_generated(
                page, f"energy {system}", energy_markdown(system, report["energy"][system]), PAGE
            )
        if report["dynamics"][system]:
            page = replace_generated(
                page,
                f"dynamics {system}",
                dynamics_markdown(system, report["dynamics"][system], report["reference"]),
                PAGE,
            )
        if report["scan"][system]:
            page = replace_generated(
                page, f"scan {system}", scan_markdown(system, report["scan"][system]), PAGE
            )
    return page


def render() -> dict:
    """docs/benchmarks.md's generated blocks from the report the last run wrote (``benchmarks.json``)."""
    report = json.loads(JSON_OUT.read_text(encoding="utf-8"))
    page = render_page(PAGE.read_text(encoding="utf-8"), report)
    from tools.reports.markdown import read_blocks

    return {PAGE: read_blocks(page)}


def main(argv: list[str] | None = None) -> int:
    """Run (optionally) the sweep, then write the JSON, the figures and the page's tables."""
    args = build_parser().parse_args(argv)
    from openmm_alphaprk.workflows.sweep import load_config, run_sweep

    config = load_config(CONFIG)
    if args.run:
        run_sweep(config, n_workers=args.workers)
    rows = load_rows(config)
    report = build_report(rows, args.no_timing)
    JSON_OUT.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    PAGE.write_text(render_page(PAGE.read_text(encoding="utf-8"), report), encoding="utf-8")
    print(
        f"wrote {JSON_OUT.relative_to(ROOT)}, {len(report['figures'])} figures, "
        f"tables in {PAGE.relative_to(ROOT)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
