"""What is made of runs: comparisons, sweeps, analyses of run directories, and their figures.

- :mod:`.comparison`: :func:`compare`, several integrators from the same start (table, JSON, figure).
- :mod:`.sweep`: :func:`run_sweep`, a grid of runs on ``dask.distributed`` collected into a table.
- :mod:`.analyze`: :func:`analyze_run`, the analyses of :mod:`openmm_alphaprk.analysis` on a run
  directory, written as ``analysis.json`` and figures.
- :mod:`.plots`: the figures (matplotlib).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .analyze import analyze_run
    from .comparison import Comparison, compare
    from .sweep import SweepConfig, load_config, run_sweep

#: Where each name lives. A module is imported on first use of one of its names, so that a
#: comparison (the command line's ``compare``, ``run``) does not import MDAnalysis (the
#: analyses) or dask (the sweeps).
_HOMES = {
    "analyze_run": ".analyze",
    "Comparison": ".comparison",
    "compare": ".comparison",
    "SweepConfig": ".sweep",
    "load_config": ".sweep",
    "run_sweep": ".sweep",
}

__all__ = ["Comparison", "SweepConfig", "analyze_run", "compare", "load_config", "run_sweep"]


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_HOMES[name], __name__), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
