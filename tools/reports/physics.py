"""The generated blocks and figures of docs/physics.md from docs/data/physics/ (``bench physics report``).

Part of ``python -m tools.reports`` (``--figures`` draws the figures).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tools.reports.markdown import markdown_table
from tools.reports.numbers import sig
from tools.reports.sources import DOCS, Source, load, provenance_line

PAGE = DOCS / "physics.md"
WATER = "physics/tip3p-2nm.json"
SOLUTE = "physics/villin-h3.json"
CLUSTER = "physics/water-cluster.json"
ESTIMATOR = "physics/half_kick_tip3p-2nm.json"
#: The rescaling every row of the estimator table is paired with (start by start).
PLAIN_RESCALING = "rattle+rescale"
FIGURES = DOCS / "figures"
#: The rows whose velocities are scaled, in the page's order.
RESCALED = ("rattle+rescale", "rattle+rescale@10", "rattle4+rescale")
#: The temperatures of a group, in the equipartition table's order.
TEMPERATURES = ("total", "translational", "rotational")
#: The temperature gaps read on the solvated solute: (group, partition) minus (group, partition).
SOLUTE_GAPS = (
    ("system", "translational", "system", "rotational and internal"),
    ("solute", "total", "solvent", "total"),
)
#: The groups of a partition in the order the pages name them.
_GROUP_ORDER = ("system", "half 1", "half 2", "solute", "solvent")
#: How far (combined standard errors) a rescaled row may sit from the reference (the issue's goal).
GOAL_ERRORS = 2.0
#: A published TIP3P self-diffusion coefficient beside ours (1e-5 cm²/s).
PUBLISHED_D = (
    "5.85 ± 0.08 (TIP3P as modified for CHARMM, 298 K, 216 molecules, truncated electrostatics, "
    "no finite-size correction: Mark & Nilsson, J. Phys. Chem. A 105 (2001) 9954)"
)


def _pm(value: float | None, error: float | None, digits: int = 3) -> str:
    """Write ``value ± error`` ("-" for no value; no error: the value alone)."""
    if value is None or value != value:
        return "-"
    if error is None or error != error:
        return f"{value:.{digits}g}"
    return f"{value:.{digits}g} ± {sig(error)}"


def _provenance(source: Source, data: dict) -> str:
    """Return the provenance line of a ``bench physics`` report: its system, platform and each mode's runs."""
    arguments = data["arguments"]
    parts = []
    if "segments" in arguments:
        a = arguments["segments"]
        parts.append(
            f"segments: {a['starts']} starts {a['spacing']:g} ps of Langevin dynamics apart, "
            f"{a['length']:g} ps of NVE each per row"
        )
    if "stress" in arguments:
        a = arguments["stress"]
        parts.append(
            f"stress: {a['time']:g} ps ({a['time_multi']:g} ps for compositions) at {a['timesteps'][0]:g} fs"
        )
    if "order" in arguments:
        a = arguments["order"]
        parts.append(f"order: {a['length']:g} ps at " + ", ".join(f"{h:g}" for h in a["timesteps"]) + " fs")
    platform = next(iter(arguments.values()))["platform"]
    return provenance_line([source], "; ".join([f"{data['system']}, {platform} platform", *parts]))


def _name(integrator: str) -> str:
    """Return the registry's canonical name of ``integrator`` (older runs wrote ``split-me``)."""
    from openmm_alphaprk.runs.integrator_names import parse_integrator

    return parse_integrator(integrator).name


def _label(setting: str) -> str:
    """``rattle+rescale h=2 fs`` → ``rattle+rescale`` at 2 fs."""
    name, _, step = setting.partition(" h=")
    return f"`{_name(name)}` at {step}"


def _mean_error(values) -> tuple[float, float]:
    """Mean over segments (or starts) and its standard error, std (ddof 1) / √n."""
    values = np.asarray(values, dtype=float)
    return float(values.mean()), float(values.std(ddof=1) / math.sqrt(len(values)))


def _segment_gap(first: dict, second: dict) -> np.ndarray:
    """T_first − T_second (K) segment by segment."""
    return np.array(first["segment_temperatures_K"]) - np.array(second["segment_temperatures_K"])


def _gap(group: dict) -> tuple[float, float]:
    """Mean and standard error over segments of T_translational − T_rotational (K)."""
    first, second = group["translational"], group["rotational"]
    if len(first.get("segment_temperatures_K") or ()) < 2 or not second.get("segment_temperatures_K"):
        return first["temperature_K"] - second["temperature_K"], math.nan
    return _mean_error(_segment_gap(first, second))


def equipartition_table(data: dict) -> str:
    """Partition temperatures per setting, their gap, and the distance from the reference in errors."""
    eq = data["segments"]["equipartition"]
    reference = eq["reference"]["label"]
    rows = []
    for label, setting in {reference: eq["reference"], **eq["settings"]}.items():
        is_reference = label == reference
        groups = setting["groups"]
        system = groups["system"]
        against = setting.get("against_reference", {}).get("system", {})
        z = [against.get(p, {}).get("in_errors") for p in ("translational", "rotational")]
        step = label.partition(" h=")[2]
        rattle = eq["settings"].get(f"rattle h={step}", {}).get("groups", {}).get("system")
        versus_rattle = "-"
        if rattle is not None and rattle is not system:  # (T_tr − T_rot) − RATTLE's, paired by start
            gaps = [_segment_gap(g["translational"], g["rotational"]) for g in (system, rattle)]
            versus_rattle = _pm(*_mean_error(gaps[0] - gaps[1]), 2)
        rows.append(
            [_label(label) + (" (reference)" if is_reference else "")]
            + [_pm(system[p]["temperature_K"], system[p]["standard_error_K"], 4) for p in TEMPERATURES]
            + [
                _pm(*_gap(system), 2),
                _pm(*_mean_error(_segment_gap(groups["half 1"]["total"], groups["half 2"]["total"])), 2),
                versus_rattle,
                " / ".join("-" if v is None or is_reference else f"{v:+.1f}" for v in z),
            ]
        )
    header = (
        "setting | T total (K) | T translation (K) | T rotation (K) | T_tr − T_rot (K) "
        "| T half 1 − half 2 (K) | gap − RATTLE's at the step (K, by start) "
        "| translation / rotation vs reference (errors)"
    )
    return markdown_table(header, rows) + (
        f"\n\nReference: {_label(reference)}. Errors: standard error of the mean over the independent "
        "segments (one temperature per segment: 2⟨K⟩/(N k_B) of physical_validation's partition of "
        "the kinetic energy over the segment's frames); distances from the reference in combined "
        "standard errors; the gap against RATTLE's at the same step is paired by start (same E_ref). "
        f"Flagged by `alphaprk validate` ({eq['flag_rule']}): "
        + (", ".join(_flag(f) for f in eq["flagged"]) or "none")
        + "."
    )


def _flag(flag: dict | str) -> str:
    """Say which partition of a setting ``alphaprk validate`` flagged, and by how much."""
    if isinstance(flag, str):
        return flag
    return (
        f"{_label(flag['setting'])}: {flag['group']} {flag['partition']} "
        f"(z = {flag['in_errors']:+.1f} against the setting's own whole-system temperature)"
    )


def solute_table(data: dict) -> str:
    """Solute and solvent temperatures per setting, their gap, and the gaps against the reference's."""
    eq = data["segments"]["equipartition"]
    reference = eq["reference"]

    def gap(setting: dict, gap: tuple[str, str, str, str]) -> np.ndarray:
        a, pa, b, pb = gap
        return _segment_gap(setting["groups"][a][pa], setting["groups"][b][pb])

    rows = []
    for label, setting in {reference["label"]: reference, **eq["settings"]}.items():
        is_reference = label == reference["label"]
        groups = setting["groups"]
        cells = [_label(label) + (" (reference)" if is_reference else "")]
        cells += [
            _pm(groups[g]["total"]["temperature_K"], groups[g]["total"]["standard_error_K"], 4)
            for g in ("solute", "solvent")
        ]
        for pair in SOLUTE_GAPS:
            cells.append(_pm(*_mean_error(gap(setting, pair)), 2))
            cells.append(
                "-" if is_reference else _pm(*_mean_error(gap(setting, pair) - gap(reference, pair)), 2)
            )
        rows.append(cells)
    header = "setting | T solute (K) | T solvent (K) | " + " | ".join(
        f"{a} {pa} − {b} {pb} (K) | − reference's, by start (K)" for a, pa, b, pb in SOLUTE_GAPS
    )
    return markdown_table(header, rows) + (
        f"\n\nReference: {_label(reference['label'])}. Mean ± standard error over the segments (one "
        "temperature per segment, 2⟨K⟩/(N k_B) of physical_validation's partition over its frames); "
        "the differences to the reference's gap are paired by start (same E_ref)."
    )


def goal_verdict(data: dict) -> str:
    """Judge the goal: every rescaled row's partitions within 2 combined errors of the reference's."""
    settings = data["segments"]["equipartition"]["settings"]
    misses = []
    for label, setting in settings.items():
        if label.split(" h=")[0] not in RESCALED:
            continue
        rattle = settings.get(f"rattle h={label.partition(' h=')[2]}", {}).get("against_reference", {})
        for group, partitions in setting.get("against_reference", {}).items():
            for partition, entry in partitions.items():
                z = entry.get("in_errors")
                if z is not None and abs(z) > GOAL_ERRORS:
                    same_step = rattle.get(group, {}).get(partition, {}).get("in_errors")
                    beside = "" if same_step is None else f" (RATTLE at the step {same_step:+.1f})"
                    misses.append(f"{_label(label)} {group} {partition} {z:+.1f}{beside}")
    if not misses:
        names = {"system": "whole system", "half 1": "random halves", "half 2": "random halves"}
        seen = {g for setting in settings.values() for g in setting.get("against_reference", {})}
        groups = ", ".join(dict.fromkeys(names.get(g, g) for g in sorted(seen, key=_GROUP_ORDER.index)))
        return (
            f"**Met**: every partition ({groups}) of every rescaled row lies within "
            f"{GOAL_ERRORS:g} combined standard errors of the reference's."
        )
    return "**Not met** for: " + "; ".join(misses) + " (combined standard errors)."


def transport_table(data: dict) -> str:
    """D, g(r) first peak, τ₂ and the VACF's first minimum per setting, against the reference."""
    settings = data["transport"]["settings"]
    reference = next(s for s in settings if s["integrator"] == "rattle" and s["timestep_ps"] == 0.0005)
    corrected = reference["mean"].get("diffusion") is not None  # Yeh–Hummer needs a cubic box
    integral = reference["mean"].get("tau2_ps") is not None  # C₂ fell below its threshold in the segments
    quantities = (
        ("diffusion", "D (1e-5 cm²/s, Yeh–Hummer)", 3)
        if corrected
        else ("diffusion_pbc", "D in the box (1e-5 cm²/s)", 3),
        ("rdf_peak_r_angstrom", "g(r) peak r (Å)", 4),
        ("rdf_peak_g", "g(r) peak height", 3),
        ("tau2_ps", "τ₂ (ps)", 3) if integral else ("tau2_fit_ps", "τ₂, exponential fit (ps)", 3),
        ("vacf_first_minimum_ps", "VACF first minimum (ps)", 3),
    )
    rows = []
    for setting in [reference] + [s for s in settings if s is not reference]:
        row = [_label(f"{setting['integrator']} h={setting['timestep_ps'] * 1000:g} fs")]
        for key, _, digits in quantities:
            mean, error = setting["mean"].get(key), setting["standard_error"].get(key)
            text = _pm(mean, error, digits)
            if setting is not reference and mean is not None and reference["mean"].get(key) is not None:
                combined = math.hypot(error or 0.0, reference["standard_error"].get(key) or 0.0)
                if combined > 0:
                    text += f" ({(mean - reference['mean'][key]) / combined:+.1f})"
            row.append(text)
        rows.append(row)
    if corrected:
        d_text = (
            "plus the Yeh–Hummer correction with TIP3P's viscosity "
            f"{data['transport']['parameters'].get('viscosity_mPa_s', 0.321)} mPa·s (González & Abascal, "
            f"J. Chem. Phys. 132 (2010) 096101). A published value: {PUBLISHED_D}."
        )
    else:
        d_text = "without a finite-size correction (the box is not cubic, where Yeh–Hummer's applies)."
    tau_text = (
        ""
        if integral
        else " τ₂: time constant of an exponential fitted to C₂ of the water dipole (C₂ stays above its "
        "integration threshold over these segments)."
    )
    return markdown_table(["setting"] + [title for _, title, _ in quantities], rows) + (
        "\n\nMean ± standard error over the segments; in brackets the distance from RATTLE at 0.5 fs in "
        "combined standard errors. D: water oxygens' MSD (MDAnalysis `EinsteinMSD`) fitted over 10–60 % of "
        f"the longest lag, {d_text}{tau_text}"
    )


def _rescalings_by_setting(data: dict) -> dict[str, list[dict]]:
    """Return the segments' rescaling records (``summary.json``'s ``rescaling``) by setting folder."""
    by_setting: dict[str, list[dict]] = {}
    for path, totals in data["segments"]["rescaling"]["runs"].items():
        by_setting.setdefault(Path(path).parent.name, []).append(totals)
    return by_setting


def rescaling_table(data: dict) -> str:
    """Tabulate what the scaling did per rescaled setting: mean and RMS of s − 1, energy added per ns."""
    by_setting = _rescalings_by_setting(data)
    rows = []
    for name, group in sorted(by_setting.items(), key=lambda item: (_step(item[0]), item[0])):
        cells = []
        for key in ("mean_scale_change", "rms_scale_change", "added_energy_per_ns"):
            values = [g[key] for g in group]
            cells.append(_pm(*_mean_error(values), 2) if len(values) > 1 else _pm(values[0], None, 2))
        rows.append([_setting(name)] + cells)
    return markdown_table("setting | mean s − 1 | RMS s − 1 | energy added (kJ/mol/ns)", rows) + (
        "\n\nPer segment over all its rescalings (`summary.json`'s `rescaling`), mean ± standard error "
        "over the segments. Energy added = −Σ(H − E_ref before each scaling) per ns of simulated time."
    )


def scaling_power_table(data: dict) -> str:
    """Tabulate the scaling's statistics per rescaled row and step over the segments; their powers of h."""
    by_setting = _rescalings_by_setting(data)
    rows = []
    for folder, group in sorted(
        by_setting.items(), key=lambda item: (item[0].split("@")[0], -_step(item[0]))
    ):
        rms = [g["rms_scale_change"] for g in group]
        added = [g["added_energy_per_ns"] for g in group]
        rows.append(
            [
                _setting(folder),
                _pm(*_mean_error(rms), 2),
                _pm(*_mean_error(added), 2),
                _pm(*_mean_error(np.abs(added)), 2),
                str(len(group)),
            ]
        )
    fits = data["segments"]["rescaling"].get("fits", {})
    powers = "; ".join(
        f"`{name}`: "
        + ", ".join(
            f"{label} {fit['power_of_h'][key]:.2f} (expected {fit['expected_power'][key]})"
            for key, label in (("rms_scale_change", "RMS s − 1"), ("added_energy_per_ns", "|energy added|"))
        )
        for name, fit in fits.items()
        if fit.get("power_of_h")
    )
    header = "setting | RMS s − 1 | energy added (kJ/mol/ns) | \\|energy added\\| (kJ/mol/ns) | starts"
    return markdown_table(header, rows) + (
        "\n\nPer segment over all its rescalings (`summary.json`'s `rescaling`), mean ± standard error "
        "over the segments; energy added = −Σ(H − E_ref before each scaling) per ns. Fitted powers of h "
        f"(log of the mean over the segments against log h): {powers or '-'}."
    )


def order_table(data: dict) -> str:
    """Tabulate the order of H's fluctuations and the rescaled rows' round-off, from the order runs."""
    order = data["order"]["order"]
    rows = []
    for name, entry in order.items():
        if entry["kind"] == "order":
            fluctuations = ", ".join(f"{sig(v, 2)}" for v in entry["rmsd_H_kJ_per_mol"])
            rows.append([f"`{_name(name)}`", fluctuations, f"{entry['fitted_order']:.2f}"])
        else:
            relative = ", ".join(sig(r["relative"], 2) for r in entry["rows"])
            verdict = "round-off" if all(r["at_round_off"] for r in entry["rows"]) else "above round-off"
            rows.append([f"`{_name(name)}`", f"RMS(H − E_ref)/|E_ref|: {relative}", verdict])
    steps = ", ".join(f"{h:g}" for h in data["arguments"]["order"]["timesteps"])
    fits = data["order"]["rescaling"].get("fits", {})
    powers = "; ".join(
        f"`{name}`: "
        + ", ".join(
            f"{key.replace('_', ' ')} {value:.2f} (expected {fit['expected_power'][key]})"
            for key, value in fit["power_of_h"].items()
        )
        for name, fit in fits.items()
        if fit.get("power_of_h")
    )
    return markdown_table(["integrator", f"RMS fluctuation of H at {steps} fs (kJ/mol)", "order"], rows) + (
        "\n\nOrder: slope of log RMS(H fluctuation) against log h (physical_validation's "
        "`integrator.convergence` data); the rescaled rows: RMS(H − E_ref) relative to |E_ref|. How the "
        f"scaling's statistics shrink with h over runs of equal length (fitted powers): {powers or '-'}."
    )


def temperature_table(data: dict) -> str:
    """Tabulate mean T and U per setting against RATTLE at 0.5 fs from the same starts; the h → 0 limit."""
    paired = data["paired"]
    # RATTLE at 1 fs and 0.5 fs (the reference, difference 0): the O(h²) limit is Δ(1 fs) − 4/3 Δ(1 fs)
    one = paired.get("rattle@1fs")
    limit = {}
    if one:
        for key in ("temperature_difference_K", "potential_difference_kJ_per_mol"):
            value, error = one[key]
            limit[key] = (-value / 3, error / 3)
    rows = []
    for name, entry in sorted(paired.items(), key=lambda item: (_step(item[0]), item[0])):
        if entry["temperature_difference_K"][1] == 0:  # the reference itself
            continue
        cells = [_setting(name)]
        for key in ("temperature_difference_K", "potential_difference_kJ_per_mol"):
            value, error = entry[key]
            distance = "-"
            if key in limit and error > 0:
                distance = f"{(value - limit[key][0]) / math.hypot(error, limit[key][1]):+.1f}"
            cells += [_signed(value, error), distance]
        rows.append(cells)
    header = "setting | ΔT (K) | ΔT − limit (errors) | ΔU (kJ/mol) | ΔU − limit (errors)"
    limit_text = "-"
    if limit:
        t, u = limit["temperature_difference_K"], limit["potential_difference_kJ_per_mol"]
        limit_text = f"ΔT = {_signed(*t)} K, ΔU = {_signed(*u)} kJ/mol"
    return markdown_table(header, rows) + (
        "\n\nΔ: the setting's mean over its run (`energies.csv`) minus RATTLE at 0.5 fs's from the same "
        "start (same E_ref), mean ± standard error over the starts. The h → 0 limit, from RATTLE at 1 fs "
        f"and 0.5 fs with an h² error (Richardson): {limit_text}; the columns in errors are each row's "
        "distance from it."
    )


def _step(folder: str) -> float:
    """Return the step (fs) of a run folder ``NAME@2fs``."""
    return float(folder.rpartition("@")[2][:-2])


def _setting(folder: str) -> str:
    """Name the setting of a run folder ``NAME@2fs`` as the page does: ```NAME`` at 2 fs`."""
    integrator, _, step = folder.rpartition("@")
    return f"`{_name(integrator)}` at {step[:-2]} fs"


def _signed(value: float, error: float) -> str:
    """Write ``+value ± error``."""
    return f"{value:+.2g} ± {sig(error)}"


def stress_table(data: dict, gaps: tuple[tuple[str, str, str, str], ...]) -> str:
    """Tabulate per stress row each gap (group a − group b) in the first and last window, and its trend."""
    rows = []
    for name, run in data["stress"].items():
        times = np.array([w["end_ps"] for w in run["windows"]])
        for group_a, a, group_b, b in gaps:
            values = np.array([_window_gap(w, group_a, a, group_b, b) for w in run["windows"]])
            fit = np.polyfit(times, values, 1, cov=True) if len(times) > 3 else None
            trend = "-" if fit is None else _pm(100 * fit[0][0], 100 * math.sqrt(fit[1][0, 0]), 2)
            length = "" if run.get("complete", True) else f" (stopped at {times[-1]:.0f} ps)"
            cells = [f"{values[0]:+.1f}", f"{values[-1]:+.1f}", trend, f"{np.std(values, ddof=1):.1f}"]
            rows.append([_setting(name) + length, f"{group_a} {a} − {group_b} {b}", *cells])
    windows = next(iter(data["stress"].values()))["windows"]
    text = (
        f"\n\n{len(windows)} consecutive windows of each run, each partition's temperature "
        "2⟨K⟩/(N k_B) over the window's frames; trend: least-squares slope of the gap against "
        "time ± its standard error; spread: standard deviation of the gap over the windows."
    )
    energy = [
        [
            f"`{name.rpartition('@')[0]}`",
            _signed(summary["drift_per_dof"] * dof, summary["drift_per_dof_standard_error"] * dof),
            "-" if not summary["rescaling"] else f"{summary['rescaling']['added_energy_per_ns']:+.3g}",
        ]
        for name, run in data["stress"].items()
        if (summary := run.get("summary")) and (dof := summary["degrees_of_freedom"])
    ]
    if energy:
        header = "row | drift of H (kJ/mol/ns) | energy the scaling added (kJ/mol/ns)"
        text += "\n\nOver each whole run:\n\n" + markdown_table(header, energy)
    header = "row | gap | first window (K) | last window (K) | trend (K per 100 ps) | spread (K)"
    return markdown_table(header, rows) + text


def _window_gap(window: dict, group_a: str, a: str, group_b: str, b: str) -> float:
    """T_a − T_b (K) of a window, each 2⟨K⟩/(N k_B) over the window's frames (where the data have it)."""
    first, second = window["temperatures"][group_a][a], window["temperatures"][group_b][b]
    key = "frame_mean_temperature_K" if "frame_mean_temperature_K" in first else "temperature_K"
    return first[key] - second[key]


def figures(data: dict, stem: str) -> None:
    """Write the g(r) overlay, the MSD and the stress gaps against time as PNG files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if "curves" in data:
        fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
        for name, curve in data["curves"].items():
            left.plot(curve["r_angstrom"], curve["g"], label=name, lw=1)
            right.plot(curve["lag_ps"], curve["msd_angstrom2"], label=name, lw=1)
        left.set(xlabel="r (Å)", ylabel="g_OO(r)", xlim=(2.3, 8))
        right.set(xlabel="lag (ps)", ylabel="MSD of O (Å²)")
        left.legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(FIGURES / f"physics_{stem}_structure.png", dpi=110)
        plt.close(fig)
    if "stress" in data:
        fig, ax = plt.subplots(figsize=(7, 4))
        gap = ("system", "translational", "system", "rotational")
        if "solute" in next(iter(data["stress"].values()))["windows"][0]["temperatures"]:
            gap = ("solute", "total", "solvent", "total")
        for name, run in data["stress"].items():
            times = [w["end_ps"] for w in run["windows"]]
            ax.plot(times, [_window_gap(w, *gap) for w in run["windows"]], marker="o", label=name)
        ax.set(xlabel="end of window (ps)", ylabel="T {} {} − T {} {} (K)".format(*gap))
        ax.axhline(0, color="grey", lw=0.5)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(FIGURES / f"physics_{stem}_stress.png", dpi=110)
        plt.close(fig)


def estimator_table(data: dict) -> str:
    """Tabulate ⟨U⟩ − limit per kinetic-energy estimator and step, paired by start with `rattle+rescale`."""
    runs = data["runs"]
    rows = []
    for step in sorted({r["timestep_fs"] for r in runs}, reverse=True):
        at_step = [r for r in runs if r["timestep_fs"] == step]
        plain = {r["start"]: r for r in at_step if r["row"] == PLAIN_RESCALING}
        names = [PLAIN_RESCALING] + sorted({r["row"] for r in at_step} - {PLAIN_RESCALING})
        for name in names:
            mine = sorted((r for r in at_step if r["row"] == name), key=lambda r: r["start"])
            paired = [r for r in mine if r["start"] in plain]
            held = name.partition(", ")[2] or "U + K"
            difference = "-"
            below = "-"
            if name != PLAIN_RESCALING and len(paired) > 1:
                difference = _pm(*_mean_error([r["U"] - plain[r["start"]]["U"] for r in paired]), 2)
                below = _pm(*_mean_error([r["H_last"] - plain[r["start"]]["H_last"] for r in paired]), 2)
            rows.append(
                [
                    f"{step:g} fs",
                    held,
                    _pm(*_mean_error([r["U_minus_limit"] for r in mine]), 2),
                    difference,
                    below,
                    "-" if name == PLAIN_RESCALING else sig(float(np.mean([r["K_a_last"] for r in mine]))),
                    str(len(mine)),
                ]
            )
    header = (
        "step | holds | ⟨U⟩ − limit (kJ/mol) | − `rattle+rescale`'s, by start | "
        "H at the end − `rattle+rescale`'s (kJ/mol) | K_a at the end (kJ/mol) | starts"
    )
    return markdown_table(header, rows) + (
        f"\n\nMean ± standard error over the starts ({data['length_ps']:g} ps of NVE from each); "
        f"limit: {data['limit']}. `rattle+rescale` holds H = E_ref, so the H column is how far "
        "below E_ref the other rows keep the true energy."
    )


def render(write_figures: bool = False) -> dict[Path, dict[str, str]]:
    """Every generated block of docs/physics.md."""
    (water, water_source), (cluster, cluster_source) = load(WATER), load(CLUSTER)
    solute, solute_source = load(SOLUTE)
    estimator, estimator_source = load(ESTIMATOR)
    if write_figures:
        figures(water, "tip3p-2nm")
        figures(solute, "villin-h3")
    cluster_provenance = _provenance(cluster_source, cluster).replace("CPU platform", "Reference platform")
    blocks = {
        "water provenance": _provenance(water_source, water),
        "equipartition": equipartition_table(water) + "\n\n" + goal_verdict(water),
        "rescaling": rescaling_table(water),
        "temperature": temperature_table(water),
        "transport": transport_table(water),
        "order": order_table(water),
        "estimator provenance": provenance_line(
            [estimator_source], "tip3p-2nm, CPU platform, one thread, the four starts of the segments"
        ),
        "estimator": estimator_table(estimator),
        "cluster provenance": cluster_provenance,
        "cluster order": order_table(cluster),
        "cluster scaling provenance": cluster_provenance,
        "cluster scaling": scaling_power_table(cluster),
        "water stress": stress_table(water, (("system", "translational", "system", "rotational"),)),
        "solute provenance": _provenance(solute_source, solute),
        "solute stress": stress_table(solute, SOLUTE_GAPS),
        "solute equipartition": solute_table(solute) + "\n\n" + goal_verdict(solute),
        "solute temperature": temperature_table(solute),
        "solute transport": transport_table(solute),
    }
    return {PAGE: blocks}
