//! Times a full diagnosis on the 7-DOF test arm: 60 s of 500 Hz logs (three 15 s fit runs and
//! one 15 s held-out run) with a hidden viscous friction on joint 2.
//!
//! `cargo run --release --example diagnose_timing [-- --seconds 15]`

use std::time::Instant;

use simgap::core::{Formulation, Model, UrdfOptions, ARM7_URDF};
use simgap::diag::bench::{gains_for, generate, random_fourier, RefSpec, RunSpec};
use simgap::diag::{diagnose, DiagnoseOptions};
use simgap::sim::{ControllerKind, Effect};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seconds: f64 = args.iter().position(|a| a == "--seconds").and_then(|i| args.get(i + 1)).map_or(Ok(15.0), |s| s.parse())?;
    let model = Model::from_urdf_str_with(ARM7_URDF, "arm7.urdf", &UrdfOptions { tip: Some("panda_hand".into()) })?;
    let n = model.dof();
    let (kp, kv) = gains_for(&model, 3.0);
    let mut b = vec![0.0; n];
    b[1] = 2.0;
    let effects = vec![Effect::ViscousFriction { b }];
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(7);
    let spec = |name: &str, rng: &mut rand_chacha::ChaCha8Rng| RunSpec {
        name: name.into(),
        controller: ControllerKind::PdGravity,
        kp: kp.clone(),
        kv: kv.clone(),
        reference: RefSpec::Fourier(random_fourier(n, 0.5, rng)),
        duration: seconds,
    };
    let t = Instant::now();
    let fit: Vec<_> =
        ["fit0", "fit1", "fit2"].iter().map(|s| generate(&model, Formulation::EulerLagrange, &effects, &spec(s, &mut rng), 0.002, 1_024_000.0)).collect::<Result<_, _>>()?;
    let hold = vec![generate(&model, Formulation::EulerLagrange, &effects, &spec("holdout", &mut rng), 0.002, 1_024_000.0)?];
    let samples: usize = fit.iter().chain(&hold).map(|r| r.len()).sum();
    println!("generated {} s of 500 Hz logs ({samples} samples, 7 joints) in {:.2} s", 4.0 * seconds, t.elapsed().as_secs_f64());
    let t = Instant::now();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {})?;
    println!("diagnosis: {:.2} s wall ({} rayon threads)", t.elapsed().as_secs_f64(), rayon::current_num_threads());
    println!("{}", d.report.verdict);
    Ok(())
}
