//! `simgap terms`: the dynamics terms as JSON lines (one object per state: `joints`, `q`, `qd`, `H`, `C`, `Hdot`, `g`), exactly the library's numbers.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{bail, Context};
use simgap::core::{coriolis_matrix_into, dynamics_terms_into, mass_matrix_derivative_into, DynamicsTerms, Model, Workspace};

/// Arguments of `simgap terms`.
#[derive(clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    model: super::ModelArgs,
    /// Joint positions, comma-separated, in model order.
    #[arg(long, allow_hyphen_values = true, requires = "qd", conflicts_with = "states")]
    q: Option<String>,
    /// Joint velocities, comma-separated, in model order.
    #[arg(long, allow_hyphen_values = true, requires = "q")]
    qd: Option<String>,
    /// CSV of states with header q_<joint>...,qd_<joint>...
    #[arg(long)]
    states: Option<PathBuf>,
}

fn parse_list(what: &str, s: &str, n: usize) -> anyhow::Result<Vec<f64>> {
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>().with_context(|| format!("--{what}: '{x}' is not a number"))).collect::<anyhow::Result<_>>()?;
    if v.len() != n {
        bail!("--{what}: expected {n} values (one per joint), got {}", v.len());
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        bail!("--{what}: expected finite numbers, got {x}");
    }
    Ok(v)
}

fn read_states(path: &std::path::Path, model: &Model) -> anyhow::Result<Vec<(Vec<f64>, Vec<f64>)>> {
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_path(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let header = rdr.headers().with_context(|| format!("{}: no header", path.display()))?.clone();
    let col = |name: String| -> anyhow::Result<usize> {
        header.iter().position(|h| h == name).with_context(|| format!("{}: missing column '{name}' (header must hold q_<joint> and qd_<joint> for every joint)", path.display()))
    };
    let names = model.joint_names();
    let qcols: Vec<usize> = names.iter().map(|n| col(format!("q_{n}"))).collect::<anyhow::Result<_>>()?;
    let qdcols: Vec<usize> = names.iter().map(|n| col(format!("qd_{n}"))).collect::<anyhow::Result<_>>()?;
    let mut out = Vec::new();
    for (line, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: row {}", path.display(), line + 2))?;
        let get = |c: usize| -> anyhow::Result<f64> {
            let s = rec.get(c).unwrap_or("");
            let v: f64 = s.parse().with_context(|| format!("{}: row {}, column '{}': '{s}' is not a number", path.display(), line + 2, &header[c]))?;
            if !v.is_finite() {
                bail!("{}: row {}, column '{}': expected a finite number, got {v}", path.display(), line + 2, &header[c]);
            }
            Ok(v)
        };
        let q = qcols.iter().map(|&c| get(c)).collect::<anyhow::Result<_>>()?;
        let qd = qdcols.iter().map(|&c| get(c)).collect::<anyhow::Result<_>>()?;
        out.push((q, qd));
    }
    Ok(out)
}

fn rows(m: &nalgebra::DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows()).map(|i| m.row(i).iter().copied().collect()).collect()
}

/// Every term finite, or an error naming the quantity and the joint (row) where it is not.
fn check_finite(names: &[&str], q: &[f64], qd: &[f64], terms: &DynamicsTerms, hdot: &nalgebra::DMatrix<f64>) -> anyhow::Result<()> {
    let matrices = [("H", &terms.mass_matrix), ("C", &terms.coriolis_matrix), ("Hdot", hdot)];
    let bad = matrices
        .iter()
        .find_map(|(what, m)| (0..m.nrows()).find_map(|i| m.row(i).iter().find(|v| !v.is_finite()).map(|v| (*what, i, *v))))
        .or_else(|| terms.gravity_torques.iter().enumerate().find(|(_, v)| !v.is_finite()).map(|(i, v)| ("g", i, *v)));
    if let Some((what, i, v)) = bad {
        bail!(
            "{what} is not finite in the row of joint '{}' ({v}) at q = {q:?}, qd = {qd:?}; expected finite results: positions or velocities this large overflow",
            names.get(i).copied().unwrap_or("?")
        );
    }
    Ok(())
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let model = args.model.load()?;
    let n = model.dof();
    let states = match (&args.q, &args.qd, &args.states) {
        (Some(q), Some(qd), None) => vec![(parse_list("q", q, n)?, parse_list("qd", qd, n)?)],
        (None, None, Some(p)) => read_states(p, &model)?,
        _ => bail!("give either --q Q --qd QD or --states STATES.csv"),
    };
    let mut ws = Workspace::new(&model);
    let mut terms = DynamicsTerms::new(&model);
    let mut hdot = nalgebra::DMatrix::zeros(n, n);
    let names = model.joint_names();
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    for (q, qd) in &states {
        dynamics_terms_into(&model, &mut ws, q, qd, args.model.formulation, &mut terms);
        mass_matrix_derivative_into(&model, &mut ws, q, qd, &mut hdot);
        // C again through its own entry point, so the output is exactly coriolis_matrix
        coriolis_matrix_into(&model, &mut ws, q, qd, args.model.formulation, &mut terms.coriolis_matrix);
        // results too large to represent are refused, naming where they first appear
        check_finite(&names, q, qd, &terms, &hdot)?;
        let line = serde_json::json!({
            "joints": names,
            "formulation": args.model.formulation.as_str(),
            "q": q,
            "qd": qd,
            "H": rows(&terms.mass_matrix),
            "C": rows(&terms.coriolis_matrix),
            "Hdot": rows(&hdot),
            "g": terms.gravity_torques.as_slice(),
        });
        writeln!(out, "{line}")?;
    }
    Ok(())
}
