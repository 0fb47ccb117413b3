"""Symplecticity defects of fixed α, the one-pass variant and the energy modes (NumPy reference)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from openmm_alphaprk.observables import convergence_order as fitted_order
from openmm_alphaprk.reference import (
    planar_pendulum,
    planar_pendulum_start,
    symplecticity_defect,
    water_cluster,
)
from openmm_alphaprk.reference.step import Array, ConstrainedProblem

from .methods import (
    ENERGY,
    ENERGY4,
    FD_FLOOR,
    Method,
    fixed,
    run_method,
)


def symplecticity_methods() -> list[Method]:
    """List fixed α (iterated midpoint), the one-pass variant, and both energy modes."""
    return [
        fixed(0.0),
        fixed(1 / 6),
        fixed(0.5),
        fixed(1.0),
        fixed(0.5, one_pass=True),
        fixed(1.0, one_pass=True),
        ENERGY,
        fixed(0.3, 4),
        fixed(0.3, 4, one_pass=True),
        ENERGY4,
    ]


def _flow(method: Method, problem: ConstrainedProblem, h: float, n: int) -> Callable[[Array, Array], tuple]:
    def step_map(x: Array, v: Array) -> tuple[Array, Array]:
        x1, v1, _, _ = run_method(method, problem, x, v, h, n)
        return x1, v1

    return step_map


def symplecticity(quick: bool) -> dict:
    """Measure the symplectic form's defect on the spring pendulum (against h) and on 3 waters (2 fs)."""
    spring = planar_pendulum(kappa=2.0)
    xs, vs = planar_pendulum_start(1.0)
    t_end = 0.4
    hs = [0.2, 0.1, 0.05] if quick else [0.2, 0.1, 0.05, 0.025]
    pendulum: dict = {
        "problem": "planar pendulum with a spring, kappa = 2, theta0 = 1",
        "t_end": t_end,
        "h": hs,
        "tangent_vectors": 2,
        "epsilon": 1e-6,
        "methods": {},
    }
    for method in symplecticity_methods():
        defects = [
            symplecticity_defect(spring, _flow(method, spring, h, round(t_end / h)), xs, vs, 2) for h in hs
        ]
        above = np.array(defects) > FD_FLOOR
        pendulum["methods"][method.key] = {
            "label": method.label,
            "defects": defects,
            "fitted_order": (
                fitted_order(np.array(hs)[above], np.array(defects)[above]) if above.sum() >= 2 else None
            ),
            "points_above_floor": int(above.sum()),
        }
    waters, xw, vw = water_cluster(3, seed=0)
    water: dict = {
        "problem": "3 rigid TIP3P waters in vacuum, h = 2 fs",
        "h": 0.002,
        "steps": 10,
        "tangent_vectors": 4,
        "epsilon": 1e-6,
        "methods": {},
    }
    for method in symplecticity_methods():
        water["methods"][method.key] = {
            "label": method.label,
            "defect": symplecticity_defect(waters, _flow(method, waters, 0.002, 10), xw, vw, 4),
        }
    return {"spring_pendulum": pendulum, "water_cluster": water}
