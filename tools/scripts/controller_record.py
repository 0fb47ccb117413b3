"""Record an energy mode per step (alpha*, slope, trials, residual, S-bar, fallback, H - E_ref), or RATTLE.

Usage: python tools/scripts/controller_record.py SYSTEM ORDER(0=RATTLE) STEPS PLATFORM PRECISION OUT.npy
(the numbers of docs/research/controller_robustness.md; ALPHAPRK_CACHE: a systems cache folder)
"""

import os
import sys
import time

import numpy as np
import openmm as mm
import openmm.unit as u

from openmm_alphaprk import AlphaRattleIntegrator, RattleIntegrator
from openmm_alphaprk.integrators import check_context
from openmm_alphaprk.systems.cache import prepare_system


def main() -> None:
    name, order, steps, platname, prec, out = (
        sys.argv[1],
        int(sys.argv[2]),
        int(sys.argv[3]),
        sys.argv[4],
        sys.argv[5],
        sys.argv[6],
    )
    p = prepare_system(name, cache_dir=os.environ.get("ALPHAPRK_CACHE"))
    plat = mm.Platform.getPlatformByName(platname)
    props = {"Precision": prec} if platname in ("CUDA", "OpenCL") else {}

    def ctx(integ):
        c = mm.Context(p.system, integ, plat, props)
        check_context(integ, c)
        c.setPeriodicBoxVectors(*p.state.getPeriodicBoxVectors())
        c.setPositions(p.positions)
        c.setVelocities(p.velocities)
        return c

    def H(c):
        s = c.getState(getEnergy=True)
        return (s.getPotentialEnergy() + s.getKineticEnergy()).value_in_unit(u.kilojoule_per_mole)

    if order == 0:
        integ = RattleIntegrator(2 * u.femtosecond)
    else:
        integ = AlphaRattleIntegrator(2 * u.femtosecond, alpha="energy", order=order)

    c = ctx(integ)
    e0 = H(c)
    rec = []
    t = time.time()
    names = ("alpha", "slope", "trials", "residual", "slope_scale", "fell_back")
    for _ in range(steps):
        integ.step(1)
        if order:
            g = integ.getGlobalVariableByName
            rec.append([g(n) for n in names] + [H(c) - e0])
        else:
            rec.append([0, 0, 1, 0, 0, 0, H(c) - e0])
    rec = np.array(rec)
    np.save(out, rec)
    r = rec[:, 6]
    print(
        name,
        order,
        platname,
        prec,
        "time",
        round(time.time() - t, 1),
        "evals",
        getattr(integ, "force_evaluations_per_step", 1),
        "rms",
        np.sqrt(np.mean(r**2)),
        "max",
        np.abs(r).max(),
        "trials",
        rec[:, 2].mean(),
        "fb",
        rec[:, 5].mean(),
        flush=True,
    )


if __name__ == "__main__":
    main()
