"""The MD benchmark report's own logic: stability scan, generated blocks, dynamics comparison."""

from __future__ import annotations

import json

import numpy as np
import pytest

from openmm_alphaprk.benchmarks.md_sweep.analysis import compare_dynamics
from openmm_alphaprk.benchmarks.md_sweep.tables import scan_table
from tools.reports.markdown import page_tables, replace_blocks
from tools.reports.md_benchmark import JSON_OUT, PAGE, blocks, scan_markdown


def _row(system, integrator, step, status="ok", max_abs=0.1, dof=1000.0):
    return {
        "system": system,
        "integrator": integrator,
        "timestep_fs": step,
        "seed": "",
        "status": status,
        "error": "" if status == "ok" else "RunFailedError: NaN",
        "degrees_of_freedom": dof,
        "max_abs_residual": max_abs,
        "rms_residual": max_abs / 3,
        "simulated_ps": 2.0,
    }


def test_largest_stable_step_is_the_last_before_the_first_unstable_or_failed_step():
    cells = [
        _row("box", "rattle", 2.0, max_abs=1.0),
        _row("box", "rattle", 3.0, max_abs=10.0),
        _row("box", "rattle", 4.0, max_abs=60.0),  # 0.06 per DOF: above the 0.05 threshold
        _row("box", "rattle", 5.0, max_abs=1.0),  # stable again, but after an unstable step
        _row("box", "energy4", 2.0, max_abs=0.1),
        _row("box", "energy4", 3.0, status="failed"),
        _row("box", "verlet", 2.0),
        _row("box", "verlet", 3.0),
        _row("box", "alpha4=0", 2.0),  # only the main run: not scanned
        _row("box", "rattle", 0.5),  # smaller RATTLE steps are not scan cells
        _row("other", "rattle", 3.0, status="failed"),
    ]
    rows = {(r["system"], r["integrator"], r["timestep_fs"], r["seed"]): r for r in cells}
    scan = scan_table(rows, "box")
    assert scan["rattle"]["largest_stable_fs"] == 3.0 and "0.5" not in scan["rattle"]
    assert scan["rattle"]["4"]["stable"] is False and scan["rattle"]["4"]["max_abs_residual_per_dof"] == 0.06
    assert scan["energy4"]["largest_stable_fs"] == 2.0 and scan["energy4"]["3"]["status"] == "failed"
    assert scan["verlet"]["largest_stable_fs"] == scan["verlet"]["scanned_to_fs"] == 3.0
    table = scan_markdown("box", scan)
    assert "| RATTLE | 1.0e-03 | 1.0e-02 | 6.0e-02 (unstable) | 1.0e-03 | 3 fs |" in table
    assert "✗" in table and "≥ 3 fs (scan end)" in table and "not scanned" in table
    # a system with only main runs has no scan
    assert scan_table({k: v for k, v in rows.items() if v["timestep_fs"] <= 2.0}, "box") == {}


def test_generated_blocks_are_replaced_and_missing_markers_reported():
    page = "intro\n<!-- generated: x -->\nold\ntext\n<!-- end generated: x -->\nrest\n<!-- generated: y -->\n"
    page += "<!-- end generated: y -->\n"
    new, missing = replace_blocks(page, {"x": "new table\n"})
    assert new.startswith("intro\n<!-- generated: x -->\nnew table\n<!-- end generated: x -->\nrest")
    assert missing == []
    filled, missing = replace_blocks(new, {"y": "filled"})
    assert filled.count("filled") == 1 and missing == []
    assert replace_blocks(page, {"z": "anything"}) == (page, ["z"])


def test_dynamics_comparison():
    r = np.linspace(0, 8, 81)
    g_ref = np.where(r > 2.5, 1.0 + np.exp(-((r - 2.8) ** 2) / 0.02), 0.0)
    freq = np.linspace(0, 2000, 401)
    spectrum = np.exp(-((freq - 550) ** 2) / 2e4)
    spectrum /= spectrum.sum() * (freq[1] - freq[0])
    reference = {
        "rdf_r": r.tolist(),
        "rdf_g": g_ref.tolist(),
        "diffusion": 6.0,
        "diffusion_error": 0.2,
        "frequencies": freq.tolist(),
        "spectrum": spectrum.tolist(),
        "bands": {"libration": {"centroid": 560.0, "weight": 0.7}},
    }
    same = compare_dynamics(reference, reference)
    assert same["rdf_rms_difference"] == 0 and same["diffusion_relative_difference"] == 0
    assert (
        same["spectrum_difference"] == pytest.approx(0, abs=1e-12) and same["libration_centroid_shift"] == 0
    )
    other = json.loads(json.dumps(reference)) | {
        "diffusion": 6.6,
        "rdf_g": (g_ref + 0.1 * (r > 2.4)).tolist(),
    }
    other["bands"] = {"libration": {"centroid": 565.0, "weight": 0.7}}
    diff = compare_dynamics(other, reference)
    assert diff["rdf_rms_difference"] == pytest.approx(0.1)
    assert diff["diffusion_relative_difference"] == pytest.approx(0.1)
    assert diff["libration_centroid_shift"] == pytest.approx(5.0)


def test_page_tables_are_the_ones_rendered_from_the_json():
    """docs/benchmarks.md's generated tables are what the report renders from its JSON."""
    report = json.loads(JSON_OUT.read_text(encoding="utf-8"))
    on_page = page_tables(PAGE)
    rendered = blocks(report)
    assert set(on_page) == set(rendered) and len(on_page) == 9
    for name, table in rendered.items():
        assert on_page[name] == table, f"table {name!r} of docs/benchmarks.md is not the JSON's"
    for figure in report["figures"]:
        assert (PAGE.parent / figure).is_file()
