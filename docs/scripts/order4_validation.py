"""Convergence of α-RATTLE-4 and the size of α* against h (NumPy reference).

Run from the repository root: ``python docs/scripts/order4_validation.py``. Writes
``docs/figures/order4_convergence.png`` and ``docs/figures/order4_alpha_star.png``
and prints the fitted slopes and |α*| ratios used in docs/validation.md.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from openmm_alphaprk.reference import (
    alpha_rattle4_step,
    alpha_rattle_step,
    integrate,
    integrate_energy_preserving,
    planar_pendulum,
    planar_pendulum_start,
)

FIGURES = Path(__file__).resolve().parents[1] / "figures"
T_END = 2.0
COUNTS = np.array([20, 40, 80, 160, 320])


def main() -> None:
    """Compute the error-vs-h and α*-vs-h data, print the slopes, save the figures."""
    problem = planar_pendulum(kappa=2.0)
    x0, v0 = planar_pendulum_start(1.0)
    x_ref, v_ref = integrate(problem, x0, v0, T_END / 4096, 4096, 0.0, step=alpha_rattle4_step)
    reference = np.concatenate([x_ref, v_ref])
    hs = T_END / COUNTS
    curves, largest_alpha = {}, {}
    for label, step, alpha in [
        ("RATTLE (α = 0, order 2)", alpha_rattle_step, 0.0),
        ("α-RATTLE-4, α = 0", alpha_rattle4_step, 0.0),
        ("α-RATTLE-4, α = 0.3", alpha_rattle4_step, 0.3),
    ]:
        errors = []
        for n in COUNTS:
            x, v = integrate(problem, x0, v0, T_END / n, int(n), alpha, step=step)
            errors.append(np.linalg.norm(np.concatenate([x, v]) - reference))
        curves[label] = np.array(errors)
    for label, step in [
        ("α-RATTLE energy mode", alpha_rattle_step),
        ("α-RATTLE-4 energy mode", alpha_rattle4_step),
    ]:
        errors, largest = [], []
        for n in COUNTS:
            x, v, alphas = integrate_energy_preserving(step, problem, x0, v0, T_END / n, int(n))
            errors.append(np.linalg.norm(np.concatenate([x, v]) - reference))
            largest.append(np.max(np.abs(alphas)))
        curves[label] = np.array(errors)
        largest_alpha[label] = np.array(largest)
    for label, errors in curves.items():
        print(f"{label:28s} slope {np.polyfit(np.log(hs), np.log(errors), 1)[0]:.2f}")
    for label, largest in largest_alpha.items():
        ratios = largest[:-1] / largest[1:]
        values = np.array2string(largest, precision=3)
        print(f"{label:28s} max|α*| {values}  ratio per halving {np.round(ratios, 2)}")

    FIGURES.mkdir(exist_ok=True)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for label, errors in curves.items():
        ax.loglog(hs, errors, "o-", label=label)
    ax.set_xlabel("step h (pendulum time units)")
    ax.set_ylabel("error at t = 2 (positions and velocities)")
    ax.set_title("Planar pendulum with a spring (κ = 2): convergence")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIGURES / "order4_convergence.png", dpi=120)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for label, largest in largest_alpha.items():
        ax.loglog(hs, largest, "o-", label=label)
    guide = largest_alpha["α-RATTLE-4 energy mode"][0] * (hs / hs[0]) ** 2
    ax.loglog(hs, guide, "k--", lw=0.8, label="∝ h²")
    ax.set_xlabel("step h")
    ax.set_ylabel("max |α*| over the run")
    ax.set_title("Size of α* in the energy mode")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIGURES / "order4_alpha_star.png", dpi=120)


if __name__ == "__main__":
    main()
