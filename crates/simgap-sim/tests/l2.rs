//! The L² index (eq. 127) against closed forms.

use simgap_sim::{l2_between, l2_index, l2_per_joint, l2_tracking, Run};

fn grid(t0: f64, t1: f64, n: usize) -> Vec<f64> {
    (0..n).map(|k| t0 + (t1 - t0) * k as f64 / (n - 1) as f64).collect()
}

#[test]
fn l2_of_a_sine_over_a_period_is_one_over_root_two() {
    let t = grid(0.0, std::f64::consts::TAU, 20001);
    let x: Vec<f64> = t.iter().map(|s| s.sin()).collect();
    assert!((l2_index(&t, &x, 1) - 0.5f64.sqrt()).abs() < 1e-8);
    // two joints: sin and 2 cos; ‖x‖² averages to 1/2 + 2
    let x2: Vec<f64> = t.iter().flat_map(|s| [s.sin(), 2.0 * s.cos()]).collect();
    assert!((l2_index(&t, &x2, 2) - 2.5f64.sqrt()).abs() < 1e-8);
    let pj = l2_per_joint(&t, &x2, 2);
    assert!((pj[0] - 0.5f64.sqrt()).abs() < 1e-8 && (pj[1] - 2.0f64.sqrt()).abs() < 1e-8);
    // constants and degenerate inputs
    assert!((l2_index(&[5.0, 6.0, 8.0], &[3.0, 3.0, 3.0], 1) - 3.0).abs() < 1e-15);
    assert_eq!(l2_index(&[1.0], &[3.0], 1), 0.0);
}

fn run(joints: &[&str], t: Vec<f64>, q: Vec<f64>) -> Run {
    let mut r = Run::new(joints.iter().map(|s| s.to_string()).collect());
    r.t = t;
    r.q = q;
    r.source = "test".into();
    r
}

#[test]
fn l2_between_matches_joints_by_name_and_resamples() {
    // a: (shoulder, elbow) on a fine grid; b: (elbow, shoulder) on a coarser, shifted grid,
    // both linear in t, so resampling is exact: the difference is constant (1, −2)
    let ta = grid(0.0, 2.0, 201);
    let a = run(&["shoulder", "elbow"], ta.clone(), ta.iter().flat_map(|s| [s + 1.0, 3.0 * s]).collect());
    let tb = grid(-0.5, 3.0, 36);
    let b = run(&["elbow", "shoulder"], tb.clone(), tb.iter().flat_map(|s| [3.0 * s + 2.0, *s]).collect());
    let r = l2_between(&a, &b, None).unwrap();
    assert_eq!(r.joints, vec!["shoulder", "elbow"]);
    assert!((r.per_joint[0] - 1.0).abs() < 1e-12 && (r.per_joint[1] - 2.0).abs() < 1e-12, "{r:?}");
    assert!((r.overall - 5.0f64.sqrt()).abs() < 1e-12);
    assert!((r.max_abs_per_joint[1] - 2.0).abs() < 1e-12);
    // a window
    let w = l2_between(&a, &b, Some((0.5, 1.0))).unwrap();
    assert_eq!(w.samples, 51);
    assert_eq!(w.span, (0.5, 1.0));
    // a missing joint is an error
    let c = run(&["shoulder"], tb.clone(), tb.clone());
    assert!(l2_between(&a, &c, None).is_err());
}

#[test]
fn l2_tracking_uses_reference_minus_position() {
    let t = grid(0.0, 1.0, 11);
    let mut r = run(&["j"], t.clone(), vec![0.0; 11]);
    r.q_ref = vec![2.0; 11];
    assert!((l2_tracking(&r, None).unwrap().overall - 2.0).abs() < 1e-15);
    r.q_ref.clear();
    assert!(l2_tracking(&r, None).is_err());
}
