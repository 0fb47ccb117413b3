r"""The README's and getting started's measured numbers: the main job's output and the test suite's time.

Record a run of the main job and the suite's times, then write the pages (from the
repository root)::

    python -m tools.reports.main_job record alphaprk-compare-tip3p-2nm --seconds 65 70 68
    python -m tools.reports.main_job suite --tests 640 --seconds 400 410 420 --first-run 500
    python -m tools.reports                   # rewrite the generated blocks (--check: compare)

``record`` copies the run's ``comparison.json`` to ``docs/data/main_job/`` (run folders
made relative) and writes ``docs/data/main_job/timing.json``: the wall-clock seconds of the
command in each run given, the platform, and the command. ``suite`` writes
``docs/data/main_job/test_suite.json``: the default suite's test count and its time in
clean-clone runs (pytest's own time) and on a machine's first run (pocl compiling). The
blocks ``main job`` and ``test suite`` of ``README.md`` and ``docs/getting_started.md`` are
rendered from them, with the machine and day (``docs/data/provenance.toml``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from openmm_alphaprk.observables import drift_text
from tools.reports.markdown import markdown_table
from tools.reports.sources import DATA, ROOT, load

COMPARISON = "main_job/comparison.json"
TIMING = "main_job/timing.json"
SUITE = "main_job/test_suite.json"
BLOCK = "main job"
SUITE_BLOCK = "test suite"
PAGES = (ROOT / "README.md", ROOT / "docs" / "getting_started.md")


def _sci(value: float) -> str:
    if not math.isfinite(value):
        return "–"
    return f"{value:.2g}" if abs(value) >= 1e-3 else f"{value:.1e}"


def _minutes(seconds: float) -> str:
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest} s" if minutes else f"{rest} s"


def render() -> str:
    """Return the block: when and where the main job ran, its table (recommended rows first), its verdict."""
    comparison, source = load(COMPARISON)
    timing, _ = load(TIMING)
    summaries = comparison["summaries"]
    first = summaries[0]
    accuracy = comparison["accuracy"]["rows"]
    after = next(iter(accuracy.values()))["time_fs"] if accuracy else None
    times = ", ".join(_minutes(s) for s in timing["wall_seconds"])
    lead = (
        f"`{timing['command']}` on {source.date}, {source.machine}, {timing['platform']} platform "
        f"(the fastest present there): {times} in {len(timing['wall_seconds'])} runs from a fresh clone "
        f"(install excluded). {first['system']}: {first['n_atoms']} atoms, {first['timestep_fs']:g} fs, "
        f"{first['steps']} steps ({first['simulated_ps']:g} ps) of each integrator from the shipped start; "
        f"RATTLE at h/k for every row of k force evaluations per step; positions against RATTLE at h/64 "
        f"after {after:g} fs. Data: {source.cite()}."
    )
    header = ["integrator", "evaluations/step", "RMS(H − E_ref) kJ/mol", "drift kJ/mol/ns/DOF"]
    if accuracy:
        header.append(f"position error after {after:g} fs (nm)")
    rows = []
    for summary in summaries:
        name = summary["integrator"]
        row = [
            f"`{name}`",
            f"{summary['force_evaluations_per_step']:.2f}",
            _sci(summary["rms_residual"]),
            drift_text(summary["drift_per_dof"], summary["drift_per_dof_standard_error"]),
        ]
        if accuracy:
            row.append(_sci(accuracy[name]["position_rms"]) if name in accuracy else "–")
        rows.append(row)
    return "\n\n".join([lead, markdown_table(header, rows), f"**{comparison['verdict']}**"])


def render_suite() -> str:
    """Return the test suite's sentence: its size and its time from clean clones and on a first run."""
    suite, source = load(SUITE)
    runs = ", ".join(_minutes(s) for s in suite["wall_seconds"])
    return (
        f"The default suite ({suite['tests']} tests, the package's doctests among them) runs in "
        f"parallel, one process per core (pytest-xdist; `-n 0` runs it in one process): {runs} in "
        f"{len(suite['wall_seconds'])} runs from a clean clone on {source.machine}, "
        f"{_minutes(suite['first_run_seconds'])} on a machine's first run, while pocl compiles (and "
        f"caches) the OpenCL kernels. Data: {source.cite()}."
    )


def record_suite(tests: int, seconds: list[float], first_run: float) -> None:
    """Write the default suite's test count and times to docs/data/main_job/test_suite.json."""
    suite = {"tests": tests, "wall_seconds": seconds, "first_run_seconds": first_run}
    (DATA / SUITE).write_text(json.dumps(suite, indent=2) + "\n", encoding="utf-8")


def blocks() -> dict[str, str]:
    """Return the generated blocks of the README and getting started, by name."""
    return {BLOCK: render(), SUITE_BLOCK: render_suite()}


def record(run: Path, seconds: list[float], platform: str, command: str = "alphaprk compare") -> None:
    """Copy a main job's ``comparison.json`` into docs/data/main_job/ and write its timing."""
    comparison = json.loads((run / "comparison.json").read_text(encoding="utf-8"))
    comparison["runs"] = {name: Path(path).name for name, path in comparison["runs"].items()}
    comparison["figure"] = Path(comparison["figure"]).name if comparison.get("figure") else None
    folder = DATA / "main_job"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "comparison.json").write_text(json.dumps(comparison, indent=2) + "\n", encoding="utf-8")
    timing = {"command": command, "platform": platform, "wall_seconds": seconds}
    (folder / "timing.json").write_text(json.dumps(timing, indent=2) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="action")
    rec = sub.add_parser("record", help="copy a main job's output into docs/data/main_job/")
    rec.add_argument("run", type=Path, help="the main job's output folder")
    rec.add_argument("--seconds", type=float, nargs="+", required=True, help="wall time of each run")
    rec.add_argument("--platform", default="CPU")
    suite = sub.add_parser("suite", help="write the default suite's test count and times")
    suite.add_argument("--tests", type=int, required=True, help="tests in the default suite")
    suite.add_argument("--seconds", type=float, nargs="+", required=True, help="pytest's time, clean clones")
    suite.add_argument("--first-run", type=float, required=True, help="pytest's time on a first run")
    args = parser.parse_args(argv)
    if args.action == "record":
        record(args.run, args.seconds, args.platform)
        return 0
    if args.action == "suite":
        record_suite(args.tests, args.seconds, args.first_run)
        return 0
    parser.print_help()
    return 2


if __name__ == "__main__":
    sys.exit(main())
