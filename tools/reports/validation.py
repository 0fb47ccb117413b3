r"""docs/validation.md: run :mod:`openmm_alphaprk.benchmarks.validation`, draw and tabulate it.

Run from the repository root::

    python -m tools.reports.validation           # run it, rewrite the JSON, figures and tables
    python -m tools.reports.validation --quick   # smaller runs into a scratch folder (1 minute)

The experiment is the package's; this writes its JSON to ``docs/data/validation/``, the
figures (:mod:`.validation_figures`) and the page's tables (:mod:`.validation_tables`, also
checked by ``python -m tools.reports --check``). ``--quick`` writes to a scratch folder
unless paths are given, so that it never overwrites the page's numbers.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from openmm_alphaprk.benchmarks.validation import compute, dump_json
from tools.reports.markdown import update_page
from tools.reports.validation_figures import write_figures
from tools.reports.validation_tables import render_tables

DOCS = Path(__file__).resolve().parents[2] / "docs"


def main(argv: list[str] | None = None) -> int:
    """Run the validation (or read its JSON), write the JSON, the figures and the page's tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small runs, to check the report")
    parser.add_argument("--json", type=Path, help="the JSON (default docs/data/validation/validation.json)")
    parser.add_argument("--figures", type=Path, help="figure folder (default docs/figures)")
    parser.add_argument(
        "--page", type=Path, help="page whose tables are rewritten (default docs/validation.md)"
    )
    parser.add_argument(
        "--workdir", type=Path, help="run directories of the OpenMM runs (default: temporary)"
    )
    parser.add_argument("--from-json", action="store_true", help="run nothing: draw and tabulate the JSON")
    args = parser.parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="alphaprk-validation-"))
    default = not args.quick
    json_path = args.json or (
        DOCS / "data" / "validation" / "validation.json" if default else scratch / "v.json"
    )
    figures = args.figures or (DOCS / "figures" if default else scratch / "figures")
    page = args.page or (DOCS / "validation.md" if default else None)
    if args.from_json:
        data = json.loads(json_path.read_text(encoding="utf-8"))
    else:
        data = compute(args.quick, args.workdir or scratch / "runs")
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(dump_json(data), encoding="utf-8")
    write_figures(data, figures)
    if page is not None and (missing := update_page(page, render_tables(data))):
        print(f"{page} has no place for the tables {', '.join(missing)}", file=sys.stderr)
    print(f"JSON: {json_path}\nfigures: {figures}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
