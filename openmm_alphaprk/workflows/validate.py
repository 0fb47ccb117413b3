"""``validate``: does holding the energy by velocity rescaling bend the physics? Checks of run directories.

Reads run directories written by :func:`~openmm_alphaprk.runs.run_nve` (``alphaprk run``
with ``--velocity-interval N``), groups them into settings (same system, integrator and
step size; several directories of one setting are independent segments) and reports,
with ``physical_validation`` (Merz & Shirts, PLOS ONE 13 (2018) e0202764) used as a library:

(a) equipartition: the temperature of each partition of the kinetic energy (translation,
    rotation, internal; solute and solvent; random halves of the molecules), its distance
    from the run's own temperature and from a reference setting, in combined standard errors
    (:class:`~openmm_alphaprk.analysis.Equipartition`);
(b) the integrator's order from the fluctuations of H at several step sizes
    (``physical_validation.integrator.convergence``), or, for RATTLE + rescaling, how far
    H's fluctuations are from round-off;
(c) what the scaling did (``summary.json``'s ``rescaling``) and the power of h with which it shrinks;
(d) the mean kinetic temperature and potential energy against h, with the h → 0 limit from
    the ``rattle`` rows at the smaller steps.

What cannot be computed from the runs given is said in one line. Nothing is written
unless :meth:`Validation.write` is called (the command line writes ``validation.json``).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import openmm as mm
from tqdm import tqdm

from .._units import InputError
from ..analysis.equipartition import (
    FLAG_SIGMAS,
    MIN_FRAMES,
    Equipartition,
    combine_segments,
    compare_settings,
    import_physical_validation,
)
from ..runs import rundir

VALIDATION_FILE = "validation.json"
#: RMS |H − E_ref| / |E_ref| below which H's fluctuations are at round-off (single precision: 1.2e-7).
ROUND_OFF = 1e-6
RESCALING_KEYS = (
    "rescalings",
    "mean_scale_change",
    "rms_scale_change",
    "removed_energy",
    "added_energy_per_ns",
)


@dataclass
class RunRecord:
    """A run directory as read: its parameters, summary, energy rows and System."""

    path: Path
    parameters: dict
    summary: dict
    energies: np.ndarray
    system: mm.System

    @property
    def setting(self) -> tuple[str, str, float]:
        """(system, integrator, step in ps): runs of one setting are segments of one another."""
        p = self.parameters
        return (p["system"], p["integrator"], float(p["timestep_ps"]))

    @property
    def label(self) -> str:
        return setting_label(self.setting)


def setting_label(setting: tuple[str, str, float]) -> str:
    """``<integrator> h=<step> fs``."""
    return f"{setting[1]} h={setting[2] * 1000:g} fs"


@dataclass
class Validation:
    """What :func:`validate` found; :meth:`text` prints it, :meth:`write` writes ``validation.json``.

    Attributes
    ----------
    system : str
        The system of every run.
    settings : list of dict
        One per setting: ``label``, ``integrator``, ``timestep_fs``, ``runs`` (its segments).
    equipartition : dict
        (a) per setting, group and partition: temperature (K) ± standard error, its deviation
        from the setting's whole-system temperature and from the reference; ``flagged``
        lists the partitions off by more than the setting's ``flag_threshold`` combined errors
        (:func:`~openmm_alphaprk.analysis.equipartition.flag_threshold`).
    order : dict
        (b) per integrator: the fitted order and physical_validation's convergence test,
        or the round-off check of H for rescaled integrators.
    rescaling : dict
        (c) per run the summary's ``rescaling``, per integrator the fitted powers of h.
    temperature_vs_h : dict
        (d) mean kinetic temperature (K) and potential energy (kJ/mol) per setting, the h → 0
        limit and each row's distance from it.
    notes : list of str
        What could not be computed, and why.
    """

    system: str
    settings: list[dict]
    equipartition: dict = field(default_factory=dict)
    order: dict = field(default_factory=dict)
    rescaling: dict = field(default_factory=dict)
    temperature_vs_h: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)

    def write(self, path: str | os.PathLike) -> Path:
        """Write :meth:`as_dict` as JSON to ``path``; return it."""
        path = Path(path)
        path.write_text(json.dumps(self.as_dict(), indent=2) + "\n", encoding="utf-8")
        return path

    def text(self) -> str:
        """Return the report as lines of text (units in the headers)."""
        lines = [f"validation of {self.system}: {len(self.settings)} setting(s)"]
        lines += _equipartition_lines(self.equipartition)
        lines += _order_lines(self.order)
        lines += _rescaling_lines(self.rescaling)
        lines += _temperature_lines(self.temperature_vs_h)
        lines += [f"note: {note}" for note in self.notes]
        return "\n".join(lines)


def validate(
    runs: list[str | os.PathLike],
    *,
    reference: list[str | os.PathLike] | None = None,
    seed: int = 0,
    workers: int = 1,
    progress: bool = False,
) -> Validation:
    """Check the physics of run directories: equipartition, order, rescaling, temperature against h.

    Parameters
    ----------
    runs : list of str or os.PathLike
        Run directories with ``trajectory.trr`` (``alphaprk run --velocity-interval N``).
        Directories of the same system, integrator and step are independent segments of one setting.
    reference : list of str or os.PathLike, optional
        Run directories of one setting to compare each setting's partition temperatures with.
    seed : int, default 0
        Seed of the random halves of the molecules and of physical_validation's bootstrap.
    workers : int, default 1
        Processes reading the frames (MDAnalysis' multiprocessing backend when above 1).
    progress : bool, default False
        Progress bars on stderr.

    Returns
    -------
    Validation

    Raises
    ------
    InputError
        For a directory that is not a run, lacks ``trajectory.trr`` (the message names
        ``--velocity-interval N``), has fewer frames than the statistics need (the message
        names the length needed), or runs of different systems.
    ImportError
        When physical_validation is not installed (the message names the extra to install).
    """
    import_physical_validation()
    if not runs:
        raise InputError("give at least one run directory.")
    records = [read_run(Path(path)) for path in runs]
    references = [read_run(Path(path)) for path in reference or []]
    _check_one_system(records + references)
    for record in records + references:
        _check_trajectory(record)
    settings = _group(records)
    result = Validation(
        system=records[0].parameters["system"],
        settings=[
            {
                "label": setting_label(key),
                "integrator": key[1],
                "timestep_fs": key[2] * 1000,
                "runs": [str(r.path) for r in group],
            }
            for key, group in settings.items()
        ],
    )
    ref_settings = _group(references)
    if len(ref_settings) > 1:
        raise InputError(
            "--reference takes the segments of one setting (one integrator and step); got "
            + ", ".join(setting_label(key) for key in ref_settings)
            + "."
        )
    result.equipartition = _equipartition(settings, ref_settings, seed, workers, progress, result.notes)
    result.order = _order(settings, result.notes)
    result.rescaling = _rescaling(settings, result.notes)
    result.temperature_vs_h = _temperature_vs_h(settings, result.notes)
    return result


# ----------------------------------------------------------------------------- reading


def read_run(path: Path) -> RunRecord:
    """Read a run directory's ``run.json``, ``summary.json``, ``energies.csv`` and ``system.xml``.

    Raises
    ------
    InputError
        If ``path`` holds no ``run.json`` or lacks the files every run writes.
    """
    problem = rundir.missing_run_files(path, "folders written by `alphaprk run --velocity-interval N`")
    if problem:
        raise InputError(problem)
    parameters = json.loads((path / rundir.PARAMETERS_FILE).read_text(encoding="utf-8"))
    summary_file = path / rundir.SUMMARY_FILE
    summary = json.loads(summary_file.read_text(encoding="utf-8")) if summary_file.is_file() else {}
    system = mm.XmlSerializer.deserialize((path / rundir.SYSTEM_FILE).read_text(encoding="utf-8"))
    energies = rundir.read_energies(path / rundir.ENERGIES_FILE)
    return RunRecord(path, parameters, summary, energies, system)


def _check_one_system(records: list[RunRecord]) -> None:
    """Refuse runs of different systems, naming each system and its runs.

    Runs of one system may start from different states (independent segments): what must
    agree is the System itself (masses, constraints, forces), compared as its XML.
    """
    systems: dict[tuple, list[str]] = {}
    for record in records:
        xml = mm.XmlSerializer.serialize(record.system).encode()
        key = (
            record.parameters["system"],
            hashlib.sha256(xml).hexdigest(),
            record.system.getNumParticles(),
        )
        systems.setdefault(key, []).append(str(record.path))
    if len(systems) > 1:
        named = "; ".join(f"{key[0]} ({key[2]} atoms: {', '.join(paths)})" for key, paths in systems.items())
        raise InputError(
            f"runs of different systems cannot be compared: {named}. Validate each system on its own."
        )


def _check_trajectory(record: RunRecord) -> None:
    """Refuse a run without ``trajectory.trr``, or with fewer than :data:`MIN_FRAMES` frames in it."""
    trr = record.path / rundir.TRR_FILE
    if not trr.is_file() or trr.stat().st_size == 0:
        raise InputError(
            f"{record.path} has no {rundir.TRR_FILE} (positions and velocities): run it again with "
            "`alphaprk run ... --velocity-interval N` (e.g. N = 10 steps) to write one."
        )
    frames = _frame_count(trr)
    if frames < MIN_FRAMES:
        interval = record.parameters.get("velocity_interval") or 1
        raise InputError(
            f"{trr} holds {frames} frames; the equipartition statistics need at least {MIN_FRAMES}: a run of "
            f"at least {MIN_FRAMES * interval} steps at --velocity-interval {interval} (or a smaller "
            "interval)."
        )


def _frame_count(trr: Path) -> int:
    from MDAnalysis.lib.formats.libmdaxdr import TRRFile

    count = 0
    with TRRFile(str(trr)) as handle:
        for _ in handle:
            count += 1
    return count


def _group(records: list[RunRecord]) -> dict[tuple, list[RunRecord]]:
    """Return the runs by setting, in order of integrator name, then larger steps first."""
    groups: dict[tuple, list[RunRecord]] = {}
    for record in records:
        groups.setdefault(record.setting, []).append(record)
    return dict(sorted(groups.items(), key=lambda item: (item[0][1], -item[0][2])))


# ----------------------------------------------------------------------------- (a) equipartition


def _equipartition(settings, ref_settings, seed, workers, progress, notes) -> dict:
    """Partition temperatures per setting (segments combined), their deviations and the flagged ones."""
    out: dict = {
        "settings": {},
        "flagged": [],
        "flag_rule": f"|z| above the Student-t quantile (segments - 1 degrees of freedom) as unlikely as "
        f"{FLAG_SIGMAS:g} normal standard errors; {FLAG_SIGMAS:g} with one segment",
    }
    every = list(settings.items()) + [(("reference",) + key, group) for key, group in ref_settings.items()]
    combined = {}
    bar = tqdm(
        total=sum(len(g) for _, g in every),
        desc="equipartition (runs)",
        disable=not progress,
        file=sys.stderr,
    )
    with bar:
        for key, group in every:
            segments = []
            for record in group:
                segments.append(_equipartition_of_run(record, seed, workers, progress).results)
                bar.update(1)
            combined[key] = combine_segments(
                [s.temperatures for s in segments], frames=[s.frames for s in segments]
            )
    for key in settings:
        entry = combined[key]
        if entry["segments"] == 1:
            notes.append(
                f"{setting_label(key)}: one segment; the errors are physical_validation's own, known to be "
                "too small here (give several run directories of the setting for the standard error over "
                "segments)"
            )
        out["settings"][setting_label(key)] = entry
        for group, partitions in entry["groups"].items():
            for partition, values in partitions.items():
                z = values["deviation_in_errors"]
                if math.isfinite(z) and abs(z) > entry["flag_threshold"]:
                    out["flagged"].append(
                        {
                            "setting": setting_label(key),
                            "group": group,
                            "partition": partition,
                            "in_errors": z,
                        }
                    )
    if ref_settings:
        ((ref_key, _),) = ref_settings.items()
        reference = combined[("reference",) + ref_key]
        out["reference"] = {"label": setting_label(ref_key), **reference}
        for key in settings:
            out["settings"][setting_label(key)]["against_reference"] = compare_settings(
                combined[key], reference
            )
    else:
        notes.append("no --reference given: partition temperatures compared with each run's own only")
    return out


def _equipartition_of_run(record: RunRecord, seed: int, workers: int, progress: bool) -> Equipartition:
    """Run :class:`~openmm_alphaprk.analysis.Equipartition` on a run's ``trajectory.trr``."""
    universe = rundir.open_universe(record.path, rundir.TRR_FILE)
    check = Equipartition.from_system(universe, record.system, halves_seed=seed, bootstrap_seed=seed)
    if workers > 1:  # MDAnalysis shows no progress bar with a parallel backend
        options = {"backend": "multiprocessing", "n_workers": workers}
    else:
        options = {"verbose": progress, "progressbar_kwargs": {"desc": f"{record.path.name} frames"}}
    return check.run(**options)


# ----------------------------------------------------------------------------- (b) order


def _by_integrator(settings) -> dict[str, list[tuple[tuple, list[RunRecord]]]]:
    out: dict[str, list] = {}
    for key, group in settings.items():
        out.setdefault(key[1], []).append((key, group))
    return out


def _order(settings, notes) -> dict:
    """Per integrator: the order from H's fluctuations at several h, or the round-off check of H."""
    pv = import_physical_validation()
    units = pv.data.UnitData.units("GROMACS")
    out = {}
    for name, rows in _by_integrator(settings).items():
        if "+rescale" in name:
            out[name] = {"kind": "rescaled", "rows": [_round_off(key, group) for key, group in rows]}
            continue
        if len(rows) < 2:
            notes.append(f"(b) {name}: one step size only ({setting_label(rows[0][0])}): no order")
            continue
        simulations, steps, rmsd = [], [], []
        for key, group in rows:  # the first segment of each step: the same start
            energies = group[0].energies
            total = energies[:, 4]
            data = pv.data.SimulationData(units=units, dt=key[2])
            data.observables = pv.data.ObservableData(constant_of_motion=total)
            simulations.append(data)
            steps.append(key[2])
            rmsd.append(pv.util.integrator.calculate_rmsd(total, energies[:, 1])[1])
        with contextlib.redirect_stdout(io.StringIO()):
            deviation = pv.integrator.convergence(simulations, verbose=False)
        h, r = np.array(steps), np.array(rmsd)
        order = float(np.polyfit(np.log(h), np.log(r), 1)[0]) if np.all(r > 0) else float("nan")
        out[name] = {
            "kind": "order",
            "timestep_fs": (h * 1000).tolist(),
            "rmsd_H_kJ_per_mol": r.tolist(),
            "fitted_order": order,
            "pairwise_order": [
                float(np.log(r[i] / r[i + 1]) / np.log(h[i] / h[i + 1])) for i in range(len(h) - 1)
            ],
            "physical_validation_max_deviation": float(deviation),
            "note": "physical_validation.integrator.convergence: largest |1 - (rmsd ratio)/(h ratio)^2|, "
            "0 for a second-order integrator",
        }
    return out


def _round_off(key, group: list[RunRecord]) -> dict:
    """RMS of H − E_ref (rows after the start) against |E_ref|, over the segments of a rescaled setting."""
    values = []
    for record in group:
        total = record.energies[:, 4]
        values.append((float(np.sqrt(np.mean((total[1:] - total[0]) ** 2))), abs(float(total[0]))))
    rms = max(v[0] for v in values)
    scale = max(v[1] for v in values)
    relative = rms / scale if scale else float("nan")
    return {
        "label": setting_label(key),
        "rms_H_minus_E_ref_kJ_per_mol": rms,
        "abs_E_ref_kJ_per_mol": scale,
        "relative": relative,
        "at_round_off": bool(relative < ROUND_OFF),
    }


# ----------------------------------------------------------------------------- (c) rescaling


def _expected_power(name: str) -> dict[str, int] | None:
    """Return the expected powers of h: order p errs by h^(p+1) per step (s - 1), h^p per ns (energy)."""
    if name.startswith("rattle4"):
        order = 4
    elif name.startswith("rattle+"):
        order = 2
    else:
        return None
    return {"mean_scale_change": order + 1, "rms_scale_change": order + 1, "added_energy_per_ns": order}


def _rescaling(settings, notes) -> dict:
    """Per run the summary's ``rescaling``; per integrator the power of h with which it shrinks."""
    runs, fits = {}, {}
    for name, rows in _by_integrator(settings).items():
        per_step = []
        for key, group in rows:
            stored = [record.summary.get("rescaling") or {} for record in group]
            for record, values in zip(group, stored):
                if values:
                    runs[str(record.path)] = {k: values.get(k) for k in RESCALING_KEYS}
            if all(stored):
                per_step.append(
                    (key[2], {k: np.mean([abs(float(s[k])) for s in stored]) for k in RESCALING_KEYS})
                )
        if "+rescale" not in name:
            continue
        if len(per_step) < 2:
            notes.append(f"(c) {name}: rescaling statistics at fewer than two step sizes: no power of h")
            continue
        h = np.array([p[0] for p in per_step])
        fit = {}
        for k in ("mean_scale_change", "rms_scale_change", "added_energy_per_ns"):
            y = np.array([p[1][k] for p in per_step])
            fit[k] = float(np.polyfit(np.log(h), np.log(y), 1)[0]) if np.all(y > 0) else float("nan")
        fits[name] = {
            "timestep_fs": (h * 1000).tolist(),
            "power_of_h": fit,
            "expected_power": _expected_power(name),
        }
    if not runs:
        notes.append("(c) no run has a `rescaling` record in summary.json (unscaled runs only)")
    return {"runs": runs, "fits": fits}


# ----------------------------------------------------------------------------- (d) temperature against h


def _mean_and_error(values: np.ndarray) -> tuple[float, float]:
    """Return the mean and its standard error (statistical inefficiency: pymbar, physical_validation's)."""
    from pymbar.timeseries import statistical_inefficiency

    values = np.asarray(values, dtype=float)
    if len(values) < 3 or np.ptp(values) == 0:
        return float(np.mean(values)), float("nan")
    g = statistical_inefficiency(values)
    return float(np.mean(values)), float(np.std(values, ddof=1) * math.sqrt(g / len(values)))


def _temperature_vs_h(settings, notes) -> dict:
    """Mean kinetic temperature and potential energy per setting, their h → 0 limit from ``rattle``."""
    rows = []
    for key, group in settings.items():
        row = {"label": setting_label(key), "integrator": key[1], "timestep_fs": key[2] * 1000}
        for column, name in ((5, "temperature_K"), (2, "potential_kJ_per_mol")):
            means = [_mean_and_error(record.energies[1:, column]) for record in group]
            if len(means) > 1:
                values = np.array([m[0] for m in means])
                row[name] = [float(values.mean()), float(values.std(ddof=1) / math.sqrt(len(values)))]
            else:
                row[name] = list(means[0])
        row["e_ref_kJ_per_mol"] = float(group[0].energies[0, 4])
        row["segments"] = len(group)
        rows.append(row)
    e_refs = [row["e_ref_kJ_per_mol"] for row in rows]
    if max(e_refs) - min(e_refs) > 1e-6 * max(abs(e) for e in e_refs):
        notes.append("(d) the settings start from different E_ref: not the same start, rows not comparable")
    out: dict = {"rows": rows, "limit": {}}
    rattle = sorted((row for row in rows if row["integrator"] == "rattle"), key=lambda r: r["timestep_fs"])
    if len(rattle) < 2:
        notes.append("(d) fewer than two `rattle` step sizes: no h -> 0 limit")
        return out
    used = rattle[:-1] if len(rattle) >= 3 else rattle
    out["limit"]["from"] = [row["label"] for row in used]
    for name in ("temperature_K", "potential_kJ_per_mol"):
        limit, error = _extrapolate(
            np.array([r["timestep_fs"] for r in used]),
            np.array([r[name][0] for r in used]),
            np.array([r[name][1] for r in used]),
        )
        out["limit"][name] = [limit, error]
        for row in rows:
            combined = math.hypot(row[name][1], error)
            row[f"{name}_from_limit_in_errors"] = (
                (row[name][0] - limit) / combined if combined else float("nan")
            )
    return out


def _extrapolate(h_fs: np.ndarray, values: np.ndarray, errors: np.ndarray) -> tuple[float, float]:
    """Weighted least squares of ``a + b h²``; return a and its standard error."""
    errors = np.where(np.isfinite(errors) & (errors > 0), errors, np.nan)
    weights = 1.0 / errors if np.all(np.isfinite(errors)) else np.ones_like(values)
    design = np.column_stack([np.ones_like(h_fs), h_fs**2]) * weights[:, None]
    (a, _), *_ = np.linalg.lstsq(design, values * weights, rcond=None)
    covariance = np.linalg.pinv(design.T @ design)
    error = float(np.sqrt(covariance[0, 0])) if np.all(np.isfinite(errors)) else float("nan")
    return float(a), error


# ----------------------------------------------------------------------------- text


def _equipartition_lines(eq: dict) -> list[str]:
    lines = [
        "(a) equipartition: T (K) +- standard error; dT = T - the setting's whole-system T (K), "
        "in combined errors (z); vs ref: T - the reference's T (K), z"
    ]
    for label, entry in eq.get("settings", {}).items():
        lines.append(
            f"  {label} ({entry['segments']} segment(s), error: {entry['error_source']}, flagged above "
            f"|z| {entry['flag_threshold']:.2f})"
        )
        against = entry.get("against_reference", {})
        for group, partitions in entry["groups"].items():
            for partition, v in partitions.items():
                line = (
                    f"    {group:<8} {partition:<24} T {v['temperature_K']:8.2f} "
                    f"+- {v['standard_error_K']:5.2f}  dT {v['deviation_K']:+7.2f} "
                    f"(z {v['deviation_in_errors']:+6.1f})"
                )
                ref = against.get(group, {}).get(partition)
                if ref:
                    line += (
                        f"  vs ref {ref['difference_K']:+7.2f} +- {ref['error_K']:5.2f} "
                        f"(z {ref['in_errors']:+6.1f})"
                    )
                lines.append(line)
    flagged = eq.get("flagged", [])
    lines.append(
        "  flagged: "
        + (
            ", ".join(
                f"{f['setting']} {f['group']} {f['partition']} (z {f['in_errors']:+.1f})" for f in flagged
            )
            or "none"
        )
    )
    return lines


def _order_lines(order: dict) -> list[str]:
    lines = ["(b) integrator order from the RMS fluctuation of H (kJ/mol) at several h"]
    for name, entry in order.items():
        if entry["kind"] == "rescaled":
            for row in entry["rows"]:
                state = "at round-off" if row["at_round_off"] else "ABOVE round-off"
                lines.append(
                    f"  {row['label']}: RMS |H - E_ref| {row['rms_H_minus_E_ref_kJ_per_mol']:.3g} kJ/mol = "
                    f"{row['relative']:.2g} x |E_ref|: {state} (< {ROUND_OFF:g}); no order (H held)"
                )
        else:
            lines.append(
                f"  {name}: h (fs) {entry['timestep_fs']}, RMS fluctuation of H (kJ/mol) "
                f"{[float(f'{r:.3g}') for r in entry['rmsd_H_kJ_per_mol']]}"
                f": order {entry['fitted_order']:.2f}; physical_validation max deviation from order 2: "
                f"{entry['physical_validation_max_deviation']:.2f}"
            )
    return lines


def _rescaling_lines(rescaling: dict) -> list[str]:
    lines = [
        "(c) rescaling: rescalings, mean and RMS of s - 1, removed energy (kJ/mol), added energy (kJ/mol/ns)"
    ]
    for path, v in rescaling.get("runs", {}).items():
        lines.append(
            f"  {path}: {v['rescalings']}, {v['mean_scale_change']:.3g}, {v['rms_scale_change']:.3g}, "
            f"{v['removed_energy']:.3g}, {v['added_energy_per_ns']:.3g}"
        )
    for name, fit in rescaling.get("fits", {}).items():
        powers = ", ".join(f"{k} {p:.2f}" for k, p in fit["power_of_h"].items())
        lines.append(
            f"  {name}: power of h ({fit['timestep_fs']} fs): {powers}; expected {fit['expected_power']}"
        )
    return lines


def _temperature_lines(tvh: dict) -> list[str]:
    lines = ["(d) mean kinetic temperature (K) and potential energy (kJ/mol) +- standard error, against h"]
    limit = tvh.get("limit", {})
    for row in tvh.get("rows", []):
        line = (
            f"  {row['label']:<28} T {row['temperature_K'][0]:8.3f} +- {row['temperature_K'][1]:.3f}   "
            f"V {row['potential_kJ_per_mol'][0]:12.3f} +- {row['potential_kJ_per_mol'][1]:.3f}"
        )
        if "temperature_K" in limit:
            line += (
                f"   from limit: T {row['temperature_K_from_limit_in_errors']:+.1f}, "
                f"V {row['potential_kJ_per_mol_from_limit_in_errors']:+.1f} errors"
            )
        lines.append(line)
    if "temperature_K" in limit:
        lines.append(
            f"  h -> 0 (a + b h^2 from {', '.join(limit['from'])}): T {limit['temperature_K'][0]:.3f} +- "
            f"{limit['temperature_K'][1]:.3f} K, V {limit['potential_kJ_per_mol'][0]:.3f} +- "
            f"{limit['potential_kJ_per_mol'][1]:.3f} kJ/mol"
        )
    return lines
