//! The bounds that spare the selection its cross-validation: a set's least-squares floor is at
//! most its in-sample residual, which is at most its cross-validated residual; a set rejected
//! against a level without cross-validation is one whose cross-validated residual is at that
//! level or above it.

use super::physical::paper_arm_data;
use crate::lsq::{fit, fit_unless, grams, least_squares_floor, Rejected};
use crate::select::{parameter_scales, Context};
use crate::vocabulary::{Term, TermDesign};
use simgap_sim::{Effect, LinkDelta};

/// The paper arm's demo runs with a heavier elbow link, viscous and Coulomb friction and a
/// torque offset, and the selection's context on them.
fn sets() -> (Vec<crate::FitData>, simgap_core::Model) {
    let effects = [
        Effect::InertialError { deltas: vec![LinkDelta { joint: 1, mass: 0.5, com: [0.0; 3], inertia: [0.0; 6] }] },
        Effect::ViscousFriction { b: vec![2.288, 0.175] },
        Effect::CoulombFriction { fc: vec![1.5, 0.4], w: vec![0.01; 2] },
        Effect::TorqueOffset { offset: vec![0.3, -0.1] },
    ];
    let (model, data, _, _) = paper_arm_data(&effects);
    (data, model)
}

#[test]
fn the_least_squares_floor_is_at_most_the_in_sample_residual_which_is_at_most_the_cross_validated_one() {
    let (data, model) = sets();
    let ctx = Context::new(&data, 0.0025, &parameter_scales(&model));
    let candidates: Vec<Vec<Term>> = vec![
        vec![Term::Viscous(0)],
        vec![Term::Viscous(0), Term::Viscous(1), Term::Coulomb { joint: 0, w: 0.01 }],
        vec![ctx.inertial_term()],
        vec![ctx.inertial_term(), Term::Viscous(0), Term::Offset(1)],
        vec![Term::Viscous(0), Term::Viscous(1), Term::Coulomb { joint: 0, w: 0.01 }, Term::Coulomb { joint: 1, w: 0.01 }, Term::Offset(0), Term::Offset(1), ctx.inertial_term()],
    ];
    for terms in &candidates {
        let designs: Vec<TermDesign> = terms.iter().map(|t| ctx.design(t)).collect();
        let refs: Vec<&TermDesign> = designs.iter().collect();
        let gr = grams(&ctx.problem, &refs);
        let floor = least_squares_floor(&ctx.problem, &gr);
        let Err(Rejected::Fitted(whole)) = fit_unless(&ctx.problem, &gr, f64::NEG_INFINITY) else { panic!("{terms:?}: the fit on all the data is made for any level") };
        let cv = fit(&ctx.problem, &gr);
        assert!(floor > 0.0 && floor <= whole.cv_mse, "{terms:?}: floor {floor:e} above the in-sample residual {:e}", whole.cv_mse);
        assert!(whole.cv_mse <= cv.cv_mse, "{terms:?}: in-sample residual {:e} above the cross-validated one {:e}", whole.cv_mse, cv.cv_mse);
        assert_eq!(whole.theta, cv.theta, "{terms:?}: the fit on all the data is the same with or without its cross-validation");
    }
}

#[test]
fn a_set_rejected_against_a_level_has_a_cross_validated_residual_at_or_above_it() {
    let (data, model) = sets();
    let ctx = Context::new(&data, 0.0025, &parameter_scales(&model));
    let terms = vec![ctx.inertial_term(), Term::Viscous(0), Term::Viscous(1)];
    let designs: Vec<TermDesign> = terms.iter().map(|t| ctx.design(t)).collect();
    let refs: Vec<&TermDesign> = designs.iter().collect();
    let truth = fit(&ctx.problem, &grams(&ctx.problem, &refs)).cv_mse;
    // levels from far below the residual to above it, each in a fresh context (nothing cached)
    for level in [0.01 * truth, 0.5 * truth, 0.999 * truth, 1.001 * truth, 2.0 * truth] {
        let fresh = Context::new(&data, 0.0025, &parameter_scales(&model));
        match fresh.fit_set_below(&terms, &designs, level) {
            None => assert!(truth >= level, "rejected at {level:e} with a cross-validated residual of {truth:e}"),
            Some(f) => {
                assert!(truth < level, "kept at {level:e} with a cross-validated residual of {truth:e}");
                assert_eq!(f.cv_mse, truth, "the set kept is the set fitted");
            }
        }
        // asked again, the cached answer is the same
        assert_eq!(fresh.fit_set_below(&terms, &designs, level).is_some(), truth < level);
        // and the whole fit is there for the full one
        assert_eq!(fresh.fit_set(&terms, &designs).cv_mse, truth);
    }
}
