"""Shared fixtures: a temporary systems cache, a small equilibrated TIP3P box, helpers to run integrators."""

from __future__ import annotations

import fcntl
import hashlib
import os
import pickle
import re
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import openmm as mm
import openmm.unit as unit
import pytest
from quick_systems import TEST_STATES, TIP4PEW_BOX, WATER_BOX, stored_water_box

from openmm_alphaprk import RattleIntegrator, observables
from openmm_alphaprk.systems import CACHE_ENV, prepare_system

REFERENCE = mm.Platform.getPlatformByName("Reference")


def pytest_configure(config: pytest.Config) -> None:
    """One pocl thread per test worker when there is a worker per core (``pytest -n auto``).

    pocl (OpenCL on the CPU) splits every kernel over one thread per core and waits for all
    of them; with a worker per core, one worker's kernels wait for threads the other
    workers' processes have taken off the cores. pocl reads ``POCL_MAX_PTHREAD_COUNT`` when
    the first OpenCL context is made; the kernels and their results are the same.
    """
    workers = getattr(config, "workerinput", {}).get("workercount", 1)
    if workers >= (os.cpu_count() or 1):
        os.environ.setdefault("POCL_MAX_PTHREAD_COUNT", "1")


@pytest.fixture(scope="session", autouse=True)
def temporary_systems_cache(tmp_path_factory):
    """Point ``$ALPHAPRK_CACHE_DIR`` at a folder of this session: tests never write into the user's cache.

    Subprocesses (the CLI tests) inherit it. The shipped start states need no cache.
    """
    previous = os.environ.get(CACHE_ENV)
    os.environ[CACHE_ENV] = str(tmp_path_factory.mktemp("systems-cache"))
    yield Path(os.environ[CACHE_ENV])
    if previous is None:
        os.environ.pop(CACHE_ENV, None)
    else:
        os.environ[CACHE_ENV] = previous


def computed_once(request: pytest.FixtureRequest, name: str, compute: Callable[[], Any]) -> Any:
    """``compute()`` once per test session: under xdist the first worker to ask runs it, the others read it.

    The recipe of pytest-xdist's documentation: the result is pickled into the folder the
    session's workers share, under a file lock. Without xdist it is computed here. A
    session fixture that calls this holds one result for every worker, so tests that
    compare against it (or against each other's use of it) see one run.
    """
    worker = getattr(request.config, "workerinput", None)
    if worker is None:
        return compute()
    shared = request.getfixturevalue("tmp_path_factory").getbasetemp().parent
    stem = re.sub(r"[^\w.=-]", "_", name) + "-" + hashlib.sha1(name.encode()).hexdigest()[:8]
    result = shared / f"{stem}.pickle"
    with open(shared / f"{stem}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if result.exists():
            return pickle.loads(result.read_bytes())
        value = compute()
        result.write_bytes(pickle.dumps(value))
        return value


def _stored_or_built(definition, what: str):
    stored = stored_water_box(definition)
    if stored is not None:
        return stored
    warnings.warn(
        f"no stored start state of {what} in {TEST_STATES} matches its definition: building it "
        "(a minute). `python tests/quick_systems.py` stores it again.",
        stacklevel=3,
    )
    return prepare_system(definition, use_cache=False)


@pytest.fixture(scope="session")
def water_box():
    """~550-atom TIP3P box (1.8 nm, PME, 0.8 nm cutoff) from its stored start state (quick_systems.WATER_BOX).

    If no stored state matches the definition, it is built (a minute) with a warning.
    """
    return _stored_or_built(WATER_BOX, "the test water box")


#: Steps of the shared RATTLE run on the water box; tests that need fewer take its prefix.
RATTLE_STEPS_ON_THE_WATER_BOX = 200


@pytest.fixture(scope="session")
def rattle_residuals_on_the_water_box(water_box, request) -> np.ndarray:
    """H − E_ref after each of 200 RATTLE steps of 2 fs on the water box, Reference platform.

    One run for the session: Reference repeats a run bitwise, so its first n residuals
    are those of an n-step run from the same start.
    """

    def run():
        problem = water_box.system, water_box.positions, water_box.velocities
        return residuals_on(problem, RattleIntegrator(0.002), RATTLE_STEPS_ON_THE_WATER_BOX)

    return computed_once(request, "rattle_residuals_on_the_water_box", run)


@pytest.fixture(scope="session")
def tip4pew_prepared():
    """A 1.8 nm TIP4P-Ew box (quick_systems.TIP4PEW_BOX) from its stored start state, as the driver takes it.

    If no stored state matches the definition, it is built with a warning.
    """
    return _stored_or_built(TIP4PEW_BOX, "the test TIP4P-Ew box")


@pytest.fixture(scope="session")
def tip4pew_box(tip4pew_prepared):
    """The test TIP4P-Ew box as (system, positions, velocities)."""
    return tip4pew_prepared.system, tip4pew_prepared.positions, tip4pew_prepared.velocities


def make_context(system, integrator, positions, velocities, platform=REFERENCE):
    context = mm.Context(system, integrator, platform)
    context.setPositions(positions)
    context.setVelocities(velocities)
    return context


def residuals_on(problem, integrator: mm.Integrator, steps: int, platform=REFERENCE) -> np.ndarray:
    """H − E_ref after each of ``steps`` steps from ``problem`` (system, positions, velocities)."""
    system, positions, velocities = problem
    context = make_context(system, integrator, positions, velocities, platform)
    return observables.energy_residuals(context, integrator, steps).residuals


def counting(system: mm.System) -> tuple[mm.System, list[int]]:
    """Return a copy of ``system`` with a force that counts the evaluations of the whole System."""
    copy = mm.XmlSerializer.deserialize(mm.XmlSerializer.serialize(system))
    calls = [0]

    def count(state):
        calls[0] += 1
        return 0.0, np.zeros((1, 3))

    counter = mm.PythonForce(count)
    counter.setParticles([0])
    copy.addForce(counter)
    return copy, calls


#: The pendulum tests' end time, and the pendulum with a horizontal spring they integrate to it.
PENDULUM_T_END = 2.0


@pytest.fixture(scope="session")
def pendulum():
    """Pendulum with a horizontal spring (position-dependent force), and a sixth-order reference at T_END."""
    from openmm_alphaprk.reference import composition_step, integrate, planar_pendulum, planar_pendulum_start

    problem = planar_pendulum(kappa=2.0)
    x0, v0 = planar_pendulum_start(1.0)
    # sixth order at 256 steps: 3e-12 from 128 steps (more steps only add SHAKE round-off)
    x_ref, v_ref = integrate(
        problem, x0, v0, PENDULUM_T_END / 256, 256, 0.0, step=composition_step, composition="mclachlan9"
    )
    return problem, x0, v0, np.concatenate([x_ref, v_ref])


def invariant_errors(problem, context, integrator, rounds: int = 15, every: int = 10) -> dict[str, float]:
    """Step ``rounds`` × ``every`` steps from the constrained start; the largest drift of each invariant.

    Returns |L0|, and the largest |L − L0|, |P| (the cluster starts at rest) and relative
    constraint error seen after each ``every`` steps, with the constraint error at the start
    (SETTLE holds water at its own geometry, a few 1e-9 off the nominal lengths).
    """
    from openmm_alphaprk.reference import angular_momentum

    context.applyConstraints(1e-12)
    context.applyVelocityConstraints(1e-12)
    l0 = angular_momentum(problem, positions_of(context).ravel(), velocities_of(context).ravel())
    masses = problem.masses.reshape(-1, 3)[:, 0]
    system = context.getSystem()
    bonds = []
    for k in range(system.getNumConstraints()):
        i, j, d = system.getConstraintParameters(k)
        bonds.append((i, j, d.value_in_unit(unit.nanometers)))

    def constraint_error(x):
        return max(abs(np.linalg.norm(x[j] - x[i]) - d) / d for i, j, d in bonds)

    found = {"l0": float(np.linalg.norm(l0)), "c_start": constraint_error(positions_of(context))}
    found.update(l_err=0.0, p_err=0.0, c_err=0.0)
    for _ in range(rounds):
        integrator.step(every)
        x, v = positions_of(context), velocities_of(context)
        found["l_err"] = max(
            found["l_err"], np.linalg.norm(angular_momentum(problem, x.ravel(), v.ravel()) - l0)
        )
        found["p_err"] = max(found["p_err"], np.linalg.norm(masses @ v))
        found["c_err"] = max(found["c_err"], constraint_error(x))
    return found


def positions_of(context) -> np.ndarray:
    return context.getState(getPositions=True).getPositions(asNumpy=True).value_in_unit(unit.nanometers)


def velocities_of(context) -> np.ndarray:
    state = context.getState(getVelocities=True)
    return state.getVelocities(asNumpy=True).value_in_unit(unit.nanometers / unit.picoseconds)


total_energy = observables.total_energy
constraint_errors = observables.system_constraint_errors


_FORCE_OR_ENERGY = re.compile(r"\b(f|energy)\d*\b")
_INVALIDATES = (mm.CustomIntegrator.ConstrainPositions, mm.CustomIntegrator.UpdateContextState)
_BLOCK_STARTS = (mm.CustomIntegrator.IfBlockStart, mm.CustomIntegrator.WhileBlockStart)


def path_on_the_water_cluster(
    steps: int = 50, h: float = 0.002
) -> Callable[[mm.Integrator, int], tuple[float, float]]:
    """Return ``error(integrator, k)``: its RMS position error after ``steps`` steps of h, and its cost.

    ``integrator`` runs at h/k, k steps a step of h, from the shipped water cluster's start on
    the CPU platform; the error is against RATTLE at h/64 (nm per atom), the cost its force
    evaluations per step of h. The equal-cost comparisons of a combination no name offers.
    """
    water = prepare_system("water-cluster")
    cpu = mm.Platform.getPlatformByName("CPU")

    def end(integrator: mm.Integrator, k: int) -> tuple[np.ndarray, float]:
        context = mm.Context(water.system, integrator, cpu)
        context.setState(water.state)
        integrator.step(steps * k)
        return positions_of(context), integrator.force_evaluations_per_step * k

    reference, _ = end(RattleIntegrator(h / 64), 64)

    def error(integrator: mm.Integrator, k: int) -> tuple[float, float]:
        x, cost = end(integrator, k)
        return float(np.sqrt(((x - reference) ** 2).sum(axis=1).mean())), cost

    return error


def analysed_blocks(integrator: mm.CustomIntegrator) -> int:
    """Blocks OpenMM's analysis of a program branches on (its cost doubles or triples with each).

    As in ``CustomIntegratorUtilities::analyzeComputations``: a block counts when a
    computation inside it reads forces or energy, sets ``x``, constrains positions or
    updates the context state. A block that only sums and sets globals does not.
    """
    steps = [integrator.getComputationStep(i) for i in range(integrator.getNumComputations())]
    count, open_blocks = 0, []
    for kind, variable, expression in steps:
        if kind in _BLOCK_STARTS:
            open_blocks.append(False)
        elif kind == mm.CustomIntegrator.BlockEnd:
            count += open_blocks.pop()
        elif kind in _INVALIDATES or variable == "x" or _FORCE_OR_ENERGY.search(expression):
            open_blocks = [True] * len(open_blocks)
    return count


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt in this process, as after Python starts in a terminal.

    A process started with SIGINT ignored (``nohup``, a script's background job) keeps it
    ignored, and a test that sends itself SIGINT would see nothing.
    """
    import signal

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
