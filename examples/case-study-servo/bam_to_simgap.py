#!/usr/bin/env python3
"""Convert Rhoban BAM's Dynamixel XL330 pendulum logs into simgap's generic servo CSV logs.

Usage (from the repository root)::

    python3 examples/case-study-servo/bam_to_simgap.py \
        --data ../shared/data/rhoban-bam-xl330 --out /tmp/bam-simgap \
        [--priors ../shared/data/rhoban-bam-xl330/params/published/m1.json]

The data are Rhoban's (github.com/Rhoban/bam, Apache-2.0; see the README next to them). They
are read where they lie and never copied into this repository; the output goes to ``--out``.

Input: every ``raw/NAME.json`` under ``--data``. BAM's log JSON holds the bench metadata
(``mass`` [kg] point mass at the tip, ``length`` [m], firmware ``kp`` register, nominal supply
``vin`` [V]) and one entry per sample (``timestamp``, ``position``, ``speed``,
``goal_position``, ``torque_enable``, ``input_volts``, ``temp``, ``load``).

**Why ``raw/`` and never ``processed/``.** ``load`` in these logs is the XL330 *Present PWM*
register as the recorder of that date stored it: an unsigned 16-bit integer that holds a
two's-complement value (65535 is −1). The signed duty is ``int16(load) / 885`` (885 = the PWM
limit = 100 %). BAM's ``processed/`` files are a linear interpolation of the *unsigned*
values onto a 5 ms grid, so wherever the PWM changes sign they hold values between 0 and 65535
that mean nothing. Only the raw register can be decoded.

Output, per log, ``OUT/NAME.csv`` (one joint, named ``servo``), simgap's generic servo CSV
convention (the servo CSV columns of ``docs/guide/servos.md``):

=====================  ====================================================================
column                 meaning
=====================  ====================================================================
``time``               [s] the raw timestamp minus the first one (the log starts at 0). The
                       stamps are kept as recorded: they are **not uniform** (about 5.3 ms
                       while the torque is on, 3.5 ms while it is off).
``q_servo``            [rad] measured position (``position``, 2π/4096 steps; 0 = hanging down)
``qd_servo``           [rad/s] the servo's own speed register (``speed``, 0.02398 rad/s steps)
``q_ref_servo``        [rad] goal position just written (``goal_position``)
``duty_servo``         [–] measured PWM duty = int16(``load``)/885, in [−1, 1]
``torque_enable_servo`` 0/1 (``torque_enable``); with 0 the H-bridge is open and τ = 0
``voltage``            [V] measured input voltage (``input_volts``, 0.1 V steps, noisy);
                       written only with ``--voltage logged``: by default the column is
                       left out and simgap drives the servo with the nominal
                       ``supply_voltage``, as BAM's model does (the register is read once
                       per 5 ms sample while the PWM switches much faster, so one reading
                       is not the voltage the motor saw over the sample)
``temperature_servo``  [°C] winding/board temperature (``temp``), reported, not modelled
=====================  ====================================================================

``OUT/NAME.experiment.json``, the sidecar simgap reads beside ``NAME.csv`` (values as strings,
like the other sidecars in ``examples/case-study-dfki``): ``controller`` = ``servo``, ``joints`` =
``servo``, ``duty_gain`` = kp·(4096/2π)/(256·885) [1/rad] (BAM's XL330 law: the firmware's
duty is that gain times the position error, clipped to ±1; the logs follow it with ratio
0.96–1.00), ``max_duty`` = 1, ``supply_voltage`` = the nominal ``vin``; with ``--priors`` a BAM
parameter file also gives ``kt`` [N·m/A] and ``R`` [Ω] as priors, nothing else.

``OUT/pendulum.urdf``: the bench. One revolute joint ``servo`` about y, gravity −z, q = 0
hanging straight down (so the gravity torque is −m g l sin q, BAM's ``Pendulum``); a child link
holding the tip mass as a point mass ``length`` below the axis (given the inertia of a 5 mm
sphere so the inertia matrix is positive definite); an empty base link. No arm mass: the logs
log none and BAM then takes 0. The rotor inertia (armature) is not in the URDF: it is an effect
the diagnosis estimates.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

JOINT = "servo"
#: XL330 position-mode scaling (BAM ``bam/dynamixel/actuator.py``): encoder counts per turn,
#: the firmware's Kp divisor (empirical) and the PWM limit register (= 100 % duty).
ENCODER_COUNTS_PER_REV = 4096
KP_DIVISOR = 256
PWM_LIMIT = 885
#: duty per radian of error per unit of the Kp register.
XL330_ERROR_GAIN = (ENCODER_COUNTS_PER_REV / (2 * math.pi)) / (KP_DIVISOR * PWM_LIMIT)

COLUMNS = ["time", f"q_{JOINT}", f"qd_{JOINT}", f"q_ref_{JOINT}", f"duty_{JOINT}", f"torque_enable_{JOINT}", "voltage", f"temperature_{JOINT}"]


def pwm_register_to_duty(load: int) -> float:
    """The XL330 Present PWM register (unsigned 16 bit, two's complement) as a duty in [−1, 1]."""
    raw = int(load) & 0xFFFF
    signed = raw - 0x10000 if raw >= 0x8000 else raw
    return signed / PWM_LIMIT


def default_data_dir() -> Path:
    """``../shared/data/rhoban-bam-xl330`` relative to the repository root."""
    repo = Path(__file__).resolve().parents[2]
    return repo.parent / "shared" / "data" / "rhoban-bam-xl330"


def raw_logs(data: Path) -> list[Path]:
    """The raw BAM log files under ``data/raw``, sorted by name."""
    files = sorted((Path(data) / "raw").glob("*.json"))
    if not files:
        raise FileNotFoundError(f"no BAM raw logs (*.json) in {Path(data) / 'raw'}")
    return files


def load_raw(path: Path) -> dict:
    """One raw BAM log as plain Python lists: metadata plus per-sample columns.

    Returns a dict with ``name``, ``meta`` (mass, length, kp, vin, arm_mass = 0 when absent,
    as BAM's ``Logs`` does) and lists ``t`` (raw stamps, not shifted), ``q``, ``qd``,
    ``goal``, ``duty`` (decoded), ``torque_enable`` (0/1), ``voltage``, ``temp``, ``load``.
    """
    path = Path(path)
    with open(path) as f:
        log = json.load(f)
    entries = log["entries"]
    meta = {k: v for k, v in log.items() if k != "entries"}
    meta.setdefault("arm_mass", meta.pop("arm-mass", 0.0))
    return {
        "name": path.stem,
        "meta": meta,
        "t": [float(e["timestamp"]) for e in entries],
        "q": [float(e["position"]) for e in entries],
        "qd": [float(e["speed"]) for e in entries],
        "goal": [float(e["goal_position"]) for e in entries],
        "load": [int(e["load"]) for e in entries],
        "duty": [pwm_register_to_duty(e["load"]) for e in entries],
        "torque_enable": [1 if e["torque_enable"] else 0 for e in entries],
        "voltage": [float(e["input_volts"]) for e in entries],
        "temp": [float(e["temp"]) for e in entries],
    }


def duty_gain(kp: float) -> float:
    """BAM's XL330 duty per radian of position error at firmware gain ``kp``."""
    return kp * XL330_ERROR_GAIN


def _num(x: float) -> str:
    """A number as text: integers without a decimal point, others at full precision."""
    x = float(x)
    return str(int(x)) if x.is_integer() and abs(x) < 1e15 else repr(x)


def write_csv(log: dict, out: Path, logged_voltage: bool = False) -> None:
    t0 = log["t"][0]
    columns = COLUMNS if logged_voltage else [c for c in COLUMNS if c != "voltage"]
    with open(out, "w") as f:
        f.write(",".join(columns) + "\n")
        for i in range(len(log["t"])):
            row = [repr(log["t"][i] - t0), repr(log["q"][i]), repr(log["qd"][i]), repr(log["goal"][i]), repr(log["duty"][i]), str(log["torque_enable"][i])]
            row += [_num(log["voltage"][i])] if logged_voltage else []
            row += [_num(log["temp"][i])]
            f.write(",".join(row) + "\n")


def experiment(log: dict, priors: dict | None = None) -> dict:
    meta = log["meta"]
    exp = {
        "controller": "servo",
        "joints": JOINT,
        "duty_gain": repr(duty_gain(meta["kp"])),
        "max_duty": "1",
        "supply_voltage": _num(meta["vin"]),
    }
    if priors is not None:
        exp["kt"] = repr(float(priors["kt"]))
        exp["R"] = repr(float(priors["R"]))
    exp["note"] = (
        f"Rhoban BAM XL330 pendulum log {log['name']} (github.com/Rhoban/bam, Apache-2.0), trajectory {meta.get('trajectory')}, "
        f"firmware Kp register {meta['kp']}; duty_gain = kp*(4096/2pi)/(256*885) per rad (BAM's XL330 law); supply_voltage = nominal vin; "
        f"mass {meta['mass']} kg at {meta['length']} m, arm mass {meta['arm_mass']} kg"
        + (f"; priors kt, R from {priors.get('_source', 'a BAM params file')}" if priors is not None else "")
    )
    return exp


def pendulum_urdf(mass: float, length: float) -> str:
    r = 0.005
    i = 0.4 * mass * r * r
    return f"""<?xml version="1.0"?>
<!-- The Rhoban BAM XL330 pendulum bench (written by examples/case-study-servo/bam_to_simgap.py).
     The joint rotates about y, gravity is -z, q = 0 hangs straight down: the tip mass
     m = {mass} kg sits l = {length} m below the axis, so g(q) = m g l sin q (BAM's Pendulum).
     The mass is a point mass given the inertia of a 5 mm sphere (2/5 m r^2) so that the
     inertia is positive definite. No arm mass (not logged; BAM takes 0). The servo's rotor
     inertia (armature) is not here: it is an effect to estimate. -->
<robot name="bam_xl330_pendulum">
  <link name="base_link"/>
  <joint name="{JOINT}" type="revolute">
    <parent link="base_link"/>
    <child link="arm"/>
    <origin xyz="0 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-3.14159265358979" upper="3.14159265358979" effort="1.0" velocity="20"/>
  </joint>
  <link name="arm">
    <inertial>
      <origin xyz="0 0 {-length!r}" rpy="0 0 0"/>
      <mass value="{mass!r}"/>
      <inertia ixx="{i:.6g}" ixy="0" ixz="0" iyy="{i:.6g}" iyz="0" izz="{i:.6g}"/>
    </inertial>
  </link>
</robot>
"""


def convert(data: Path, out: Path, priors_file: Path | None = None, logged_voltage: bool = False) -> list[Path]:
    """Convert every raw log under ``data``; returns the CSV files written (with the logged
    input voltage as the ``voltage`` column when ``logged_voltage``)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    priors = None
    if priors_file is not None:
        with open(priors_file) as f:
            priors = json.load(f)
        priors["_source"] = f"{Path(priors_file).parent.name}/{Path(priors_file).name}"
    written = []
    bench = None
    for path in raw_logs(data):
        log = load_raw(path)
        meta = log["meta"]
        if bench is None:
            bench = (meta["mass"], meta["length"])
        elif bench != (meta["mass"], meta["length"]):
            raise ValueError(f"{path.name}: bench {meta['mass']} kg at {meta['length']} m differs from the first log's {bench}; one URDF cannot hold both")
        csv = out / f"{log['name']}.csv"
        write_csv(log, csv, logged_voltage)
        with open(out / f"{log['name']}.experiment.json", "w") as f:
            json.dump(experiment(log, priors), f, indent=2)
            f.write("\n")
        written.append(csv)
    (out / "pendulum.urdf").write_text(pendulum_urdf(*bench))
    return written


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=default_data_dir(), help="the rhoban-bam-xl330 folder (default: ../shared/data/rhoban-bam-xl330 beside the repository)")
    ap.add_argument("--out", type=Path, required=True, help="output folder (created); never inside the data folder")
    ap.add_argument("--priors", type=Path, default=None, help="a BAM params JSON whose kt and R go into the sidecars as priors")
    ap.add_argument("--voltage", choices=["nominal", "logged"], default="nominal", help="drive the servo with the nominal supply (default, as BAM) or the logged input voltage (a 'voltage' column)")
    args = ap.parse_args(argv)
    written = convert(args.data, args.out, args.priors, args.voltage == "logged")
    print(f"wrote {len(written)} logs (+ sidecars, pendulum.urdf) to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
