//! URDF pitfalls named from the data: the inertia about the joint axis written as if about the
//! centre of mass, a missing rotor inertia, a flipped gravity; none on a correct URDF.

use std::path::Path;

use crate::check::bench::{demo_specs, generate};
use crate::prepare::align_run;
use crate::report::pitfalls::urdf_pitfalls;
use crate::{FitData, PrepareOptions};
use simgap_core::{Formulation, Model, SpatialInertia};
use simgap_sim::{ControllerKind, Effect, Experiment};

/// Fit data of the paper arm's demo runs (simulated on the true arm with `effects`), prepared
/// against `urdf` (the model a user would have).
fn data_for(urdf: &Model, effects: &[Effect]) -> Vec<FitData> {
    data_on(&Model::paper_arm(), urdf, effects)
}

/// The same with the runs simulated on `truth`.
fn data_on(truth: &Model, urdf: &Model, effects: &[Effect]) -> Vec<FitData> {
    let (fit, _) = demo_specs(1);
    fit.iter()
        .map(|s| {
            let run = generate(truth, Formulation::EulerLagrange, effects, s, 0.0025, 1_024_000.0).unwrap();
            FitData::new(urdf, Formulation::EulerLagrange, align_run(urdf, &run).unwrap(), &PrepareOptions::default()).unwrap()
        })
        .collect()
}

#[test]
fn a_correct_urdf_has_no_pitfall() {
    let model = Model::paper_arm();
    let notes = urdf_pitfalls(&model, &data_for(&model, &[Effect::ViscousFriction { b: vec![2.288, 0.175] }]));
    assert!(notes.is_empty(), "{notes:#?}");
}

#[test]
fn inertia_about_the_joint_axis_written_as_about_the_com_is_named() {
    // the URDF a user wrote: each link's moment about its joint axis put where the moment about
    // the centre of mass belongs (I_c + m d² instead of I_c)
    // an arm whose forearm carries its mass far out (centre of mass 0.3 m from the elbow)
    let mut truth = Model::paper_arm();
    let fore = truth.joints()[1].inertia;
    let c = fore.com() * (0.3 / fore.com().norm());
    truth.set_link_inertia(1, SpatialInertia::from_com(fore.mass, c, nalgebra::Matrix3::identity() * 0.02)).unwrap();
    let mut wrong = truth.clone();
    for (i, j) in truth.joints().iter().enumerate() {
        let s = &j.inertia;
        let c = s.com();
        let a = j.axis.normalize();
        let d2 = c.norm_squared() - a.dot(&c).powi(2);
        // (added to every principal moment, as the DFKI URDFs write one number thrice)
        let ic = s.inertia_about_com() + nalgebra::Matrix3::identity() * (s.mass * d2);
        wrong.set_link_inertia(i, SpatialInertia::from_com(s.mass, c, ic)).unwrap();
    }
    let notes = urdf_pitfalls(&wrong, &data_on(&truth, &wrong, &[]));
    println!("{notes:#?}");
    assert!(notes.iter().any(|n| n.contains("elbow") && n.contains("about the joint axis")), "{notes:#?}");
}

#[test]
fn a_missing_rotor_inertia_is_named() {
    let model = Model::paper_arm();
    let notes = urdf_pitfalls(&model, &data_for(&model, &[Effect::Armature { ia: vec![0.0, 0.05] }]));
    println!("{notes:#?}");
    assert!(notes.iter().any(|n| n.contains("elbow") && n.contains("rotor inertia")), "{notes:#?}");
}

#[test]
fn a_flipped_gravity_is_named() {
    let truth = Model::paper_arm();
    let mut wrong = truth.clone();
    wrong.set_gravity(-truth.gravity());
    let notes = urdf_pitfalls(&wrong, &data_for(&wrong, &[]));
    println!("{notes:#?}");
    assert!(notes.iter().any(|n| n.contains("gravity has the wrong sign")), "{notes:#?}");
}

#[test]
fn dfki_double_pendulum_inertia_pitfall() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/dfki-double-pendulum");
    if !super::common::have_data("dfki_double_pendulum_inertia_pitfall", &root) {
        return;
    }
    // the published C.0 URDF places DFKI's inertias about the joint axes as COM inertias
    let model = Model::from_urdf_file(root.join("system_identification/identified_parameters/design_C.0/model_3.1/acrobot.urdf")).unwrap();
    let rec = root.join("experiment_records/design_C.0/20220914/sys_id");
    let data: Vec<FitData> = ["00", "03"]
        .iter()
        .map(|i| {
            let mut r = simgap_log::csv::read_csv_auto(&rec.join(format!("trajectory_{i}.csv.gz"))).unwrap();
            r.experiment = Some(Experiment {
                controller: ControllerKind::Replay,
                joints: r.joints.clone(),
                kp: vec![0.0; 2],
                kv: vec![0.0; 2],
                sample_period: 0.002,
                extra: Default::default(),
            });
            FitData::new(&model, Formulation::EulerLagrange, align_run(&model, &r).unwrap(), &PrepareOptions::default()).unwrap()
        })
        .collect();
    let notes = urdf_pitfalls(&model, &data);
    println!("{notes:#?}");
    assert!(notes.iter().any(|n| n.contains("about the joint axis")), "the documented DFKI pitfall is not named: {notes:#?}");
}

/// The fit data with the elbow's commanded torque replaced by `factor` × the torque the model
/// needs for the logged motion (the residual kept consistent).
fn with_elbow_torque(mut data: Vec<FitData>, factor: f64) -> Vec<FitData> {
    for d in &mut data {
        for s in 0..d.len() {
            let i = s * d.dof + 1;
            let model_tau = d.tau[i] - d.residual[i];
            d.tau[i] = factor * model_tau;
            d.residual[i] = d.tau[i] - model_tau;
        }
    }
    data
}

#[test]
fn a_flipped_joint_sign_is_named_only_where_the_model_torque_dominates() {
    let model = Model::paper_arm();
    let data = data_for(&model, &[]);
    // the commanded torque is the model's with the opposite sign: a flipped axis
    let notes = urdf_pitfalls(&model, &with_elbow_torque(data.clone(), -1.0));
    assert!(notes.iter().any(|n| n.contains("elbow") && n.contains("flipped")), "{notes:#?}");
    // opposed, but the model's torque only a third of what was measured (e.g. a spring and
    // friction against a light link's inertial torque): it says nothing of the axis
    let notes = urdf_pitfalls(&model, &with_elbow_torque(data, -3.0));
    assert!(!notes.iter().any(|n| n.contains("flipped")), "{notes:#?}");
}
