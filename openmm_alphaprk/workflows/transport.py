"""Transport and structure of water from run directories, grouped into settings with error bars.

:func:`transport_of_runs` reads NVE run directories (several independent segments per
setting), computes for each the self-diffusion coefficient (MSD, with the Yeh–Hummer
finite-size correction), the O–O g(r)'s first peak, the dipole's rotational correlation
times and a summary of the oxygens' velocity autocorrelation, and gives per setting (same
system, integrator and time step, from ``run.json``) the mean over segments and its
standard error. The analyses are those of :mod:`openmm_alphaprk.analysis`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._units import InputError
from ..analysis import (
    TIP3P_SHEAR_VISCOSITY_MPA_S,
    WATER_MOLECULES,
    WATER_OXYGENS,
    YEH_HUMMER_XI,
    Diffusion,
    DipoleReorientation,
    VelocityAutocorrelation,
    first_peak,
    oxygen_rdf,
    yeh_hummer_correction,
)
from ..analysis.diffusion import ANGSTROM2_PER_PS_IN_1E5_CM2_PER_S
from ..runs import rundir

#: Velocities (Å/ps) stored as DCD coordinates, as run directories written before
#: ``trajectory.trr`` (:data:`~openmm_alphaprk.runs.rundir.TRR_FILE`) held them.
LEGACY_VELOCITIES_FILE = "velocities.dcd"

#: The per-segment numbers that are averaged over the segments of a setting.
QUANTITIES = (
    "diffusion",
    "diffusion_pbc",
    "diffusion_correction",
    "rdf_peak_r_angstrom",
    "rdf_peak_g",
    "tau2_ps",
    "tau2_fit_ps",
    "tau1_ps",
    "vacf_first_minimum_ps",
    "vacf_first_minimum_value",
    "vacf_diffusion",
    "temperature_k",
)


@dataclass
class SegmentTransport:
    """What one run directory (one segment) gives; NaN where an analysis could not be done.

    Attributes
    ----------
    run : str
        The run directory.
    system, integrator : str
        From ``run.json``.
    timestep_ps : float
        From ``run.json``.
    frames : int
        Frames of ``trajectory.dcd`` analysed (0: none).
    temperature_k : float
        Mean temperature of ``energies.csv`` (K).
    box_length_nm : float
        Edge of the cubic box (nm), first frame; NaN without a cubic box.
    diffusion_pbc, diffusion_pbc_standard_error : float
        D of the water oxygens in the periodic box (MSD fit, :class:`~openmm_alphaprk.analysis.Diffusion`)
        and its standard error over groups of molecules, 1e-5 cm²/s.
    diffusion_correction : float
        Yeh–Hummer ξ k_B T / (6 π η L), 1e-5 cm²/s (:func:`~openmm_alphaprk.analysis.yeh_hummer_correction`).
    diffusion : float
        D_PBC + correction, 1e-5 cm²/s.
    rdf_peak_r_angstrom, rdf_peak_g : float
        Position (Å) and height of the O–O g(r)'s first peak (:func:`~openmm_alphaprk.analysis.first_peak`).
    tau1_ps, tau2_ps : float
        Integral correlation times of C₁ and C₂ of the dipole (ps; NaN if C does not fall
        below the threshold within the run; :class:`~openmm_alphaprk.analysis.DipoleReorientation`).
    tau2_fit_ps : float
        Exponential-fit correlation time of C₂ (ps).
    vacf_source : str or None
        The velocity file the VACF was read from (``trajectory.trr`` or ``velocities.dcd``), None if none.
    vacf_first_minimum_ps, vacf_first_minimum_value : float
        Lag (ps) and value of the first minimum of the oxygens' normalized VACF, C(t)/C(0).
    vacf_diffusion : float
        (1/3) ∫₀^max_lag C(t) dt of the oxygens (Green–Kubo, truncated at ``vacf_max_lag_ps``;
        no finite-size correction), 1e-5 cm²/s.
    vacf_max_lag_ps : float
        The VACF's longest lag (ps).
    notes : list of str
        What was skipped, and why.
    """

    run: str
    system: str
    integrator: str
    timestep_ps: float
    frames: int = 0
    temperature_k: float = math.nan
    box_length_nm: float = math.nan
    diffusion_pbc: float = math.nan
    diffusion_pbc_standard_error: float = math.nan
    diffusion_correction: float = math.nan
    diffusion: float = math.nan
    rdf_peak_r_angstrom: float = math.nan
    rdf_peak_g: float = math.nan
    tau1_ps: float = math.nan
    tau2_ps: float = math.nan
    tau2_fit_ps: float = math.nan
    vacf_source: str | None = None
    vacf_first_minimum_ps: float = math.nan
    vacf_first_minimum_value: float = math.nan
    vacf_diffusion: float = math.nan
    vacf_max_lag_ps: float = math.nan
    notes: list[str] = field(default_factory=list)


@dataclass
class SettingTransport:
    """The segments of one setting: mean over segments and standard error of the mean.

    Attributes
    ----------
    system, integrator : str
        The setting.
    timestep_ps : float
        The setting's time step.
    runs : list of str
        Its run directories (segments).
    mean, standard_error : dict of str to float
        Per name of :data:`QUANTITIES`: the mean over the segments where it is finite, and
        the standard error of that mean, std (ddof 1) / √n (NaN below two segments).
    count : dict of str to int
        The number of segments each mean is over.
    """

    system: str
    integrator: str
    timestep_ps: float
    runs: list[str]
    mean: dict[str, float]
    standard_error: dict[str, float]
    count: dict[str, int]


@dataclass
class TransportResult:
    """Settings and segments of :func:`transport_of_runs`, and the parameters used.

    Attributes
    ----------
    settings : list of SettingTransport
        One per (system, integrator, time step), in the order first met.
    segments : list of SegmentTransport
        One per run directory, in the order given.
    parameters : dict
        Viscosity (mPa·s), ξ, selections and the other settings of the analyses.
    """

    settings: list[SettingTransport]
    segments: list[SegmentTransport]
    parameters: dict[str, Any]

    def as_dict(self) -> dict[str, Any]:
        """Plain data for ``json.dumps``: NaN and infinities become None."""
        return _json_safe(asdict(self))

    def to_json(self, **kwargs) -> str:
        """``json.dumps`` of :meth:`as_dict` (keyword arguments passed on, e.g. ``indent=2``)."""
        return json.dumps(self.as_dict(), **kwargs)


def _json_safe(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(item) for item in value]
    return value


def transport_of_runs(
    run_dirs: list[str | os.PathLike],
    *,
    viscosity: object = TIP3P_SHEAR_VISCOSITY_MPA_S,
    oxygens: str = WATER_OXYGENS,
    waters: str = WATER_MOLECULES,
    rdf_bins: int = 100,
    rdf_max: float = 8.0,
    peak_r_max: float | None = None,
    threshold: float = 0.05,
    fit_start: float = 0.1,
    rotation_max_lag: float | None = None,
    vacf_max_lag: float | None = None,
    progress: bool = False,
) -> TransportResult:
    """Transport and structure of water in run directories, grouped into settings.

    For each run directory (a segment, written by :func:`~openmm_alphaprk.runs.run_nve`):
    D of the water oxygens from ``trajectory.dcd`` (unwrapped) with the Yeh–Hummer
    correction for the cubic box at the run's mean temperature; the first peak of the O–O
    g(r); the dipole's correlation times τ₁, τ₂ (integral to C = ``threshold``) and τ₂ from
    an exponential fit; and, where velocities were written (``trajectory.trr``, else
    ``velocities.dcd``), the first minimum of the oxygens' normalized VACF and its
    Green–Kubo integral. Segments with the same system, integrator and time step
    (``run.json``) form a setting; each quantity's mean and standard error are over the
    segments where it could be computed.

    Parameters
    ----------
    run_dirs : list of str or os.PathLike
        Run directories.
    viscosity : float or openmm.unit.Quantity, default TIP3P_SHEAR_VISCOSITY_MPA_S
        Shear viscosity of the water model for the Yeh–Hummer correction, mPa·s (default:
        rigid TIP3P at 298 K, 0.321 mPa·s).
    oxygens : str, default WATER_OXYGENS
        Selection of the water oxygens (MSD, g(r), VACF).
    waters : str, default WATER_MOLECULES
        Selection of the water molecules (dipole reorientation).
    rdf_bins : int, default 100
        g(r) histogram bins.
    rdf_max : float, default 8.0
        g(r)'s largest distance (Å; capped at half the box).
    peak_r_max : float, optional
        Largest r (Å) searched for the first peak; default the whole g(r) (water's first
        peak is its highest).
    threshold : float, default 0.05
        Where the correlation integrals stop.
    fit_start : float, default 0.1
        First lag (ps) of the exponential fit of C₂.
    rotation_max_lag, vacf_max_lag : float, optional
        Longest lags (ps) of the dipole correlation and of the VACF; defaults those of
        :class:`~openmm_alphaprk.analysis.DipoleReorientation` and
        :class:`~openmm_alphaprk.analysis.VelocityAutocorrelation`.
    progress : bool, default False
        Show MDAnalysis progress bars.

    Returns
    -------
    TransportResult
        Settings (means, standard errors) and segments; ``as_dict()`` / ``to_json()`` for
        a JSON file.

    Raises
    ------
    InputError
        If ``run_dirs`` is empty or a directory holds no ``run.json``.

    Examples
    --------
    Two short segments of one setting (far too short for converged numbers; this shows
    the call and the result's shape):

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> from openmm_alphaprk.workflows.transport import transport_of_runs
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     runs = [os.path.join(folder, name) for name in ("a", "b")]
    ...     for run, seed in zip(runs, (1, 2)):
    ...         _ = run_nve("tip3p-2nm", "rattle", run, steps=40, trajectory_interval=2,
    ...                     velocity_seed=seed, progress=False)
    ...     result = transport_of_runs(runs)
    >>> [(s.system, s.integrator, s.timestep_ps, len(s.runs)) for s in result.settings]
    [('tip3p-2nm', 'rattle', 0.002, 2)]
    >>> setting = result.settings[0]
    >>> setting.count["diffusion"], bool(2.6 < setting.mean["rdf_peak_r_angstrom"] < 3.0)
    (2, True)
    """
    runs = [Path(run) for run in run_dirs]
    if not runs:
        raise InputError("no run directories given; pass a list of folders written by run_nve.")
    segments = [
        _segment(
            run,
            viscosity=viscosity,
            oxygens=oxygens,
            waters=waters,
            rdf_bins=rdf_bins,
            rdf_max=rdf_max,
            peak_r_max=peak_r_max,
            threshold=threshold,
            fit_start=fit_start,
            rotation_max_lag=rotation_max_lag,
            vacf_max_lag=vacf_max_lag,
            progress=progress,
        )
        for run in runs
    ]
    groups: dict[tuple[str, str, float], list[SegmentTransport]] = {}
    for segment in segments:
        groups.setdefault((segment.system, segment.integrator, segment.timestep_ps), []).append(segment)
    settings = [_setting(key, members) for key, members in groups.items()]
    from openmm import unit

    from .._units import to_float

    parameters = {
        "viscosity_mpa_s": to_float(viscosity, unit.millipascal * unit.second, "viscosity", positive=True),
        "yeh_hummer_xi": YEH_HUMMER_XI,
        "oxygens": oxygens,
        "waters": waters,
        "rdf_bins": rdf_bins,
        "rdf_max_angstrom": rdf_max,
        "peak_r_max_angstrom": peak_r_max,
        "correlation_threshold": threshold,
        "fit_start_ps": fit_start,
        "rotation_max_lag_ps": rotation_max_lag,
        "vacf_max_lag_ps": vacf_max_lag,
        "units": {
            "diffusion": "1e-5 cm^2/s",
            "times": "ps",
            "rdf_peak_r": "angstrom",
            "temperature": "K",
            "box_length": "nm",
        },
    }
    return TransportResult(settings=settings, segments=segments, parameters=parameters)


def _setting(key: tuple[str, str, float], members: list[SegmentTransport]) -> SettingTransport:
    """Mean and standard error of each quantity over the segments where it is finite."""
    mean, error, count = {}, {}, {}
    for name in QUANTITIES:
        values = np.array([getattr(member, name) for member in members], dtype=float)
        values = values[np.isfinite(values)]
        count[name] = len(values)
        mean[name] = float(values.mean()) if len(values) else math.nan
        error[name] = float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else math.nan
    system, integrator, timestep = key
    return SettingTransport(
        system=system,
        integrator=integrator,
        timestep_ps=timestep,
        runs=[member.run for member in members],
        mean=mean,
        standard_error=error,
        count=count,
    )


def _has_frames(path: Path) -> bool:
    return path.is_file() and path.stat().st_size > 0


def _segment(run: Path, **options) -> SegmentTransport:
    """Run all analyses of one run directory."""
    parameters_file = run / rundir.PARAMETERS_FILE
    if not parameters_file.is_file():
        raise InputError(
            f"{run} is not a run directory (no {rundir.PARAMETERS_FILE}); give folders written by run_nve."
        )
    parameters = json.loads(parameters_file.read_text(encoding="utf-8"))
    segment = SegmentTransport(
        run=str(run),
        system=str(parameters["system"]),
        integrator=str(parameters["integrator"]),
        timestep_ps=float(parameters["timestep_ps"]),
    )
    energies = run / rundir.ENERGIES_FILE
    if energies.is_file():
        segment.temperature_k = float(np.mean(rundir.read_energies(energies)[:, 5]))
    else:
        segment.notes.append(f"no {rundir.ENERGIES_FILE}: no temperature, no Yeh–Hummer correction")
    if _has_frames(run / rundir.TRAJECTORY_FILE):
        universe = rundir.open_universe(run)
        frame_ps = parameters["trajectory_interval"] * parameters["timestep_ps"]
        _positions(segment, universe, frame_ps, options)
    else:
        segment.notes.append(f"no {rundir.TRAJECTORY_FILE} frames: MSD, g(r) and rotation skipped")
    _velocities(segment, run, parameters, options)
    return segment


def _cubic_edge_nm(dimensions) -> float:
    """Return the edge (nm) of a cubic box given as MDAnalysis dimensions (Å, degrees); NaN otherwise."""
    if dimensions is None:
        return math.nan
    a, b, c, alpha, beta, gamma = (float(x) for x in dimensions)
    cubic = np.allclose([b, c], a, rtol=1e-4) and np.allclose([alpha, beta, gamma], 90.0, atol=1e-3)
    return a / 10.0 if cubic and a > 0 else math.nan


def _positions(segment: SegmentTransport, universe, frame_ps: float, options: dict) -> None:
    """Add the MSD with its correction, the g(r)'s first peak and the dipole's correlation times."""
    progress = options["progress"]
    segment.frames = len(universe.trajectory)
    segment.box_length_nm = _cubic_edge_nm(universe.dimensions)
    try:
        msd = Diffusion(universe, options["oxygens"]).run(verbose=progress)
        segment.diffusion_pbc = float(msd.results.diffusion_coefficient)
        segment.diffusion_pbc_standard_error = float(msd.results.diffusion_coefficient_standard_error)
    except InputError as error:
        segment.notes.append(f"MSD skipped: {error}")
    if math.isfinite(segment.box_length_nm) and math.isfinite(segment.temperature_k):
        segment.diffusion_correction = yeh_hummer_correction(
            segment.temperature_k, segment.box_length_nm, options["viscosity"]
        )
        segment.diffusion = segment.diffusion_pbc + segment.diffusion_correction
    else:
        segment.notes.append("no cubic box or temperature: D not corrected (Yeh–Hummer), diffusion is NaN")
    if universe.dimensions is not None:
        try:
            rdf = oxygen_rdf(universe, options["oxygens"], options["rdf_bins"], options["rdf_max"])
            segment.rdf_peak_r_angstrom, segment.rdf_peak_g = first_peak(
                rdf.results.bins, rdf.results.rdf, r_max=options["peak_r_max"]
            )
        except InputError as error:
            segment.notes.append(f"g(r) skipped: {error}")
    else:
        segment.notes.append("no periodic box: g(r) skipped")
    try:
        rotation = DipoleReorientation(
            universe,
            options["waters"],
            dt=frame_ps,
            max_lag=options["rotation_max_lag"],
            threshold=options["threshold"],
            fit_start=options["fit_start"],
        ).run(verbose=progress)
        segment.tau1_ps = float(rotation.results.tau1)
        segment.tau2_ps = float(rotation.results.tau2)
        segment.tau2_fit_ps = float(rotation.results.tau2_fit)
        if not math.isfinite(segment.tau2_ps):
            segment.notes.append(
                f"C2 stays above {options['threshold']} up to {rotation.results.max_lag:.4g} ps: "
                "no integral tau2 (run longer)"
            )
    except InputError as error:
        segment.notes.append(f"rotation skipped: {error}")


def _first_minimum(lags: np.ndarray, c: np.ndarray) -> tuple[float, float]:
    """Lag and value of the first interior local minimum of ``c``; NaN if there is none."""
    for i in range(1, len(c) - 1):
        if c[i] < c[i - 1] and c[i] <= c[i + 1]:
            return float(lags[i]), float(c[i])
    return math.nan, math.nan


def _velocities(segment: SegmentTransport, run: Path, parameters: dict, options: dict) -> None:
    """Add the oxygens' VACF to ``segment``: its first minimum and its Green–Kubo integral."""
    interval = parameters.get("velocity_interval")
    if _has_frames(run / rundir.TRR_FILE):
        name, source = rundir.TRR_FILE, "velocities"
    elif _has_frames(run / LEGACY_VELOCITIES_FILE):
        name, source = LEGACY_VELOCITIES_FILE, "positions"
    else:
        segment.notes.append("no velocities written (velocity_interval): VACF skipped")
        return
    if not interval:
        segment.notes.append("run.json has no velocity_interval: VACF skipped")
        return
    try:
        universe = rundir.open_universe(run, name)
        vacf = VelocityAutocorrelation(
            universe,
            options["oxygens"],
            source=source,
            dt=interval * parameters["timestep_ps"],
            max_lag=options["vacf_max_lag"],
        ).run(verbose=options["progress"])
    except InputError as error:
        segment.notes.append(f"VACF skipped: {error}")
        return
    lags = vacf.results.lags
    segment.vacf_source = name
    segment.vacf_first_minimum_ps, segment.vacf_first_minimum_value = _first_minimum(
        lags, vacf.results.normalized_vacf
    )
    integral = float(np.sum(0.5 * (vacf.results.vacf[1:] + vacf.results.vacf[:-1]) * np.diff(lags)))
    segment.vacf_diffusion = integral / 3.0 * ANGSTROM2_PER_PS_IN_1E5_CM2_PER_S
    segment.vacf_max_lag_ps = float(vacf.results.max_lag)
