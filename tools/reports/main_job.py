r"""The README's and getting started's measured numbers: the main job's output and the test suite's time.

Record a run of the main job and the suite's times, then write the pages (from the
repository root)::

    python -m tools.reports.main_job record alphaprk-compare-tip3p-2nm --seconds 65 70 68
    python -m tools.reports.main_job suite --tests 640 --seconds 400 410 420 --first-run 500
    python -m tools.reports                   # rewrite the generated blocks (--check: compare)

``record`` copies the run's ``comparison.json`` to ``docs/data/main_job/`` (run folders
made relative) with ``timing.json`` (the command's wall-clock seconds in each run, the
platform); ``suite`` writes ``test_suite.json`` (the default suite's test count, its time
in clean-clone runs and on a machine's first run, when pocl compiles).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from openmm_alphaprk.observables import drift_text
from tools.reports.markdown import Column, table
from tools.reports.sources import DATA, ROOT, load, provenance_line

COMPARISON = "main_job/comparison.json"
TIMING = "main_job/timing.json"
SUITE = "main_job/test_suite.json"


def _sci(value: float) -> str:
    """Two significant digits, in e notation below 1e-3; "–" for no finite value."""
    if not math.isfinite(value):
        return "–"
    return f"{value:.2g}" if abs(value) >= 1e-3 else f"{value:.1e}"


def _minutes(seconds: float) -> str:
    """Write seconds as ``M min S s``."""
    minutes, rest = divmod(round(seconds), 60)
    return f"{minutes} min {rest} s" if minutes else f"{rest} s"


def render(link: str = "data/") -> str:
    """Return the block: when and where the main job ran, its table, and the verdict it printed."""
    comparison, source = load(COMPARISON)
    timing, _ = load(TIMING)
    first = comparison["summaries"][0]
    accuracy = comparison["accuracy"]["rows"]
    after = next(iter(accuracy.values()))["time_fs"]
    caption = provenance_line(
        [source],
        f"`{timing['command']}`, {timing['platform']} platform (the fastest present there), wall time "
        f"{' / '.join(_minutes(s) for s in timing['wall_seconds'])} in runs from a fresh clone (install "
        f"excluded); {first['system']} ({first['n_atoms']} atoms), {first['timestep_fs']:g} fs, "
        f"{first['steps']} steps of each integrator from the shipped start; RATTLE at h/k for every row "
        "of k force evaluations per step; positions against RATTLE at h/64",
        link,
    )
    columns = [
        Column("integrator", "`{integrator}`"),
        Column("evaluations/step", "{force_evaluations_per_step:.2f}"),
        Column("RMS(H − E_ref) kJ/mol", lambda r: _sci(r["rms_residual"])),
        Column(
            "drift kJ/mol/ns/DOF", lambda r: drift_text(r["drift_per_dof"], r["drift_per_dof_standard_error"])
        ),
        Column(
            f"position error after {after:g} fs (nm)",
            lambda r: _sci(accuracy[r["integrator"]]["position_rms"]) if r["integrator"] in accuracy else "–",
        ),
    ]
    return table(comparison["summaries"], columns, caption) + f"\n\n**{comparison['verdict']}**"


def render_suite(link: str = "data/") -> str:
    """Return the test suite's table: its size, its time from clean clones and on a first run."""
    suite, source = load(SUITE)
    columns = [
        Column("tests (doctests among them)", lambda s: str(s["tests"])),
        Column("clean clone", lambda s: " / ".join(_minutes(t) for t in s["wall_seconds"])),
        Column("a machine's first run (pocl compiling)", lambda s: _minutes(s["first_run_seconds"])),
    ]
    caption = provenance_line([source], "`python -m pytest`, pytest's own time", link)
    return table([suite], columns, caption)


def pages() -> dict[Path, dict[str, str]]:
    """Return the generated blocks of the README (the main job) and getting started (and the suite)."""
    return {
        ROOT / "README.md": {"main job": render("docs/data/")},
        ROOT / "docs" / "getting_started.md": {"main job": render(), "test suite": render_suite()},
    }


def _write(path: str, data: dict) -> None:
    """Write ``data`` as JSON to ``path`` under docs/data/."""
    (DATA / path).parent.mkdir(parents=True, exist_ok=True)
    (DATA / path).write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")


def record(run: Path, seconds: list[float], platform: str, command: str = "alphaprk compare") -> None:
    """Copy a main job's ``comparison.json`` into docs/data/main_job/ and write its timing."""
    comparison = json.loads((run / "comparison.json").read_text(encoding="utf-8"))
    comparison["runs"] = {name: Path(path).name for name, path in comparison["runs"].items()}
    comparison["figure"] = Path(comparison["figure"]).name if comparison.get("figure") else None
    _write(COMPARISON, comparison)
    _write(TIMING, {"command": command, "platform": platform, "wall_seconds": seconds})


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
        _write(
            SUITE, {"tests": args.tests, "wall_seconds": args.seconds, "first_run_seconds": args.first_run}
        )
        return 0
    parser.print_help()
    return 2


if __name__ == "__main__":
    sys.exit(main())
