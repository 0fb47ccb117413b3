"""``python -m tools.reports``: every generated block of the documentation, from docs/data/.

Run from the repository's root::

    python -m tools.reports            # rewrite every generated block (and docs/step_programs.md)
    python -m tools.reports --figures  # ... and draw the figures drawn from docs/data/
    python -m tools.reports --check    # write nothing; exit 1 if a block is not what its data renders

A generated block is the text between ``<!-- generated: NAME -->`` and ``<!-- end generated:
NAME -->``; the prose around it is written by hand and cites it. Each page's blocks come from
one generator of :data:`GENERATORS`; this command only reads the data.
"""

from __future__ import annotations

import argparse
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
from tools.reports.sources import ROOT

#: Every generator: what it renders, by page and block name.
GENERATORS: tuple[Callable[[], dict[Path, dict[str, str]]], ...] = (
    guide.render,
    main_job.pages,
    accuracy.render,
    md_benchmark.render,
    validation.render,
    long_runs.render,
    splitting.render,
    physics.render,
    energy_program.render,
)


def render() -> dict[Path, dict[str, str]]:
    """Every generated block of every page, by page and block name."""
    pages: dict[Path, dict[str, str]] = {}
    for make in GENERATORS:
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
    """Rewrite (or with ``--check`` compare) every generated block; return the exit status."""
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
