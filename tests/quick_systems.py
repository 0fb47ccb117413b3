"""Helpers for tests: systems built with a shortened equilibration into a per-session cache."""

from __future__ import annotations

import openmm.app as app

from openmm_alphaprk.systems import prepare_system

#: Minimization and equilibration cut short: the build path is the real one, only shorter.
QUICK = {"equilibration.minimize_max_iterations": 50, "equilibration.langevin_steps": 10}
#: The same on the Reference platform: the same start state on every run.
QUICK_REFERENCE = {**QUICK, "equilibration.platform": "Reference"}


def quick_system(name: str, cache_dir, reference: bool = False):
    return prepare_system(name, cache_dir=cache_dir, overrides=QUICK_REFERENCE if reference else QUICK)


class StopAt:
    """An OpenMM reporter that raises KeyboardInterrupt at a step: an interrupted run."""

    def __init__(self, step: int):
        self.step = step

    def describeNextReport(self, simulation: app.Simulation) -> dict:
        remaining = self.step - simulation.currentStep
        return {"steps": remaining if remaining > 0 else 10**9, "periodic": None, "include": []}

    def report(self, simulation, state) -> None:
        raise KeyboardInterrupt
