"""``python -m tools.reports``: every generated block of the documentation, from docs/data/.

Run from the repository's root::

    python -m tools.reports            # rewrite every generated block (and docs/step_programs.md)
    python -m tools.reports --figures  # ... and draw the figures drawn from docs/data/
    python -m tools.reports --check    # write nothing; exit 1 if a block is not what its data renders

A generated block is the text between ``<!-- generated: NAME -->`` and ``<!-- end generated:
NAME -->``; the prose around it is written by hand and cites it. Each page's blocks come from
one generator of :data:`GENERATORS`; the experiments that write the data are elsewhere
(``alphaprk bench``, ``openmm_alphaprk.benchmarks``, ``tools/scripts``), so this command
only reads. ``tests/test_guide_reports.py`` runs the check.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

from tools.reports import (
    accuracy,
    energy_program,
    guide,
    long_runs,
    main_job,
    md_benchmark,
    physics,
    splitting,
    step_programs,
    validation,
)
from tools.reports.markdown import stale_blocks, update_page
from tools.reports.sources import DATA, DOCS, ROOT


def _validation() -> dict[Path, dict[str, str]]:
    data = json.loads((DATA / "validation" / "validation.json").read_text(encoding="utf-8"))
    return {DOCS / "validation.md": validation.render_tables(data)}


#: Every generator: its name and what it renders, by page and block name.
GENERATORS: dict[str, Callable[[], dict[Path, dict[str, str]]]] = {
    "guide": guide.render,
    "main job": main_job.pages,
    "accuracy": accuracy.render,
    "benchmarks": md_benchmark.render,
    "validation": _validation,
    "long runs": long_runs.render,
    "splitting": splitting.render,
    "physics": physics.render,
    "energy program": lambda: {energy_program.PAGE: energy_program.render_blocks()},
}


def render() -> dict[Path, dict[str, str]]:
    """Every generated block of every page, by page and block name."""
    pages: dict[Path, dict[str, str]] = {}
    for make in GENERATORS.values():
        for page, blocks in make().items():
            pages.setdefault(page, {}).update(blocks)
    return pages


def stale() -> list[str]:
    """Return ``PAGE: BLOCK`` for each block unlike what its data renders (and the step programs' page)."""
    found = stale_blocks(render(), ROOT)
    if step_programs.PAGE.read_text(encoding="utf-8") != step_programs.page_text():
        found.append(str(step_programs.PAGE.relative_to(ROOT)))
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if a block differs")
    parser.add_argument("--figures", action="store_true", help="also draw the figures from docs/data/")
    args = parser.parse_args(argv)
    if args.check:
        found = stale()
        print("\n".join(found) or "every generated block is its data's")
        return 1 if found else 0
    for page, blocks in render().items():
        if missing := update_page(page, blocks):
            raise SystemExit(f"{page.relative_to(ROOT)} has no block for {missing}")
    step_programs.PAGE.write_text(step_programs.page_text(), encoding="utf-8")
    if args.figures:
        accuracy.figures()
        physics.render(write_figures=True)
    print("rewrote the generated blocks of every page")
    return 0


if __name__ == "__main__":
    sys.exit(main())
