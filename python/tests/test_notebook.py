"""The diagnosis in a notebook: progress, an experiment for bare runs, the HTML repr, and the
simgap.plot helpers; and URDF input that must not crash the interpreter."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import simgap

PD = {"controller": "pd", "kp": [64.72, 32.36], "kv": [48.54, 6.472]}
FRICTION = ["viscous_friction:b=2.288,0.175"]


@pytest.fixture(scope="module")
def arm() -> simgap.Model:
    return simgap.Model.paper_arm()


@pytest.fixture(scope="module")
def runs(arm: simgap.Model) -> tuple[list[simgap.Run], simgap.Run]:
    fit = [simgap.simulate(arm, target, duration=2.0, effects=FRICTION, **PD) for target in ([np.pi / 4, np.pi / 2], [-0.6, 1.0], [0.3, -0.8])]
    held = simgap.simulate(arm, [0.5, -0.4], duration=2.0, effects=FRICTION, **PD)
    return fit, held


@pytest.fixture(scope="module")
def report(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run]) -> simgap.Report:
    fit, held = runs
    return simgap.diagnose(arm, fit, [held])


def test_progress_callback_sees_every_stage_in_order(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run]) -> None:
    fit, held = runs
    calls: list[tuple[str, int, int]] = []
    simgap.diagnose(arm, fit, [held], progress=lambda stage, done, total: calls.append((stage, done, total)))
    assert calls, "the callback was never called"
    stages = [c[0] for c in calls]
    assert len(set(stages)) >= 2 and all(isinstance(s, str) and s for s in stages), stages
    assert all(isinstance(d, int) and isinstance(t, int) and 0 <= d <= max(t, 1) for _, d, t in calls), calls


def test_progress_callback_exception_stops_and_is_raised(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run]) -> None:
    fit, held = runs

    def boom(stage: str, done: int, total: int) -> None:
        raise RuntimeError(f"stop at {stage}")

    with pytest.raises(RuntimeError, match="stop at"):
        simgap.diagnose(arm, fit, [held], progress=boom)


def test_progress_true_shows_a_bar_without_tqdm_or_with_it(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run], capsys: pytest.CaptureFixture[str]) -> None:
    fit, held = runs
    simgap.diagnose(arm, fit, [held], progress=True)
    assert capsys.readouterr().err.strip(), "progress=True printed nothing on stderr"


def test_progress_must_be_callable(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run]) -> None:
    fit, held = runs
    with pytest.raises(TypeError, match="progress"):
        simgap.diagnose(arm, fit, [held], progress=3)  # type: ignore[arg-type]


def bare(run: simgap.Run) -> simgap.Run:
    return simgap.Run(run.joints, run.t, run.q, run.qd, tau=run.tau, q_ref=run.q_ref, qd_ref=run.qd_ref)


def test_experiment_applies_to_runs_without_one(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run], report: simgap.Report, tmp_path: Path) -> None:
    fit, held = runs
    with pytest.raises(simgap.LogError, match="experiment"):
        simgap.diagnose(arm, [bare(r) for r in fit], [bare(held)])
    with_runs_own = report
    report = simgap.diagnose(arm, [bare(r) for r in fit], [bare(held)], experiment=fit[0].experiment)
    # the same answer as when every run carries the experiment itself
    assert "viscous_friction" in [e["effect"] for e in report.selected_effects], report.summary()
    assert report.selected_effects == with_runs_own.selected_effects
    # the same from an experiment file, as the CLI's --experiment
    import json

    path = tmp_path / "exp.json"
    path.write_text(json.dumps(fit[0].experiment))
    again = simgap.diagnose(arm, [bare(r) for r in fit], [bare(held)], experiment=path)
    assert again.selected_effects == report.selected_effects


def test_bad_experiment_is_a_clear_error(arm: simgap.Model, runs: tuple[list[simgap.Run], simgap.Run]) -> None:
    fit, held = runs
    with pytest.raises(TypeError, match="experiment"):
        simgap.diagnose(arm, fit, [held], experiment=3)  # type: ignore[arg-type]
    with pytest.raises(simgap.LogError, match="experiment"):
        simgap.diagnose(arm, [bare(r) for r in fit], [bare(held)], experiment={"controller": "nope"})


def test_report_shows_as_html_in_a_notebook(report: simgap.Report) -> None:
    html = report._repr_html_()
    assert html.startswith("<!DOCTYPE html>") and "<svg" in html
    assert 'id="verdict"' in html and "viscous_friction" in html and "N·m·s/rad" in html


def test_fit_residuals_have_one_entry_per_fit_run(report: simgap.Report) -> None:
    res = report.fit_residuals
    assert len(res) == 3
    for r in res:
        n = len(r["t"])
        assert r["qd"].shape == r["residual"].shape == (n, 2)


def test_plot_helpers_draw_log_error_panels_and_outside_legends(report: simgap.Report) -> None:
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import simgap.plot

    fig = simgap.plot.trajectories(report, run=0)
    axes = fig.get_axes()
    assert len(axes) == 4  # two joints: position and error panel each
    assert [ax.get_yscale() for ax in axes] == ["linear", "log", "linear", "log"]
    assert all("since the log's start" in ax.get_xlabel() for ax in axes[1::2])
    assert fig.legends, "the legend is the figure's (outside the plots), not an axes'"
    assert axes[0].get_lines()[0].get_xdata()[0] == 0.0
    fig = simgap.plot.error_panel(report, 0, "elbow")
    assert fig.get_axes()[0].get_yscale() == "log"
    fig = simgap.plot.residual_vs_velocity(report, "shoulder")
    assert fig.get_axes()[0].collections
    fig = simgap.plot.candidates(report)
    ax = fig.get_axes()[0]
    assert ax.get_xscale() == "log" and len(ax.patches) == len(report.candidates)
    with pytest.raises(ValueError, match="not a joint"):
        simgap.plot.error_panel(report, 0, "wrist")


def test_deeply_nested_urdf_is_an_error_not_a_crash(tmp_path: Path) -> None:
    # ~15,000 levels once overflowed the stack inside the XML reader and killed Python (SIGSEGV)
    depth = 15_000
    path = tmp_path / "deep.urdf"
    path.write_text(f'<robot name="r"><link name="a">{"<x>" * depth}{"</x>" * depth}</link></robot>')
    code = f"import simgap\ntry:\n    simgap.Model.from_urdf({str(path)!r})\nexcept simgap.UrdfError as e:\n    print('UrdfError:', e)\n"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False)
    assert out.returncode == 0, f"Python died: {out.returncode}\n{out.stderr}"
    assert "UrdfError:" in out.stdout and "15002 levels deep" in out.stdout, out.stdout


def test_unexpanded_xacro_names_element_and_attribute(tmp_path: Path) -> None:
    path = tmp_path / "robot.urdf"
    path.write_text('<robot name="r"><link name="a"><inertial><mass value="${m}"/></inertial></link></robot>')
    with pytest.raises(simgap.UrdfError, match=r"<mass> attribute value=\"\$\{m\}\".*run xacro first"):
        simgap.Model.from_urdf(path)
