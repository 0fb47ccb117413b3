"""docs/platforms.md's measured blocks: the energy noise, the H100 test runs, the CPU cost of rescaling.

Part of ``python -m tools.reports.guide``. The energy noise comes from
``tools/scripts/energy_noise.py`` runs (CUDA on an H100; CPU and pocl's OpenCL on the
development machine), the test counts from the pytest logs of the H100 runs, the CPU cost of
the rescaling from the accuracy runs and ``tools/scripts/rescale_sync_cost.py`` on the CPU.
"""

from __future__ import annotations

import re

from openmm_alphaprk.platforms import energy_noise
from tools.reports.markdown import markdown_table
from tools.reports.numbers import two
from tools.reports.sources import DATA, Source, load, source

NOISE_CUDA = "platforms/cuda_h100/energy_noise.json"
NOISE_CPU = "platforms/energy_noise.json"
#: The noise table's columns: (title, file, platform spec, the model's precision for it).
NOISE_COLUMNS = (
    ("CUDA single", NOISE_CUDA, "CUDA:single", "single"),
    ("CUDA mixed", NOISE_CUDA, "CUDA:mixed", "mixed"),
    ("CPU", NOISE_CPU, "CPU", "mixed"),
    ("OpenCL (pocl) mixed", NOISE_CPU, "OpenCL:mixed", "mixed"),
    ("OpenCL (pocl) double", NOISE_CPU, "OpenCL:double", "double"),
)
#: pocl's single precision: measured, but not the implementation the model is for.
POCL_SINGLE = "OpenCL:single"
#: The pytest logs of the H100 runs, by what they ran.
LOG_COMMON = "platforms/cuda_h100/common_platform_tests.log"
LOG_COMMON_RESCALE = "platforms/cuda_h100/common_platform_and_rescale_tests.log"
LOG_RESCALE = "platforms/cuda_h100/rescale_tests_final.log"
LOG_COMPOSITIONS = "compositions/cuda_h100/cuda_tests.log"
LOG_COMPOSITIONS_FIXED = "compositions/cuda_h100/single_tests.log"
#: The CPU platform's cost of what a rescaling step could need (plain CustomIntegrators).
SYNC_CPU = "platforms/rescale_sync_cost_cpu.json"
#: The same on an H100 (CUDA mixed), the table of the "rescale sync cost" block.
SYNC_H100 = "platforms/cuda_h100/rescale_sync_cost.json"
#: The H100 run of the package's rescaling before the momentum sums moved to per-DOF axis weights.
RESCALE_BEFORE = "platforms/cuda_h100/bench_core_rescale_6_before_axis_weights.json"
RESCALE = "RATTLE + rescaling"


# ------------------------------------------------------------------ energy noise
def noise_table() -> str:
    """Render the table of the potential energy's noise by platform and precision, with the model's σ."""
    cuda, cuda_source = load(NOISE_CUDA)
    cpu, cpu_source = load(NOISE_CPU)
    by_file = {NOISE_CUDA: cuda, NOISE_CPU: cpu}
    atoms = sorted({entry["atoms"] for data in by_file.values() for entry in data})
    measured = {
        (path, entry["atoms"], spec): value
        for path, data in by_file.items()
        for entry in data
        for spec, value in entry["std"].items()
    }
    lines, ratios = [], []
    for n in atoms:
        cells = [f"{n:,}"]
        for title, path, spec, precision in NOISE_COLUMNS:
            value = measured.get((path, n, spec))
            cells.append("" if value is None else two(value))
            if value is not None:
                ratios.append((value / energy_noise(n, precision), title, n))
        cells.append(two(energy_noise(n, "mixed")))
        lines.append(cells)
    (pocl_single,) = [v for (path, n, spec), v in measured.items() if spec == POCL_SINGLE and n == atoms[1]]
    references = {entry["reference"] for data in by_file.values() for entry in data}
    caption = (
        "Standard deviation (kJ/mol) of the potential energy against double precision, 10 states per box "
        "(`python tools/scripts/energy_noise.py`): CUDA on an H100 against CUDA double "
        f"({cuda_source.date}), the others on {cpu_source.machine}, against Reference ({cpu_source.date}; "
        f"OpenCL there is pocl). Data: {files_of([cuda_source, cpu_source])}."
    )
    assert references == {"CUDA:double", "Reference"}, references
    table = markdown_table(["atoms", *(c[0] for c in NOISE_COLUMNS), "model σ, mixed"], lines)
    low, high = min(ratios), max(ratios)
    model = (
        "The model σ = a (N/1000)^0.75 (`openmm_alphaprk.platforms.energy_noise`; a = 0.0018 for mixed "
        "precision and the CPU platform, 0.0026 single, 1.2e-4 double) is "
        f"{two(low[0])}–{two(high[0])}× each measurement's (measured σ over the model's for its precision; "
        f"the highest: {high[1]} at {high[2]:,} atoms); pocl's single precision, {two(pocl_single)} at "
        f"{atoms[1]:,} atoms, is an outlier of that implementation."
    )
    return caption + "\n\n" + table + "\n\n" + model


def files_of(sources: list[Source]) -> str:
    """Link each data file (the page lives in docs/, its data under docs/data/)."""
    return ", ".join(f"[{s.path.split('/')[-1]}](data/{s.path}) (commit {s.commit})" for s in sources)


# ------------------------------------------------------------------ the H100 test runs
def pytest_counts(path: str) -> dict[str, int]:
    """Return the counts of pytest's last summary line in the log ``path`` (passed, failed, ...)."""
    text = (DATA / path).read_text(encoding="utf-8")
    (summary,) = [line for line in text.splitlines() if re.search(r"\d+ passed.* in [\d.]+s", line)][-1:]
    return {word: int(n) for n, word in re.findall(r"(\d+) (passed|failed|skipped|deselected)", summary)}


def h100_tests() -> str:
    """Render the paragraph on the common-platform tests on an H100, counted from the logs."""
    common, common_source = pytest_counts(LOG_COMMON), source(LOG_COMMON)
    rescale, rescale_source = pytest_counts(LOG_COMMON_RESCALE), source(LOG_COMMON_RESCALE)
    final, final_source = pytest_counts(LOG_RESCALE), source(LOG_RESCALE)
    return (
        f"On an H100 (CUDA 13 wheel, OpenMM 8.6.1; {common_source.date}) the programs of that day passed all "
        f"{common['passed']} of these tests on CUDA double and mixed "
        f"([{LOG_COMMON.split('/')[-1]}](data/{LOG_COMMON}); deselected: {common.get('deselected', 0)}, "
        "the driver test, which needs MDAnalysis, which that machine lacked). With RATTLE + rescaling "
        f"({rescale_source.date}) these tests and the rescaling's passed again, {rescale['passed']} of them "
        f"([{LOG_COMMON_RESCALE.split('/')[-1]}](data/{LOG_COMMON_RESCALE})), and the {final['passed']} "
        "rescaling tests passed again after its last change "
        f"([{LOG_RESCALE.split('/')[-1]}](data/{LOG_RESCALE}), {final_source.date})."
    )


def h100_composition_tests() -> str:
    """Render the counts of the H100 run with the compositions as data."""
    run, run_source = pytest_counts(LOG_COMPOSITIONS), source(LOG_COMPOSITIONS)
    fixed = pytest_counts(LOG_COMPOSITIONS_FIXED)
    return (
        "With the compositions as data (Suzuki's fourth-order default, α on any stage, the sixth-order "
        "members, RATTLE-4 + rescaling), these tests and `tests/test_rescale.py` ran on the H100 again in "
        f"mixed and single precision ({run_source.date}, [{LOG_COMPOSITIONS.split('/')[-1]}]"
        f"(data/{LOG_COMPOSITIONS})): {run['passed']} passed, {run.get('skipped', 0)} double-only test "
        f"skipped, {run.get('failed', 0)} failed in single precision, both defects of the tests (a "
        "comparison "
        "with the velocities as given instead of as the single-precision Context holds them, and two "
        "energy-mode trials whose energies differed by less than single precision's noise); after the fix "
        f"the {fixed['passed']} runs of both on CUDA single and mixed pass "
        f"([{LOG_COMPOSITIONS_FIXED.split('/')[-1]}](data/{LOG_COMPOSITIONS_FIXED}); "
        '[compositions.md, "On a GPU"](compositions.md#on-a-gpu-cuda-on-an-h100)).'
    )


# ------------------------------------------------------------------ the rescaling's cost
#: ``alphaprk bench cost --integrators all`` (CPU) and ``core`` (OpenCL) of the program that sums K alone.
RESCALE_NOW = (
    "platforms/bench_cost_cpu_tip3p-2nm_7rounds.json",
    "platforms/bench_cost_cpu_tip3p-3nm_7rounds.json",
    "platforms/bench_cost_cpu_tip3p-2nm.json",
    "platforms/bench_cost_cpu_tip3p-3nm.json",
    "platforms/bench_cost_opencl_tip3p-2nm.json",
    "platforms/bench_cost_interval_cpu_tip3p-2nm.json",
    "platforms/bench_cost_interval_opencl_tip3p-2nm.json",
)
#: The rows that rescale every N-th step, by N.
EVERY = {10: "RATTLE + rescaling every 10 steps", 100: "RATTLE + rescaling every 100 steps"}
RESCALE4 = "RATTLE-4 + rescaling"
RATTLE = "RATTLE"
ALPHA4 = "α-RATTLE-4 α = 0"


def rescale_cost_now() -> str:
    """Render the present program's cost: RATTLE + rescaling against RATTLE, and on Suzuki's composition."""
    parts, sources = [], []
    for path in RESCALE_NOW:
        run, run_source = load(path)
        sources.append(run_source)
        rows = {row["name"]: row for row in run["rows"]}
        header = run["header"]
        atoms = run.get("atoms") or int(header.split(" atoms")[0].rsplit(" ", 1)[1])
        platform = header.split("platform ")[1].split(";")[0].split(", precision single (the CPU")[0]
        rounds = header.split("median of ")[1].split(";")[0]
        text = (
            f"{rows[RESCALE]['ms_per_step'] / rows[RATTLE]['ms_per_step']:.2f}× RATTLE's step on {atoms:,} "
            f"atoms ({platform}, median of {rounds}; "
            f"{rows[RESCALE]['host_syncs_per_step']:.2f} sums per step)"
        )
        every = [
            f"every {n}th step {rows[name]['ms_per_step'] / rows[RATTLE]['ms_per_step']:.2f}×"
            for n, name in EVERY.items()
            if name in rows
        ]
        if every:
            text += ", " + ", ".join(every)
        if run.get("note"):
            text += f" ({run['note']})"
        if RESCALE4 in rows:
            text += (
                f", RATTLE-4 + rescaling {rows[RESCALE4]['ms_per_step'] / rows[ALPHA4]['ms_per_step']:.2f}× "
                "Suzuki's composition without it"
            )
        parts.append(text)
    return (
        "Since 2026-11-27 a rescaling step in a periodic box reads the energy and sums the kinetic energy, "
        "nothing more: P is carried from when E_ref was taken or the state was set, and whether the state "
        "was set is checked once per `step()` call. `alphaprk bench cost`, each line one run against "
        f"RATTLE in that run ({sources[0].date}, {sources[0].machine}): "
        + "; ".join(parts)
        + f". Data: {files_of(sources)}. On an H100 this program is measured at the end of this "
        "section; the table just below is of what each part could cost, measured on 2026-11-26."
    )


def rescale_cost_notes(a2) -> str:
    """Render what follows the H100 cost of the rescaling: the earlier program, the sums, the CPU platform.

    ``a2`` is the guide's accuracy runs at 2 fs (:class:`tools.reports.guide.Accuracy`).
    """
    before, before_source = load(RESCALE_BEFORE)
    (row,) = [r for r in before["rows"] if r["name"] == RESCALE]
    gpu, gpu_source = load(SYNC_H100)
    gpu = {int(n): medians for n, medians in gpu.items() if int(n) > 10_000}
    gpu_read = [medians["energy"] / medians["rattle"] for medians in gpu.values()]
    per_sum = {n: (m["K+P"] - m["K"]) / 3 for n, m in gpu.items()}
    smallest = min(gpu)
    sync, sync_source = load(SYNC_CPU)
    cpu = {int(n): medians for n, medians in sync.items()}
    cpu_read = [medians["energy"] / medians["rattle"] for medians in cpu.values()]
    systems = ("tip3p-2nm", "tip3p-3nm")
    cost = " and ".join(f"{a2.row(s, RESCALE)['time_ratio']:.2f}×" for s in systems)
    return (
        "The 72k-atom run is of the program before the momentum sums moved to per-DOF axis weights (that "
        f"program measured {row['ratio_per_evaluation']:.2f}× at 21k atoms, {before_source.date}: "
        f"{files_of([before_source])}). The energy read alone costs {min(gpu_read):.2f}–{max(gpu_read):.2f}× "
        f"at {_k(min(gpu))}–{_k(max(gpu))} atoms (OpenMM evaluates and downloads the PME energy; the table "
        "above), so no rescaling that holds E_ref at every step can come within 1.1× of RATTLE in a "
        f"`CustomIntegrator` on this GPU; each further sum costs about {per_sum[smallest]:.2f} ms "
        f"({per_sum[smallest] / gpu[smallest]['rattle']:.0%} of a {_k(smallest)}-atom step; the momentum's "
        "three sums against the kinetic energy alone). On the CPU platform the program of that day cost "
        f"{cost} RATTLE's step on {' and '.join(systems)} (the accuracy runs of {_dates(a2.sources)}, "
        "interleaved timing); the energy read alone costs "
        + " and ".join(f"{r:.2f}×" for r in cpu_read)
        + f" on boxes of {' and '.join(f'{n:,}' for n in cpu)} atoms (`tools/scripts/rescale_sync_cost.py "
        f"--platform CPU`, on {sync_source.date} on {sync_source.machine}, shared with other jobs: "
        f"{files_of([sync_source])})."
    ).replace("%", " %")


def _k(atoms: int) -> str:
    """21384 → 21k."""
    return f"{atoms / 1000:.0f}k"


def _dates(sources: list[Source]) -> str:
    days = sorted({s.date for s in sources})
    return days[0] if len(days) == 1 else f"{days[0]} to {days[-1]}"


def blocks(a2) -> dict[str, str]:
    """Every block of docs/platforms.md rendered here, by name."""
    return {
        "energy noise": noise_table(),
        "h100 tests": h100_tests(),
        "h100 composition tests": h100_composition_tests(),
        "rescale cost notes": rescale_cost_notes(a2),
        "rescale cost now": rescale_cost_now(),
    }
