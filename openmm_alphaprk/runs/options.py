"""The options of an NVE run, their defaults and their checks, in one place.

:class:`RunOptions` is what :func:`~openmm_alphaprk.runs.run_nve`,
:func:`~openmm_alphaprk.workflows.compare`, the sweeps and the ``alphaprk`` command
take; each builds one instead of spelling the options out again.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

import openmm as mm
import openmm.unit as unit

from .._units import InputError, to_dimensionless, to_float
from ..observables import positive_int

PRECISIONS = ("single", "mixed", "double")

#: Options counted in steps (a sweep gives them as times, ``<name>_fs``).
INTERVALS = (
    "energy_interval",
    "trajectory_interval",
    "checkpoint_interval",
    "velocity_interval",
    "controller_interval",
)
#: Intervals that may be None: ``velocity_interval`` (no file), ``controller_interval`` (the energy interval).
OPTIONAL_INTERVALS = ("velocity_interval", "controller_interval")
#: Options a sweep's configuration passes through under their own names.
NAMED_OPTIONS = ("platform", "precision", "cpu_threads", "constraint_tolerance", "checkpoint_seconds")


@dataclass(frozen=True)
class RunOptions:
    """How an NVE run is made: its length, step, platform, intervals and start velocities.

    Built from keywords, checked and normalized on construction (``timestep`` becomes a
    float in ps, ``constraint_tolerance`` a float, counts ints); the platform, its
    precision and ``cpu_threads`` are checked by :meth:`openmm_platform`, when the run
    needs the platform.

    Attributes
    ----------
    steps : int, default 1000
        Total number of steps of the run.
    timestep : openmm.unit.Quantity or float, default 0.002
        Step size: a Quantity, or a number in ps (default 0.002 ps = 2 fs).
    platform : str, default "CPU"
        OpenMM platform name (``CPU``, ``Reference``, ``CUDA``, ``OpenCL``).
    precision : {"single", "mixed", "double"}, optional
        ``single``, ``mixed`` or ``double`` for platforms with a Precision property
        (CUDA, OpenCL); None keeps the platform's default. Reference is double; CPU
        has no setting.
    constraint_tolerance : float, default 1e-8
        Relative tolerance of SHAKE/SETTLE/CCMA and the velocity constraints.
    energy_interval, trajectory_interval, checkpoint_interval : int
        Steps between energy rows, DCD frames and checkpoints (defaults 10, 100, 500).
        Energies cost one extra force evaluation each on most platforms.
    controller_interval : int, optional
        Steps between rows of the energy mode's ``controller.csv``; None (default): the
        energy interval, so that the rows fall on the steps of the energy rows and do
        not make ``Simulation`` step one step at a time. Statistics over every step come
        from the integrator's totals, whatever the interval.
    checkpoint_seconds : openmm.unit.Quantity or float, default 60.0
        Wall time (a Quantity, or a number in s) after which a checkpoint is also
        written between the step-count ones (checked at the end of every energy
        interval; default 60 s): an interruption loses at most about this much work.
        Not part of the run's identity.
    velocity_interval : int, optional
        Steps between frames of ``trajectory.trr`` (positions, velocities and box, see
        :class:`~openmm_alphaprk.runs.TRRReporter`); None (default) writes none.
    velocity_seed : int, optional
        None (default): start from the prepared state's velocities. An integer: draw new
        Maxwell–Boltzmann velocities at the definition's temperature with this seed
        (constrained components removed), for independent runs from the same structure.
    cpu_threads : int, optional
        Threads of the CPU platform (default: OpenMM's choice, all cores); not part of
        the run's identity.
    cache_dir : str or os.PathLike, optional
        Cache of equilibrated systems (default: see :func:`~openmm_alphaprk.systems.default_cache_dir`).
    progress : bool, default True
        Show progress bars on stderr.

    Raises
    ------
    ValueError, TypeError
        For bad numbers or units.

    Examples
    --------
    >>> import openmm.unit as unit
    >>> from openmm_alphaprk.runs import RunOptions
    >>> options = RunOptions(steps=500, timestep=1 * unit.femtoseconds, platform="Reference")
    >>> options.timestep  # normalized to ps
    0.001
    >>> options.intervals
    {'energy_interval': 10, 'trajectory_interval': 100, 'checkpoint_interval': 500, 'controller_interval': 10}
    >>> RunOptions.build(options, steps=2000).steps  # a copy with fields replaced
    2000
    >>> platform, properties = options.openmm_platform()
    >>> platform.getName(), properties
    ('Reference', {})
    >>> RunOptions(steps=0)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.errors.InputError: steps must be ...
    """

    steps: int = 1000
    timestep: unit.Quantity | float = 0.002
    platform: str = "CPU"
    precision: str | None = None
    constraint_tolerance: float = 1e-8
    energy_interval: int = 10
    trajectory_interval: int = 100
    checkpoint_interval: int = 500
    velocity_interval: int | None = None
    controller_interval: int | None = None
    checkpoint_seconds: float = 60.0
    velocity_seed: int | None = None
    cpu_threads: int | None = None
    cache_dir: str | os.PathLike | None = None
    progress: bool = True

    def __post_init__(self) -> None:
        self._set("timestep", to_float(self.timestep, unit.picoseconds, "timestep", positive=True))
        self._set("steps", positive_int(self.steps, "steps"))
        for name in INTERVALS:
            value = getattr(self, name)
            if value is not None or name not in OPTIONAL_INTERVALS:
                self._set(name, positive_int(value, name))
        seconds = to_float(self.checkpoint_seconds, unit.seconds, "checkpoint_seconds", positive=True)
        self._set("checkpoint_seconds", seconds)
        seed = self.velocity_seed
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
            raise InputError(f"velocity_seed must be an integer or None, got {seed!r}.")
        tolerance = to_dimensionless(self.constraint_tolerance, "constraint_tolerance", positive=True)
        self._set("constraint_tolerance", tolerance)

    def _set(self, name: str, value: object) -> None:
        object.__setattr__(self, name, value)

    @classmethod
    def build(cls, options: RunOptions | None = None, **keywords) -> RunOptions:
        """Return ``options`` (default: the defaults) with ``keywords`` replacing its fields."""
        if options is None:
            return cls(**keywords)
        return replace(options, **keywords) if keywords else options

    @property
    def timestep_ps(self) -> float:
        """The step size in ps."""
        return self.timestep

    @property
    def intervals(self) -> dict[str, int]:
        """The intervals in steps, by name (``velocity_interval`` only when given).

        ``controller_interval`` is always there: the energy interval when not given.
        """
        values = {name: getattr(self, name) for name in INTERVALS}
        values["controller_interval"] = self.controller_interval or self.energy_interval
        return {name: value for name, value in values.items() if value is not None}

    def openmm_platform(self) -> tuple[mm.Platform, dict[str, str]]:
        """Return the OpenMM Platform and its properties (precision, threads), checked.

        Raises
        ------
        ValueError
            For a platform not available here, a precision the platform has no setting
            for, or ``cpu_threads`` on another platform than CPU.
        """
        platform, properties = _platform(self.platform, self.precision)
        if self.cpu_threads is not None:
            if self.platform != "CPU":
                raise InputError(
                    f"cpu_threads applies to the CPU platform only, not {self.platform}; leave it unset."
                )
            properties["Threads"] = str(positive_int(self.cpu_threads, "cpu_threads"))
        return platform, properties


#: The defaults, for the command line and the sweeps.
DEFAULTS = RunOptions()


def _platform(name: str, precision: str | None) -> tuple[mm.Platform, dict]:
    names = [mm.Platform.getPlatform(i).getName() for i in range(mm.Platform.getNumPlatforms())]
    if name not in names:
        raise InputError(f"unknown OpenMM platform {name!r}; available here: {', '.join(names)}.")
    platform = mm.Platform.getPlatformByName(name)
    if precision is None:
        return platform, {}
    if precision not in PRECISIONS:
        raise InputError(f"precision must be one of {PRECISIONS}, got {precision!r}.")
    if "Precision" not in platform.getPropertyNames():
        raise InputError(
            f"platform {name} has no precision setting (Reference computes in double, CPU in single with "
            "some double accumulation); leave precision unset, or use CUDA/OpenCL."
        )
    return platform, {"Precision": precision}
