"""One NVE run: its options, its directory, its reporters, the driver and its summary.

- :mod:`.options`: :class:`RunOptions`, every option of a run with its default and checks.
- :mod:`.rundir`: the files of a run directory, its parameters, resume checks.
- :mod:`.reporters`: :class:`AlphaControllerReporter` (α* controller CSV) and
  :class:`TRRReporter` (positions with velocities, TRR), controller summaries.
- :mod:`.checkpoints`: checkpoints by steps, by wall time and on Ctrl-C, and
  :class:`RunInterrupted`, which says from which step a run resumes.
- :mod:`.driver`: :func:`run_nve`, prepare → simulate → write.
- :mod:`.summary`: :class:`RunSummary`, what ``summary.json`` holds.
"""

from .checkpoints import RunInterrupted
from .driver import RunFailedError, run_nve
from .options import RunOptions
from .reporters import (
    AlphaControllerReporter,
    ControllerSummary,
    TRRReporter,
    read_controller_csv,
    summarize_controller,
)
from .rundir import RunDirectoryError, read_energies
from .summary import RunSummary

__all__ = [
    "AlphaControllerReporter",
    "ControllerSummary",
    "RunDirectoryError",
    "RunFailedError",
    "RunInterrupted",
    "RunOptions",
    "RunSummary",
    "TRRReporter",
    "read_controller_csv",
    "read_energies",
    "run_nve",
    "summarize_controller",
]
