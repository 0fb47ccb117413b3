"""Helpers for tests: systems built with a shortened equilibration into a per-session cache."""

from __future__ import annotations

import os
import signal

import openmm.app as app

from openmm_alphaprk.systems import prepare_system

#: Minimization and equilibration cut short: the build path is the real one, only shorter.
QUICK = {"equilibration.minimize_max_iterations": 50, "equilibration.langevin_steps": 10}
#: The same on the Reference platform: the same start state on every run.
QUICK_REFERENCE = {**QUICK, "equilibration.platform": "Reference"}


def quick_system(name: str, cache_dir, reference: bool = False):
    return prepare_system(name, cache_dir=cache_dir, overrides=QUICK_REFERENCE if reference else QUICK)


class StopAt:
    """An OpenMM reporter that interrupts a run at a step.

    ``how``: ``"raise"`` raises KeyboardInterrupt after the run's own reports of that
    step (OpenMM calls this reporter last); ``"before"`` raises it before them (it asks
    for wrapped positions, so OpenMM calls it first: the step's output is incomplete);
    ``"signal"`` sends this process SIGINT, which is what Ctrl-C does.
    """

    def __init__(self, step: int, how: str = "raise"):
        self.step = step
        self.how = how

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        remaining = self.step - simulation.currentStep
        steps = remaining if remaining > 0 else 10**9
        if self.how == "before":
            return {"steps": steps, "periodic": True, "include": ["positions"]}
        return {"steps": steps, "periodic": None, "include": []}

    def report(self, simulation, state) -> None:
        if self.how == "signal":
            os.kill(os.getpid(), signal.SIGINT)
        else:
            raise KeyboardInterrupt
