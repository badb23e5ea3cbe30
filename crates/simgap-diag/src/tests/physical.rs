//! Physically consistent answers: bounded fits keep friction, rotor inertia and payload mass
//! non-negative; inertial corrections keep every link physical (mass > 0, positive-definite
//! pseudo-inertia, centre of mass within reach); no selected effect and no candidate of a
//! diagnosis, on synthetic runs and on the DFKI hardware runs, is physically impossible.
//!
//! The DFKI part needs `../shared/data` next to the repository; without it, it prints why and
//! passes.

use super::common::{have_data, replay, shared_data};
use crate::check::bench::{demo_specs, generate};
use crate::lsq::bounded::{solve, solve_bounded};
use crate::lsq::inertial::{link_is_physical, link_reach};
use crate::lsq::Problem;
use crate::prepare::align_run;
use crate::select::{parameter_scales, Context};
use crate::vocabulary::effects;
use crate::vocabulary::fit_terms;
use crate::vocabulary::Term;
use crate::{diagnose, DiagnoseOptions, EffectReport, FitData, Param, PrepareOptions};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use simgap_core::{inertial_parameters, Formulation, Model, SpatialInertia};
use simgap_sim::{Effect, LinkDelta, Run};

/// Fit data of the paper arm's demo runs with hidden `effects`.
pub(super) fn paper_arm_data(effects: &[Effect]) -> (Model, Vec<FitData>, Vec<Run>, Vec<Run>) {
    let model = Model::paper_arm();
    let (fit, hold) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, effects, s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<Run> = fit.iter().map(gen).collect();
    let hold: Vec<Run> = hold.iter().map(gen).collect();
    let data = fit.iter().map(|r| FitData::new(&model, Formulation::EulerLagrange, align_run(&model, r).unwrap(), &PrepareOptions::default()).unwrap()).collect();
    (model, data, fit, hold)
}

#[test]
fn bounded_fit_keeps_coulomb_non_negative() {
    let (_, data, _, _) = paper_arm_data(&[Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.01; 2] }]);
    let mut p = Problem::new(&data);
    let terms = [Term::Coulomb { joint: 0, w: 0.01 }, Term::Coulomb { joint: 1, w: 0.01 }];
    // friction that dissipates: recovered
    let (_, _, f) = fit_terms(&p, &data, &terms);
    assert!((f.theta[0] - 7.17).abs() < 0.1 * 7.17 && (f.theta[1] - 1.734).abs() < 0.1 * 1.734, "fc = {}", f.theta);
    // the same residual with the opposite sign (friction that would feed energy in): the
    // unconstrained fit is negative, the bounded one stops at fc = 0
    for v in std::sync::Arc::make_mut(&mut p.y.values).iter_mut() {
        *v = -*v;
    }
    let (_, gr, f) = fit_terms(&p, &data, &terms);
    let (g, c) = (gr.g.iter().fold(DMatrix::zeros(2, 2), |a, b| a + b), gr.c.iter().fold(DVector::zeros(2), |a, b| a + b));
    let (free, _) = solve(&g, &c);
    assert!(free[0] < 0.0 && free[1] < 0.0, "the unconstrained fit is negative: {free}");
    assert!(f.theta.iter().all(|&v| v == 0.0), "bounded fc = {}", f.theta);
}

#[test]
fn bounded_fits_keep_viscous_armature_stribeck_and_payload_physical() {
    let (model, data, _, _) = paper_arm_data(&[Effect::ViscousFriction { b: vec![2.288, 0.175] }, Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.01; 2] }]);
    let mut p = Problem::new(&data);
    for v in std::sync::Arc::make_mut(&mut p.y.values).iter_mut() {
        *v = -*v;
    }
    let terms =
        [Term::Viscous(0), Term::Armature(1), Term::Stribeck { joint: 0, vs: 0.1, w: 0.01 }, Term::Gain(1), Term::Payload { com: [0.2, 0.0, 0.0], max_mass: f64::INFINITY }];
    let (designs, gr, f) = fit_terms(&p, &data, &terms);
    let std = crate::lsq::bootstrap_std(&gr, 20, 3);
    let fitted = crate::vocabulary::fitted_terms(&terms, &designs, &f.theta, Some(&std));
    for t in &fitted {
        assert!(crate::vocabulary::physical(&t.term, &t.theta), "{:?}: {:?}", t.term, t.theta);
    }
    let th: Vec<f64> = fitted.iter().flat_map(|t| t.theta.clone()).collect();
    // b ≥ 0, ia ≥ 0, 0 ≤ fc ≤ fs, k in [0.2, 5], payload mass ≥ 0
    assert!(th[0] >= 0.0 && th[1] >= 0.0 && th[2] >= 0.0 && th[3] >= th[2] && (0.2..=5.0).contains(&(1.0 - th[4])) && th[5] >= 0.0, "{th:?}");
    // and they simulate
    let effects = effects::to_effects(&model, &fitted);
    simgap_sim::effects::validate_effects(&effects, model.dof()).expect("the bounded fit is a valid simulator effect");
}

#[test]
fn bounded_solve_satisfies_the_optimality_conditions() {
    // random convex quadratics with boxes: at the answer, free parameters have zero gradient and
    // parameters at a bound have the gradient pointing out of the box
    let mut seed = 12345u64;
    let mut rnd = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    for _ in 0..200 {
        let k = 5;
        let a = DMatrix::from_fn(8, k, |_, _| rnd());
        let g = a.transpose() * &a;
        let c = DVector::from_fn(k, |_, _| 3.0 * rnd());
        let lo: Vec<f64> = (0..k).map(|i| if i % 2 == 0 { 0.0 } else { f64::NEG_INFINITY }).collect();
        let hi: Vec<f64> = (0..k).map(|i| if i == 3 { 0.5 } else { f64::INFINITY }).collect();
        let (th, _) = solve_bounded(&g, &c, &lo, &hi);
        let w = &c - &g * &th;
        for i in 0..k {
            assert!(th[i] >= lo[i] - 1e-12 && th[i] <= hi[i] + 1e-12, "θ{i} = {} outside [{}, {}]", th[i], lo[i], hi[i]);
            let at_lo = th[i] <= lo[i] + 1e-12;
            let at_hi = th[i] >= hi[i] - 1e-12;
            let tol = 1e-7 * (1.0 + c.amax());
            assert!((at_lo && w[i] <= tol) || (at_hi && w[i] >= -tol) || w[i].abs() <= tol, "KKT at θ{i} = {}: gradient {}", th[i], -w[i]);
        }
    }
}

/// The link inertia after an inertial-error delta (the simulator's rule: new = old + delta, the
/// inertia delta about the new centre of mass).
fn corrected(model: &Model, d: &LinkDelta) -> SpatialInertia {
    let old = &model.joints()[d.joint].inertia;
    let c = old.com() + Vector3::from(d.com);
    let i = old.inertia_about_com() + Matrix3::new(d.inertia[0], d.inertia[1], d.inertia[2], d.inertia[1], d.inertia[3], d.inertia[4], d.inertia[2], d.inertia[4], d.inertia[5]);
    SpatialInertia::from_com(old.mass + d.mass, c, i)
}

#[test]
fn inertial_fit_recovers_known_link_mass_from_synthetic_data() {
    // the elbow link 0.8 kg heavier (centre of mass and inertia about it unchanged): its first
    // moment m c (what gravity and the motion see of its mass) rises by 21 %
    let truth = LinkDelta { joint: 1, mass: 0.8, com: [0.0; 3], inertia: [0.0; 6] };
    let (model, data, _, _) = paper_arm_data(&[Effect::InertialError { deltas: vec![truth.clone()] }]);
    let prior = parameter_scales(&model);
    let ctx = Context::new(&data, 0.0025, &prior);
    let term = ctx.inertial_term();
    let (designs, _, f) = fit_terms(&ctx.problem, &data, std::slice::from_ref(&term));
    let fitted = crate::vocabulary::fitted_terms(std::slice::from_ref(&term), &designs, &f.theta, None);
    assert!(crate::vocabulary::physical(&fitted[0].term, &fitted[0].theta));
    let Some(Effect::InertialError { deltas }) = effects::to_effects(&model, &fitted).into_iter().next() else { panic!("no inertial effect") };
    let reach = link_reach(&model);
    for d in &deltas {
        let s = corrected(&model, d);
        assert!(link_is_physical(&inertial_parameters(&s), reach[d.joint] * 1.000001), "link {} not physical: {s:?}", d.joint);
    }
    let elbow = deltas.iter().find(|d| d.joint == 1).expect("the elbow link is corrected");
    let (found, want) = (corrected(&model, elbow), corrected(&model, &truth));
    let (h_found, h_want) = (found.first_moment.norm(), want.first_moment.norm());
    assert!((h_found - h_want).abs() < 0.03 * h_want, "elbow link first moment {h_found} kg·m, truth {h_want}");
    assert!(elbow.mass > 0.0, "the elbow link gets heavier: Δm = {}", elbow.mass);
    let r = effects::to_reports(&model, &fitted);
    assert!(r[0].description.contains("mass +"), "{}", r[0].description);
}

#[test]
fn inertial_fit_of_a_fold_started_from_the_whole_fit_reaches_the_same_minimum() {
    // the cross-validation folds and the resamples start from the fit on all data: the problem
    // is convex in the inertial parameters, so the start must not change the minimum
    let truth = LinkDelta { joint: 1, mass: 0.8, com: [0.0; 3], inertia: [0.0; 6] };
    let (model, data, _, _) = paper_arm_data(&[Effect::InertialError { deltas: vec![truth] }]);
    let prior = parameter_scales(&model);
    let ctx = Context::new(&data, 0.0025, &prior);
    let design = ctx.design(&ctx.inertial_term());
    let gr = crate::lsq::grams(&ctx.problem, &[&design]);
    let (g, c, _) = crate::lsq::sum_blocks(&gr, |_, _| true);
    let (_, start) = gr.solve_from(&g, &c, None);
    assert!(start.is_some(), "an inertial correction has a start");
    let (gf, cf, _) = crate::lsq::sum_blocks(&gr, |b, _| b / crate::lsq::BLOCKS_PER_FOLD != 0);
    let (cold, _) = gr.solve_from(&gf, &cf, None);
    let (warm, _) = gr.solve_from(&gf, &cf, start.as_ref());
    let objective = |th: &nalgebra::DVector<f64>| 0.5 * th.dot(&(&gf * th)) - cf.dot(th);
    let (f_cold, f_warm) = (objective(&cold), objective(&warm));
    assert!((f_warm - f_cold).abs() <= 1e-5 * f_cold.abs(), "fold objective from the URDF {f_cold}, from the whole fit {f_warm}");
    // the mass-weighted directions the data see agree: the elbow's first moment
    let h = |th: &nalgebra::DVector<f64>, i: usize| design.inertial.as_ref().unwrap().corrected(th.as_slice(), 1)[i];
    for i in 1..4 {
        assert!((h(&cold, i) - h(&warm, i)).abs() < 1e-3 * (1.0 + h(&cold, i).abs()), "elbow first moment {i}: {} from the URDF, {} from the whole fit", h(&cold, i), h(&warm, i));
    }
}

/// Asserts that a reported effect is physically possible on `model`.
fn assert_physical(model: &Model, e: &EffectReport, delivered: &[f64], what: &str) {
    let list = |k: &str| match e.parameters.get(k) {
        Some(Param::PerJoint(v)) => v.clone(),
        Some(Param::Number(x)) => vec![*x],
        _ => vec![],
    };
    let reach = link_reach(model);
    match e.effect.as_str() {
        "viscous_friction" | "coulomb_friction" | "armature" => {
            for (k, v) in e.parameters.iter() {
                if let Param::PerJoint(v) = v {
                    assert!(v.iter().all(|x| *x >= 0.0), "{what}: {} {k} = {v:?}", e.effect);
                }
            }
        }
        "stribeck_friction" => {
            let (fc, fs) = (list("fc"), list("fs"));
            assert!(fc.iter().zip(&fs).all(|(c, s)| *c >= 0.0 && *s >= *c - 1e-12), "{what}: Stribeck fc {fc:?} fs {fs:?}");
        }
        "torque_gain" => assert!(list("k").iter().all(|k| (0.2 - 1e-9..=5.0 + 1e-9).contains(k)), "{what}: gain {:?}", list("k")),
        "payload" => {
            assert!(list("mass").iter().all(|m| *m >= 0.0), "{what}: payload mass {:?}", list("mass"));
            if let Some(Param::Vector(c)) = e.parameters.get("com") {
                let n = c.iter().map(|x| x * x).sum::<f64>().sqrt();
                assert!(n <= reach[model.dof() - 1] * 1.000001, "{what}: payload COM {c:?} beyond reach {}", reach[model.dof() - 1]);
            }
        }
        "torque_saturation" => {
            for (j, l) in e.joints.iter().zip(list("limit")) {
                let i = model.joint_index(j).unwrap();
                assert!(l >= delivered.get(i).copied().unwrap_or(0.0), "{what}: saturation {l} on {j} below the delivered {}", delivered[i]);
            }
        }
        "inertial_error" => {
            let (Some(Param::PerJoint(dm)), Some(Param::PerLink(dc)), Some(Param::PerLink(di))) =
                (e.parameters.get("delta_mass"), e.parameters.get("delta_com"), e.parameters.get("delta_inertia"))
            else {
                panic!("{what}: inertial_error without delta_mass/com/inertia: {e:?}")
            };
            for (k, j) in e.joints.iter().enumerate() {
                let i = model.joint_index(j).unwrap();
                let d = LinkDelta { joint: i, mass: dm[k], com: [dc[k][0], dc[k][1], dc[k][2]], inertia: std::array::from_fn(|a| di[k][a]) };
                let s = corrected(model, &d);
                assert!(s.mass > 0.0, "{what}: link of {j} mass {}", s.mass);
                assert!(link_is_physical(&inertial_parameters(&s), reach[i] * 1.000001), "{what}: link of {j} not physical or COM {:?} beyond reach {}: {s:?}", s.com(), reach[i]);
            }
        }
        _ => {}
    }
}

fn assert_report_physical(model: &Model, d: &crate::Diagnosis, delivered: &[f64], name: &str) {
    for e in &d.report.selected_effects {
        assert_physical(model, e, delivered, &format!("{name}, selected"));
        assert!(!e.description.is_empty(), "{name}: {} has no description", e.effect);
    }
    for c in &d.report.candidates {
        let e = EffectReport {
            effect: c.effect,
            joints: c.joints.clone(),
            parameters: c.parameters.clone(),
            uncertainty: Default::default(),
            units: Default::default(),
            description: String::new(),
        };
        assert_physical(model, &e, delivered, &format!("{name}, candidate"));
        assert!(!c.reason.contains("not physical"), "{name}: candidate {} left unsimulated: {}", c.effect, c.reason);
    }
}

#[test]
fn no_effect_is_physically_impossible_on_synthetic_runs() {
    // a heavier elbow link plus friction that dissipates
    let effects = [Effect::InertialError { deltas: vec![LinkDelta { joint: 1, mass: 1.0, com: [0.0; 3], inertia: [0.0; 6] }] }, Effect::ViscousFriction { b: vec![2.288, 0.175] }];
    let (model, _, fit, hold) = paper_arm_data(&effects);
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    println!("{}", d.report.summary());
    assert_report_physical(&model, &d, &[], "paper arm");
}

#[test]
fn no_effect_is_physically_impossible_in_selfcheck_scenarios() {
    // blind scenarios of the self-check (robots, hidden effects, open and closed loop)
    for index in 0..4 {
        let sc = crate::check::selfcheck::scenario(3, index).unwrap();
        let d = diagnose(&sc.model, Formulation::EulerLagrange, &sc.fit, &sc.holdout, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
        let truth: Vec<&str> = sc.effects.iter().map(|e| e.name()).collect();
        let found: Vec<&str> = d.report.selected_effects.iter().map(|e| e.effect.as_str()).collect();
        println!("scenario {index} ({}, {}): hidden {truth:?}, selected {found:?}", sc.model.name(), sc.family);
        assert_report_physical(&sc.model, &d, &[], &format!("self-check scenario {index}"));
    }
}

/// The first `seconds` of a run.
fn head(mut run: Run, seconds: f64) -> Run {
    let dof = run.dof();
    let n = run.t.iter().take_while(|&&t| t - run.t[0] <= seconds).count();
    run.t.truncate(n);
    for m in [&mut run.q, &mut run.qd, &mut run.tau, &mut run.q_ref, &mut run.qd_ref, &mut run.tau_ff, &mut run.tau_measured] {
        if !m.is_empty() {
            m.truncate(n * dof);
        }
    }
    run
}

#[test]
fn no_effect_is_physically_impossible_on_dfki_runs() {
    let root = shared_data();
    let dp = root.join("dfki-double-pendulum");
    if !have_data("no_effect_is_physically_impossible_on_dfki_runs", &dp) {
        return;
    }
    // double pendulum C.0, open-loop replays: the first 4 s of 00 and 03 fitted, of 04 held out
    let model = Model::from_urdf_file(dp.join("system_identification/identified_parameters/design_C.0/model_3.1/acrobot.urdf")).unwrap();
    let rec = dp.join("experiment_records/design_C.0/20220914/sys_id");
    let load = |i: &str| {
        let path = rec.join(format!("trajectory_{i}.csv.gz"));
        // the reader gives the torque the drives report (tau_meas1/2) as the measured torque
        let r = simgap_log::csv::read_csv_auto(&path).unwrap();
        assert!(!r.tau_measured.is_empty(), "the DFKI reader gives the measured torque");
        let mut r = head(r, 4.0);
        replay(&mut r, 0.002);
        r
    };
    let (fit, hold) = (vec![load("00"), load("03")], vec![load("04")]);
    let delivered: Vec<f64> = (0..model.dof()).map(|j| fit.iter().flat_map(|r| r.tau_measured.iter().skip(j).step_by(r.dof())).fold(0.0f64, |m, v| m.max(v.abs()))).collect();
    let started = std::time::Instant::now();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    println!("{}\n(C.0 diagnosis {:.1} s)", d.report.summary(), started.elapsed().as_secs_f64());
    for e in d.report.selected_effects.iter() {
        println!("selected: {}", e.description);
    }
    assert_report_physical(&model, &d, &delivered, "DFKI C.0");

    // simple pendulum, PD system identification record (3.9 s): the first 60 % fitted, the rest held out
    let sp = root.join("dfki-simple-pendulum");
    let model = Model::from_urdf_file(sp.join("urdf/simplependul_dfki_pino_Modi.urdf")).unwrap();
    let run = simgap_log::csv::read_csv_auto(&sp.join("control_method_pd/system_identification/data_measured.csv.gz")).unwrap();
    let t0 = run.t[0];
    let period = run.duration() / (run.len() - 1) as f64;
    let split = 0.6 * run.duration();
    let mut fit = head(run.clone(), split);
    replay(&mut fit, period);
    let mut rest = run.clone();
    let k = rest.t.iter().position(|&t| t - t0 > split).unwrap_or(rest.len());
    let dof = rest.dof();
    rest.t.drain(..k);
    for m in [&mut rest.q, &mut rest.qd, &mut rest.tau, &mut rest.q_ref, &mut rest.qd_ref, &mut rest.tau_ff, &mut rest.tau_measured] {
        if !m.is_empty() {
            m.drain(..k * dof);
        }
    }
    let mut hold = head(rest, 10.0);
    replay(&mut hold, period);
    let d = diagnose(&model, Formulation::EulerLagrange, &[fit], &[hold], &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    println!("{}", d.report.summary());
    for e in d.report.selected_effects.iter() {
        println!("selected: {}", e.description);
    }
    for c in d.report.candidates.iter().filter(|c| c.effect.as_str() == "inertial_error") {
        println!("simple pendulum inertial_error candidate: {:?}", c.parameters);
    }
    assert_report_physical(&model, &d, &[], "DFKI simple pendulum");
}
