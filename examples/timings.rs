//! Per-call timings of every dynamics function on one robot, as one JSON line: median over
//! repetitions of (time of one pass over all states) / (number of states), in nanoseconds.
//! `scripts/compare_pinocchio.py` runs it next to Pinocchio on the same URDFs and states.
//!
//! ```text
//! cargo run --release --example timings -- --urdf panda.urdf --tip panda_hand --states states.csv
//! cargo run --release --example timings -- --robot panda --count 1000 --seed 1
//! ```
//!
//! `--robot` takes `paper_arm`, `ur5`, `panda` (located as in `benches/support/robots.rs`) or
//! `chainN` (`Model::random_chain(N, 42 + N)`); `--urdf PATH [--tip LINK]` loads any URDF.
//! `--states` reads a CSV with columns `q_<joint>`, `qd_<joint>`, `qdd_<joint>`, `tau_<joint>`
//! (mapped by joint name; missing `qdd_`/`tau_` columns are zero); otherwise `--count` random
//! states from `--seed`. `--reps` repetitions (default 21). `--write-urdf PATH` writes the
//! robot as a URDF and exits (how the comparison script gives Pinocchio the random chains).

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use nalgebra::DMatrix;
use simgap::core::{
    bias_torques_into, coriolis_matrix_into, coriolis_torques_into, dynamics_terms_into, forward_dynamics_aba_into, forward_dynamics_crba_into, forward_dynamics_into,
    gravity_torques_into, inverse_dynamics_into, mass_matrix_derivative_into, mass_matrix_into, DynamicsTerms, Formulation, Model, Workspace,
};

#[path = "../benches/support/robots.rs"]
mod robots;

use robots::{all_robots, load_urdf, random_states, State};

struct Args {
    robot: Option<String>,
    urdf: Option<PathBuf>,
    tip: Option<String>,
    name: Option<String>,
    states: Option<PathBuf>,
    count: usize,
    seed: u64,
    reps: usize,
    write_urdf: Option<PathBuf>,
}

fn parse_args() -> anyhow::Result<Args> {
    let mut a = Args { robot: None, urdf: None, tip: None, name: None, states: None, count: 1000, seed: 1, reps: 21, write_urdf: None };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().with_context(|| format!("{flag} needs a value"));
        match flag.as_str() {
            "--robot" => a.robot = Some(value()?),
            "--urdf" => a.urdf = Some(value()?.into()),
            "--tip" => a.tip = Some(value()?),
            "--name" => a.name = Some(value()?),
            "--states" => a.states = Some(value()?.into()),
            "--count" => a.count = value()?.parse().context("--count")?,
            "--seed" => a.seed = value()?.parse().context("--seed")?,
            "--reps" => a.reps = value()?.parse().context("--reps")?,
            "--write-urdf" => a.write_urdf = Some(value()?.into()),
            "-h" | "--help" => {
                println!("timings (--robot NAME | --urdf PATH [--tip LINK]) [--name NAME] [--states CSV | --count N --seed S] [--reps R] [--write-urdf PATH]");
                std::process::exit(0);
            }
            other => bail!("unknown argument '{other}'"),
        }
    }
    if a.reps == 0 || a.count == 0 {
        bail!("--reps and --count must be positive");
    }
    Ok(a)
}

/// Reads states by joint name; `qdd_` and `tau_` columns are optional (zero when absent).
fn read_states(path: &Path, model: &Model) -> anyhow::Result<Vec<State>> {
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_path(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let header = rdr.headers()?.clone();
    let col = |prefix: &str, joint: &str| header.iter().position(|h| h == format!("{prefix}_{joint}"));
    let names = model.joint_names();
    let mut cols = Vec::new();
    for prefix in ["q", "qd", "qdd", "tau"] {
        let c: Vec<Option<usize>> = names.iter().map(|n| col(prefix, n)).collect();
        if matches!(prefix, "q" | "qd") && c.iter().any(Option::is_none) {
            bail!("{}: needs columns {prefix}_<joint> for joints {names:?}", path.display());
        }
        cols.push(c);
    }
    let mut out = Vec::new();
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec?;
        let get = |c: &[Option<usize>]| -> anyhow::Result<Vec<f64>> {
            c.iter()
                .map(|c| match c {
                    Some(c) => rec[*c].parse::<f64>().with_context(|| format!("{}: row {}: '{}' is not a number", path.display(), row + 2, &rec[*c])),
                    None => Ok(0.0),
                })
                .collect()
        };
        out.push(State { q: get(&cols[0])?, qd: get(&cols[1])?, qdd: get(&cols[2])?, tau: get(&cols[3])? });
    }
    if out.is_empty() {
        bail!("{}: no states", path.display());
    }
    Ok(out)
}

/// Buffers of the timed functions, allocated once.
struct Buffers {
    ws: Workspace,
    h: DMatrix<f64>,
    c: DMatrix<f64>,
    v: Vec<f64>,
    terms: DynamicsTerms,
}

type Timed = fn(&Model, &mut Buffers, &State);

/// The timed functions, named as the criterion groups of `benches/dynamics.rs`.
fn functions() -> Vec<(&'static str, Timed)> {
    const EL: Formulation = Formulation::EulerLagrange;
    vec![
        ("mass_matrix", |m, b, s| mass_matrix_into(m, &mut b.ws, &s.q, &mut b.h)),
        ("coriolis_matrix/euler_lagrange", |m, b, s| coriolis_matrix_into(m, &mut b.ws, &s.q, &s.qd, EL, &mut b.c)),
        ("coriolis_matrix/simplified", |m, b, s| coriolis_matrix_into(m, &mut b.ws, &s.q, &s.qd, Formulation::Simplified, &mut b.c)),
        ("coriolis_torques", |m, b, s| coriolis_torques_into(m, &mut b.ws, &s.q, &s.qd, EL, &mut b.v)),
        ("gravity_torques", |m, b, s| gravity_torques_into(m, &mut b.ws, &s.q, &mut b.v)),
        ("mass_matrix_derivative", |m, b, s| mass_matrix_derivative_into(m, &mut b.ws, &s.q, &s.qd, &mut b.c)),
        ("bias_torques", |m, b, s| bias_torques_into(m, &mut b.ws, &s.q, &s.qd, EL, &mut b.v)),
        ("inverse_dynamics", |m, b, s| inverse_dynamics_into(m, &mut b.ws, &s.q, &s.qd, &s.qdd, &mut b.v)),
        ("forward_dynamics", |m, b, s| forward_dynamics_into(m, &mut b.ws, &s.q, &s.qd, &s.tau, EL, &mut b.v)),
        // the two algorithms forward_dynamics picks from (ABA from ABA_MIN_DOF joints on)
        ("forward_dynamics_crba", |m, b, s| forward_dynamics_crba_into(m, &mut b.ws, &s.q, &s.qd, &s.tau, EL, &mut b.v)),
        ("forward_dynamics_aba", |m, b, s| forward_dynamics_aba_into(m, &mut b.ws, &s.q, &s.qd, &s.tau, EL, &mut b.v)),
        ("dynamics_terms", |m, b, s| dynamics_terms_into(m, &mut b.ws, &s.q, &s.qd, EL, &mut b.terms)),
        // H, C and g as three separate calls, to compare with dynamics_terms
        ("h_c_g_three_calls", |m, b, s| {
            mass_matrix_into(m, &mut b.ws, &s.q, &mut b.h);
            coriolis_matrix_into(m, &mut b.ws, &s.q, &s.qd, EL, &mut b.c);
            gravity_torques_into(m, &mut b.ws, &s.q, &mut b.v);
        }),
    ]
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn main() -> anyhow::Result<()> {
    let args = parse_args()?;
    let (name, model, source) = match (&args.robot, &args.urdf) {
        (Some(r), None) => {
            let robot = all_robots(true).into_iter().find(|x| &x.name == r).with_context(|| format!("robot '{r}' not available (see the messages above)"))?;
            (robot.name, robot.model, robot.source)
        }
        (None, Some(path)) => {
            let name = args.name.clone().unwrap_or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default());
            let robot = load_urdf(&name, path, args.tip.as_deref()).map_err(anyhow::Error::msg)?;
            (robot.name, robot.model, robot.source)
        }
        _ => bail!("give either --robot NAME or --urdf PATH"),
    };
    if let Some(path) = &args.write_urdf {
        std::fs::write(path, to_urdf(&model)).with_context(|| format!("{}: cannot write", path.display()))?;
        return Ok(());
    }
    let states = match &args.states {
        Some(p) => read_states(p, &model)?,
        None => random_states(&model, args.count, args.seed),
    };
    let n = model.dof();
    let mut b = Buffers { ws: Workspace::new(&model), h: DMatrix::zeros(n, n), c: DMatrix::zeros(n, n), v: vec![0.0; n], terms: DynamicsTerms::new(&model) };
    let mut results = serde_json::Map::new();
    for (function, f) in functions() {
        // one untimed pass to warm caches and branch predictors, then the timed repetitions
        let mut per_call = Vec::with_capacity(args.reps);
        for rep in 0..=args.reps {
            let start = Instant::now();
            for s in &states {
                f(&model, &mut b, black_box(s));
                black_box(&b.v);
            }
            let ns = start.elapsed().as_nanos() as f64 / states.len() as f64;
            if rep > 0 {
                per_call.push(ns);
            }
        }
        black_box((&b.h, &b.c, &b.terms));
        results.insert(function.to_string(), serde_json::json!(median(per_call)));
    }
    let out = serde_json::json!({
        "robot": args.name.clone().unwrap_or(name),
        "source": source,
        "dof": n,
        "joints": model.joint_names(),
        "states": states.len(),
        "reps": args.reps,
        "unit": "ns per call, median over repetitions of one pass over all states",
        "ns_per_call": results,
    });
    println!("{out}");
    Ok(())
}

/// The model as a URDF: one link per joint (inertia about its centre of mass), joint origins
/// as xyz + roll-pitch-yaw, gravity not included (URDF has none).
fn to_urdf(model: &Model) -> String {
    use std::fmt::Write;
    let mut s = format!("<?xml version=\"1.0\"?>\n<robot name=\"{}\">\n  <link name=\"{}\"/>\n", model.name(), model.base_link());
    let mut parent = model.base_link().to_string();
    for j in model.joints() {
        let (com, i) = (j.inertia.com(), j.inertia.inertia_about_com());
        let _ = write!(
            s,
            "  <link name=\"{}\">\n    <inertial>\n      <origin xyz=\"{:e} {:e} {:e}\" rpy=\"0 0 0\"/>\n      <mass value=\"{:e}\"/>\n      \
             <inertia ixx=\"{:e}\" ixy=\"{:e}\" ixz=\"{:e}\" iyy=\"{:e}\" iyz=\"{:e}\" izz=\"{:e}\"/>\n    </inertial>\n  </link>\n",
            j.link,
            com.x,
            com.y,
            com.z,
            j.inertia.mass,
            i[(0, 0)],
            i[(0, 1)],
            i[(0, 2)],
            i[(1, 1)],
            i[(1, 2)],
            i[(2, 2)]
        );
        let (roll, pitch, yaw) = nalgebra::Rotation3::from_matrix_unchecked(j.placement.rotation).euler_angles();
        let t = &j.placement.translation;
        let l = &j.limits;
        let limit = if l.lower.is_finite() { format!("lower=\"{:e}\" upper=\"{:e}\" ", l.lower, l.upper) } else { String::new() };
        let _ = write!(
            s,
            "  <joint name=\"{}\" type=\"{}\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    <origin xyz=\"{:e} {:e} {:e}\" rpy=\"{:e} {:e} {:e}\"/>\n    \
             <axis xyz=\"{:e} {:e} {:e}\"/>\n    <limit {limit}effort=\"{:e}\" velocity=\"{:e}\"/>\n  </joint>\n",
            j.name,
            j.kind.as_str(),
            parent,
            j.link,
            t.x,
            t.y,
            t.z,
            roll,
            pitch,
            yaw,
            j.axis.x,
            j.axis.y,
            j.axis.z,
            l.effort.min(1e9),
            l.velocity.min(1e9)
        );
        parent = j.link.clone();
    }
    s + "</robot>\n"
}
