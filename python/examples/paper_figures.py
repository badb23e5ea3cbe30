"""The seed paper's Figures 3–5 redrawn from the simgap bindings, as PNG files.

Run (after `make python-package`):

    .venv/bin/python python/examples/paper_figures.py --out-dir figures

The experiment is the paper's: its two-link arm (`Model.paper_arm()`) under a sampled PD
controller from q = 0 to q_d = (π/4, π/2), Kp = diag(64.72, 32.36), Kv = diag(48.54, 6.472),
sample period 2.5 ms, 3 s, encoder of 1,024,000 counts per revolution and backward-difference
velocity (the defaults of `simgap.simulate`), simulated once with each formulation of C:

- `fig3_joint1_response.png`: joint 1 position under both formulations over the experiment;
- `fig4_joint1_zoom.png`: the same in the window t = 1.070–1.115 s, where they differ;
- `fig5_l2_indices.png`: the L² indices (eq. 127) of each model's tracking error q_d − q and
  of the difference between the two models' positions.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import simgap  # noqa: E402

Q_DESIRED = [np.pi / 4, np.pi / 2]
KP = [64.72, 32.36]
KV = [48.54, 6.472]
SAMPLE_PERIOD = 0.0025
DURATION = 3.0
ZOOM = (1.070, 1.115)
LABELS = {"euler_lagrange": "Euler–Lagrange C", "simplified": "simplified C (Ḣ/2)"}
STYLES: dict[str, dict[str, Any]] = {"euler_lagrange": {"color": "tab:blue", "linestyle": "-"}, "simplified": {"color": "tab:red", "linestyle": "--"}}


def simulate_both() -> dict[str, simgap.Run]:
    """The paper's experiment under each formulation of C."""
    arm = simgap.Model.paper_arm()
    return {
        f: simgap.simulate(arm, Q_DESIRED, controller="pd", kp=KP, kv=KV, formulation=f, sample_period=SAMPLE_PERIOD, duration=DURATION)  # type: ignore[arg-type]
        for f in LABELS
    }


def figure3(runs: dict[str, simgap.Run], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=130)
    for f, run in runs.items():
        ax.plot(run.t, run.q[:, 0], label=LABELS[f], linewidth=1.4, **STYLES[f])
    ax.axhline(Q_DESIRED[0], color="0.5", linewidth=0.8, linestyle=":", label="q_d,1 = π/4")
    ax.axvspan(*ZOOM, color="0.85", label="Fig. 4 window")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("q₁ [rad]")
    ax.set_title("Fig. 3: joint 1 response, PD to (π/4, π/2)")
    ax.set_xlim(0, DURATION)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def figure4(runs: dict[str, simgap.Run], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=130)
    for f, run in runs.items():
        t = run.t
        # one sample either side so that the curves reach the window's edges
        k = np.flatnonzero((t >= ZOOM[0] - SAMPLE_PERIOD) & (t <= ZOOM[1] + SAMPLE_PERIOD))
        ax.plot(t[k], run.q[k, 0], marker="o", markersize=3, drawstyle="steps-post", label=LABELS[f], linewidth=1.2, **STYLES[f])
    ax.set_xlim(*ZOOM)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("q₁ [rad] (as sampled by the encoder)")
    ax.set_title(f"Fig. 4: joint 1, zoom on t = {ZOOM[0]:.3f}–{ZOOM[1]:.3f} s")
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def l2_indices(runs: dict[str, simgap.Run]) -> dict[str, simgap.L2Report]:
    """Eq. 127 of each model's tracking error, and of the difference between the models."""
    out = {LABELS[f]: simgap.l2_tracking(run) for f, run in runs.items()}
    out["difference (EL − simplified)"] = simgap.compare(runs["euler_lagrange"], runs["simplified"])
    return out


def figure5(indices: dict[str, simgap.L2Report], path: Path) -> None:
    names = list(indices)
    joints = indices[names[0]].joints
    x = np.arange(len(names))
    width = 0.25
    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=130)
    series = [("overall", [indices[n].overall for n in names])]
    series += [(j, [float(indices[n].per_joint[i]) for n in names]) for i, j in enumerate(joints)]
    for i, (label, values) in enumerate(series):
        bars = ax.bar(x + (i - 1) * width, values, width, label=label)
        ax.bar_label(bars, labels=[f"{v:.2e}" for v in values], fontsize=7, rotation=90, padding=2)
    ax.set_yscale("log")
    ax.set_xticks(x, names)
    ax.set_ylabel("L² index (eq. 127) [rad]")
    ax.set_title("Fig. 5: L² indices of the tracking errors and of their difference")
    lo = min(min(v) for _, v in series)
    hi = max(max(v) for _, v in series)
    ax.set_ylim(lo / 3, hi * 30)
    ax.grid(axis="y", alpha=0.3, which="both")
    ax.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> list[Path]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--out-dir", type=Path, default=Path("figures"), help="where to write the PNG files (created if missing)")
    args = parser.parse_args(argv)
    out: Path = args.out_dir
    out.mkdir(parents=True, exist_ok=True)

    runs = simulate_both()
    indices = l2_indices(runs)
    paths = [out / "fig3_joint1_response.png", out / "fig4_joint1_zoom.png", out / "fig5_l2_indices.png"]
    figure3(runs, paths[0])
    figure4(runs, paths[1])
    figure5(indices, paths[2])
    for name, report in indices.items():
        per_joint = ", ".join(f"{j} {v:.4e}" for j, v in zip(report.joints, report.per_joint, strict=True))
        print(f"L2 {name:<30} overall {report.overall:.4e} rad ({per_joint})")
    for p in paths:
        print(f"wrote {p}")
    return paths


if __name__ == "__main__":
    main()
