"""The exported corrected model where users simulate (docs/guide/export.md), checked by round trips:

- the exported URDF loads in Pinocchio and in simgap with H and g equal to the corrected model
  (Pinocchio's model of the input URDF with the reported corrections added through
  ``pinocchio.Inertia``, the sidecar's armature on the diagonal);
- the exported MJCF compiles in MuJoCo, whose mass matrix (``mj_fullM``, armature included) and
  bias force at rest (``qfrc_bias`` = g) equal the corrected model's;
- MuJoCo's k-step prediction of a held-out run (state set from the log at every window start,
  the logged torque held per sample as ``ctrl``) agrees with simgap's prediction of the same
  windows with the selected effects, on a case whose effects the MJCF holds.

The cases are made with the simulator (no data files needed): the paper's arm with hidden
viscous and Coulomb friction, rotor inertia and a payload, diagnosed through the Python API; and
``simgap demo`` (friction and a saturation), through the CLI (needs SIMGAP_BIN, as the other CLI
tests).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import simgap

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is not installed (pip install mujoco; it is in requirements-test.txt)")
pinocchio = pytest.importorskip("pinocchio", reason="Pinocchio is not installed (pip install pin; it is in requirements-test.txt)")

ROOT = Path(__file__).resolve().parents[2]
PAPER_ARM = ROOT / "crates" / "simgap-core" / "models" / "paper_arm.urdf"
KP = [64.72, 32.36]
KV = [48.54, 6.472]
HIDDEN = [
    "viscous_friction:b=2.288,0.175",
    "coulomb_friction:fc=7.17,1.734",
    "armature:ia=0.3,0.04",
    "payload:mass=1.5;com=0,0,-0.25",
]
HORIZONS = (0.1, 0.25, 0.5)


def sine_reference(model: simgap.Model, duration: float, freqs: tuple[float, float], amps: tuple[float, float], name: str) -> simgap.Run:
    """A smooth reference (q_ref, q̇_ref) from rest at q = 0."""
    t = np.arange(0.0, duration + 1e-9, 0.0025)
    w = 2 * np.pi * np.asarray(freqs)
    a = np.asarray(amps)
    q = a * (1 - np.cos(np.outer(t, w)))
    qd = a * w * np.sin(np.outer(t, w))
    return simgap.Run(model.joint_names, t, q, qd, q_ref=q, qd_ref=qd, source=name)


def simulate(model: simgap.Model, reference: simgap.Run) -> simgap.Run:
    return simgap.simulate(model, reference, controller="pd_gravity", kp=KP, kv=KV, effects=HIDDEN)


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory: pytest.TempPathFactory) -> tuple[simgap.Report, simgap.Run, Path]:
    """The paper's arm with friction, rotor inertia and a payload hidden, diagnosed blind from
    three fit runs; one held-out run; the corrected model exported into a temporary folder."""
    model = simgap.Model.from_urdf(PAPER_ARM)
    fit = [
        simulate(model, sine_reference(model, 4.0, (0.5, 0.8), (0.6, 0.8), "fit-a")),
        simulate(model, sine_reference(model, 4.0, (0.3, 1.3), (0.9, 0.6), "fit-b")),
        simulate(model, sine_reference(model, 4.0, (0.7, 0.45), (0.4, 1.0), "fit-c")),
    ]
    held = simulate(model, sine_reference(model, 6.0, (0.35, 1.1), (0.8, 0.5), "held"))
    report = simgap.diagnose(model, fit, [held], urdf=PAPER_ARM)
    out = tmp_path_factory.mktemp("export")
    report.export_urdf(out / "corrected.urdf")
    report.export_mjcf(out / "corrected.xml")
    return report, held, out


# --- the corrected model, built independently in Pinocchio from the report's numbers ----------


def per_joint(effect: dict[str, Any], key: str, names: list[str], neutral: float) -> np.ndarray:
    """A per-joint parameter of a report entry, in model order, neutral where it does not act."""
    out = np.full(len(names), neutral)
    for j, v in zip(effect["joints"], effect["parameters"][key]):
        out[names.index(j)] = v
    return out


def corrected_pinocchio(urdf: Path, effects: list[dict[str, Any]], last_joint: str | None = None) -> tuple[Any, np.ndarray]:
    """Pinocchio's model of the input URDF with the reported payload (on ``last_joint``, default
    Pinocchio's last) and inertial corrections added to its body inertias, and the reported
    armature (Pinocchio's joint order)."""
    model = pinocchio.buildModelFromUrdf(str(urdf))
    names = [model.names[i] for i in range(1, model.njoints)]
    armature = np.zeros(model.nv)
    for e in effects:
        if e["effect"] == "payload":
            last = model.getJointId(last_joint) if last_joint else model.njoints - 1
            point = pinocchio.Inertia(e["parameters"]["mass"], np.asarray(e["parameters"]["com"]), np.zeros((3, 3)))
            model.inertias[last] = model.inertias[last] + point
        elif e["effect"] == "inertial_error":
            for k, joint in enumerate(e["joints"]):
                jid = model.getJointId(joint)
                old = model.inertias[jid]
                ixx, ixy, ixz, iyy, iyz, izz = e["parameters"]["delta_inertia"][k]
                di = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
                model.inertias[jid] = pinocchio.Inertia(
                    old.mass + e["parameters"]["delta_mass"][k], old.lever + np.asarray(e["parameters"]["delta_com"][k]), old.inertia + di
                )
        elif e["effect"] == "armature":
            armature += per_joint(e, "ia", names, 0.0)
    return model, armature


def random_states(dof: int, n: int = 50, seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, (n, dof))


def test_the_diagnosis_found_inertial_and_joint_effects(diagnosed: tuple[simgap.Report, simgap.Run, Path]) -> None:
    # the case must exercise the inertial export, or the round trips below prove little
    report, _, _ = diagnosed
    names = {e["effect"] for e in report.selected_effects}
    assert names & {"payload", "inertial_error"}, names
    assert {"viscous_friction", "coulomb_friction", "armature"} <= names, names


def test_exported_urdf_loads_in_pinocchio_and_simgap_with_the_corrected_h_and_g(diagnosed: tuple[simgap.Report, simgap.Run, Path]) -> None:
    report, _, out = diagnosed
    exported = pinocchio.buildModelFromUrdf(str(out / "corrected.urdf"))
    reference, armature = corrected_pinocchio(PAPER_ARM, report.selected_effects)
    nominal = pinocchio.buildModelFromUrdf(str(PAPER_ARM))
    ours = simgap.Model.from_urdf(out / "corrected.urdf")
    sidecar = json.loads((out / "corrected.urdf.effects.json").read_text())
    side_armature = np.zeros(exported.nv)
    for e in sidecar["selected_effects"]:
        if e["effect"] == "armature":
            side_armature += per_joint(e, "ia", ours.joint_names, 0.0)
    np.testing.assert_array_equal(side_armature, armature)
    d_e, d_r, d_n = exported.createData(), reference.createData(), nominal.createData()
    worst_h = worst_g = moved = 0.0
    for q in random_states(exported.nq):
        h_e = pinocchio.crba(exported, d_e, q)
        h_r = pinocchio.crba(reference, d_r, q)
        h_e, h_r = np.triu(h_e) + np.triu(h_e, 1).T, np.triu(h_r) + np.triu(h_r, 1).T
        g_e = pinocchio.computeGeneralizedGravity(exported, d_e, q)
        g_r = pinocchio.computeGeneralizedGravity(reference, d_r, q)
        worst_h = max(worst_h, np.abs(h_e + np.diag(side_armature) - h_r - np.diag(armature)).max() / np.abs(h_r).max())
        worst_g = max(worst_g, np.abs(g_e - g_r).max() / max(np.abs(g_r).max(), 1e-9))
        # simgap loads the same file to the same numbers
        np.testing.assert_allclose(ours.mass_matrix(q), h_e, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ours.gravity_torques(q), g_e, rtol=1e-9, atol=1e-9)
        g_n = pinocchio.computeGeneralizedGravity(nominal, d_n, q)
        moved = max(moved, np.abs(g_e - g_n).max() / max(np.abs(g_n).max(), 1e-9))
    print(f"URDF round trip: H rel. {worst_h:.1e}, g rel. {worst_g:.1e} (the correction moves g by {moved:.1%})")
    assert worst_h < 1e-9 and worst_g < 1e-9
    assert moved > 1e-3, "the corrected URDF is the nominal one"
    # names, limits and the comment are the input's
    text = (out / "corrected.urdf").read_text()
    for line in ("<!-- The 2-DOF direct-drive arm", '<limit lower="-3.14159265358979" upper="3.14159265358979" effort="15" velocity="10"/>'):
        assert line in text


def full_mass_matrix(m: Any, d: Any) -> np.ndarray:
    """MuJoCo's dense mass matrix (armature included) after mj_forward: ``mj_fullM(m, d, dst)``
    from MuJoCo 4, ``mj_fullM(m, dst, d.qM)`` before."""
    full = np.zeros((m.nv, m.nv))
    if hasattr(d, "qM"):
        mujoco.mj_fullM(m, full, d.qM)
    else:
        mujoco.mj_fullM(m, d, full)
    return full


def test_exported_mjcf_compiles_with_the_corrected_mass_matrix_and_gravity(diagnosed: tuple[simgap.Report, simgap.Run, Path]) -> None:
    report, _, out = diagnosed
    m = mujoco.MjModel.from_xml_path(str(out / "corrected.xml"))
    d = mujoco.MjData(m)
    reference, armature = corrected_pinocchio(PAPER_ARM, report.selected_effects)
    d_r = reference.createData()
    assert m.nv == reference.nv and m.nu == reference.nv
    assert m.opt.timestep == pytest.approx(0.0025)
    worst_h = worst_g = 0.0
    for q in random_states(m.nq):
        d.qpos[:] = q
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        full = full_mass_matrix(m, d)
        h_r = pinocchio.crba(reference, d_r, q)
        h_r = np.triu(h_r) + np.triu(h_r, 1).T + np.diag(armature)
        g_r = pinocchio.computeGeneralizedGravity(reference, d_r, q)
        worst_h = max(worst_h, np.abs(full - h_r).max() / np.abs(h_r).max())
        worst_g = max(worst_g, np.abs(d.qfrc_bias - g_r).max() / max(np.abs(g_r).max(), 1e-9))
    print(f"MJCF round trip: H rel. {worst_h:.1e}, g rel. {worst_g:.1e}")
    assert worst_h < 1e-9 and worst_g < 1e-9


# --- k-step prediction: MuJoCo against simgap on the same windows ------------------------------


def effect_specs(effects: list[dict[str, Any]], names: list[str]) -> list[str]:
    """The report's selected effects in the simulator's spelling (for ``simgap.simulate``)."""
    specs = []
    for e in effects:
        kind, p = e["effect"], e["parameters"]
        if kind == "payload":
            specs.append(f"payload:mass={p['mass']};com={','.join(map(str, p['com']))}")
        elif kind == "inertial_error":
            for k, joint in enumerate(e["joints"]):
                com = ",".join(map(str, p["delta_com"][k]))
                inertia = ",".join(map(str, p["delta_inertia"][k]))
                specs.append(f"inertial_error:joint={names.index(joint)};mass={p['delta_mass'][k]};com={com};inertia={inertia}")
        else:
            # the width w of a dry friction is spelled as the report states it (joints the
            # effect does not act on have fc = 0: any width there)
            neutral = {"k": 1.0, "limit": float("inf"), "w": 0.01}
            params = [f"{key}={','.join(map(str, per_joint(e, key, names, neutral.get(key, 0.0))))}" for key in p]
            specs.append(f"{kind}:{';'.join(params)}")
    return specs


def window_starts(run: simgap.Run, horizon: float, every: float = 0.1) -> list[int]:
    dt = float(np.median(np.diff(run.t)))
    steps = round(horizon / dt)
    return [k for k in range(0, len(run.t) - steps, round(every / dt))]


def kstep_mujoco(xml: Path, run: simgap.Run) -> list[float]:
    """RMS position error at the window ends, MuJoCo restarted from the logged state at every
    window start and driven by the logged torque held per sample."""
    m = mujoco.MjModel.from_xml_path(str(xml))
    d = mujoco.MjData(m)
    dt = m.opt.timestep
    out = []
    for h in HORIZONS:
        steps = round(h / dt)
        errors = []
        for k in window_starts(run, h):
            mujoco.mj_resetData(m, d)
            d.qpos[:] = run.q[k]
            d.qvel[:] = run.qd[k]
            for s in range(steps):
                d.ctrl[:] = run.tau[k + s]
                mujoco.mj_step(m, d)
            errors.append(d.qpos - run.q[k + steps])
        out.append(float(np.sqrt(np.mean(np.square(errors)))))
    return out


def kstep_simgap(model: simgap.Model, run: simgap.Run, effects: list[str]) -> list[float]:
    """The same windows predicted by simgap: the logged torque replayed open loop from the
    logged state, with the selected effects."""
    dt = float(np.median(np.diff(run.t)))
    out = []
    for h in HORIZONS:
        steps = round(h / dt)
        errors = []
        for k in window_starts(run, h):
            pred = simgap.simulate(
                model, run, controller="replay", replay=run, t0=float(run.t[k]), duration=steps * dt, q0=run.q[k], qd0=run.qd[k],
                effects=effects, counts_per_rev=None, velocity="exact", sample_period=dt,
            )
            end = int(np.argmin(np.abs(pred.t - (run.t[k] + steps * dt))))
            errors.append(pred.q[end] - run.q[k + steps])
        out.append(float(np.sqrt(np.mean(np.square(errors)))))
    return out


def check_kstep(model: simgap.Model, run: simgap.Run, report_effects: list[dict[str, Any]], xml: Path, label: str, unit: str = "rad", better_than_nominal: float = 0.2) -> None:
    """MuJoCo on the exported MJCF against simgap's corrected model, k-step RMS error on the same
    windows: within 10 % at 0.1 and 0.5 s (45 % at every horizon), the dry friction mattering on
    the run, and both well below the nominal model's error."""
    corrected = kstep_simgap(model, run, effect_specs(report_effects, model.joint_names))
    nominal = kstep_simgap(model, run, [])
    ours = kstep_mujoco(xml, run)
    # the same file without its dry friction: the friction must matter on this run, or the
    # agreement proves nothing about it
    stripped = xml.with_name(xml.stem + "-no-dry-friction.xml")
    stripped.write_text(re.sub(r' frictionloss="[^"]*"', "", xml.read_text()))
    without = kstep_mujoco(stripped, run)
    print(
        f"{label}: k-step RMS [{unit}] at {HORIZONS} s: simgap nominal {nominal}, simgap corrected {corrected}, MuJoCo corrected MJCF {ours} "
        f"(MuJoCo/simgap {[round(mj / c, 3) for mj, c in zip(ours, corrected)]}), MuJoCo without frictionloss {without}"
    )
    for h, n, c, mj, wo in zip(HORIZONS, nominal, corrected, ours, without):
        assert abs(mj - c) <= 0.45 * c, f"{label}, h = {h} s: MuJoCo {mj:.3e}, simgap {c:.3e}, nominal {n:.3e}"
        assert mj < better_than_nominal * n, f"{label}, h = {h} s: MuJoCo {mj:.3e} is not better than the nominal model's {n:.3e}"
        if h not in (0.1, 0.5):
            continue
        # the target: MuJoCo's error within 10 % of simgap's. Measured with MuJoCo 4.0.1
        # (docs/guide/export.md): +0.8 % and +0.0 % on the carriage, +1.7 % and +1.1 % on the
        # paper arm, +5.8 % and +3.0 % on the demo at 0.1 and 0.5 s; what is left is the
        # difference of MuJoCo's band −fc·clip(q̇/(2 ln 2·w)) and simgap's −fc·tanh(q̇/w). The
        # friction constraint written before (a time constant of two steps, 90 % stiction)
        # failed it on the carriage (+22 %, +72 %) and the demo (+37 %, +16 %)
        assert abs(mj - c) <= 0.10 * c, f"{label}, h = {h} s: MuJoCo {mj:.3e}, simgap {c:.3e} ({mj / c - 1:+.1%}), nominal {n:.3e}"
        # the friction matters: without it MuJoCo's error is at least five times simgap's
        assert wo > 5 * c, f"{label}, h = {h} s: MuJoCo without frictionloss {wo:.3e}, simgap corrected {c:.3e}"


def prediction_gap_without_dry_friction(model: simgap.Model, run: simgap.Run, report_effects: list[dict[str, Any]], xml: Path, horizon: float = 0.5, limits: bool = True) -> float:
    """The largest difference [rad] between MuJoCo's and simgap's predictions of the same
    windows (not against the log) with the dry friction taken out of both: what is left of the
    two simulators' difference once MuJoCo's constraint friction and simgap's tanh are gone."""
    text = re.sub(r' frictionloss="[^"]*"', "", xml.read_text())
    m = mujoco.MjModel.from_xml_string(text)
    if not limits:
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT
    d = mujoco.MjData(m)
    dt = m.opt.timestep
    steps = round(horizon / dt)
    specs = [spec for spec in effect_specs(report_effects, model.joint_names) if not spec.startswith("coulomb_friction")]
    worst = 0.0
    for k in window_starts(run, horizon, every=0.5):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = run.q[k]
        d.qvel[:] = run.qd[k]
        for s in range(steps):
            d.ctrl[:] = run.tau[k + s]
            mujoco.mj_step(m, d)
        pred = simgap.simulate(
            model, run, controller="replay", replay=run, t0=float(run.t[k]), duration=steps * dt, q0=run.q[k], qd0=run.qd[k],
            effects=specs, counts_per_rev=None, velocity="exact", sample_period=dt,
        )
        worst = max(worst, float(np.abs(d.qpos - pred.q[-1]).max()))
    return worst


def test_mujoco_predicts_the_held_out_run_as_simgap_does(diagnosed: tuple[simgap.Report, simgap.Run, Path]) -> None:
    report, held, out = diagnosed
    sidecar = json.loads((out / "corrected.xml.effects.json").read_text())
    # every selected effect is in the MJCF: the comparison is of one model in two simulators
    assert sidecar["selected_effects"] == [], sidecar["selected_effects"]
    model = simgap.Model.from_urdf(PAPER_ARM)
    check_kstep(model, held, report.selected_effects, out / "corrected.xml", "paper arm + payload")
    # apart from dry friction the two simulators integrate one model: RK4 at the log's period,
    # the torque held per sample, the same inertias, damping and rotor inertia
    gap = prediction_gap_without_dry_friction(model, held, report.selected_effects, out / "corrected.xml")
    print(f"paper arm + payload: MuJoCo vs simgap without dry friction, 0.5 s windows: {gap:.1e} rad")
    assert gap < 1e-9


# --- simgap demo writes both files and says how to load them --------------------------------


def simgap_bin() -> str:
    binary = os.environ.get("SIMGAP_BIN")
    if not binary:
        if os.environ.get("CI"):
            pytest.fail("SIMGAP_BIN is not set: CI must build the CLI (cargo build --release --bin simgap) and set it")
        pytest.skip("SIMGAP_BIN is not set (cargo build --release --bin simgap; SIMGAP_BIN=$PWD/target/release/simgap)")
    return binary


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("demo")
    done = subprocess.run([simgap_bin(), "demo", "--out-dir", str(out)], capture_output=True, text=True, timeout=900, check=False)
    assert done.returncode == 0, done.stderr
    return out, done.stdout


def test_demo_writes_the_corrected_urdf_and_mjcf_and_the_lines_to_load_them(demo: tuple[Path, str]) -> None:
    out, stdout = demo
    for name in ("corrected.urdf", "corrected.xml", "corrected.urdf.effects.json", "corrected.xml.effects.json"):
        assert (out / name).is_file(), name
    lines = [line.strip() for line in stdout.splitlines()]
    pin_line = next(line for line in lines if "buildModelFromUrdf" in line)
    mj_line = next(line for line in lines if "MjModel.from_xml_path" in line)
    # the printed lines work as printed
    for line in (pin_line, mj_line):
        assert line.startswith("python -c ")
        code = line[len("python -c ") :].strip("'")
        subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, timeout=120)
    # the demo's saturation is a motor force range in the MJCF; the URDF's sidecar holds it
    urdf_side = json.loads((out / "corrected.urdf.effects.json").read_text())
    assert [e["effect"] for e in urdf_side["selected_effects"]] == ["torque_saturation"]
    assert "forcelimited=\"true\"" in (out / "corrected.xml").read_text()


def test_mujoco_predicts_the_demo_held_out_run_as_simgap_does(demo: tuple[Path, str]) -> None:
    out, _ = demo
    report = json.loads((out / "report.json").read_text())
    model = simgap.Model.from_urdf(out / "paper_arm.urdf")
    held = simgap.read_log(next(out.glob("holdout*.mcap")))
    check_kstep(model, held, report["selected_effects"], out / "corrected.xml", "simgap demo")
    gap = prediction_gap_without_dry_friction(model, held, report["selected_effects"], out / "corrected.xml")
    print(f"simgap demo: MuJoCo vs simgap without dry friction, 0.5 s windows: {gap:.1e} rad")
    assert gap < 1e-9


def test_export_errors_name_the_file_and_what_was_expected(diagnosed: tuple[simgap.Report, simgap.Run, Path], tmp_path: Path) -> None:
    report, _, _ = diagnosed
    pendulum = ROOT / "crates" / "simgap-core" / "models" / "pendulum.urdf"
    with pytest.raises(simgap.UrdfError, match=r"pendulum\.urdf: robot: .*not the URDF the model was loaded from"):
        report.export_urdf(tmp_path / "x.urdf", urdf=pendulum)
    with pytest.raises(simgap.UrdfError, match=r"missing\.urdf: cannot read"):
        report.export_urdf(tmp_path / "x.urdf", urdf=tmp_path / "missing.urdf")
    with pytest.raises(simgap.SimgapError, match=r"cannot write"):
        report.export_mjcf(tmp_path / "no-such-folder" / "x.xml")
    assert not (tmp_path / "x.urdf").exists()


# --- frames: a 7-DOF arm with rotated joints, fixed links merged and a prismatic finger --------

ARM7 = ROOT / "crates" / "simgap-core" / "models" / "arm7.urdf"
ARM7_TIP = "panda_leftfinger"
ARM7_KP = [200.0, 200, 100, 100, 20, 10, 4, 1]
ARM7_KV = [20.0, 20, 10, 10, 2, 1, 0.4, 0.05]
# friction only: this case checks frames (rotor inertia is checked on the paper's arm), and its
# diagnosis stays near a minute on two cores
ARM7_HIDDEN = ["viscous_friction:b=0.5,0.5,0.5,0.5,0.5,0.5,0.5,0.05"]


def arm7_reference(model: simgap.Model, seed: int, name: str, duration: float = 3.0) -> simgap.Run:
    """Smooth motion of every joint from q = 0 (the finger by 1 cm)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration + 1e-9, 0.0025)
    w = 2 * np.pi * rng.uniform(0.2, 0.8, model.dof)
    a = rng.uniform(0.1, 0.4, model.dof)
    a[-1] = 0.01
    q = a * (1 - np.cos(np.outer(t, w)))
    qd = a * w * np.sin(np.outer(t, w))
    return simgap.Run(model.joint_names, t, q, qd, q_ref=q, qd_ref=qd, source=name)


@pytest.fixture(scope="module")
def arm7(tmp_path_factory: pytest.TempPathFactory) -> tuple[simgap.Report, simgap.Model, simgap.Run, Path]:
    """The 7-DOF fixture to its left finger (rpy joint placements, rotated inertial frames, the
    flange and hand merged by fixed joints, the right finger locked, a prismatic last joint),
    with viscous friction hidden, diagnosed and exported."""
    model = simgap.Model.from_urdf(ARM7, tip=ARM7_TIP)

    def run(seed: int, name: str) -> simgap.Run:
        return simgap.simulate(model, arm7_reference(model, seed, name), controller="pd_gravity", kp=ARM7_KP, kv=ARM7_KV, effects=ARM7_HIDDEN)

    fit = [run(0, "fit-0"), run(1, "fit-1")]
    held = run(9, "held")
    report = simgap.diagnose(model, fit, [held], urdf=ARM7)
    out = tmp_path_factory.mktemp("arm7")
    report.export_urdf(out / "corrected.urdf")
    report.export_mjcf(out / "corrected.xml")
    return report, model, held, out


def test_arm7_mjcf_frames_give_simgaps_mass_matrix_and_gravity(arm7: tuple[simgap.Report, simgap.Model, simgap.Run, Path]) -> None:
    report, model, _, out = arm7
    m = mujoco.MjModel.from_xml_path(str(out / "corrected.xml"))
    d = mujoco.MjData(m)
    assert [m.joint(i).name for i in range(m.njnt)] == model.joint_names
    assert m.jnt_type[-1] == mujoco.mjtJoint.mjJNT_SLIDE
    # simgap's corrected model: the exported URDF loaded with the same tip (equal to the
    # simulator's corrected model, crates/simgap-diag/tests/export.rs), plus the armature
    corrected = simgap.Model.from_urdf(out / "corrected.urdf", tip=ARM7_TIP)
    armature = np.zeros(model.dof)
    for e in report.selected_effects:
        if e["effect"] == "armature":
            armature += per_joint(e, "ia", model.joint_names, 0.0)
    worst_h = worst_g = 0.0
    for q in random_states(model.dof, seed=11):
        q[-1] = 0.02 * q[-1] / np.pi
        d.qpos[:] = q
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        h = corrected.mass_matrix(q) + np.diag(armature)
        g = corrected.gravity_torques(q)
        worst_h = max(worst_h, np.abs(full_mass_matrix(m, d) - h).max() / np.abs(h).max())
        worst_g = max(worst_g, np.abs(d.qfrc_bias - g).max() / np.abs(g).max())
    print(f"arm7 MJCF: H rel. {worst_h:.1e}, g rel. {worst_g:.1e}")
    assert worst_h < 1e-9 and worst_g < 1e-9


def test_arm7_urdf_loads_in_pinocchio_with_the_chain_simgap_models(arm7: tuple[simgap.Report, simgap.Model, simgap.Run, Path]) -> None:
    # Pinocchio keeps the right finger movable: at its zero the chain's rows and columns of H
    # and g are simgap's, whose model locks it there
    report, model, _, out = arm7
    exported = pinocchio.buildModelFromUrdf(str(out / "corrected.urdf"))
    reference, _ = corrected_pinocchio(ARM7, report.selected_effects, last_joint=model.joint_names[-1])
    corrected = simgap.Model.from_urdf(out / "corrected.urdf", tip=ARM7_TIP)
    joints = [exported.joints[exported.getJointId(name)] for name in model.joint_names]
    idx = [j.idx_v for j in joints]
    d_e, d_r = exported.createData(), reference.createData()
    worst = 0.0
    for q8 in random_states(model.dof, seed=12):
        q8[-1] = 0.02 * q8[-1] / np.pi
        # Pinocchio's configuration: a continuous joint is (cos, sin), every other one angle
        q = pinocchio.neutral(exported)
        for j, v in zip(joints, q8):
            if j.nq == 2:
                q[j.idx_q : j.idx_q + 2] = [np.cos(v), np.sin(v)]
            else:
                q[j.idx_q] = v
        for pin_model, data in ((exported, d_e), (reference, d_r)):
            h = pinocchio.crba(pin_model, data, q)
            h = (np.triu(h) + np.triu(h, 1).T)[np.ix_(idx, idx)]
            g = pinocchio.computeGeneralizedGravity(pin_model, data, q)[idx]
            worst = max(worst, np.abs(h - corrected.mass_matrix(q8)).max() / np.abs(h).max(), np.abs(g - corrected.gravity_torques(q8)).max() / np.abs(g).max())
    print(f"arm7 URDF in Pinocchio: H, g rel. {worst:.1e}")
    assert worst < 1e-9


def test_arm7_mujoco_and_simgap_predict_alike_in_motion(arm7: tuple[simgap.Report, simgap.Model, simgap.Run, Path]) -> None:
    # in motion the Coriolis and centrifugal torques of the rotated frames enter too
    # (simgap does not simulate joint limits, and this motion leaves panda_joint4's range
    # [-3.07, -0.07] rad: with MuJoCo's limits on the two differ, as docs/guide/export.md says)
    report, model, held, out = arm7
    free = prediction_gap_without_dry_friction(model, held, report.selected_effects, out / "corrected.xml", limits=False)
    limited = prediction_gap_without_dry_friction(model, held, report.selected_effects, out / "corrected.xml")
    print(f"arm7: MuJoCo vs simgap without dry friction, 0.5 s windows: {free:.1e} rad (m); with MuJoCo's joint limits {limited:.1e}")
    assert free < 1e-8
    assert limited > 1e-3
