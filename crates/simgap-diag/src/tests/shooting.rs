//! Multiple shooting: parameters fitted to k-step prediction where the torque-residual fit is
//! biased, and the corrected model of the DFKI double pendulum C.0 against the published URDF.
//!
//! The DFKI part needs `../shared/data` next to the repository; without it, it prints why and
//! passes.

use super::common::{have_data, replay, shared_data};

use crate::check::bench::{demo_specs, generate};
use crate::lsq::Problem;
use crate::prepare::align_run;
use crate::prepare::windows::{PredictionRun, DEFAULT_HORIZONS, FIT_WINDOWS_PER_RUN, FOLDS_PER_RUN};
use crate::select::shooting;
use crate::vocabulary::effects;
use crate::vocabulary::Term;
use crate::vocabulary::{fit_terms, fitted_terms};
use crate::{diagnose, DiagnoseOptions, FitData, Param, PrepareOptions};
use rand::{Rng, SeedableRng};
use simgap_core::{mass_matrix, Formulation, Model, Workspace};
use simgap_sim::{Effect, Run, SensorParams};

/// The run as an open-loop replay of its commanded torque, its stamps written with a jitter of up
/// to `jitter` sample periods (as a logger on a busy computer stamps samples).
fn replay_with_jittered_stamps(mut run: Run, period: f64, jitter: f64, rng: &mut impl Rng) -> Run {
    replay(&mut run, period);
    for t in run.t.iter_mut().skip(1) {
        *t += jitter * period * rng.random_range(-1.0..1.0);
    }
    run
}

#[test]
fn shooting_recovers_what_the_torque_residual_fit_gets_wrong() {
    let model = Model::paper_arm();
    let formulation = Formulation::EulerLagrange;
    let h = mass_matrix(&model, &mut Workspace::new(&model), &[0.0, 0.0]);
    // hidden: rotor inertia of 30 % of each joint's inertia at rest, and Coulomb friction
    let ia = [0.3 * h[(0, 0)], 0.3 * h[(1, 1)]];
    let fc = [7.17, 1.734];
    let hidden = [Effect::Armature { ia: ia.to_vec() }, Effect::CoulombFriction { fc: fc.to_vec(), w: vec![0.01; fc.len()] }];
    let truth = [ia[0], ia[1], fc[0], fc[1]];
    let period = 0.0025;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let (fit_specs, hold_specs) = demo_specs(2);
    let mut gen = |s| replay_with_jittered_stamps(generate(&model, formulation, &hidden, s, period, 1_024_000.0).unwrap(), period, 0.4, &mut rng);
    let fit: Vec<Run> = fit_specs.iter().map(&mut gen).collect();
    let hold: Vec<Run> = hold_specs.iter().map(&mut gen).collect();

    // the torque-residual fit, on accelerations differentiated over the jittered stamps
    let prepare = PrepareOptions::default();
    let data: Vec<FitData> = fit.iter().map(|r| FitData::new(&model, formulation, align_run(&model, r).unwrap(), &prepare).unwrap()).collect();
    let problem = Problem::new(&data);
    let terms = [Term::Armature(0), Term::Armature(1), Term::Coulomb { joint: 0, w: 0.01 }, Term::Coulomb { joint: 1, w: 0.01 }];
    let (designs, _, torque_fit) = fit_terms(&problem, &data, &terms);

    // multiple shooting from it
    let horizons = DEFAULT_HORIZONS;
    let fit_pred: Vec<PredictionRun> = fit
        .iter()
        .enumerate()
        .map(|(i, r)| PredictionRun::new(align_run(&model, r).unwrap(), &horizons, prepare.window, SensorParams::exact(), i * FOLDS_PER_RUN, FIT_WINDOWS_PER_RUN))
        .collect();
    let options = shooting::Options::default();
    let runs = shooting::shooting_runs(&fit_pred, prepare.window, &options);
    let keep = |_: usize, _: usize| true;
    let sp = shooting::Problem { model: &model, formulation, terms: &terms, designs: &designs, runs: &runs, keep: &keep, options: &options };
    let shot = shooting::fit(&sp, std::slice::from_ref(&torque_fit.theta), None).unwrap();

    let rel = |th: &[f64]| -> Vec<f64> { th.iter().zip(&truth).map(|(a, b)| (a - b).abs() / b).collect() };
    let (e_torque, e_shot) = (rel(torque_fit.theta.as_slice()), rel(shot.theta.as_slice()));
    println!(
        "truth {truth:?}\ntorque fit {:?} (relative error {e_torque:?})\nshooting {:?} (relative error {e_shot:?}), cost {} → {} in {} iterations",
        torque_fit.theta.as_slice(),
        shot.theta.as_slice(),
        shot.cost_start,
        shot.cost,
        shot.iterations
    );
    let worst = |e: &[f64]| e.iter().cloned().fold(0.0, f64::max);
    assert!(worst(&e_torque) > 0.05, "the jittered stamps should bias the torque-residual fit: {e_torque:?}");
    assert!(worst(&e_shot) < 0.5 * worst(&e_torque), "shooting {e_shot:?} against torque fit {e_torque:?}");
    assert!(shot.cost < shot.cost_start, "{} → {}", shot.cost_start, shot.cost);
    assert!(shot.std.iter().all(|s| s.is_finite() && *s >= 0.0), "{}", shot.std);

    // the same fit asked again of the same windows is answered from them, bit for bit what new
    // windows compute; a fit of other windows is a fit of its own
    let again = shooting::fit(&sp, std::slice::from_ref(&torque_fit.theta), None).unwrap();
    let fresh = shooting::shooting_runs(&fit_pred, prepare.window, &options);
    let computed = shooting::fit(&shooting::Problem { runs: &fresh, ..sp }, std::slice::from_ref(&torque_fit.theta), None).unwrap();
    for s in [&again, &computed] {
        assert_eq!((&s.theta, &s.std, s.cost_start, s.cost, s.iterations), (&shot.theta, &shot.std, shot.cost_start, shot.cost, shot.iterations));
    }
    assert_eq!(runs.fits_done(), 1);
    let even = |_: usize, w: usize| w % 2 == 0;
    shooting::fit(&shooting::Problem { keep: &even, ..sp }, std::slice::from_ref(&torque_fit.theta), None).unwrap();
    assert_eq!(runs.fits_done(), 2);

    // held-out prediction: shooting at least as good at every horizon
    let eff = |th| effects::to_effects(&model, &fitted_terms(&terms, &designs, th, None));
    let k_torque = crate::predict(&model, formulation, &eff(&torque_fit.theta), &hold, &horizons, prepare.window).unwrap();
    let k_shot = crate::predict(&model, formulation, &eff(&shot.theta), &hold, &horizons, prepare.window).unwrap();
    println!("held-out k-step: nominal {:?}, torque fit {:?}, shooting {:?}", k_torque.before, k_torque.after, k_shot.after);
    for i in 0..horizons.len() {
        assert!(k_shot.after[i] <= k_torque.after[i], "horizon {}: shooting {} against torque fit {}", horizons[i], k_shot.after[i], k_torque.after[i]);
    }
}

#[test]
fn a_set_without_parameters_is_fitted_as_it_is() {
    // (a panic in nalgebra's eigen-decomposition of an empty matrix, before)
    let model = Model::paper_arm();
    let formulation = Formulation::EulerLagrange;
    let (fit_specs, _) = demo_specs(1);
    let run = generate(&model, formulation, &[], &fit_specs[0], 0.0025, 1_024_000.0).unwrap();
    let horizons = DEFAULT_HORIZONS;
    let pr = PredictionRun::new(align_run(&model, &run).unwrap(), &horizons, 0.05, SensorParams::exact(), 0, FIT_WINDOWS_PER_RUN);
    let options = shooting::Options::default();
    let runs = shooting::shooting_runs(&[pr], 0.05, &options);
    let keep = |_: usize, _: usize| true;
    for terms in [vec![], vec![Term::CoriolisStructure]] {
        let designs = vec![crate::vocabulary::TermDesign::default(); terms.len()];
        let sp = shooting::Problem { model: &model, formulation, terms: &terms, designs: &designs, runs: &runs, keep: &keep, options: &options };
        let shot = shooting::fit(&sp, &[nalgebra::DVector::zeros(0)], None).unwrap();
        assert!(shot.theta.is_empty() && shot.std.is_empty() && shot.iterations == 0, "{terms:?}: {shot:?}");
        assert!(shot.cost.is_finite() && shot.cost == shot.cost_start);
    }
}

#[test]
fn long_logs_are_searched_on_fewer_windows_spread_evenly_than_the_final_fit_takes() {
    // 240 s of logs (480 consecutive windows of 0.5 s): the search keeps about SEARCH_WINDOWS of
    // them spread over every run in proportion to its length, the final fit MAX_WINDOWS; a
    // short log is searched and fitted on all of its windows
    let model = Model::paper_arm();
    let period = 0.01;
    let options = shooting::Options::default();
    let run_of = |seconds: f64| {
        let k = (seconds / period) as usize + 1;
        let t: Vec<f64> = (0..k).map(|i| i as f64 * period).collect();
        let q: Vec<f64> = t.iter().flat_map(|t| [0.3 * t.sin(), 0.2 * (0.7 * t).cos()]).collect();
        let mut run = Run::new(model.joint_names().iter().map(|s| s.to_string()).collect());
        (run.tau, run.t, run.q) = (vec![0.0; 2 * k], t, q);
        align_run(&model, &run).unwrap()
    };
    let pr = |i: usize, seconds: f64| PredictionRun::new(run_of(seconds), &DEFAULT_HORIZONS, 0.05, SensorParams::exact(), i * FOLDS_PER_RUN, FIT_WINDOWS_PER_RUN);
    let long = shooting::shooting_runs(&[pr(0, 160.0), pr(1, 80.0)], 0.05, &options);
    let (searched, all, consecutive) = long.counts();
    assert_eq!(consecutive, 480);
    assert!((shooting::SEARCH_WINDOWS..=shooting::SEARCH_WINDOWS + 2).contains(&searched), "searched on {searched}");
    assert!((shooting::MAX_WINDOWS..=shooting::MAX_WINDOWS + 2).contains(&all), "fitted on {all}");
    // each run's share follows its length, and the search's windows span the whole run
    let (a, b) = (long.runs[0].windows(), long.runs[1].windows());
    assert!(a > b && (a as f64 / b as f64 - 2.0).abs() < 0.1, "{a} and {b} windows");
    let last = *long.runs[0].starts.last().unwrap() as f64 * period;
    assert!(last > 150.0, "the last window of the 160 s run starts at {last} s");
    let short = shooting::shooting_runs(&[pr(0, 30.0)], 0.05, &options);
    assert_eq!(short.counts(), (60, 60, 60));
    assert!(std::ptr::eq(short.whole(), &short));
}

#[test]
fn dfki_c0_corrected_model_beats_the_urdf_on_a_held_out_run() {
    let root = shared_data();
    let dp = root.join("dfki-double-pendulum");
    if !have_data("dfki_c0_corrected_model_beats_the_urdf_on_a_held_out_run", &dp) {
        return;
    }
    // C.0 open-loop runs 00, 01, 03, 04 fitted, run 02 held out (the fold where the torque-residual
    // fit alone predicted worse than the URDF at 0.1 s)
    let model = Model::from_urdf_file(dp.join("system_identification/identified_parameters/design_C.0/model_3.1/acrobot.urdf")).unwrap();
    let rec = dp.join("experiment_records/design_C.0/20220914/sys_id");
    let load = |i: &str| {
        let mut r = simgap_log::csv::read_csv_auto(&rec.join(format!("trajectory_{i}.csv.gz"))).unwrap();
        replay(&mut r, 0.002);
        r
    };
    let fit: Vec<Run> = ["00", "01", "03", "04"].iter().map(|i| load(i)).collect();
    let hold = vec![load("02")];
    let options = DiagnoseOptions { horizons: vec![0.1, 0.5], ..Default::default() };
    let started = std::time::Instant::now();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &options, &mut |_| {}).unwrap();
    println!("{}\n(C.0 diagnosis {:.1} s)", d.report.summary(), started.elapsed().as_secs_f64());
    for s in d.report.selection_log.iter().filter(|s| s.reason.starts_with("not a finding") || s.reason.contains("simpler")) {
        println!("plausibility: {} on {:?}: {}", s.effect, s.joint, s.reason);
    }
    let k = &d.report.gap.kstep;
    for (i, h) in k.horizons_s.iter().enumerate() {
        assert!(k.after[i] < k.before[i], "held-out run 02 at {h} s: corrected {} against the published URDF {}", k.after[i], k.before[i]);
    }
    assert!(!d.report.selected_effects.is_empty());
    // nothing selected is physically impossible
    let reach = crate::lsq::inertial::link_reach(&model);
    for e in &d.report.selected_effects {
        println!("selected: {}", e.description);
        match e.effect.as_str() {
            "viscous_friction" | "coulomb_friction" | "armature" | "stribeck_friction" => {
                for (key, v) in &e.parameters {
                    if let Param::PerJoint(v) = v {
                        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{} {key} = {v:?}", e.effect);
                    }
                }
            }
            "payload" => {
                let Some(Param::Number(m)) = e.parameters.get("mass") else { panic!("payload without mass: {e:?}") };
                assert!(*m >= 0.0 && *m <= 2.0 * model.total_mass() + 1e-9, "payload mass {m}");
            }
            "inertial_error" => {
                let (Some(Param::PerJoint(dm)), Some(Param::PerLink(dc)), Some(Param::PerLink(di))) =
                    (e.parameters.get("delta_mass"), e.parameters.get("delta_com"), e.parameters.get("delta_inertia"))
                else {
                    panic!("inertial_error without deltas: {e:?}")
                };
                for (a, j) in e.joints.iter().enumerate() {
                    let i = model.joint_index(j).unwrap();
                    let old = &model.joints()[i].inertia;
                    let d = simgap_sim::LinkDelta { joint: i, mass: dm[a], com: [dc[a][0], dc[a][1], dc[a][2]], inertia: std::array::from_fn(|b| di[a][b]) };
                    let ic = old.inertia_about_com()
                        + nalgebra::Matrix3::new(d.inertia[0], d.inertia[1], d.inertia[2], d.inertia[1], d.inertia[3], d.inertia[4], d.inertia[2], d.inertia[4], d.inertia[5]);
                    let s = simgap_core::SpatialInertia::from_com(old.mass + d.mass, old.com() + nalgebra::Vector3::from(d.com), ic);
                    assert!(s.mass > 0.0, "link of {j}: mass {}", s.mass);
                    assert!(crate::lsq::inertial::link_is_physical(&simgap_core::inertial_parameters(&s), reach[i] * 1.000001), "link of {j} not physical: {s:?}");
                }
            }
            _ => {}
        }
    }
}
