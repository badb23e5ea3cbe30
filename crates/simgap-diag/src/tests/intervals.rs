//! The pieces of the reported 95 % intervals.

use crate::lsq::t_quantile_975;
use crate::select::uncertainty::interval_std;
use nalgebra::DVector;

#[test]
fn student_quantile_matches_tables() {
    // two-sided 95 % points of Student's t (any statistics table)
    for (nu, t) in [(1, 12.706), (2, 4.303), (3, 3.182), (4, 2.776), (9, 2.262), (14, 2.145), (29, 2.045), (100, 1.984)] {
        let got = t_quantile_975(nu);
        assert!((got - t).abs() <= 0.002 * t, "t(0.975, {nu}) = {got}, table {t}");
    }
    assert!(t_quantile_975(0).is_infinite());
}

#[test]
fn interval_takes_the_pipeline_error_where_it_exceeds_the_larger_resampling_spread() {
    let boot = DVector::from_vec(vec![1.0, 3.0, 2.0, 1.0]);
    let jack = DVector::from_vec(vec![2.0, 1.0, f64::NAN, 0.5]);
    let bias = DVector::from_vec(vec![0.0, 4.0, f64::NAN, -1.5]);
    let s = interval_std(&boot, &jack, Some(&bias));
    // the pipeline error (of either sign) where it shows beyond the scatter, else the scatter:
    // one synthetic refit carries a scatter of about σ itself, so |b| ≤ σ is no shared error
    assert_eq!(s.as_slice(), &[2.0, 4.0, 2.0, 1.5]);
    let boot = DVector::from_vec(vec![1.0, 3.0, 2.0]);
    let jack = DVector::from_vec(vec![2.0, 1.0, f64::NAN]);
    // no bias known: the resampling spread alone
    let s = interval_std(&boot, &jack, None);
    assert_eq!(s.as_slice(), &[2.0, 3.0, 2.0]);
}
