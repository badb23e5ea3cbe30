//! Servos with a hidden torque limit, simulated: the servo draws of `simgap selfcheck`
//! ([`selfcheck::servo_draw`] without the self-check's own limit; seed SEED, scenarios
//! 0..COUNT) with the drive of their first joint limited to 0.6 of the
//! pendulum's gravity torque at the horizontal (or of the servo's stall torque, if smaller), and
//! goals large enough to reach it. Prints, per scenario, the hidden effects, whether a fit log
//! shows the servo stalled (and so whether the intervals took the delete-one-log jackknife), the
//! selected effects with their 95 % half-widths (`*`: not established), the most torque the
//! corrected drive delivers against the hidden limit, and whether the mechanical effects
//! selected are the hidden ones; then the counts. Not part of the self-check: a measurement
//! quoted in `docs/results/case-study-servo.md`.
//!
//! `cargo run --release --example servo_limit -- [SEED] [COUNT]` (default 3 and 12)

use std::collections::BTreeSet;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use simgap::core::Formulation;
use simgap::diag::bench::{generate_servo, random_fourier};
use simgap::diag::{diagnose, selfcheck, DiagnoseOptions, Param};
use simgap::sim::{Effect, EffectKind};

/// The hidden limit as a share of the gravity torque at the horizontal.
const LIMIT_SHARE: f64 = 0.6;

/// The drive's own effect beside the corrections of its fitted motor constants
/// ([`selfcheck::MOTOR_CONSTANTS`]): the limit itself.
const LIMIT: EffectKind = EffectKind::TorqueSaturation;

struct Outcome {
    text: String,
    stalled: bool,
    limit_within_15: bool,
    mechanics_right: bool,
}

fn one(seed: u64, i: usize) -> Result<Outcome, String> {
    let sc = selfcheck::servo_draw(seed, i, false).map_err(|e| e.to_string())?;
    let servo = sc.servo.clone().ok_or("no servo")?;
    let model = sc.model.clone();
    let n = model.dof();
    let gravity: f64 = model.joints().iter().map(|j| j.inertia.mass).sum::<f64>() * 9.81 * 0.5;
    let stall = servo.kt[0] * servo.volts / servo.r[0];
    let limit = LIMIT_SHARE * gravity.max(1.0).min(stall);
    let mut effects = sc.effects.clone();
    effects.push(Effect::TorqueSaturation { limit: (0..n).map(|j| if j == 0 { limit } else { f64::INFINITY }).collect() });
    // goals larger than the self-check's (0.5 and 0.7 rad), to reach the limit
    let amplitude = if n > 1 { 0.9 } else { 1.2 };
    let mut rng = ChaCha8Rng::seed_from_u64(1000 + i as u64);
    let mut log =
        |off: f64, name: &str| generate_servo(&model, &effects, &servo, &random_fourier(n, amplitude, &mut rng), 8.0, off, 0.005, 1_024_000.0, name).map_err(|e| e.to_string());
    let fit = vec![log(5.0, "fit0")?, log(5.0, "fit1")?, log(f64::INFINITY, "fit2")?];
    let hold = vec![log(f64::INFINITY, "held-out")?];
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).map_err(|e| e.to_string())?;
    let r = &d.report;
    let stalled = r.notes.iter().any(|n| n.contains("delete-one-log jackknife"));
    let per_joint = |kind: EffectKind, key: &str| {
        r.selected_effects.iter().find(|e| e.effect == kind).and_then(|e| match e.parameters.get(key) {
            Some(Param::PerJoint(v)) => v.first().copied(),
            _ => None,
        })
    };
    let most = per_joint(LIMIT, "limit").map(|l| l * per_joint(EffectKind::TorqueGain, "k").unwrap_or(1.0));
    let names = model.joint_names();
    let hidden: BTreeSet<String> =
        sc.effects.iter().flat_map(|e| e.joints_acted().into_iter().map(move |j| (e.name().to_string(), j))).map(|(e, j)| format!("{e}@{}", names[j])).collect();
    let mechanics: BTreeSet<String> = r
        .selected_effects
        .iter()
        .filter(|e| e.effect != LIMIT && !selfcheck::MOTOR_CONSTANTS.contains(&e.effect.as_str()))
        .flat_map(|e| e.joints.iter().map(move |j| format!("{}@{j}", e.effect)))
        .collect();
    let selected: Vec<String> = r
        .selected_effects
        .iter()
        .map(|e| {
            let params: Vec<String> = e
                .parameters
                .iter()
                .filter_map(|(k, v)| match (v, e.uncertainty.get(k)) {
                    (Param::PerJoint(x), Some(Param::PerJoint(u))) if u.first().is_some_and(|u| u.is_finite()) => Some(format!("{k} = {:.4} ± {:.4}", x[0], u[0])),
                    (Param::PerJoint(x), _) if k != "w" && k != "periods_per_rev" => Some(format!("{k} = {:.4}", x[0])),
                    _ => None,
                })
                .collect();
            format!("{}({}){}", e.effect, params.join(", "), if e.description.contains("not established") { "*" } else { "" })
        })
        .collect();
    let limit_within_15 = most.is_some_and(|m| (m / limit - 1.0).abs() <= 0.15);
    let mechanics_right = mechanics == hidden;
    let text = format!(
        "scenario {i} ({} joint{}): hidden {} and a limit of {limit:.3} N·m on {}; stalled: {}; most torque {}; mechanics {}\n    selected: {}",
        n,
        if n > 1 { "s" } else { "" },
        hidden.iter().cloned().collect::<Vec<_>>().join(", "),
        names[0],
        if stalled { "yes (jackknife)" } else { "no" },
        most.map_or("none".to_string(), |m| format!("{m:.3} N·m ({:+.0} %)", 100.0 * (m / limit - 1.0))),
        if mechanics_right { "right" } else { "wrong" },
        selected.join("; ")
    );
    Ok(Outcome { text, stalled, limit_within_15, mechanics_right })
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (seed, count) = match (args.first().map(|s| s.parse::<u64>()), args.get(1).map(|s| s.parse::<usize>())) {
        (None | Some(Ok(_)), None | Some(Ok(_))) if args.len() <= 2 => {
            (args.first().and_then(|s| s.parse().ok()).unwrap_or(3), args.get(1).and_then(|s| s.parse().ok()).unwrap_or(12))
        }
        _ => {
            eprintln!("usage: servo_limit [SEED] [COUNT] (unsigned integers; default 3 and 12), got {args:?}");
            std::process::exit(2);
        }
    };
    let outcomes: Vec<Result<Outcome, String>> = (0..count).into_par_iter().map(|i| one(seed, i)).collect();
    let mut done = Vec::new();
    for (i, o) in outcomes.into_iter().enumerate() {
        match o {
            Ok(o) => {
                println!("{}", o.text);
                done.push(o);
            }
            Err(e) => println!("scenario {i}: {e}"),
        }
    }
    let count_of = |f: &dyn Fn(&Outcome) -> bool| done.iter().filter(|o| f(o)).count();
    let stalled = count_of(&|o| o.stalled);
    println!(
        "{} scenarios diagnosed; stalled: {stalled}; most torque within 15 % of the limit: {} of the stalled, {} of the others; mechanical effects right: {} of the stalled, {} of the others",
        done.len(),
        count_of(&|o| o.stalled && o.limit_within_15),
        count_of(&|o| !o.stalled && o.limit_within_15),
        count_of(&|o| o.stalled && o.mechanics_right),
        count_of(&|o| !o.stalled && o.mechanics_right),
    );
}
