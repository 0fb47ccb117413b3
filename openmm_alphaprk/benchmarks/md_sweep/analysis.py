"""The MD benchmark's dynamics analyses and timing: RDF, diffusion, VACF spectrum, interleaved cost.

:func:`analyse_run` analyses one run directory with MDAnalysis (cached in it),
:func:`compare_dynamics` compares a run with the small-step reference, and
:func:`timing_table` times the integrators of the energy table in this process.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from openmm_alphaprk.observables import rms

from .results import ENERGY_ROWS, run_label

ANALYSIS_FILE = "md_benchmark_analysis.json"
ANALYSIS_VERSION = 1
WATER_O = "resname HOH and name O"
WATER_H = "resname HOH and name H1 H2"
RDF_RANGE = (0.0, 8.0)  # Å
RDF_BINS = 80
RDF_COMPARE = (2.4, 8.0)  # Å: where g(r) is compared (below 2.4 Å it is zero)
BANDS = {"translation": (0.0, 300.0), "libration": (300.0, 1100.0)}  # cm⁻¹
SPECTRUM_COMPARE = (0.0, 1200.0)  # cm⁻¹


def analyse_run(directory: Path) -> dict:
    """Return the O–O RDF, water O diffusion and water-H VACF spectrum of one run (cached in the run dir)."""
    cache = directory / ANALYSIS_FILE
    if cache.is_file():
        stored = json.loads(cache.read_text(encoding="utf-8"))
        if stored.get("version") == ANALYSIS_VERSION:
            return stored

    from openmm_alphaprk.analysis import Diffusion, VelocityAutocorrelation, band_summary
    from openmm_alphaprk.analysis.structure import oxygen_rdf
    from openmm_alphaprk.runs.rundir import open_universe

    result: dict = {"version": ANALYSIS_VERSION}
    positions = open_universe(directory)
    rdf = oxygen_rdf(positions, select=WATER_O, nbins=RDF_BINS, r_max=RDF_RANGE[1])
    result["rdf_r"] = rdf.results.bins.tolist()
    result["rdf_g"] = rdf.results.rdf.tolist()
    msd = Diffusion(positions, select=WATER_O, error_groups=4).run()
    result["diffusion"] = float(msd.results.diffusion_coefficient)
    # error of D: the spread of D over 4 disjoint groups of molecules, / sqrt(4)
    result["diffusion_error"] = msd.results.diffusion_coefficient_standard_error
    velocities_file = directory / "trajectory.trr"
    if velocities_file.is_file():
        velocities = open_universe(directory, velocities_file.name)
        vacf = VelocityAutocorrelation(velocities, select=WATER_H, max_lag=1.0, source="velocities").run()
        result["frequencies"] = vacf.results.frequencies.tolist()
        result["spectrum"] = vacf.results.spectrum.tolist()
        result["bands"] = {
            name: band_summary(vacf.results.frequencies, vacf.results.spectrum, low, high)
            for name, (low, high) in BANDS.items()
        }
    cache.write_text(json.dumps(result) + "\n", encoding="utf-8")
    return result


def compare_dynamics(run: dict, reference: dict) -> dict:
    """Return the differences of RDF, D and spectrum of a run from the reference run."""
    from openmm_alphaprk.analysis import spectrum_difference

    r = np.asarray(run["rdf_r"])
    window = (r >= RDF_COMPARE[0]) & (r <= RDF_COMPARE[1])
    g, g_ref = np.asarray(run["rdf_g"]), np.asarray(reference["rdf_g"])
    out = {
        "rdf_rms_difference": rms(g[window] - g_ref[window]),
        "rdf_first_peak": float(g[window].max()),
        "diffusion": run["diffusion"],
        "diffusion_error": run["diffusion_error"],
        "diffusion_relative_difference": run["diffusion"] / reference["diffusion"] - 1.0,
    }
    if "spectrum" in run and "spectrum" in reference:
        out["spectrum_difference"] = spectrum_difference(
            np.asarray(run["frequencies"]),
            np.asarray(run["spectrum"]),
            np.asarray(reference["frequencies"]),
            np.asarray(reference["spectrum"]),
            *SPECTRUM_COMPARE,
        )
        out["libration_centroid"] = run["bands"]["libration"]["centroid"]
        out["libration_centroid_shift"] = (
            run["bands"]["libration"]["centroid"] - reference["bands"]["libration"]["centroid"]
        )
        out["libration_weight"] = run["bands"]["libration"]["weight"]
    return out


# ---------------------------------------------------------------- timing


def timing_table(system: str, steps: int = 30, rounds: int = 3) -> dict[str, dict]:
    """Time every integrator of the energy table on one system in interleaved rounds (this process).

    The sweep's cells ran one after another, each timing itself, while other work may have
    shared the machine; interleaving the integrators round by round puts such load on all
    of them alike, so the ratios to RATTLE 2 fs are the numbers to read. Median ms/step of
    ``rounds`` rounds of ``steps`` steps from the equilibrated start, CPU platform.
    """
    import openmm as mm

    from openmm_alphaprk.benchmarks.cost import interleaved_timing
    from openmm_alphaprk.integrators import check_context
    from openmm_alphaprk.runs.integrator_names import make_integrator
    from openmm_alphaprk.systems import prepare_system

    prepared = prepare_system(system, progress=False)
    platform = mm.Platform.getPlatformByName("CPU")
    runs = {}
    for integrator_name, step in ENERGY_ROWS:
        integrator = make_integrator(integrator_name, step / 1000.0, 1e-8)
        context = mm.Context(prepared.system, integrator, platform)
        check_context(integrator, context)
        context.setState(prepared.state)
        integrator.step(2)  # program analysis, first forces
        runs[run_label(integrator_name, step)] = (integrator, context, step)
    medians = interleaved_timing(
        {name: (integrator, 1) for name, (integrator, _context, _step) in runs.items()}, steps, rounds
    )
    baseline = medians[run_label("rattle", 2.0)]
    table = {}
    for name, (_integrator, _context, step) in runs.items():
        ms = medians[name]
        table[name] = {
            "ms_per_step": ms,
            "time_per_step_ratio": ms / baseline,
            "time_per_ps_ratio": ms / baseline * 2.0 / step,
            "ns_per_day": step * 1e-6 / (ms * 1e-3) * 86400.0,
        }
    return table
