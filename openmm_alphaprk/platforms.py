"""What the integrators need to know about the OpenMM platform they run on.

OpenMM runs a ``CustomIntegrator`` step program with two different semantics:

- the **Reference and CPU** platforms (``ReferenceCustomDynamics``): a position
  constraint projects along the directions of the positions at the previous
  constraint step; virtual sites are placed only at the end of a step;
- the **common platform** (CUDA, OpenCL, HIP: ``CommonIntegrateCustomStepKernel``):
  a position assignment followed in program text by a constraint step is stored as
  a displacement (forces see the old positions until that constraint step runs), a
  constraint projects along the directions of the positions stored at that moment,
  virtual sites are placed at every constraint step, and atoms are reordered and
  re-wrapped into the box every 250 steps.

The step programs in :mod:`openmm_alphaprk.integrators` are written to give the same
step under both. What still depends on the platform — whether forces at constrained
positions see correct virtual sites, and how noisy the ``energy`` the energy mode
targets is — is decided here, from a Context given to the integrators'
``check_context`` (OpenMM gives an integrator no access to its Context).
"""

from __future__ import annotations

import openmm as mm
import openmm.unit as unit

from ._units import InputError

#: Platforms that run OpenMM's common CustomIntegrator implementation.
COMMON_PLATFORMS = ("CUDA", "OpenCL", "HIP")

#: Standard deviation of a potential energy against the same state in double
#: precision, σ = a (N/1000)^0.75 kJ/mol for N atoms, by force precision: the scales a fitted
#: to smooth-PME TIP3P boxes (python -m openmm_alphaprk.benchmarks.energy_noise); docs/platforms.md sets the
#: model beside each platform's measured noise.
_NOISE_SCALE = {"single": 2.6e-3, "mixed": 1.8e-3, "double": 1.2e-4}
_NOISE_EXPONENT = 0.75
#: The energy mode's default tolerance, in units of the noise σ: a target inside the
#: noise only buys trials that chase round-off.
TOLERANCE_IN_NOISE_UNITS = 3.0
#: Smallest default energy tolerance (kJ/mol).
_TOLERANCE_FLOOR = 1e-5
#: The precision assumed when the platform is not known: the noisiest, so that a
#: default energy tolerance is never inside the noise.
UNKNOWN_PRECISION = "single"


def massless_particles(system: mm.System) -> list[int]:
    """Return the indices of the particles with zero mass or defined as virtual sites."""
    return [
        i
        for i in range(system.getNumParticles())
        if system.isVirtualSite(i) or system.getParticleMass(i).value_in_unit(unit.dalton) == 0
    ]


def runs_common_platform(context: mm.Context) -> bool:
    """Tell whether the context runs OpenMM's common CustomIntegrator code (CUDA, OpenCL, HIP)."""
    return context.getPlatform().getName() in COMMON_PLATFORMS


def force_precision(context: mm.Context) -> str:
    """'double', 'mixed' or 'single': the precision forces and energies are computed in.

    The CPU platform computes forces in single precision and integrates in double,
    like the common platform's mixed precision.
    """
    platform = context.getPlatform()
    name = platform.getName()
    if name == "Reference":
        return "double"
    if name == "CPU":
        return "mixed"
    if "Precision" in platform.getPropertyNames():
        return platform.getPropertyValue(context, "Precision").lower()
    return "single"


def energy_noise(n_atoms: int, precision: str) -> float:
    """Return the expected noise (kJ/mol, one standard deviation) of OpenMM's potential energy.

    Parameters
    ----------
    n_atoms
        Number of particles in the system.
    precision
        'single', 'mixed' or 'double' (see :func:`force_precision`).
    """
    if precision not in _NOISE_SCALE:
        raise InputError(f"precision must be one of {sorted(_NOISE_SCALE)}, got {precision!r}.")
    return _NOISE_SCALE[precision] * (max(n_atoms, 1) / 1000.0) ** _NOISE_EXPONENT


def default_energy_tolerance(n_atoms: int, precision: str) -> float:
    """Return the energy mode's default |H − E_ref| target (kJ/mol) for a system and precision.

    ``TOLERANCE_IN_NOISE_UNITS`` × :func:`energy_noise`, at least 1e-5 kJ/mol: e.g.
    0.011 kJ/mol for 2,661 atoms in mixed precision or on the CPU platform, 0.053 for
    21k atoms, 0.13 for 72k; 0.00075 for 2,661 atoms in double precision.
    """
    return max(TOLERANCE_IN_NOISE_UNITS * energy_noise(n_atoms, precision), _TOLERANCE_FLOOR)


#: The platform name that asks for :func:`fastest_platform`.
AUTO = "auto"
#: The platforms ``platform="auto"`` tries, fastest first; OpenCL only on a GPU.
AUTO_ORDER = ("CUDA", "HIP", "OpenCL", "CPU")
#: OpenCL's device-type bit for a GPU (``CL_DEVICE_TYPE_GPU``).
_CL_DEVICE_TYPE_GPU = 1 << 2


def available_platforms() -> list[str]:
    """Return the names of the OpenMM platforms whose plugins loaded here."""
    return [mm.Platform.getPlatform(i).getName() for i in range(mm.Platform.getNumPlatforms())]


def opencl_gpu_count() -> int:
    """Return the number of GPU devices the OpenCL loader (ICD) lists, 0 if it is missing or fails.

    pocl's CPU device is not a GPU: a machine with only pocl counts 0.
    """
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("OpenCL")
    try:
        library = ctypes.CDLL(name or "libOpenCL.so.1")
        count = ctypes.c_uint(0)
        if library.clGetPlatformIDs(0, None, ctypes.byref(count)) != 0 or count.value == 0:
            return 0
        ids = (ctypes.c_void_p * count.value)()
        if library.clGetPlatformIDs(count.value, ids, None) != 0:
            return 0
        gpus = 0
        for platform_id in ids:
            devices = ctypes.c_uint(0)
            status = library.clGetDeviceIDs(
                ctypes.c_void_p(platform_id),
                ctypes.c_uint64(_CL_DEVICE_TYPE_GPU),
                0,
                None,
                ctypes.byref(devices),
            )
            gpus += devices.value if status == 0 else 0
        return gpus
    except (OSError, AttributeError):
        return 0


def _can_run(name: str) -> bool:
    """Tell whether the platform ``name`` makes a Context here (its plugin may load without a GPU)."""
    system = mm.System()
    system.addParticle(1.0)
    try:
        context = mm.Context(system, mm.VerletIntegrator(0.001), mm.Platform.getPlatformByName(name))
    except Exception:  # OpenMMException (no device, no driver) or a failed plugin
        return False
    del context
    return True


def fastest_platform(available: list[str] | None = None, opencl_gpus: int | None = None) -> tuple[str, str]:
    """Return the fastest OpenMM platform present and why it was chosen.

    CUDA, then HIP, then OpenCL where the OpenCL loader lists a GPU, else CPU; a GPU
    platform counts only if it makes a Context here. OpenCL on a CPU (pocl) is never
    chosen: it runs a few hundred atoms at a fraction of the CPU platform's speed.

    Parameters
    ----------
    available : list of str, optional
        The platform names to choose from (default: :func:`available_platforms`).
    opencl_gpus : int, optional
        GPU devices of the OpenCL loader (default: :func:`opencl_gpu_count`).

    Returns
    -------
    tuple of (str, str)
        The platform's name and a sentence that says why.

    Examples
    --------
    >>> from openmm_alphaprk.platforms import fastest_platform
    >>> fastest_platform(available=["Reference", "CPU", "OpenCL"], opencl_gpus=0)[0]
    'CPU'
    """
    names = available_platforms() if available is None else list(available)
    notes = []
    for name in AUTO_ORDER[:-1]:
        if name not in names:
            notes.append(f"{name}: not installed")
            continue
        if name == "OpenCL" and not (opencl_gpu_count() if opencl_gpus is None else opencl_gpus):
            notes.append("OpenCL: no GPU device")
            continue
        if available is None and not _can_run(name):
            notes.append(f"{name}: no usable device")
            continue
        return name, f"{name}: the fastest platform present"
    return "CPU", "CPU: no GPU platform usable here (" + "; ".join(notes) + ")"
