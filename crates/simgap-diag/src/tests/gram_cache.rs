//! The block products of design columns a problem keeps ([`crate::lsq::grams`]) are those of
//! the columns asked for: a column made where another was dropped never gets the other's
//! products; rows left out of a problem add nothing to a fit.

use super::physical::paper_arm_data;
use crate::lsq::design::{Column, TermDesign};
use crate::lsq::{grams, Problem};
use simgap_sim::Effect;

#[test]
fn a_column_made_after_another_was_dropped_never_gets_its_cached_products() {
    let (_, data, _, _) = paper_arm_data(&[Effect::ViscousFriction { b: vec![2.288, 0.175] }]);
    let p = Problem::new(&data);
    let samples = p.samples;
    let column = |j: usize, scale: f64| Column::new(Some(j), (0..samples).map(|s| scale * ((s % 97) as f64 - 48.0)).collect());
    let kept = column(1, 1.0);
    for round in 0..50 {
        // a design whose columns live for this round only: same length, other values
        let d = TermDesign::free(vec![column(0, 1.0 + round as f64), kept.clone()]);
        let cached = grams(&p, &[&d]);
        // the same columns in a problem with nothing cached
        let fresh = grams(&Problem::new(&data), &[&d]);
        for (a, b) in cached.g.iter().zip(&fresh.g) {
            assert_eq!(a, b, "round {round}: the products of a new column came from a dropped one");
        }
    }
}

/// Rows left out of a problem ([`Problem::without_rows`], with its designs'
/// [`TermDesign::without_rows`]) add nothing to a fit: whatever their residual, the fit is the
/// same, and where they were wrong the fit without them finds the effect the others hold.
#[test]
fn rows_left_out_add_nothing_to_a_fit() {
    let b = [2.288, 0.175];
    let (_, data, _, _) = paper_arm_data(&[Effect::ViscousFriction { b: b.to_vec() }]);
    let p = Problem::new(&data);
    let dof = p.dof;
    let qd: Vec<f64> = data.iter().flat_map(|d| d.qd.iter().copied()).collect();
    let design = TermDesign::free((0..dof).map(|j| Column::new(Some(j), (0..p.samples).map(|s| qd[s * dof + j]).collect())).collect());
    // every seventh sample of the elbow made wrong (a friction 20 times the elbow's on them)
    let rows: Vec<(usize, usize)> = (0..p.samples).filter(|s| s % 7 == 3).map(|s| (s, 1)).collect();
    let mut wrong = Problem::new(&data);
    let values = std::sync::Arc::make_mut(&mut wrong.y.values);
    for &(s, j) in &rows {
        values[s * dof + j] += 20.0 * b[1] * qd[s * dof + j];
    }
    let left_out = design.without_rows(&rows, dof);
    let fit_without = |p: &Problem| {
        let q = p.without_rows(&rows);
        crate::lsq::fit(&q, &grams(&q, &[&left_out])).theta
    };
    assert_eq!(fit_without(&p), fit_without(&wrong), "the left-out rows changed the fit");
    let theta = fit_without(&wrong);
    for j in 0..dof {
        assert!((theta[j] / b[j] - 1.0).abs() < 0.05, "b{j}: {} against {}", theta[j], b[j]);
    }
    // kept, the wrong rows move the elbow's friction
    let kept = crate::lsq::fit(&wrong, &grams(&wrong, &[&design])).theta;
    assert!((kept[1] / b[1] - 1.0).abs() > 0.5, "b1 with the wrong rows: {}", kept[1]);
}
