//! The block products of design columns a problem keeps ([`crate::lsq::grams`]) are those of
//! the columns asked for: a column made where another was dropped never gets the other's
//! products.

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
