"""Helpers for tests: the stored test water box, systems built with a shortened equilibration.

``python tests/quick_systems.py`` builds the test water boxes (TIP3P: a minute on Reference;
TIP4P-Ew) and stores their start states in ``tests/data/states`` again, after their
definitions or the builder changed.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import openmm.app as app

from openmm_alphaprk.systems import PreparedSystem, prepare_system, water_box_definition
from openmm_alphaprk.systems.ship import write_shipped_state
from openmm_alphaprk.systems.shipped import load_shipped_state

#: The tests' water box: ~550-atom TIP3P box (1.8 nm, PME, 0.8 nm cutoff), equilibrated on
#: Reference, which makes it the same on every run (the multithreaded CPU platform's force
#: sums are not bitwise reproducible).
WATER_BOX = water_box_definition(1.8, cutoff=0.8, equilibration_steps=300, seed=7, platform="Reference")
#: A 1.8 nm TIP4P-Ew box (M-sites are massless virtual sites), equilibrated on CPU; stored,
#: so that every run starts from the same state.
TIP4PEW_BOX = water_box_definition(
    1.8, model="tip4pew", cutoff=0.8, equilibration_steps=200, seed=3, platform="CPU"
)
#: Where their start states are stored (the shipped-state format: ``NAME.xml.gz`` and ``NAME.json``).
TEST_STATES = Path(__file__).parent / "data" / "states"


def stored_water_box(definition=WATER_BOX) -> PreparedSystem | None:
    """A test water box from its stored start state (System made here), or None if none matches."""
    shipped = load_shipped_state(definition, TEST_STATES)
    return None if shipped is None else PreparedSystem.from_shipped(definition, shipped)


#: Minimization and equilibration cut short: the build path is the real one, only shorter.
QUICK = {"equilibration.minimize_max_iterations": 10, "equilibration.langevin_steps": 10}
#: The same on the Reference platform: the same start state on every run.
QUICK_REFERENCE = {**QUICK, "equilibration.platform": "Reference"}


def quick_system(name: str, cache_dir, reference: bool = False):
    return prepare_system(name, cache_dir=cache_dir, overrides=QUICK_REFERENCE if reference else QUICK)


class StopAt:
    """An OpenMM reporter that interrupts a run at a step.

    ``how``: ``"raise"`` raises KeyboardInterrupt after the run's own reports of that
    step (OpenMM calls this reporter last); ``"before"`` raises it before them (it asks
    for wrapped positions, so OpenMM calls it first: the step's output is incomplete);
    ``"signal"`` sends this process SIGINT, which is what Ctrl-C does; ``"sigterm"`` sends
    it SIGTERM, which is what ``kill``, ``timeout`` and batch schedulers send.
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
        if self.how in ("signal", "sigterm"):
            os.kill(os.getpid(), signal.SIGINT if self.how == "signal" else signal.SIGTERM)
        else:
            raise KeyboardInterrupt


if __name__ == "__main__":
    for definition in (WATER_BOX, TIP4PEW_BOX):
        print(write_shipped_state(prepare_system(definition, use_cache=False), TEST_STATES))
