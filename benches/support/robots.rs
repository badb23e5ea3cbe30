//! Robots shared by `benches/dynamics.rs` and `examples/timings.rs`: the paper arm (built in),
//! UR5 and Panda from the PyPI package `example-robot-data` (located at run time, never copied
//! into the repository) and synthetic random chains.
//!
//! The `example-robot-data` robots directory (the one holding `ur_description/` and
//! `panda_description/`) is taken from `SIMGAP_ROBOTS_DIR`, else asked from the Python of the
//! repository's `.venv` (or `python3`), else the robot is skipped with a message on stderr.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use simgap::core::{Model, UrdfOptions};

/// A robot to time: its short name (the benchmark id), the model and where it came from.
pub(crate) struct Robot {
    pub(crate) name: String,
    pub(crate) model: Model,
    pub(crate) source: String,
}

/// UR5 and Panda: (name, path inside the robots directory, tip link). The Panda's tip is the
/// hand, so the two finger joints are merged, locked at zero, into the hand link.
pub(crate) const URDF_ROBOTS: [(&str, &str, Option<&str>); 2] =
    [("ur5", "ur_description/urdf/ur5_robot.urdf", None), ("panda", "panda_description/urdf/panda.urdf", Some("panda_hand"))];

/// Joint counts of the synthetic chains.
pub(crate) const CHAIN_SIZES: [usize; 6] = [2, 4, 8, 16, 32, 64];

/// The `example-robot-data` robots directory, or `None` with the reason.
pub(crate) fn robots_dir() -> Result<PathBuf, String> {
    if let Some(dir) = std::env::var_os("SIMGAP_ROBOTS_DIR") {
        let dir = PathBuf::from(dir);
        return if dir.is_dir() { Ok(dir) } else { Err(format!("SIMGAP_ROBOTS_DIR={} is not a directory", dir.display())) };
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let venv = root.join(".venv/bin/python");
    let pythons: Vec<PathBuf> = if venv.exists() { vec![venv] } else { vec![PathBuf::from("python3")] };
    // older releases ship a module whose getModelPath returns the robots directory; the
    // cmeel wheels (6.x) ship only data, under cmeel.prefix/share/example-robot-data/robots
    let code = concat!(
        "try:\n",
        "    import example_robot_data as e\n",
        "    print(e.getModelPath('ur_description/urdf/ur5_robot.urdf'))\n",
        "except ImportError:\n",
        "    import importlib.metadata as m\n",
        "    print(m.distribution('example-robot-data').locate_file('cmeel.prefix/share/example-robot-data/robots'))\n",
    );
    for py in pythons {
        if let Ok(out) = Command::new(&py).args(["-c", code]).output() {
            let dir = String::from_utf8_lossy(&out.stdout).trim().to_string();
            if out.status.success() && Path::new(&dir).is_dir() {
                return Ok(PathBuf::from(dir));
            }
        }
    }
    Err("example-robot-data not found: run `make venv` or set SIMGAP_ROBOTS_DIR to its robots directory".into())
}

/// Loads a URDF robot, with the chain ending at `tip` when given.
pub(crate) fn load_urdf(name: &str, path: &Path, tip: Option<&str>) -> Result<Robot, String> {
    let options = UrdfOptions { tip: tip.map(str::to_string) };
    let model = Model::from_urdf_file_with(path, &options).map_err(|e| format!("{name}: {e}"))?;
    Ok(Robot { name: name.into(), model, source: path.display().to_string() })
}

/// The paper arm, UR5 and Panda (those found), then the random chains when `chains`.
pub(crate) fn all_robots(chains: bool) -> Vec<Robot> {
    let mut robots = vec![Robot { name: "paper_arm".into(), model: Model::paper_arm(), source: "built-in".into() }];
    match robots_dir() {
        Ok(dir) => {
            for (name, rel, tip) in URDF_ROBOTS {
                match load_urdf(name, &dir.join(rel), tip) {
                    Ok(r) => robots.push(r),
                    Err(e) => eprintln!("skipping {name}: {e}"),
                }
            }
        }
        Err(e) => eprintln!("skipping ur5 and panda: {e}"),
    }
    if chains {
        for n in CHAIN_SIZES {
            robots.push(Robot { name: format!("chain{n}"), model: Model::random_chain(n, 42 + n as u64), source: format!("Model::random_chain({n}, {})", 42 + n) });
        }
    }
    robots
}

/// A joint state with its acceleration and torque.
#[derive(Clone, Debug)]
pub(crate) struct State {
    pub(crate) q: Vec<f64>,
    pub(crate) qd: Vec<f64>,
    pub(crate) qdd: Vec<f64>,
    pub(crate) tau: Vec<f64>,
}

/// `count` random states from `seed` (splitmix64): q within the limits (±π where unlimited,
/// ±0.5 m for prismatic), q̇ in ±2, q̈ in ±5, τ in ±20.
pub(crate) fn random_states(model: &Model, count: usize, seed: u64) -> Vec<State> {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    };
    let n = model.dof();
    (0..count)
        .map(|_| {
            let q = model
                .joints()
                .iter()
                .map(|j| {
                    let default = if j.kind.is_rotational() { std::f64::consts::PI } else { 0.5 };
                    let lo = if j.limits.lower.is_finite() { j.limits.lower } else { -default };
                    let hi = if j.limits.upper.is_finite() { j.limits.upper } else { default };
                    lo + (hi - lo) * next()
                })
                .collect();
            let mut uniform = |a: f64| -> Vec<f64> { (0..n).map(|_| a * (2.0 * next() - 1.0)).collect() };
            let qd = uniform(2.0);
            let qdd = uniform(5.0);
            let tau = uniform(20.0);
            State { q, qd, qdd, tau }
        })
        .collect()
}
