"""Checkpoints and interruptions of a run: when a checkpoint is written, and what Ctrl-C leaves.

- :class:`CheckpointReporter` writes ``checkpoint.chk`` every ``checkpoint_interval``
  steps, after ``checkpoint_seconds`` of wall time and on demand, atomically.
- :func:`deferred_interrupt` turns a first Ctrl-C into a flag the driver reads between
  steps, where the state and the files agree.
- The run's reporters are :class:`Tracked`: they remember the step of their last
  report, so that a KeyboardInterrupt raised inside a step is checkpointed only when
  the files are complete at that step.
- :func:`interrupted` writes that checkpoint and returns :class:`RunInterrupted`, whose
  message says from which step the same call resumes.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import openmm as mm
import openmm.app as app

from .reporters import AlphaControllerReporter, TRRReporter


class RunInterrupted(KeyboardInterrupt):
    """Raised when a run is interrupted (Ctrl-C); the message says what the same call will do next.

    A ``KeyboardInterrupt``, so code that stops on Ctrl-C still does.

    Parameters
    ----------
    message : str
        What happened and what the same call will do next.
    output : pathlib.Path
        The run directory.
    step : int
        The step the run stopped at.
    checkpoint_step : int or None
        The step of the checkpoint on disk, from which the same call resumes; None if
        there is none (the same call starts again from step 0).

    Attributes
    ----------
    output : pathlib.Path
        The run directory.
    step : int
        The step the run stopped at.
    checkpoint_step : int or None
        The step of the checkpoint on disk, from which the same call resumes; None if
        there is none (the same call starts again from step 0).

    Examples
    --------
    A reporter that presses Ctrl-C at step 10; the same call then resumes from there:

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import RunInterrupted, RunOptions, run_nve
    >>> class CtrlC:
    ...     def describeNextReport(self, simulation):
    ...         return {"steps": 10 - simulation.currentStep % 10, "periodic": None, "include": []}
    ...     def report(self, simulation, state):
    ...         raise KeyboardInterrupt
    >>> options = RunOptions(steps=20, energy_interval=5, platform="Reference", progress=False)
    >>> with tempfile.TemporaryDirectory() as folder:  # doctest: +ELLIPSIS
    ...     run = os.path.join(folder, "run")
    ...     try:
    ...         run_nve("water-cluster", "rattle", run, options, extra_reporters=[CtrlC()])
    ...     except RunInterrupted as interruption:
    ...         print(interruption)
    ...         print(interruption.step, interruption.checkpoint_step)
    ...     summary = run_nve("water-cluster", "rattle", run, options)  # resumes
    ...     print(summary.steps, summary.steps_this_call)
    run in .../run interrupted at step 10 of 20; checkpoint written: the same command resumes it from step 10.
    10 10
    20 10
    """

    def __init__(self, message: str, output: Path, step: int, checkpoint_step: int | None) -> None:
        super().__init__(message)
        self.output, self.step, self.checkpoint_step = output, step, checkpoint_step


class CheckpointReporter:
    """Write ``checkpoint.chk``: every ``interval`` steps, after ``seconds`` of wall time, and on demand.

    An OpenMM reporter for the step-count checkpoints; :meth:`save_if_due` writes one
    when ``seconds`` of wall time have passed, :meth:`save` at once. It remembers the
    step of the last one (``last_step``). A checkpoint is written to a temporary file
    and renamed over the last one, so an interruption while writing leaves the previous
    checkpoint whole.
    """

    def __init__(
        self, path: Path, previous: Path, interval: int, seconds: float, last_step: int | None
    ) -> None:
        self.path, self.previous, self._interval, self._seconds = path, previous, interval, seconds
        self.last_step = last_step
        self._written = time.monotonic()

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        """Return the steps to the next multiple of the interval; no State data is needed."""
        steps = self._interval - simulation.currentStep % self._interval
        return {"steps": steps, "periodic": None, "include": []}

    def report(self, simulation: app.Simulation, state: mm.State) -> None:
        """Write the checkpoint of the step just taken."""
        self.save(simulation)

    def save(self, simulation: app.Simulation) -> None:
        """Write a checkpoint of the current state (call it between steps, after the step's reports).

        The last one is kept as ``previous`` (the run directory's
        ``checkpoint.previous.chk``): should the new one be damaged, a resume loses one
        interval.
        """
        temporary = self.path.with_name(self.path.name + ".part")
        temporary.write_bytes(simulation.context.createCheckpoint())
        if self.path.is_file():
            os.replace(self.path, self.previous)
        os.replace(temporary, self.path)
        self.last_step = simulation.currentStep
        self._written = time.monotonic()

    def save_if_due(self, simulation: app.Simulation) -> None:
        """Write a checkpoint if ``seconds`` of wall time have passed since the last one."""
        if time.monotonic() - self._written >= self._seconds and self.last_step != simulation.currentStep:
            self.save(simulation)


class Tracked:
    """Mixin of the run's reporters: remembers the step of its last report.

    A KeyboardInterrupt raised inside ``Simulation.step`` can come between a step and
    its reports; :meth:`complete_at` tells whether this reporter's output of a step is
    all written, i.e. whether a checkpoint of that step would match the files.
    """

    def __init__(self, file, reportInterval: int, **keywords) -> None:
        super().__init__(file, reportInterval, **keywords)
        self.every = reportInterval
        self.last_report: int | None = None

    def report(self, simulation: app.Simulation, state: mm.State) -> None:
        """Report as the reporter does, then remember the step."""
        super().report(simulation, state)
        self.last_report = simulation.currentStep

    def complete_at(self, step: int) -> bool:
        """Tell whether everything this reporter writes for ``step`` is written."""
        return step % self.every != 0 or self.last_report == step


class TrackedStateDataReporter(Tracked, app.StateDataReporter):
    """``StateDataReporter`` that remembers the step of its last row."""


class TrackedDCDReporter(Tracked, app.DCDReporter):
    """``DCDReporter`` that remembers the step of its last frame."""


class TrackedControllerReporter(Tracked, AlphaControllerReporter):
    """:class:`AlphaControllerReporter` that remembers the step of its last row."""


class TrackedTRRReporter(Tracked, TRRReporter):
    """:class:`TRRReporter` that remembers the step of its last frame."""


@contextlib.contextmanager
def deferred_interrupt() -> Iterator[Callable[[], bool]]:
    """Within the block, a first Ctrl-C (SIGINT) or SIGTERM only sets a flag; yield what reads the flag.

    The caller checks the flag between steps, where the state and the files agree, so
    the interruption can be checkpointed. A second signal of the same kind acts at once
    (the previous handler is back). SIGTERM is what ``kill``, ``timeout`` and batch
    schedulers send at a run's time limit; it is deferred only where its handler is
    the default one. Outside the main thread (dask workers) nothing changes and the
    flag stays unset; a signal that is ignored stays ignored (a script's background
    job starts with SIGINT ignored: SIGTERM still stops it with its files complete).
    """
    received = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield received.is_set
        return
    previous = {}
    on_interrupt = signal.getsignal(signal.SIGINT)
    if on_interrupt is not signal.SIG_IGN:
        previous[signal.SIGINT] = signal.default_int_handler if on_interrupt is None else on_interrupt
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        previous[signal.SIGTERM] = signal.SIG_DFL

    def handler(signum, frame) -> None:
        received.set()
        signal.signal(signum, previous[signum])

    for signum in previous:
        signal.signal(signum, handler)
    try:
        yield received.is_set
    finally:
        for signum, handler_before in previous.items():
            signal.signal(signum, handler_before)


def interrupted(
    simulation: app.Simulation, output: Path, steps: int, checkpoints: CheckpointReporter, complete: bool
) -> RunInterrupted:
    """Checkpoint an interrupted run if its files are complete at its step; say what resuming will do.

    Parameters
    ----------
    simulation
        The run's Simulation, stopped between steps.
    output, steps
        The run directory and the run's length.
    checkpoints
        The run's checkpoint writer.
    complete
        Whether every file of the run is written up to the current step (then a
        checkpoint of it matches them and is written).
    """
    step = simulation.currentStep
    if complete and checkpoints.last_step != step:
        checkpoints.save(simulation)
    stopped = f"run in {output} interrupted at step {step} of {steps}"
    last = checkpoints.last_step
    if last == step:
        message = f"{stopped}; checkpoint written: the same command resumes it from step {step}."
    elif last is not None:
        message = (
            f"{stopped}, while the output of that step was being written, so no checkpoint of it was "
            f"taken; the same command resumes it from step {last}, its last checkpoint."
        )
    else:
        message = f"{stopped}; no checkpoint yet: the same command starts it again from step 0."
    return RunInterrupted(message, output, step, last)
