//! Logs as real robots record them: a glitch sample, a held-out log that repeats a fit log, an
//! impossible sample period, open-loop replays, and a held-out run the answer does not help.

use simgap_core::{Formulation, Model};
use simgap_diag::bench::{demo_effects, demo_specs, generate};
use simgap_diag::{diagnose, DiagnoseOptions, Diagnosis, Error};
use simgap_sim::{ControllerKind, Effect, Run};

fn demo_runs(effects: &[Effect]) -> (Vec<Run>, Vec<Run>) {
    let model = Model::paper_arm();
    let (fit, hold) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, effects, s, 0.0025, 1_024_000.0).unwrap();
    (fit.iter().map(gen).collect(), hold.iter().map(gen).collect())
}

fn run_diagnosis(fit: &[Run], hold: &[Run]) -> simgap_diag::Result<Diagnosis> {
    diagnose(&Model::paper_arm(), Formulation::EulerLagrange, fit, hold, &DiagnoseOptions::default(), &mut |_| {})
}

fn selected(d: &Diagnosis) -> Vec<String> {
    let mut v: Vec<String> = d.report.selected_effects.iter().map(|e| e.effect.to_string()).collect();
    v.sort();
    v
}

#[test]
fn one_glitch_sample_does_not_change_the_answer() {
    let (mut fit, hold) = demo_runs(&demo_effects());
    // a 10 rad position on the elbow for one sample, 1.5 s into the second fit run
    let n = fit[1].dof();
    let k = 600;
    fit[1].q[k * n + 1] = 10.0;
    let d = run_diagnosis(&fit, &hold).unwrap();
    assert_eq!(selected(&d), ["coulomb_friction", "torque_saturation", "viscous_friction"], "{}", d.report.summary());
    let note = d.report.notes.iter().find(|n| n.contains("glitch")).unwrap_or_else(|| panic!("no glitch note in {:?}", d.report.notes));
    assert!(note.contains("elbow") && note.contains("sample 600"), "{note}");
}

#[test]
fn held_out_log_repeating_a_fit_log_is_refused() {
    let (fit, _) = demo_runs(&[]);
    let mut again = fit[0].clone();
    again.source = "renamed-copy.mcap".into();
    match run_diagnosis(&fit, &[again]) {
        Err(Error::Input(m)) => assert!(m.contains("renamed-copy.mcap") && m.contains("same samples"), "{m}"),
        other => panic!("expected the repeated held-out log to be refused, got {:?}", other.map(|d| d.report.verdict)),
    }
}

#[test]
fn impossible_sample_period_is_an_error_naming_the_log() {
    let (fit, mut hold) = demo_runs(&[]);
    if let Some(e) = hold[0].experiment.as_mut() {
        e.sample_period = 1e-12;
    }
    match run_diagnosis(&fit, &hold) {
        Err(Error::Log { log, message }) => {
            assert_eq!(log, hold[0].source);
            assert!(message.contains("sample_period") && message.contains("stamps"), "{message}");
        }
        other => panic!("expected an error, got {:?}", other.map(|d| d.report.verdict)),
    }
}

/// The same robot driven open loop: every log replays its commanded torque.
fn as_replay(mut runs: Vec<Run>) -> Vec<Run> {
    for r in &mut runs {
        if let Some(e) = r.experiment.as_mut() {
            e.controller = ControllerKind::Replay;
            e.kp = vec![0.0; e.joints.len()];
            e.kv = vec![0.0; e.joints.len()];
        }
    }
    runs
}

#[test]
fn open_loop_replays_are_judged_by_k_step_prediction() {
    // friction only, the logs relabelled as open-loop replays of the commanded torque
    let effects = vec![Effect::ViscousFriction { b: vec![2.288, 0.175] }, Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.01; 2] }];
    let (fit, hold) = demo_runs(&effects);
    let d = run_diagnosis(&as_replay(fit), &as_replay(hold)).unwrap();
    let g = &d.report.gap;
    assert_eq!(g.headline, "k_step", "{}", g.headline_reason);
    assert!(selected(&d).iter().any(|e| e == "coulomb_friction"), "{}", d.report.summary());
    // prediction restarted from the measured state improves at every horizon, and beats the floor
    for i in 0..g.kstep.horizons_s.len() {
        assert!(g.kstep.after[i] < 0.5 * g.kstep.before[i], "horizon {}: {:?}", g.kstep.horizons_s[i], g.kstep);
        assert!(g.kstep.after[i] < g.kstep.floor[i], "horizon {}: {:?}", g.kstep.horizons_s[i], g.kstep);
    }
    assert!(d.report.verdict.contains("k-step"), "{}", d.report.verdict);
}

#[test]
fn verdict_never_says_explained_when_the_held_out_run_gets_worse() {
    // the fit runs have friction, the held-out run is of a robot without it
    let (fit, _) = demo_runs(&demo_effects());
    let (_, hold) = demo_runs(&[]);
    let d = run_diagnosis(&fit, &hold).unwrap();
    let g = &d.report.gap;
    let last = g.kstep.after.len() - 1;
    assert!(g.kstep.after[last] > g.kstep.before[last], "the corrected model should predict the friction-free run worse: {:?}", g.kstep);
    assert!(!d.report.verdict.contains("is explained"), "{}", d.report.verdict);
    assert!(d.report.verdict.starts_with("not explained"), "{}", d.report.verdict);
}
