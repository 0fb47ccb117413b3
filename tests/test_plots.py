"""The H − E_ref figure of ``alphaprk compare``, built from synthetic traces and read back."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from openmm_alphaprk.observables import drift_text, fit_drift, residual_statistics  # noqa: E402
from openmm_alphaprk.runs.integrator_names import label  # noqa: E402
from openmm_alphaprk.workflows.plots import (  # noqa: E402
    NOT_COMPARABLE,
    build_energy_residual_figure,
    plot_energy_residuals,
    pyplot,
    run_caption,
)

#: name → (noise amplitude kJ/mol, drift kJ/mol/ps), like the main job's integrators.
AMPLITUDES = {"rattle": (3.0, -0.5), "energy": (1.0, 0.0), "energy4": (0.01, 0.001), "alpha4=0": (0.05, 0.0)}
CAPTION = run_caption("water-cluster", 222, 2.0, 400, "CUDA", precision="mixed", dof=444, energy_interval=10)


def _traces(names=(*AMPLITUDES, "verlet"), samples=201):
    rng = np.random.default_rng(1)
    times = np.linspace(0.0, 2.0, samples)
    traces = {}
    for name in names:
        amplitude, slope = AMPLITUDES.get(name, (3.0, -1.0))
        residuals = amplitude * rng.standard_normal(samples) + slope * times
        residuals[0] = 0.0
        traces[name] = times, residuals
    return traces


@pytest.fixture
def figure():
    fig = build_energy_residual_figure(_traces(), caption=CAPTION, dof=444)
    fig.canvas.draw()
    yield fig
    pyplot().close(fig)


def _names_on(ax) -> set[str]:
    return {line.get_gid() for line in ax.lines if line.get_gid()}


def _panel(fig, name):
    """The linear panel holding only ``name``'s trace."""
    (ax,) = [ax for ax in fig.axes if _names_on(ax) == {name} and ax.get_yscale() == "linear"]
    return ax


def test_one_log_panel_holds_the_comparable_integrators_readably(figure):
    (log_ax,) = [ax for ax in figure.axes if ax.get_yscale() == "log"]
    assert _names_on(log_ax) == set(AMPLITUDES)
    low, high = log_ax.get_ylim()
    assert low <= 0.01 / 3 and high >= 3.0  # the 0.01 kJ/mol trace and the 3 kJ/mol one both inside
    assert "kJ/mol" in log_ax.get_ylabel() and "ps" in log_ax.get_xlabel()


def test_every_integrator_has_its_own_linear_panel_not_flattened(figure):
    for name, (_, residuals) in _traces().items():
        ax = _panel(figure, name)
        low, high = ax.get_ylim()
        assert low <= residuals.min() and residuals.max() <= high, name
        assert high - low <= 100 * np.ptp(residuals), name  # 0.01 kJ/mol is not a flat line
        assert "kJ/mol" in ax.get_ylabel() and "ps" in ax.get_xlabel(), name
    for ax in figure.axes:
        assert "kJ/mol" in ax.get_ylabel() and "(ps)" in ax.get_xlabel()


def test_verlet_never_shares_an_axis_with_the_velocity_verlet_integrators(figure):
    for ax in figure.axes:
        names = _names_on(ax)
        assert "verlet" not in names or names == {"verlet"}
    title = _panel(figure, "verlet").get_title()
    assert NOT_COMPARABLE in title and "drift only" in title and "leapfrog" in title
    for name in AMPLITUDES:
        assert "not comparable" not in _panel(figure, name).get_title()


def test_not_comparable_can_be_named():
    fig = build_energy_residual_figure(_traces(("rattle", "energy4")), not_comparable=["rattle"])
    try:
        assert NOT_COMPARABLE in _panel(fig, "rattle").get_title()
        (log_ax,) = [ax for ax in fig.axes if ax.get_yscale() == "log"]
        assert _names_on(log_ax) == {"energy4"}
    finally:
        pyplot().close(fig)


def test_panels_are_labelled_from_the_vocabulary_with_drift_and_noise(figure):
    for name, (times, residuals) in _traces().items():
        ax = _panel(figure, name)
        assert ax.get_title().startswith(label(name))
        texts = [text.get_text() for text in ax.get_legend().get_texts()]
        fit = fit_drift(times, residuals)
        drift = drift_text(fit.slope / 444, fit.standard_error / 444, "kJ/mol/ns")
        assert f"drift/DOF {drift}" in texts, texts
        assert "±" in drift  # every drift comes with its standard error
        if name != "verlet":
            assert any("σ" in text and "scatter about the drift line" in text for text in texts), texts


def test_log_panel_states_the_rms_of_the_tables():
    """The legend's RMS is that of the samples after the start (the tables' number), not of all samples."""
    traces = _traces(("rattle", "energy4"), samples=11)  # few samples: leaving out the 0 at t = 0 shows
    fig = build_energy_residual_figure(traces)
    try:
        (log_ax,) = [ax for ax in fig.axes if ax.get_yscale() == "log"]
        texts = [text.get_text() for text in log_ax.get_legend().get_texts()]
        for name, (_, residuals) in traces.items():
            rms = residual_statistics(residuals)[0]
            assert f"{label(name)}: RMS {rms:.3g} kJ/mol" in texts, texts
            assert f"{np.sqrt(np.mean(residuals**2)):.3g}" != f"{rms:.3g}"
    finally:
        pyplot().close(fig)


def test_an_unresolved_drift_is_not_shown_as_a_number():
    rng = np.random.default_rng(2)
    times = np.linspace(0.0, 0.2, 11)
    residuals = rng.normal(0.0, 1.0, times.size)
    residuals[0] = 0.0
    fig = build_energy_residual_figure({"rattle": (times, residuals)})
    try:
        texts = [text.get_text() for text in _panel(fig, "rattle").get_legend().get_texts()]
        fit = fit_drift(times, residuals)
        assert not fit.resolved
        assert f"drift not resolved (±{fit.standard_error:.2g} kJ/mol/ns)" in texts, texts
    finally:
        pyplot().close(fig)


def test_legends_do_not_hide_the_data(figure):
    renderer = figure.canvas.get_renderer()
    for name, (times, residuals) in _traces().items():
        ax = _panel(figure, name)
        box = ax.get_legend().get_window_extent(renderer)
        top_of_data = ax.transData.transform((times[0], residuals.max()))[1]
        assert box.y0 > top_of_data, name


def test_caption_and_title(figure):
    texts = " ".join(text.get_text() for text in figure.texts)
    for needed in ("water-cluster", "222 atoms", "2 fs", "CUDA", "mixed", "400 steps", "0.8 ps"):
        assert needed in texts, needed
    assert figure._suptitle.get_fontsize() >= 11 and "H − E_ref" in figure._suptitle.get_text()
    for ax in figure.axes:
        assert ax.title.get_fontsize() >= 11 and ax.get_title()


def test_plot_energy_residuals_writes_a_png(tmp_path):
    path = plot_energy_residuals(_traces(samples=3), tmp_path / "energy_residuals.png", caption=CAPTION)
    image = pyplot().imread(path)
    assert image.ndim == 3 and image.shape[0] > 500 and image.shape[1] > 500
