"""The files of a run directory, and what resuming a run needs of them.

A run directory holds::

    run.json         parameters of the run (what makes it "the same run")
    system.xml       the System (XmlSerializer), topology.pdb the start structure
    energies.csv     StateDataReporter rows: step, time, potential, kinetic, total energy, temperature
    controller.csv   energy mode only: AlphaControllerReporter rows every controller_interval steps
    trajectory.dcd   DCDReporter frames (unwrapped coordinates) every trajectory_interval steps
    trajectory.trr   optional: positions, velocities and box (TRR, nm and nm/ps) every velocity_interval steps
    start_state.xml  with velocity_seed: the start State (XmlSerializer) with the new velocities
    checkpoint.chk   the last checkpoint (OpenMM binary, platform-specific)
    summary.json     written when the run is complete

On resume every file is cut back to the checkpoint's step, so rows and frames written
after the last checkpoint by an interrupted run are not duplicated.
"""

from __future__ import annotations

import json
import math
import os
import re
import struct
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._units import InputError

if TYPE_CHECKING:
    from ..systems import PreparedSystem
    from .integrator_names import IntegratorSpec
    from .options import RunOptions

RUN_FORMAT = "openmm_alphaprk.run/1"
PARAMETERS_FILE = "run.json"
ENERGIES_FILE = "energies.csv"
CONTROLLER_FILE = "controller.csv"
TRAJECTORY_FILE = "trajectory.dcd"
TRR_FILE = "trajectory.trr"
START_STATE_FILE = "start_state.xml"
CHECKPOINT_FILE = "checkpoint.chk"
#: The checkpoint before the last one, kept so that a damaged last one loses one interval.
PREVIOUS_CHECKPOINT_FILE = "checkpoint.previous.chk"
#: Held (``flock``) by the process running in the directory; holds its pid.
LOCK_FILE = ".lock"
SUMMARY_FILE = "summary.json"
SYSTEM_FILE = "system.xml"
TOPOLOGY_FILE = "topology.pdb"

#: What a run writes as it goes; a run interrupted before its first checkpoint starts them anew.
OUTPUT_FILES = (
    ENERGIES_FILE,
    CONTROLLER_FILE,
    TRAJECTORY_FILE,
    TRR_FILE,
    START_STATE_FILE,
    SUMMARY_FILE,
)

#: Parameters that may differ between invocations on the same directory.
_MAY_DIFFER = ("steps",)
#: Parameters added to ``run.json`` later, with the value that directories written before them used.
_IMPLIED = {"controller_interval": 1}


class RunDirectoryError(InputError):
    """Raised when an output directory holds something other than this run.

    Examples
    --------
    The same directory, another step size:

    >>> import os, tempfile
    >>> from openmm_alphaprk.runs import run_nve
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     _ = run_nve("water-cluster", "rattle", run, steps=10, platform="Reference", progress=False)
    ...     run_nve("water-cluster", "rattle", run, steps=10, timestep=0.001, platform="Reference",
    ...             progress=False)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    openmm_alphaprk.runs.rundir.RunDirectoryError: output directory .../run holds a different run (...
    """


def run_parameters(prepared: PreparedSystem, spec: IntegratorSpec, options: RunOptions) -> dict[str, Any]:
    """Return the parameters stored in ``run.json``; a directory with other values holds a different run.

    ``velocity_interval`` and ``velocity_seed`` are stored only when set, and
    ``controller_interval`` only for the energy mode (the only one writing
    ``controller.csv``), so run directories written before they existed stay valid.
    """
    optional = {
        "velocity_interval": options.velocity_interval,
        "velocity_seed": options.velocity_seed,
        "controller_interval": options.intervals["controller_interval"] if spec.kind == "energy" else None,
    }
    return {
        "format": RUN_FORMAT,
        "system": prepared.name,
        "system_key": prepared.key,
        "integrator": spec.name,
        "timestep_ps": options.timestep_ps,
        "steps": options.steps,
        "platform": options.platform,
        "precision": options.precision,
        "constraint_tolerance": options.constraint_tolerance,
        "energy_interval": options.energy_interval,
        "trajectory_interval": options.trajectory_interval,
        "checkpoint_interval": options.checkpoint_interval,
    } | {key: value for key, value in optional.items() if value is not None}


def missing_run_files(path: Path, what_to_give: str) -> str | None:
    """Say why ``path`` is not a run directory (no ``run.json``, or a file every run writes missing).

    None if it is one. ``what_to_give`` ends the first message: what the caller takes instead
    (e.g. "a folder written by `alphaprk run`").
    """
    if not (path / PARAMETERS_FILE).is_file():
        return f"{path} is not a run directory (no {PARAMETERS_FILE}); give {what_to_give}."
    for name in (ENERGIES_FILE, SYSTEM_FILE, TOPOLOGY_FILE):
        if not (path / name).is_file():
            return f"{path / name} is missing; the run did not start properly."
    return None


def check_run_directory(path: Path, parameters: dict[str, Any]) -> dict[str, Any] | None:
    """Return the stored parameters if ``path`` holds this run, None if it is new or empty.

    Raises
    ------
    RunDirectoryError
        If ``path`` is a file, holds files but no ``run.json``, holds a run with
        different parameters (the message names them), or holds a finished run longer
        than the ``steps`` asked for (a run is never reported as shorter than it is).
    """
    if path.exists() and not path.is_dir():
        raise RunDirectoryError(f"output {path} is a file; give a directory.")
    if not path.exists() or not any(entry.name != LOCK_FILE for entry in path.iterdir()):
        return None
    stored_file = path / PARAMETERS_FILE
    if not stored_file.is_file():
        raise RunDirectoryError(
            f"output directory {path} is not empty and holds no {PARAMETERS_FILE}: it is not a run "
            "directory. Choose a new or empty directory."
        )
    stored = json.loads(stored_file.read_text(encoding="utf-8"))
    stored = {key: value for key, value in _IMPLIED.items() if key in parameters} | stored
    keys = list(parameters) + [key for key in stored if key not in parameters]
    differences = [
        f"{key}: stored {stored.get(key)!r}, requested {parameters.get(key)!r}"
        for key in keys
        if key not in _MAY_DIFFER and not _same(stored.get(key), parameters.get(key))
    ]
    if differences:
        raise RunDirectoryError(
            f"output directory {path} holds a different run ({'; '.join(differences)}). Choose another "
            "output directory, or repeat the stored settings to resume or extend that run."
        )
    summary_file = path / SUMMARY_FILE
    if summary_file.is_file():
        done = json.loads(summary_file.read_text(encoding="utf-8")).get("steps", 0)
        if done > parameters["steps"]:
            raise RunDirectoryError(longer_run_message(path, done, parameters["steps"]))
    return stored


def checkpoint_files(path: Path) -> list[Path]:
    """Return the run's checkpoints that exist, the last first, then the one before it."""
    return [path / name for name in (CHECKPOINT_FILE, PREVIOUS_CHECKPOINT_FILE) if (path / name).is_file()]


def lock_run_directory(path: Path):
    """Hold ``path/.lock`` exclusively while the returned file is open; refuse a directory another run holds.

    The lock is the operating system's (``flock``): it ends with the process, so a killed
    run leaves none behind. Where there is no ``fcntl`` (Windows) nothing is locked and
    None is returned.

    Raises
    ------
    RunDirectoryError
        If another process holds the directory (the message gives its pid).
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return None
    handle = open(path / LOCK_FILE, "a+", encoding="utf-8")  # noqa: SIM115 - held for the run's length
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.seek(0)
        holder = handle.read().strip()
        handle.close()
        raise RunDirectoryError(
            f"run directory {path} is in use by another run"
            + (f" (process {holder})" if holder else "")
            + ": wait until it ends (the same command then resumes or extends it), or give another output "
            "directory."
        ) from None
    handle.seek(0)
    handle.truncate()
    handle.write(f"{os.getpid()}\n")
    handle.flush()
    return handle


def longer_run_message(path: Path, done: int, requested: int) -> str:
    """Return the refusal of a directory holding a run of ``done`` steps when fewer were requested."""
    return (
        f"output directory {path} holds a run of {done} steps, longer than the {requested} asked for; it is "
        f"not cut short or reported as {requested} steps. Ask for {done} steps (--steps {done}) to report "
        f"it, or more to extend it, or choose another output directory for a {requested}-step run."
    )


def _same(a: Any, b: Any) -> bool:
    """Equal, with floats compared to 1e-12 relative (unit conversions round differently)."""
    if isinstance(a, float) or isinstance(b, float):
        return (
            isinstance(a, (int, float)) and isinstance(b, (int, float)) and math.isclose(a, b, rel_tol=1e-12)
        )
    return a == b


def write_parameters(path: Path, parameters: dict[str, Any]) -> None:
    replace_text(path / PARAMETERS_FILE, json.dumps(parameters, indent=2) + "\n")


def read_energies(path: str | os.PathLike) -> np.ndarray:
    """Rows of ``energies.csv``: step, time (ps), potential, kinetic, total (kJ/mol), temperature (K).

    Parameters
    ----------
    path : str or os.PathLike
        The ``energies.csv`` of a run directory (OpenMM's ``StateDataReporter`` CSV).

    Returns
    -------
    numpy.ndarray
        One row per report, the start state's first.

    Raises
    ------
    ValueError
        If the file holds no rows.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np
    >>> from openmm_alphaprk.runs import read_energies, run_nve
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     run = os.path.join(folder, "run")
    ...     _ = run_nve("water-cluster", "rattle", run, steps=20, energy_interval=5,
    ...                 platform="Reference", progress=False)
    ...     energies = read_energies(os.path.join(run, "energies.csv"))
    >>> energies[:, 0]  # steps
    array([ 0.,  5., 10., 15., 20.])
    >>> energies.shape
    (5, 6)
    >>> bool(np.allclose(energies[:, 2] + energies[:, 3], energies[:, 4]))  # potential + kinetic = total
    True
    """
    data = np.loadtxt(path, delimiter=",", comments="#", ndmin=2)
    if data.shape[0] == 0:
        raise InputError(f"{path} holds no energy rows.")
    return data


def last_energy_step(path: Path) -> int | None:
    """Return the step of the last complete row of ``energies.csv``, None if it has none."""
    if not path.is_file():
        return None
    last = None
    for line in path.read_text(encoding="utf-8").splitlines(keepends=True):
        if line.endswith("\n") and line[:1].isdigit():
            last = line
    return None if last is None else int(float(last.split(",")[0]))


def remove_outputs(path: Path) -> None:
    """Delete the files of :data:`OUTPUT_FILES` that exist in ``path``."""
    for name in OUTPUT_FILES:
        (path / name).unlink(missing_ok=True)


def cut_back(path: Path, step: int, intervals: dict[str, int]) -> None:
    """Cut the CSV, DCD and TRR files of a run back to ``step`` (its checkpoint's) before it resumes."""
    truncate_csv(path / ENERGIES_FILE, step)
    truncate_csv(path / CONTROLLER_FILE, step)
    truncate_dcd(path / TRAJECTORY_FILE, step // intervals["trajectory_interval"])
    if "velocity_interval" in intervals:
        truncate_trr(path / TRR_FILE, step // intervals["velocity_interval"])


def truncate_csv(path: Path, last_step: int) -> None:
    """Keep the header and the complete rows whose first column (step) is ≤ ``last_step``."""
    if not path.is_file():
        return
    kept = []
    for line in path.read_text(encoding="utf-8").splitlines(keepends=True):
        if line.startswith(("#", "step")):
            kept.append(line)
            continue
        if not line.endswith("\n"):
            break  # a row cut off by the interruption
        try:
            step = float(line.split(",")[0])
        except ValueError:
            break
        if step > last_step:
            break
        kept.append(line)
    replace_text(path, "".join(kept))


def replace_text(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file, then rename it over ``path``: never a half-written file."""
    temporary = path.with_name(path.name + ".part")
    temporary.write_text(text, encoding="utf-8")
    os.replace(temporary, path)


def truncate_dcd(path: Path, n_frames: int) -> int:
    """Cut an OpenMM-written DCD file to its first ``n_frames`` frames; return the frames kept.

    Updates the frame count and last step in the header, so that ``DCDReporter(append=True)``
    continues from there. A file without a header (no frame written yet) is left as it is.
    """
    if not path.is_file() or path.stat().st_size == 0:
        return 0
    with open(path, "r+b") as handle:
        header = handle.read(276)
        if len(header) < 100 or header[4:8] != b"CORD":
            raise RunDirectoryError(f"{path} is not a DCD file written by OpenMM; move it away to resume.")
        count, first_step, interval = struct.unpack("<3i", header[8:20])
        has_box = struct.unpack("<i", header[48:52])[0]
        comments = struct.unpack("<i", header[92:96])[0]
        handle.seek(104 + comments)
        n_atoms = struct.unpack("<i", handle.read(4))[0]
        header_size = 104 + comments + 8
        frame_size = 56 * bool(has_box) + 3 * (8 + 4 * n_atoms)
        size = handle.seek(0, os.SEEK_END)
        complete = (size - header_size) // frame_size
        keep = max(0, min(n_frames, complete, count))
        handle.truncate(header_size + keep * frame_size)
        handle.seek(8)
        handle.write(struct.pack("<i", keep))
        handle.seek(20)
        handle.write(struct.pack("<i", first_step + max(keep - 1, 0) * interval))
    return keep


def truncate_trr(path: Path, n_frames: int) -> int:
    """Cut a TRR file to its first ``n_frames`` complete frames; return the frames kept.

    The frames of one run are all of one size (same atoms, same fields), so a frame cut
    off by an interruption is the tail beyond the last whole multiple of it.
    """
    from MDAnalysis.lib.formats.libmdaxdr import TRRFile

    if not path.is_file() or path.stat().st_size == 0:
        return 0
    size = path.stat().st_size
    try:
        with TRRFile(str(path), "r") as trr:
            offsets = list(trr.offsets)
    except (OSError, RuntimeError, ValueError) as error:
        raise RunDirectoryError(
            f"{path} is not a readable TRR file ({error}); move it away to resume."
        ) from None
    frame_size = offsets[1] - offsets[0] if len(offsets) > 1 else size
    complete = size // frame_size
    keep = max(0, min(n_frames, complete))
    with open(path, "r+b") as handle:
        handle.truncate(keep * frame_size)
    return keep


def has_dcd_header(path: Path) -> bool:
    """Tell whether ``path`` starts with a DCD header (OpenMM writes it with the first frame)."""
    if not path.is_file():
        return False
    with open(path, "rb") as handle:
        return handle.read(8)[4:8] == b"CORD"


def open_universe(path: str | os.PathLike, trajectory: str = TRAJECTORY_FILE):
    """Return an MDAnalysis ``Universe`` of a run directory's ``topology.pdb`` and one of its trajectories.

    ``trajectory``: :data:`TRAJECTORY_FILE` (DCD, positions) or :data:`TRR_FILE` (TRR,
    positions and velocities).

    MDAnalysis 2.x warns (``DeprecationWarning``) on every ``DCDReader`` that from 3.0
    on its frames will be updated in place instead of copied (MDAnalysis GitHub #3889);
    there is no other API to read DCD files. This package copies what it keeps of a frame
    (``positions`` into its own arrays), so the change does not affect it, and only that
    warning is silenced here, with the PDB reader's notes on records it does not use.
    """
    import MDAnalysis as mda

    path = Path(path)
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message="DCDReader currently makes independent timesteps", category=DeprecationWarning
        )
        warnings.simplefilter("ignore", UserWarning)  # PDB records MDAnalysis does not use
        return mda.Universe(str(path / TOPOLOGY_FILE), str(path / trajectory))


def folder_name(text: str) -> str:
    """File-system-safe folder name: anything but letters, digits and ``.=+-`` becomes ``_``."""
    return re.sub(r"[^A-Za-z0-9.=+-]", "_", text)
