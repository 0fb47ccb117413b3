"""The measured tables of the README and the user guide, from the data under docs/data/.

Part of ``python -m tools.reports``. Every block here is a table and the one line of its
provenance (the run, the machine, the day, a link to each data file); the sentences around
the blocks are written by hand and cite the tables, so no number is typed on a page. Rows
are the data's, keyed by the registry's integrator name (:func:`tools.reports.sources.pick`);
each table is a list of :class:`~tools.reports.markdown.Column` given to the one renderer.
"""

from __future__ import annotations

import re
from pathlib import Path

from openmm_alphaprk.equal_cost import equal_cost_divisor
from openmm_alphaprk.observables import drift_text
from openmm_alphaprk.platforms import energy_noise
from tools.reports.markdown import Column, table
from tools.reports.numbers import percent, sig, times, tolerance, two, whole_percent
from tools.reports.sources import DATA, DOCS, ROOT, Source, link, load, pick, provenance_line, source

SYSTEMS = ("tip3p-2nm", "tip3p-3nm", "villin")
#: The accuracy runs at 2 fs (the water boxes, villin), all rows of a system in one run.
ACCURACY_2FS = (
    "compositions/compositions_accuracy_2fs.json",
    "compositions/compositions_accuracy_2fs_villin.json",
)
#: The horizon (fs) at which the guide compares position errors.
HORIZON_FS = 100.0
LONG_RUN = "long_runs/cuda_h100/long_sequential_mixed.json"
LONG_RUN_DHFR = "long_runs/cuda_h100/cost_dhfr_2fs.json"
GPU_COST = ("compositions/cuda_h100/cost_6.json", "compositions/cuda_h100/cost_9.json")


# ------------------------------------------------------------------ the accuracy runs at 2 fs
def accuracy() -> tuple[dict[str, list[dict]], list[Source]]:
    """Return the rows of the 2 fs accuracy runs by system, and their sources."""
    rows, sources = {}, []
    for path in ACCURACY_2FS:
        data, found = load(path)
        sources.append(found)
        assert data["settings"]["timestep_fs"] == 2.0 and data["settings"]["platform"] == "CPU"
        rows.update({system: result["rows"] for system, result in data["systems"].items()})
    return rows, sources


def position(row: dict) -> float:
    """Return a row's RMS position error at the guide's horizon."""
    (error,) = [h["position_rms"] for h in row["horizons"] if h["time_fs"] == HORIZON_FS]
    return error


def gain(rows: list[dict], name: str) -> float:
    """RATTLE's position error at equal force evaluations over ``name``'s (above 1: ``name`` is better)."""
    row = pick(rows, name)
    k = equal_cost_divisor(row["force_evaluations_per_step"])
    return position(pick(rows, "rattle", k)) / position(row)


def accuracy_columns(every: bool) -> list[Column]:
    """Return the columns of the accuracy tables: one per system for each measure, or the three joined."""

    def measure(title, value, show=sig, joined=not every):
        if not joined:
            return [Column(f"{title}, {s}", lambda r, s=s: show(value(r[s], r["name"]))) for s in SYSTEMS]
        return [Column(title, lambda r: " / ".join(show(value(r[s], r["name"])) for s in SYSTEMS))]

    def field(key: str):
        return lambda rows, name: pick(rows, name)[key]

    columns = [
        Column("integrator", "`{name}`"),
        *measure("evaluations/step", field("force_evaluations_per_step"), "{:.3g}".format),
        *measure("RMS(H − E_ref) kJ/mol", field("rms_residual")),
        *measure(f"position error at {HORIZON_FS:g} fs (nm)", lambda rows, n: position(pick(rows, n))),
        *measure("× below RATTLE at equal evaluations", gain, times),
    ]
    if every:
        columns += measure("CPU time / RATTLE's", field("time_ratio"), two, joined=True)
    return columns


def accuracy_table(names: tuple[str, ...]) -> str:
    """Render the accuracy runs' table of the integrators ``names``, one column per system and measure."""
    rows, sources = accuracy()
    caption = provenance_line(
        sources,
        "`alphaprk bench accuracy`: CPU platform, 2 fs, 100 steps per row from each system's shipped "
        f"start, every row of a system in one run; systems {' / '.join(SYSTEMS)}; position error: RMS "
        "distance per atom to RATTLE at h/64; equal evaluations: RATTLE at h/k, k the row's evaluations "
        "rounded up",
    )
    return table([{"name": n, **rows} for n in names], accuracy_columns(True), caption)


# ------------------------------------------------------------------ the README's long runs
def _drift(row: dict) -> str:
    drift, error = row["drift_per_dof"], row["drift_per_dof_standard_error"]
    shown = f"{sig(drift)} ± {sig(error)}" if row["drift_resolved"] else f"none (± {sig(error)})"
    return f"{shown} ({row['simulated_ps']:.0f} ps)"


def _maybe(rows: list[dict], name: str) -> dict | None:
    try:
        return pick(rows, name)
    except LookupError:
        return None


# ------------------------------------------------------------------ cost on an H100
def gpu_cost_table() -> str:
    """Time per force evaluation against RATTLE's on an H100 at 21k and 72k atoms."""
    runs = [load(path) for path in GPU_COST]
    columns = [Column("integrator", "`{}`".format)] + [
        Column(f"{_atoms(data)} atoms", lambda n, d=data: two(pick(d["rows"], n)["ratio_per_evaluation"]))
        for data, _ in runs
    ]
    run = "`alphaprk bench cost` on TIP3P boxes, H100, CUDA mixed, 2 fs; time per force evaluation / RATTLE's"
    names = ("alpha4=0", "alpha6=0", "rattle4+rescale", "energy4")
    return table(names, columns, provenance_line([s for _, s in runs], run))


def _atoms(data: dict) -> str:
    """Return the atoms of a ``bench cost`` run, from its header in older files."""
    atoms = data.get("atoms") or int(re.search(r"(\d+) atoms", data["header"]).group(1))
    return f"{atoms:,}"


# ------------------------------------------------------------------ rescaling every N-th step
RESCALE_INTERVAL = "platforms/rescale_interval_cpu.json"


def rescale_interval_table() -> str:
    """Render the cost and energy of ``rattle+rescale@N`` beside RATTLE's, from one run of each."""
    data, found = load(RESCALE_INTERVAL)
    cost = {box: entry["rows"] for box, entry in data["single_thread_cpu_time"].items()}

    def cost_cell(rows: list[dict], name: str) -> str:
        row = pick(rows, name)
        return (
            f"1 ({row['cpu_ms_per_step']:.3g} ms)" if name == "rattle" else f"{row['ratio_to_rattle']:.2f}×"
        )

    def drift(run: dict) -> str:
        text = f"{sig(run['drift_per_dof'])} ± {sig(run['drift_per_dof_standard_error'])}"
        if run["at_rescaling_steps"]["samples"] < run["steps"]:
            text += f" ({sig(run['at_rescaling_steps']['drift_per_dof'])} at the rescaling steps)"
        return text

    at = "at_rescaling_steps"
    columns = [
        Column("", lambda r: "RATTLE" if r["name"] == "rattle" else f"`{r['name']}`"),
        *(
            Column(f"cost {box}", lambda r, rows=rows: cost_cell(rows, r["name"]))
            for box, rows in cost.items()
        ),
        Column("RMS(H − E_ref) kJ/mol, every step", lambda r: sig(r["rms_residual"])),
        Column("max \\|H − E_ref\\|", lambda r: sig(r["max_abs_residual"])),
        Column(
            "RMS at the rescaling steps",
            lambda r: "—" if r["name"] == "rattle" else sig(r[at]["rms_residual"]),
        ),
        Column("drift kJ/mol/ns/DOF", drift),
    ]
    run = (
        f"`python -m openmm_alphaprk.benchmarks.rescale_interval`, {data['platform']} platform, h = 2 fs; "
        f"cost: single-thread process time per step, {data['rounds_single_thread_cpu_time']} interleaved "
        f"rounds, median, ratio to RATTLE in the same run; energy: {data['energy']['box']} from its "
        f"shipped start, {data['energy']['picoseconds']:g} ps, H read after every step"
    )
    return table(data["energy"]["runs"], columns, provenance_line([found], run))


# ------------------------------------------------------------------ the order-2 energy mode
ORDER2_SYSTEMS = "research/controller_robustness/energy_benchmark_systems.json"
ORDER2_BUDGET = (
    "research/one_trial_per_step/order2_trial_budget_tip3p-2nm.json",
    "research/one_trial_per_step/order2_trial_budget_villin.json",
)


def order2_table() -> str:
    """Render the order-2 energy mode against RATTLE: fallbacks, RMS, and with its trials capped at 2."""
    systems, systems_source = load(ORDER2_SYSTEMS)
    budgets = [load(path) for path in ORDER2_BUDGET]
    rows = []
    for system in ("tip3p-3nm", "villin"):
        energy = pick(systems[system]["rows"], "energy", labelled="α-RATTLE energy")
        rattle = pick(systems[system]["rows"], "rattle")["rms_residual"]
        rows.append({"system": system, "trials": "every trial", **energy, "rattle": rattle})
    for (data, _), path in zip(budgets, ORDER2_BUDGET):
        two_trials = data["max_trials=2"]
        two_trials = {**two_trials, **two_trials["totals"], "rms_residual": two_trials["rms"]}
        system = path.split("_")[-1].removesuffix(".json")
        rows.append({**two_trials, "system": system, "trials": "2 trials", "rattle": data["rattle"]["rms"]})
    columns = [
        Column("system", "{system}"),
        Column("trials per step", "{trials}"),
        Column("steps fallen back", lambda r: percent(r["fraction_fallen_back"])),
        Column("evaluations/step", "{force_evaluations_per_step:.2g}"),
        Column("RMS(H − E_ref) kJ/mol", "{rms_residual:.3g}"),
        Column("RATTLE's RMS", "{rattle:.3g}"),
    ]
    run = (
        "`alphaprk bench energy`, CPU platform, 2 fs from each system's start (500 steps; with 2 trials: "
        "1,000 steps of tip3p-2nm and 300 of villin), the controller of its day"
    )
    return table(rows, columns, provenance_line([systems_source] + [s for _, s in budgets], run))


# ------------------------------------------------------------------ platforms.md
NOISE = ("platforms/cuda_h100/energy_noise.json", "platforms/energy_noise.json")
NOISE_COLUMNS = (
    ("CUDA single", "CUDA:single", "single"),
    ("CUDA mixed", "CUDA:mixed", "mixed"),
    ("CPU", "CPU", "mixed"),
    ("OpenCL (pocl) single", "OpenCL:single", "single"),
    ("OpenCL (pocl) mixed", "OpenCL:mixed", "mixed"),
    ("OpenCL (pocl) double", "OpenCL:double", "double"),
)


def noise_table() -> str:
    """σ of the potential energy against double precision by atoms and platform, and the model's."""
    runs = [load(path) for path in NOISE]
    measured = {(e["atoms"], spec): v for data, _ in runs for e in data for spec, v in e["std"].items()}
    atoms = sorted({n for n, _ in measured})
    columns = [
        Column("atoms", "{:,}".format),
        *(
            Column(t, lambda n, s=spec, p=p: _noise(measured.get((n, s)), n, p))
            for t, spec, p in NOISE_COLUMNS
        ),
        Column("model σ, mixed", lambda n: two(energy_noise(n, "mixed"))),
    ]
    run = (
        "`python -m openmm_alphaprk.benchmarks.energy_noise`, 10 states per box: σ (kJ/mol) of the "
        "potential energy against double precision (CUDA double on the H100, Reference on the CPU "
        "machine, where OpenCL is pocl), and in brackets σ over the model's for its precision"
    )
    return table(atoms, columns, provenance_line([s for _, s in runs], run))


def _noise(value: float | None, atoms: int, precision: str) -> str:
    """Return σ and, in brackets, σ over the model's for ``precision``; empty where not measured."""
    return "" if value is None else f"{two(value)} ({two(value / energy_noise(atoms, precision))})"


H100_LOGS = (
    "platforms/cuda_h100/common_platform_tests.log",
    "platforms/cuda_h100/common_platform_and_rescale_tests.log",
    "platforms/cuda_h100/rescale_tests_final.log",
    "compositions/cuda_h100/cuda_tests.log",
    "compositions/cuda_h100/single_tests.log",
)


def pytest_counts(path: str) -> dict[str, int]:
    """Return the counts of pytest's last summary line in the log ``path`` (passed, failed, ...)."""
    text = (DATA / path).read_text(encoding="utf-8")
    (summary,) = [line for line in text.splitlines() if re.search(r"\d+ passed.* in [\d.]+s", line)][-1:]
    return {word: int(n) for n, word in re.findall(r"(\d+) (passed|failed|skipped|deselected)", summary)}


def h100_tests_table() -> str:
    """Render pytest's counts of each test run on the H100, from its log."""
    columns = [Column("log", link), Column("day", lambda p: source(p).date)] + [
        Column(w, lambda p, w=w: str(pytest_counts(p).get(w, 0)))
        for w in ("passed", "failed", "skipped", "deselected")
    ]
    caption = "pytest's summary line of each run on the H100 (CUDA 13 wheel, OpenMM 8.6.1):"
    return table(H100_LOGS, columns, caption)


SYNC = ("platforms/cuda_h100/rescale_sync_cost.json", "platforms/rescale_sync_cost_cpu.json")
SYNC_VARIANTS = (
    ("energy", "the potential energy read once per step"),
    ("K", "and the kinetic energy summed, the velocities scaled uniformly"),
    ("K+moved", "and the start-of-step check of a state set by the user"),
    ("K+P", "and the momentum (3 sums) instead of that check"),
    ("K+P+moved", "all of it (what `rattle+rescale` did before 2026-11-27)"),
)


def sync_cost_table() -> str:
    """Render what each part of a rescaling step costs in a plain CustomIntegrator, H100 and CPU."""
    runs = [load(path) for path in SYNC]
    columns = [Column("added to RATTLE", lambda v: v[1])]
    for data, found in runs:
        where = "H100" if "H100" in found.machine else "CPU"
        columns += [
            Column(f"{where}, {int(n):,} atoms", lambda v, d=data[n]: f"{d[v[0]] / d['rattle']:.2f}")
            for n in sorted(data, key=int)
        ]
    caption = provenance_line(
        [s for _, s in runs],
        "`python -m openmm_alphaprk.benchmarks.rescale_sync_cost`: time per step "
        "against a RATTLE `CustomIntegrator` (H100: CUDA mixed; CPU: shared with other jobs)",
    )
    return table(SYNC_VARIANTS, columns, caption)


#: ``alphaprk bench cost`` of the rescaling that sums K alone per step, against RATTLE in each run.
RESCALE_COST = (
    "platforms/bench_cost_interval_cpu_tip3p-2nm_rattle_program.json",
    "platforms/bench_cost_interval_cpu_tip3p-3nm_rattle_program.json",
    "platforms/bench_cost_interval_opencl_tip3p-2nm_rattle_program.json",
    "platforms/bench_cost_interval_cpu_tip3p-2nm_41rounds.json",
    "platforms/bench_cost_interval_cpu_tip3p-3nm_41rounds.json",
    "platforms/bench_cost_cpu_tip3p-2nm_7rounds.json",
    "platforms/bench_cost_cpu_tip3p-3nm_7rounds.json",
    "platforms/bench_cost_cpu_tip3p-2nm.json",
    "platforms/bench_cost_cpu_tip3p-3nm.json",
    "platforms/bench_cost_opencl_tip3p-2nm.json",
    "platforms/bench_cost_interval_cpu_tip3p-2nm.json",
    "platforms/bench_cost_interval_opencl_tip3p-2nm.json",
    "long_runs/cuda_h100/cost_tip3p-3nm.json",
    "long_runs/cuda_h100/cost_tip3p-6nm.json",
    "long_runs/cuda_h100/cost_tip3p-9nm.json",
    "long_runs/cuda_h100/cost_dhfr_2fs.json",
    "platforms/cuda_h100/bench_core_rescale_6_before_axis_weights.json",
    "platforms/cuda_h100/bench_core_rescale_6.json",
    "platforms/cuda_h100/bench_core_rescale_9.json",
)


def rescale_cost_table() -> str:
    """RATTLE + rescaling's step against RATTLE's in each run of ``alphaprk bench cost``."""

    def ratio(name: str, against: str = "rattle"):
        def cell(r):
            row = _maybe(r["rows"], name)
            return f"{row['ms_per_step'] / pick(r['rows'], against)['ms_per_step']:.2f}" if row else ""

        return cell

    def platform(r):
        return r["header"].split("platform ")[1].split(";")[0].split(", precision single (the CPU")[0]

    runs = [{**load(p)[0], "path": p} for p in RESCALE_COST]
    columns = [
        Column("data", lambda r: link(r["path"])),
        Column("day", lambda r: source(r["path"]).date),
        Column("platform", platform),
        Column("atoms", _atoms),
        Column("timing", lambda r: re.search(r"median of ([^;]+)", r["header"]).group(1)),
        Column("every step", ratio("rattle+rescale")),
        Column("every 10th", ratio("rattle+rescale@10")),
        Column("every 100th", ratio("rattle+rescale@100")),
        Column("`rattle4+rescale` / `alpha4=0`", ratio("rattle4+rescale", "alpha4=0")),
        Column("note", lambda r: r.get("note", "")),
    ]
    machines = " and ".join(sorted({source(p).machine for p in RESCALE_COST}))
    caption = "RATTLE + rescaling's time per step over RATTLE's in the same run of `alphaprk bench cost`"
    return table(runs, columns, f"{caption}; {machines}:")


#: tools/scripts/instruction_cost.py, each file one run: the interval programs before and after
#: they kept P/M per degree of freedom.
INSTRUCTION_COST = (
    "platforms/instruction_cost_tip3p-2nm_vector_centre.json",
    "platforms/instruction_cost_tip3p-2nm.json",
    "platforms/instruction_cost_tip3p-2nm_again.json",
    "platforms/instruction_cost_tip3p-3nm_vector_centre.json",
    "platforms/instruction_cost_tip3p-3nm.json",
)


def instruction_cost_table() -> str:
    """RATTLE + rescaling's instructions per step over RATTLE's, counted by callgrind in each run."""

    def rows(r: dict) -> dict[str, dict]:
        return {row["integrator"]: row for row in r["rows"]}

    def ratio(name: str):
        return lambda r: f"{rows(r)[name]['ratio']:.4f}" if name in rows(r) else ""

    runs = [{**load(p)[0], "path": p} for p in INSTRUCTION_COST]
    columns = [
        Column("data", lambda r: link(r["path"])),
        Column("program", lambda r: r.get("note", "")),
        Column("system", "{system}"),
        Column(
            "RATTLE, M instructions/step", lambda r: f"{rows(r)['rattle']['instructions_per_step'] / 1e6:.1f}"
        ),
        Column("every step", ratio("rattle+rescale")),
        Column("every 10th", ratio("rattle+rescale@10")),
        Column("every 100th", ratio("rattle+rescale@100")),
    ]
    counted = {r["system"]: re.search(r"/ (\d+);", r["header"]).group(1) for r in runs}
    steps = ", ".join(f"{n} steps on {system}" for system, n in counted.items())
    caption = provenance_line(
        [source(p) for p in INSTRUCTION_COST],
        "`python tools/scripts/instruction_cost.py`: instructions per step over RATTLE's in the same run, "
        "counted by valgrind's callgrind on the CPU platform with one thread: the difference of two runs' "
        f"counts over the steps between them ({steps})",
    )
    return table(runs, columns, caption)


# ------------------------------------------------------------------ smooth_forces.md
PME = "smooth_forces/pme_tolerance.json"
PME_VILLIN = "smooth_forces/pme_tolerance_villin_cost.json"
#: The integrators of the PME run as the table names them (order 4 was the triple jump that day).
THEN = {"rattle": "`rattle`", "energy4": "`energy4` †", "alpha4=0": "`alpha4=0` †"}
DIAGNOSIS = "smooth_forces/energy_tip3p-2nm_300.json"


def pme_table() -> str:
    """Render the PME tolerance runs: energy error and cost of each integrator at each Ewald tolerance."""
    data, found = load(PME)
    villin, villin_source = load(PME_VILLIN)
    runs = {float(k): v for k, v in data.items() if isinstance(v, dict)}
    villin_ms = {float(k): v["rows"][0]["ms_per_step"] for k, v in villin.items() if isinstance(v, dict)}
    tightest = min(runs)
    rows = [
        {
            **row,
            "tol": tol,
            "pme": runs[tol]["pme"],
            "rattle": pick(runs[tol]["rows"], "rattle"),
            "tight": pick(runs[tightest]["rows"], row["integrator"]),
            "villin": villin_ms[tol] / villin_ms[tightest] if row["integrator"] == "rattle" else None,
        }
        for tol in sorted(runs, reverse=True)
        for row in runs[tol]["rows"]
    ]
    fell = "fraction_fallen_back"
    columns = [
        Column("Ewald tolerance", lambda r: tolerance(r["tol"])),
        Column("PME", "{pme}"),
        Column("integrator", lambda r: THEN[r["integrator"]]),
        Column("RMS(H − E_ref) kJ/mol", "{rms_residual:.3g}"),
        Column("RATTLE's RMS / this", lambda r: f"{r['rattle']['rms_residual'] / r['rms_residual']:.3g}"),
        Column("evaluations/step", "{force_evaluations_per_step:.2f}"),
        Column("fallen back", lambda r: whole_percent(r[fell]) if r.get(fell, 0) > 0 else "–"),
        Column("ms/step", "{ms_per_step:.1f}"),
        Column("time / RATTLE's", lambda r: f"{r['ms_per_step'] / r['rattle']['ms_per_step']:.2f}"),
        Column(
            f"time / at {tolerance(tightest)}",
            lambda r: f"{r['ms_per_step'] / r['tight']['ms_per_step']:.2f}",
        ),
        Column(
            f"villin: time / at {tolerance(tightest)}",
            lambda r: "" if r["villin"] is None else f"{r['villin']:.2f}",
        ),
    ]
    run = (
        "`python -m openmm_alphaprk.benchmarks.pme_tolerance`: "
        f"{data['steps']} steps of 2 fs per row from the shipped {data['system']} start (villin: "
        "RATTLE's cost alone), CPU platform, load average "
        f"{' / '.join(f'{v:.1f}' for v in data['load'])} at its start; ms/step: the fastest of the "
        "interleaved rounds. † That day the order-4 composition was the triple jump: `alpha4=0` is today's "
        "`alpha4=0:triple-jump`, `energy4` the energy mode of that day on it"
    )
    return table(rows, columns, provenance_line([found, villin_source], run))


def diagnosis_table() -> str:
    """Render the share of the energy modes' steps that ended outside the tolerance with smooth forces."""
    data, found = load(DIAGNOSIS)
    rows = [{"name": n, **pick(data["tip3p-2nm"]["rows"], n)} for n in ("energy", "energy4")]
    columns = [
        Column("integrator", "`{name}`"),
        Column(
            "steps ending outside the tolerance", lambda r: whole_percent(1 - r["fraction_within_tolerance"])
        ),
    ]
    run = "`alphaprk bench energy` on tip3p-2nm, CPU platform, smooth forces, 300 steps of 2 fs"
    return table(rows, columns, provenance_line([found], f"{run} from the shipped start"))


# ------------------------------------------------------------------ own_files.md and driver.md
PEPTIDE = {
    "2fs": ("own_files/amber_2fs.json", "own_files/charmm_2fs.json"),
    "hmr 4fs": ("own_files/amber_hmr_4fs.json",),
}


def peptide_table(paths: tuple[str, ...]) -> str:
    """``alphaprk compare`` on the test peptide's files: each row, and the equal-cost verdicts."""
    rows, sources = [], []
    for path in paths:
        data, found = load(path)
        sources.append(found)
        verdicts = {v["integrator"]: v for v in data["equal_cost"]}
        for name, summary in zip(data["runs"], data["summaries"]):
            rows.append(
                {
                    "files": path.split("/")[-1].split("_")[0],
                    "name": name,
                    **summary,
                    "position": data["accuracy"]["rows"][name]["position_rms"],
                    "time_fs": data["accuracy"]["rows"][name]["time_fs"],
                    "verdict": verdicts.get(name),
                }
            )
    first = rows[0]

    def divisor(r: dict) -> str | None:
        return r["name"].split("/")[1] if " h/" in r["name"] else None

    rms = "rms_residual"
    columns = [
        Column("files", "{files}"),
        Column("row", lambda r: f"RATTLE at h/{divisor(r)}" if divisor(r) else f"`{r['name']}`"),
        Column("evaluations/step", lambda r: divisor(r) or f"{r['force_evaluations_per_step']:.3g}"),
        Column("RMS(H − E_ref) kJ/mol", lambda r: f"{r[rms]:.3g}" if r[rms] >= 1 else sig(r[rms])),
        Column(
            "drift kJ/mol/ns/DOF", lambda r: drift_text(r["drift_per_dof"], r["drift_per_dof_standard_error"])
        ),
        Column(f"position error at {first['time_fs']:g} fs (nm)", lambda r: sig(r["position"])),
        Column(
            "RMS: × below RATTLE at equal cost", lambda r: times(r["verdict"]["gain"]) if r["verdict"] else ""
        ),
        Column(
            "positions: × below RATTLE at equal cost",
            lambda r: two(r["verdict"]["position_gain"]) if r["verdict"] else "",
        ),
    ]
    run = (
        f"`alphaprk compare`: {first['platform']} platform, {first['timestep_fs']:g} fs, "
        f"{first['steps']:,} steps ({first['simulated_ps']:g} ps) per row from the same start"
    )
    return table(rows, columns, provenance_line(sources, run))


REPORTER_COST = "driver/reporter_cost.json"


def reporter_cost_table() -> str:
    """Render what a reporter costs the driver per step, by integrator and reporting interval."""
    data, found = load(REPORTER_COST)
    s = data["settings"]
    columns = [
        Column("integrator", "{integrator}"),
        Column("reporting", "{reporting}"),
        Column("steps/s (median)", "{steps_per_s:.1f}", "---:"),
        Column("× no reporter", "{ratio_to_no_reporter:.3f}", "---:"),
        Column("one report (µs)", lambda r: "–" if r["report_us"] is None else two(r["report_us"]), "---:"),
        Column(
            "one report / step",
            lambda r: "–" if r["report_us"] is None else f"{r['report_us'] * r['steps_per_s'] / 1e4:.2g} %",
            "---:",
        ),
    ]
    run = (
        "`python -m openmm_alphaprk.benchmarks.reporter_cost "
        f"--threads {s['threads']} --rounds {s['rounds']}`: "
        f"{s['platform']} platform, `{s['system']}` ({s['atoms']:,} atoms), {s['timestep_fs']:g} fs, "
        f"{s['rounds']} interleaved rounds of {s['energy4_steps']} energy4 / {s['rattle_steps']} RATTLE "
        f"steps per row; one report timed alone (median of {s['repeats']:,}); load average "
        f"{s['load'][0]:.1f}"
    )
    return table(data["rows"], columns, provenance_line([found], run))


# ------------------------------------------------------------------ the pages
GUIDE_NAMES = (
    "rattle",
    "rattle+rescale",
    "rattle4+rescale",
    "alpha4=0",
    "alpha4=0:triple-jump",
    "alpha6=0",
    "rattle6+rescale",
    "energy4",
)


def readme_block() -> str:
    """Render the README's table: the accuracy runs and the H100 long runs, joined by integrator name."""
    rows, sources = accuracy()
    long, long_source = load(LONG_RUN)
    ((_, entry),) = long.items()
    dhfr, dhfr_source = load(LONG_RUN_DHFR)
    days = sorted({s.date for s in sources + [long_source, dhfr_source]})
    summary = (
        f"Values for tip3p-2nm / tip3p-3nm / villin, 2 fs, on the CPU platform of a 2-core machine "
        f"({days[0]}); long runs on an H100, CUDA mixed ({days[-1]}); "
        "every file and its provenance: "
        "[the integrators](docs/integrators.md#which-integrator-for-which-job), "
        "[long runs](docs/long_runs.md), [data](docs/data/README.md)."
    )
    columns = [
        *(
            Column(c.title, lambda r, c=c: c.text(r) if r["measured"] or c.title == "integrator" else "–")
            for c in accuracy_columns(False)
        ),
        Column("drift kJ/mol/ns/DOF", lambda r: _drift(r["long"])),
        Column(
            "ns/day tip3p-3nm / dhfr",
            lambda r: (
                f"{r['long']['ns_per_day']:,.0f} / "
                + (f"{r['dhfr']['ns_per_day']:,.0f}" if r["dhfr"] else "–")
            ),
        ),
    ]
    names = ("rattle", "rattle+rescale", "rattle+rescale@10", "rattle4+rescale", "alpha4=0", "energy4")
    joined = [
        {
            "name": n,
            **rows,
            "measured": _maybe(rows["tip3p-2nm"], n) is not None,
            "long": pick(entry["rows"], n),
            "dhfr": _maybe(dhfr["rows"], n),
        }
        for n in names
    ]
    return table(joined, columns, summary)


def render() -> dict[Path, dict[str, str]]:
    """Every generated block of the README and the user guide, by page and block name."""
    return {
        ROOT / "README.md": {"which integrator": readme_block()},
        DOCS / "integrators.md": {
            "which integrator": accuracy_table(GUIDE_NAMES),
            "gpu in short": gpu_cost_table(),
            "rescale interval": rescale_interval_table(),
        },
        DOCS / "energy_mode.md": {
            "what it achieves": accuracy_table(("rattle", "rattle4+rescale", "energy4")),
            "order 2": order2_table(),
        },
        DOCS / "platforms.md": {
            "energy noise": noise_table(),
            "h100 tests": h100_tests_table(),
            "rescale cost": rescale_cost_table(),
            "rescale sync cost": sync_cost_table(),
            "instruction cost": instruction_cost_table(),
        },
        DOCS / "smooth_forces.md": {"pme tolerance table": pme_table(), "diagnosis": diagnosis_table()},
        DOCS / "own_files.md": {f"peptide {k}": peptide_table(v) for k, v in PEPTIDE.items()},
        DOCS / "driver.md": {"reporter cost": reporter_cost_table()},
    }
