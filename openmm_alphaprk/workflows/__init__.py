"""What is made of runs: comparisons, sweeps, analyses of run directories, and their figures.

- :mod:`.comparison`: :func:`compare`, several integrators from the same start (table, JSON, figure).
- :mod:`.sweep`: :func:`run_sweep`, a grid of runs on ``dask.distributed`` collected into a table.
- :mod:`.analyze`: :func:`analyze_run`, the analyses of :mod:`openmm_alphaprk.analysis` on a run
  directory, written as ``analysis.json`` and figures.
- :mod:`.plots`: the figures (matplotlib).
"""

from .analyze import analyze_run
from .comparison import Comparison, compare
from .sweep import SweepConfig, load_config, run_sweep

__all__ = ["Comparison", "SweepConfig", "analyze_run", "compare", "load_config", "run_sweep"]
