r"""Plot H − E_ref against time from ``energy_benchmark --traces FILE.npz``.

Run from the repository root::

    alphaprk bench energy --scan 2 3 4 5 --json docs/energy_benchmark.json \\
        --traces energy_traces.npz
    python tools/scripts/energy_benchmark_figure.py energy_traces.npz docs/figures/energy_benchmark.png
"""

from __future__ import annotations

import sys

import numpy as np


def main(traces_path: str, figure_path: str) -> None:
    """Two panels: every row on a common scale, and the α-RATTLE-4 rows close up."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    traces = np.load(traces_path)
    step_ps = float(traces["timestep_ps"])
    names = [name for name in traces.files if name != "timestep_ps"]
    fig, axes = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for ax, subset in zip(axes, (names, [n for n in names if "RATTLE-4" in n or "h/" in n])):
        for name in subset:
            residuals = traces[name]
            t = (np.arange(residuals.size) + 1) * step_ps
            ax.plot(t, residuals, lw=0.6, label=name)
        ax.set_ylabel("H − E_ref (kJ/mol)")
        ax.legend(fontsize=8, loc="upper left")
    axes[1].set_xlabel("time (ps)")
    axes[0].set_title("2,661-atom TIP3P box, 2 fs (RATTLE h/k: same force evaluations), CPU platform")
    fig.tight_layout()
    fig.savefig(figure_path, dpi=120)


if __name__ == "__main__":
    main(*sys.argv[1:3])
