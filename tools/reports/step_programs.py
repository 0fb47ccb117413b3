"""docs/step_programs.md: the program listing of each configuration (``-m tools.reports.step_programs``)."""

from __future__ import annotations

from openmm_alphaprk.runs.integrator_names import make_integrator
from tools.reports.sources import DOCS

PAGE = DOCS / "step_programs.md"

#: The programs the page shows, by their names in the registry (every form's listing is in
#: tests/golden/step_programs.txt).
PROGRAMS = (
    "rattle",
    "rattle+rescale",
    "rattle+rescale@10",
    "rattle4+rescale",
    "alpha=0.1",
    "alpha4=0.01",
    "alpha4:triple-jump=0.01",
    "energy",
    "energy4",
    "split:me2",
    "split:bcss3",
)


def page_text() -> str:
    """Return the page: a section per configuration with its program listing."""
    parts = [
        "# Step programs\n",
        "Every program as OpenMM runs it: `integrator.program_listing()` of each configuration, "
        "one computation per line, numbered as OpenMM numbers them and indented by block. "
        "Written by `python -m tools.reports.step_programs`; the same programs, computation for "
        "computation, are the stored listings of `tests/golden/step_programs.txt`.\n",
    ]
    for name in PROGRAMS:
        integrator = make_integrator(name, 0.002)
        parts.append(
            f"## `{name}`\n\n`{integrator!r}`: {integrator.getNumComputations()} computations.\n\n```text\n"
        )
        parts.append(integrator.program_listing() + "\n```\n")
    return "\n".join(parts)


if __name__ == "__main__":
    PAGE.write_text(page_text(), encoding="utf-8")
    print(f"wrote {PAGE}")
