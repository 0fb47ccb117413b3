"""Figures (matplotlib, the ``plots`` extra), written as PNG files without a display."""

from __future__ import annotations

import os
import textwrap
from collections.abc import Collection, Mapping

import numpy as np

from ..observables import DriftFit, drift_text, fit_drift, residual_statistics, rms
from ..runs import integrator_names as names

#: Title of the H − E_ref figure when none is given.
RESIDUALS_TITLE = "Energy conservation: H − E_ref per integrator (NVE from the same start)"
#: What the panel of an integrator whose H − E_ref is not comparable step for step says.
NOT_COMPARABLE = "not comparable step for step (leapfrog kinetic energy); drift only"
_COLOURS = (
    "tab:blue",
    "tab:orange",
    "tab:green",
    "tab:red",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:olive",
)


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


def run_caption(
    system: str,
    atoms: int,
    timestep_fs: float,
    steps: int,
    platform: str,
    *,
    precision: str | None = None,
    dof: int | None = None,
    energy_interval: int | None = None,
) -> str:
    """Return a comparison figure's caption: system (atoms, DOF), step, length, platform, sampling."""
    where = f"platform {platform}" + (f" ({precision} precision)" if precision else "")
    sampled = f"; H − E_ref sampled every {energy_interval} steps" if energy_interval else ""
    size = f"{atoms:,} atoms" + (f", {dof:,} DOF" if dof else "")
    return (
        f"System {system} ({size}); step {timestep_fs:g} fs, {steps:,} steps = "
        f"{steps * timestep_fs / 1000:g} ps NVE; {where}{sampled}"
    )


def _display(name: str) -> str:
    """Return the vocabulary's label of an integrator name; other keys as given."""
    try:
        return names.label(name)
    except ValueError:
        return name


def _is_leapfrog(name: str) -> bool:
    try:
        return names.parse_integrator(name).kind == "verlet"
    except ValueError:
        return False


def _fit(times: np.ndarray, residuals: np.ndarray) -> DriftFit | None:
    """Return the trace's drift fit (:func:`~openmm_alphaprk.observables.fit_drift`), None below 2 samples."""
    return fit_drift(times, residuals) if len(times) >= 2 else None


def _drift_label(fit: DriftFit, dof: int | None) -> str:
    """Return the drift as the tables print it: drift/DOF with ``dof``, else the total, ± standard error."""
    if dof:
        return "drift/DOF " + drift_text(*fit.per_dof(dof), "kJ/mol/ns")
    return "drift " + drift_text(fit.slope, fit.standard_error, "kJ/mol/ns")


def _rms_label(name: str, residuals: np.ndarray) -> str:
    """Return the legend entry of a trace on the log panel: its RMS |H − E_ref| as the tables print it."""
    rms = residual_statistics(residuals)[0]
    return f"{_display(name)}: RMS {rms:.3g} kJ/mol"


def _running_rms(times: np.ndarray, residuals: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred running RMS of H − E_ref over ``window`` samples (valid part only)."""
    running = rms(np.lib.stride_tricks.sliding_window_view(residuals, window), axis=1)
    start = (window - 1) // 2
    return times[start : start + len(running)], running


def _log_panel(ax, traces: Mapping[str, tuple[np.ndarray, np.ndarray]], colours: Mapping[str, str]) -> None:
    """|H − E_ref| of the comparable integrators on a log axis: every sample thin, running RMS thick."""
    floor, ceiling, smoothed = np.inf, 0.0, False
    for name, (times, residuals) in traces.items():
        magnitude = np.abs(residuals)
        rms = residual_statistics(residuals)[0]
        shown = np.where(magnitude > 0, magnitude, np.nan)
        window = max(1, len(times) // 25)
        thin = window >= 3
        smoothed |= thin
        ax.plot(
            times,
            shown,
            color=colours[name],
            lw=0.7 if thin else 1.5,
            alpha=0.35 if thin else 1.0,
            gid=name,
            label="_" + name if thin else _rms_label(name, residuals),
        )
        if thin:
            ax.plot(
                *_running_rms(times, residuals, window),
                color=colours[name],
                lw=2.2,
                gid=name,
                label=_rms_label(name, residuals),
            )
        if rms > 0:
            floor, ceiling = min(floor, rms / 30), max(ceiling, float(np.nanmax(shown)))
    ax.set_yscale("log")
    columns = min(len(traces), 3)
    if ceiling > 0:  # room above the curves for the legend: 8 % of the height per row
        share = 0.03 + 0.08 * -(-len(traces) // columns)
        decades = np.log10(2 * ceiling / floor)
        ax.set_ylim(floor, 2 * ceiling * 10 ** (decades * share / (1 - share)))
    ax.set_xlabel("time (ps)", fontsize=10)
    ax.set_ylabel("|H − E_ref| (kJ/mol, log)", fontsize=10)
    how = "thin: every sample; thick: running RMS" if smoothed else "every sample"
    ax.set_title(
        f"|H − E_ref| of the velocity-Verlet integrators on one log scale ({how}); "
        "E_ref = total energy of the start state",
        fontsize=11,
    )
    ax.grid(True, which="major", lw=0.4, alpha=0.5)
    legend = ax.legend(loc="upper center", ncol=max(columns, 1), fontsize=9, frameon=False)
    legend.set_in_layout(False)


def _with_headroom(ax, values: np.ndarray) -> None:
    """Y-limits from the data, with room above it for a two-line legend that hides nothing."""
    low, high = float(np.nanmin(values)), float(np.nanmax(values))
    span = max(high - low, 0.1 * max(abs(low), abs(high)), 1e-9)
    ax.set_ylim(low - 0.08 * span, high + 0.6 * span)


def _linear_panel(
    ax, name: str, trace: tuple[np.ndarray, np.ndarray], colour: str, dof: int | None, comparable: bool
) -> None:
    """One integrator's H − E_ref on its own linear axis, with its drift line and ±σ noise band."""
    times, residuals = trace
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.plot(
        times, residuals, color=colour, lw=1.0, alpha=1.0 if comparable else 0.5, gid=name, label="_trace"
    )
    values = [residuals]
    fit = _fit(times, residuals)
    if fit is not None:
        line = fit.line(times)
        ax.plot(times, line, color="k", ls="--", lw=1.5, gid=name, label=_drift_label(fit, dof))
        if comparable:
            sigma = fit.scatter
            band = f"±σ: scatter about the drift line, σ = {sigma:.3g} kJ/mol"
            ax.fill_between(times, line - sigma, line + sigma, color=colour, alpha=0.25, lw=0, label=band)
            values += [line - sigma, line + sigma]
    _with_headroom(ax, np.concatenate(values))
    if fit is not None:
        legend = ax.legend(loc="upper left", fontsize=9, frameon=False, borderaxespad=0.2)
        legend.set_in_layout(False)
    ax.set_xlabel("time (ps)", fontsize=10)
    ax.set_ylabel("H − E_ref (kJ/mol)", fontsize=10)
    ax.grid(True, lw=0.4, alpha=0.5)
    if comparable:
        ax.set_title(_display(name), fontsize=12, fontweight="bold", color=colour)
    else:
        ax.set_facecolor("0.95")
        ax.set_title(f"{_display(name)}: {NOT_COMPARABLE}", fontsize=12, fontweight="bold", color="0.3")


def build_energy_residual_figure(
    traces: Mapping[str, tuple[np.ndarray, np.ndarray]],
    title: str = "",
    *,
    caption: str = "",
    not_comparable: Collection[str] | None = None,
    dof: int | None = None,
):
    """Build the H − E_ref figure of a comparison; return the Figure (the caller saves and closes it).

    ``traces`` maps integrator names (or any keys) to (time in ps, H − E_ref in kJ/mol),
    each starting at the start state (H − E_ref = 0), as a run's energy rows do.
    On top, |H − E_ref| of every comparable integrator on one log axis, labelled with its
    RMS |H − E_ref| (:func:`~openmm_alphaprk.observables.residual_statistics`, the
    number of the tables); below, one linear panel per integrator with its own y-range,
    its drift line (:func:`~openmm_alphaprk.observables.fit_drift`), labelled with the
    drift ± its standard error per DOF with ``dof`` (else in kJ/mol/ns), or "not
    resolved" (:func:`~openmm_alphaprk.observables.drift_text`), and the ±σ band of the
    samples' scatter about that line. The integrators of
    ``not_comparable`` (by default ``verlet``, leapfrog) get a separate, grey panel at the
    bottom labelled :data:`NOT_COMPARABLE`, never an axis shared with the others.
    ``caption`` is written under the panels (system, step, platform: see :func:`run_caption`).
    """
    plt = pyplot()
    apart = set(not_comparable) if not_comparable is not None else {n for n in traces if _is_leapfrog(n)}
    comparable = {name: trace for name, trace in traces.items() if name not in apart}
    separate = {name: trace for name, trace in traces.items() if name in apart}
    colours = {name: _COLOURS[i % len(_COLOURS)] for i, name in enumerate(traces)}
    columns = 2 if len(comparable) > 1 else 1
    rows = -(-len(comparable) // columns)
    heights = ([1.5] if comparable else []) + [1.0] * (rows + len(separate))
    fig = plt.figure(figsize=(12, 1.0 + 2.6 * sum(heights)), layout="constrained")
    grid = fig.add_gridspec(max(len(heights), 1), columns, height_ratios=heights or None)
    row = 0
    if comparable:
        _log_panel(fig.add_subplot(grid[0, :]), comparable, colours)
        row = 1
    for i, (name, trace) in enumerate(comparable.items()):
        last_alone = columns == 2 and i == len(comparable) - 1 and i % 2 == 0
        cell = grid[row + i // columns, :] if last_alone else grid[row + i // columns, i % columns]
        _linear_panel(fig.add_subplot(cell), name, trace, colours[name], dof, comparable=True)
    for j, (name, trace) in enumerate(separate.items()):
        _linear_panel(fig.add_subplot(grid[row + rows + j, :]), name, trace, "0.35", dof, comparable=False)
    fig.suptitle(title or RESIDUALS_TITLE, fontsize=14, fontweight="bold")
    if caption:
        fig.supxlabel(textwrap.fill(caption, 150), fontsize=10.5)
    return fig


def plot_energy_residuals(
    traces: Mapping[str, tuple[np.ndarray, np.ndarray]],
    path: str | os.PathLike,
    title: str = "",
    *,
    caption: str = "",
    not_comparable: Collection[str] | None = None,
    dof: int | None = None,
) -> str:
    """Write :func:`build_energy_residual_figure` as a PNG; returns the path."""
    plt = pyplot()
    fig = build_energy_residual_figure(traces, title, caption=caption, not_comparable=not_comparable, dof=dof)
    fig.savefig(path, dpi=110)
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


def plot_accuracy(systems: Mapping[str, Mapping], path: str | os.PathLike, title: str = "") -> str:
    """Plot each system's RMS position error against time, one panel per system; returns the path.

    ``systems``: the ``systems`` of ``alphaprk bench accuracy``'s JSON (each with ``rows``
    and ``reference_convergence``). One colour per integrator; rows at h are solid, rows at
    h/k dashed with a marker per k; the grey dotted line is the reference's own difference
    from RATTLE at h/128, the floor below which no error is resolved. The legend gives each
    row's force evaluations per step and RMS(H − E_ref).
    """
    plt = pyplot()
    panels = len(systems)
    fig, axes = plt.subplots(1, panels, figsize=(5.4 * panels, 7.2), constrained_layout=True, squeeze=False)
    markers = ("o", "s", "^", "v", "D", "P", "X", "*")
    for ax, (system, result) in zip(axes[0], systems.items()):
        colours: dict[str, str] = {}
        divisors = sorted({row["divisor"] for row in result["rows"]})
        for row in result["rows"]:
            horizons = row["horizons"]
            if not horizons:
                continue
            colour = colours.setdefault(row["integrator"], _COLOURS[len(colours) % len(_COLOURS)])
            ax.plot(
                [h["time_fs"] for h in horizons],
                [h["position_rms"] for h in horizons],
                ls="-" if row["divisor"] == 1 else "--",
                marker=markers[divisors.index(row["divisor"]) % len(markers)],
                ms=3.5,
                lw=1.4 if row["divisor"] == 1 else 1.0,
                color=colour,
                label=f"{row['name']} ({row['force_evaluations_per_step']:.2g} ev., "
                f"RMS|H−E_ref| {row['rms_residual']:.2g})",
            )
        floor = result.get("reference_convergence") or []
        if floor:
            ax.plot(
                [h["time_fs"] for h in floor],
                [h["position_rms"] for h in floor],
                ls=":",
                color="grey",
                label="reference h/64 vs h/128",
            )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time (fs)")
        ax.set_ylabel("RMS position error per atom (nm)")
        atoms = result.get("header", "").split(":", 1)[-1].split(",", 1)[0].strip()
        ax.set_title(f"{system} ({atoms})", fontsize=9)
        ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=1)
        ax.grid(True, which="both", alpha=0.25)
    fig.suptitle(
        title or "Position error against RATTLE at h/64, same start: solid at h, dashed at h/k",
        fontsize=10,
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)
