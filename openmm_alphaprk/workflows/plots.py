"""Figures (matplotlib, the ``plots`` extra), written as PNG files without a display."""

from __future__ import annotations

import os
import textwrap
from collections.abc import Mapping

import numpy as np


def pyplot():
    """Return ``matplotlib.pyplot`` on the Agg backend, or explain how to install it."""
    try:
        import matplotlib
    except ImportError:
        raise ImportError(
            "figures need matplotlib: pip install -e '.[plots]' (or pip install matplotlib); "
            "or switch the figures off (--no-plot)."
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_energy_residuals(
    traces: Mapping[str, tuple[np.ndarray, np.ndarray]], path: str | os.PathLike, title: str = ""
) -> str:
    """H − E_ref (kJ/mol) against time (ps), one line per integrator; returns the path."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    for name, (times, residuals) in traces.items():
        ax.plot(times, residuals, label=name, lw=1.0)
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("time (ps)")
    ax.set_ylabel("H − E_ref (kJ/mol)")
    ax.set_title(textwrap.fill(title, 110), fontsize=8)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)


def plot_xy(
    x: np.ndarray,
    ys: Mapping[str, np.ndarray],
    path: str | os.PathLike,
    *,
    xlabel: str,
    ylabel: str,
    title: str = "",
) -> str:
    """Plot one or more series against ``x``; returns the path."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    for label, y in ys.items():
        ax.plot(x, y, label=label, lw=1.0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    if len(ys) > 1:
        ax.legend(fontsize=8)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return str(path)
