//! The payload's centre-of-mass search. The last link's first moment is identified better than
//! its mass, whose linear estimate can come out negative: its quotient h/m then points to the
//! opposite side of the link, and a search started there alone stays on the wrong side.

use crate::lsq::{fit, grams};
use crate::select::{parameter_scales, Context, Family};
use crate::vocabulary::Term;

#[test]
fn a_payload_is_searched_on_the_side_its_first_moment_points_to_when_the_mass_guess_is_negative() {
    // the self-check's `equivalence` scenario 12 of seed 2: a 0.64 kg payload on the 7-DOF arm,
    // whose linear guess of the last link's mass is −0.31 kg
    let sc = crate::check::selfcheck::scenario(2, 12).unwrap();
    let (mass, com) = match sc.effects.as_slice() {
        [simgap_sim::Effect::Payload { mass, com }] => (*mass, *com),
        other => panic!("the scenario hides a payload alone: {other:?}"),
    };
    let model = &sc.diagnosis_model;
    let prep = crate::prepare::prepare(model, simgap_core::Formulation::EulerLagrange, &sc.fit, &sc.holdout, &Default::default(), &[]).unwrap();
    let ctx = Context::new(&prep.data, 0.005, &parameter_scales(model));
    // the linear guess the search starts from: mass and first moment of the last link
    let linear = fit(&ctx.problem, &grams(&ctx.problem, &[&crate::vocabulary::payload_linear_design(&prep.data)])).theta;
    println!("linear guess of the last link: mass {:.3} kg, first moment {:?} kg·m (payload {mass:.3} kg at {com:?} m)", linear[0], &linear.as_slice()[1..]);
    let found = ctx.best_of(&Family::Payload, &ctx.problem.y);
    let Term::Payload { com: c, .. } = found else { panic!("{found:?}") };
    let side = c.iter().zip(&com).map(|(a, b)| a * b).sum::<f64>();
    assert!(side > 0.0, "payload searched at {c:?}, on the other side of the link from the true {com:?}");
    let d = ctx.design(&found);
    let m = fit(&ctx.problem, &grams(&ctx.problem, &[&d])).theta[0];
    assert!(m > 0.1 * mass, "the payload found at {c:?} carries {m} kg of the true {mass}");
}
