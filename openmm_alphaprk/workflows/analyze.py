"""``analyze``: the analyses of a run directory, written as ``analysis.json`` and PNG figures.

The analyses themselves are the MDAnalysis classes and functions of
:mod:`openmm_alphaprk.analysis`; this module reads a run directory, runs them and
writes their results.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import openmm as mm

from ..analysis import WATER_OXYGENS, ConstraintDeviation, Diffusion, energy_drift, oxygen_rdf
from ..observables import degrees_of_freedom
from ..runs import rundir
from ..runs.reporters import read_controller_csv, summarize_controller

ANALYSIS_FILE = "analysis.json"
#: Why the trajectory's constraint deviation is larger than the run summary's constraint error.
CONSTRAINT_NOTE = (
    "the DCD stores float32 coordinates in Å, so ~1e-6 relative is the resolution limit of this "
    "per-frame deviation; the run summary's max_relative_constraint_error comes from the full-precision "
    "final state and can be far smaller"
)


def analyze_run(
    run: str | os.PathLike,
    *,
    select: str = WATER_OXYGENS,
    rdf_bins: int = 100,
    rdf_max: float = 8.0,
    plot: bool = True,
    progress: bool = False,
) -> dict:
    """Analyse a run directory written by :func:`~openmm_alphaprk.runs.run_nve`.

    Computes :func:`~openmm_alphaprk.observables.energy_drift` of ``energies.csv`` (E_ref,
    drift ± standard error, RMS and max |H − E_ref|), the constraint deviation per frame,
    the O–O RDF (MDAnalysis ``InterRDF``; periodic systems only) and the MSD with D, its
    standard error and the frames it is from (:class:`~openmm_alphaprk.analysis.Diffusion`).
    Writes ``analysis.json`` and, with ``plot``, ``energy.png``,
    ``constraint_deviation.png``, ``rdf_OO.png``, ``msd.png``.

    Parameters
    ----------
    run : str or os.PathLike
        The run directory.
    select : str, default WATER_OXYGENS
        MDAnalysis selection of the atoms for RDF and MSD (default: water oxygens).
    rdf_bins : int, default 100
        RDF histogram bins.
    rdf_max : float, default 8.0
        RDF's largest distance (Å; capped at half the box).
    plot : bool, default True
        Write the figures (needs matplotlib).
    progress : bool, default False
        Show MDAnalysis progress bars.

    Returns
    -------
    dict
        What ``analysis.json`` holds.

    Raises
    ------
    FileNotFoundError
        If ``run`` is not a run directory (no ``run.json``) or lacks its files.

    Examples
    --------
    A short RATTLE run of the 2 nm water box, then its analyses (``alphaprk analyze``):

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.workflows import analyze_run
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     _ = run_nve("tip3p-2nm", "rattle", run, steps=20, trajectory_interval=2, progress=False)
    ...     analysis = analyze_run(run, plot=False)
    ...     written = os.path.isfile(os.path.join(run, "analysis.json"))
    >>> written, sorted(analysis)
    (True, ['constraints', 'energy', 'figures', 'msd', 'notes', 'parameters', 'rdf', 'run'])
    >>> analysis["energy"]["samples"], analysis["constraints"]["frames"]
    (3, 10)
    >>> bool(analysis["constraints"]["overall_max_relative_deviation"] < 1e-5)
    True
    """
    run = Path(run)
    _check_run_directory(run)
    parameters = json.loads((run / rundir.PARAMETERS_FILE).read_text(encoding="utf-8"))
    system = mm.XmlSerializer.deserialize((run / rundir.SYSTEM_FILE).read_text(encoding="utf-8"))
    result: dict = {"run": str(run), "parameters": parameters, "notes": []}
    figures = _energy(result, run, system, parameters, plot)
    trajectory = run / rundir.TRAJECTORY_FILE
    if not trajectory.is_file() or trajectory.stat().st_size == 0:
        result["notes"].append("no trajectory frames: constraint, RDF and MSD analyses skipped")
    else:
        universe = rundir.open_universe(run)
        frame_ps = parameters["trajectory_interval"] * parameters["timestep_ps"]
        figures |= _constraints(result, run, universe, system, frame_ps, plot, progress)
        figures |= _rdf(result, run, universe, select, rdf_bins, rdf_max, plot)
        figures |= _msd(result, run, universe, select, plot, progress)
    result["figures"] = {key: str(value) for key, value in figures.items()}
    (run / ANALYSIS_FILE).write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return result


def _check_run_directory(run: Path) -> None:
    """Raise ``FileNotFoundError`` unless ``run`` holds ``run.json`` and the files every run writes."""
    problem = rundir.missing_run_files(
        run, "a folder written by `alphaprk run` (or one integrator's folder of `alphaprk compare`)"
    )
    if problem:
        raise FileNotFoundError(problem)


def _energy(result: dict, run: Path, system: mm.System, parameters: dict, plot: bool) -> dict:
    """Add the drift fit (and the controller's statistics) to ``result``; return the figure written."""
    energies = rundir.read_energies(run / rundir.ENERGIES_FILE)
    drift = energy_drift(energies[:, 1], energies[:, 4], degrees_of_freedom(system))
    result["energy"] = drift.as_dict()
    if (run / rundir.CONTROLLER_FILE).is_file():
        result["controller"] = summarize_controller(
            read_controller_csv(run / rundir.CONTROLLER_FILE)
        ).as_dict()
    if not plot:
        return {}
    from .plots import plot_xy

    figure = plot_xy(
        energies[:, 1],
        {"H - E_ref": energies[:, 4] - energies[0, 4]},
        run / "energy.png",
        xlabel="time (ps)",
        ylabel="H − E_ref (kJ/mol)",
        title=f"{parameters['system']}, {parameters['integrator']}",
    )
    return {"energy": figure}


def _constraints(
    result: dict, run: Path, universe, system: mm.System, frame_ps: float, plot: bool, progress: bool
) -> dict:
    """Add the constraint deviation per frame to ``result``; return the figure written."""
    deviation = ConstraintDeviation.from_system(universe, system).run(
        verbose=progress, progressbar_kwargs={"desc": "constraint deviation"}
    )
    result["constraints"] = {
        "frames": len(universe.trajectory),
        "overall_max_relative_deviation": deviation.results.overall_max_relative_deviation,
        "max_relative_deviation_per_frame": deviation.results.max_relative_deviation.tolist(),
        "note": CONSTRAINT_NOTE,
    }
    summary_file = run / rundir.SUMMARY_FILE
    if summary_file.is_file():
        summary = json.loads(summary_file.read_text(encoding="utf-8"))
        result["constraints"]["run_summary_max_relative_constraint_error"] = summary.get(
            "max_relative_constraint_error"
        )
    if not plot:
        return {}
    from .plots import plot_xy

    times = (np.arange(len(universe.trajectory)) + 1) * frame_ps
    figure = plot_xy(
        times,
        {"max": deviation.results.max_relative_deviation, "RMS": deviation.results.rms_relative_deviation},
        run / "constraint_deviation.png",
        xlabel="time (ps)",
        ylabel="|r − d| / d",
        title="constraint-length deviation per frame",
    )
    return {"constraint_deviation": figure}


def _rdf(result: dict, run: Path, universe, select: str, bins: int, r_max: float, plot: bool) -> dict:
    """Add the RDF of ``select`` (periodic systems) to ``result``; return the figure written."""
    if universe.dimensions is None or len(universe.select_atoms(select)) < 2:
        result["notes"].append("RDF skipped: no periodic box or fewer than two selected atoms")
        return {}
    rdf = oxygen_rdf(universe, select, bins, r_max)
    peak = int(np.argmax(rdf.results.rdf))
    result["rdf"] = {
        "selection": select,
        "r_angstrom": rdf.results.bins.tolist(),
        "g": rdf.results.rdf.tolist(),
        "first_peak_r_angstrom": float(rdf.results.bins[peak]),
        "first_peak_g": float(rdf.results.rdf[peak]),
    }
    if not plot:
        return {}
    from .plots import plot_xy

    figure = plot_xy(
        rdf.results.bins,
        {"g(r)": rdf.results.rdf},
        run / "rdf_OO.png",
        xlabel="r (Å)",
        ylabel="g(r)",
        title=f"RDF of {select}",
    )
    return {"rdf": figure}


def _msd(result: dict, run: Path, universe, select: str, plot: bool, progress: bool) -> dict:
    """Add the MSD and diffusion coefficient of ``select`` to ``result``; return the figure written."""
    if len(universe.trajectory) < 3 or not len(universe.select_atoms(select)):
        result["notes"].append("MSD skipped: fewer than three frames or no selected atoms")
        return {}
    msd = Diffusion(universe, select).run(verbose=progress, progressbar_kwargs={"desc": "MSD (EinsteinMSD)"})
    d_error = msd.results.diffusion_coefficient_standard_error
    result["msd"] = {
        "selection": select,
        "lag_ps": msd.results.delta_t_values.tolist(),
        "msd_angstrom2": msd.results.timeseries.tolist(),
        "fit_window_ps": list(msd.results.fit_window),
        "frames": msd.results.frames,
        "diffusion_coefficient_1e-5_cm2_per_s": msd.results.diffusion_coefficient,
        "diffusion_coefficient_standard_error_1e-5_cm2_per_s": d_error,
        "error_groups": msd.results.error_groups,
        "note": (
            f"standard error: the spread of D over {msd.results.error_groups} disjoint groups of the "
            "selected atoms; a short run's D is not converged, whatever its standard error"
        ),
    }
    if not plot:
        return {}
    from .plots import plot_xy

    figure = plot_xy(
        msd.results.delta_t_values,
        {"MSD": msd.results.timeseries},
        run / "msd.png",
        xlabel="lag time (ps)",
        ylabel="MSD (Å²)",
        title=f"D = {msd.results.diffusion_coefficient:.3g} ± "
        f"{msd.results.diffusion_coefficient_standard_error:.2g} × 1e-5 cm²/s "
        f"({select}, {msd.results.frames} frames)",
    )
    return {"msd": figure}
