"""Shared fixtures: a small equilibrated TIP3P box and helpers to run integrators."""

from __future__ import annotations

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest

from openmm_alphaprk.waterbox import build_water_box

REFERENCE = mm.Platform.getPlatformByName("Reference")


@pytest.fixture(scope="session")
def water_box():
    """~550-atom TIP3P box (1.8 nm, PME, 0.8 nm cutoff), equilibrated on Reference.

    The Reference platform makes the box the same on every run (the multithreaded
    CPU platform's force sums are not bitwise reproducible).
    """
    return build_water_box(1.8, cutoff=0.8, equilibration_steps=300, seed=7, platform="Reference")


def make_context(system, integrator, positions, velocities, platform=REFERENCE):
    context = mm.Context(system, integrator, platform)
    context.setPositions(positions)
    context.setVelocities(velocities)
    return context


def positions_of(context) -> np.ndarray:
    return context.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(unit.nanometers)


def velocities_of(context) -> np.ndarray:
    state = context.getState(getVelocities=True)
    return state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)


def total_energy(context) -> float:
    state = context.getState(getEnergy=True)
    return (state.getPotentialEnergy() + state.getKineticEnergy()).value_in_unit(unit.kilojoules_per_mole)


def constraint_errors(system, x: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """Max relative bond-length error and max |relative velocity along the bond| (nm/ps)."""
    pos_err, vel_err = 0.0, 0.0
    for k in range(system.getNumConstraints()):
        i, j, d = system.getConstraintParameters(k)
        d = d.value_in_unit(unit.nanometers)
        r = x[j] - x[i]
        norm = np.linalg.norm(r)
        pos_err = max(pos_err, abs(norm - d) / d)
        vel_err = max(vel_err, abs(np.dot(v[j] - v[i], r)) / norm)
    return pos_err, vel_err
