"""Energy drift from an energies CSV: linear fit of H − E_ref against time."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..observables import drift_per_dof


@dataclass
class EnergyDrift:
    """Linear fit of H − E_ref (kJ/mol) against time (ps)."""

    e_ref: float
    samples: int
    duration_ps: float
    drift_kj_per_mol_per_ns: float
    drift_per_dof: float  # kJ/mol/ns per degree of freedom
    rms_residual: float
    max_abs_residual: float

    def as_dict(self) -> dict:
        return asdict(self)


def energy_drift(times_ps: np.ndarray, total_energies: np.ndarray, dof: int) -> EnergyDrift:
    """Fit H(t) − H(0) with a line; E_ref is the first total energy (the start state).

    RMS and max of |H − E_ref| are taken over the samples after the first.
    """
    times_ps = np.asarray(times_ps, dtype=float)
    total = np.asarray(total_energies, dtype=float)
    if len(total) < 2:
        raise ValueError("need at least two energy samples to fit a drift.")
    if not np.all(np.isfinite(total)):
        raise ValueError("the energies contain NaN or infinity: the run blew up; no drift can be fitted.")
    residual = total - total[0]
    slope_per_ps = np.polyfit(times_ps, residual, 1)[0]
    return EnergyDrift(
        e_ref=float(total[0]),
        samples=len(total),
        duration_ps=float(times_ps[-1] - times_ps[0]),
        drift_kj_per_mol_per_ns=float(slope_per_ps * 1000.0),
        drift_per_dof=drift_per_dof(times_ps, residual, dof),
        rms_residual=float(np.sqrt(np.mean(residual[1:] ** 2))),
        max_abs_residual=float(np.max(np.abs(residual[1:]))),
    )
