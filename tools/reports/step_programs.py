r"""docs/step_programs.md: the flat listing of every step program the package builds.

Run from the repository root::

    python -m tools.reports.step_programs

One section per integrator configuration, its ``program_listing()`` (OpenMM's
computations, numbered as OpenMM numbers them, indented by block). The docstrings of
the integrator classes link here.
"""

from __future__ import annotations

from pathlib import Path

from openmm_alphaprk import (
    AlphaRattleEnergyIntegrator,
    AlphaRattleIntegrator,
    RattleIntegrator,
    RattleRescaleIntegrator,
    SplittingRattleIntegrator,
)

PAGE = Path(__file__).resolve().parents[2] / "docs" / "step_programs.md"

PROGRAMS = {
    "RattleIntegrator(h)": lambda: RattleIntegrator(0.002),
    "RattleRescaleIntegrator(h)": lambda: RattleRescaleIntegrator(0.002),
    "RattleRescaleIntegrator(h, order=4)": lambda: RattleRescaleIntegrator(0.002, order=4),
    "AlphaRattleIntegrator(h, alpha)": lambda: AlphaRattleIntegrator(0.002, alpha=0.1),
    "AlphaRattleIntegrator(h, alpha, order=4)": lambda: AlphaRattleIntegrator(0.002, alpha=0.01, order=4),
    "AlphaRattleIntegrator(h, alpha, composition='triple-jump')": lambda: AlphaRattleIntegrator(
        0.002, alpha=0.01, composition="triple-jump"
    ),
    "AlphaRattleEnergyIntegrator(h)": lambda: AlphaRattleEnergyIntegrator(0.002),
    "AlphaRattleEnergyIntegrator(h, order=4)": lambda: AlphaRattleEnergyIntegrator(0.002, order=4),
    "SplittingRattleIntegrator(h)": lambda: SplittingRattleIntegrator(0.002),
    "SplittingRattleIntegrator(h, splitting='bcss3')": lambda: SplittingRattleIntegrator(
        0.002, splitting="bcss3"
    ),
}


def page_text() -> str:
    """Return the page: a section per configuration with its program listing."""
    parts = [
        "# Step programs\n",
        "Every program as OpenMM runs it: `integrator.program_listing()` of each configuration, "
        "one computation per line, numbered as OpenMM numbers them and indented by block. "
        "Written by `python -m tools.reports.step_programs`; the same programs, computation for "
        "computation, are the stored listings of `tests/golden/step_programs.txt`.\n",
    ]
    for name, make in PROGRAMS.items():
        integrator = make()
        parts.append(f"## `{name}`\n\n{integrator.getNumComputations()} computations.\n\n```text\n")
        parts.append(integrator.program_listing() + "\n```\n")
    return "\n".join(parts)


def main() -> None:
    PAGE.write_text(page_text(), encoding="utf-8")
    print(f"wrote {PAGE}")


if __name__ == "__main__":
    main()
