//! Dry friction seen through the torque's filter: the fit's torque side is the command filtered
//! by the smoothing kernel, so a dry-friction column must pass through the same kernel, or
//! least squares trades Coulomb friction for viscous friction at every velocity reversal.

use super::physical::paper_arm_data;
use crate::lsq::Problem;
use crate::vocabulary::{fit_terms, Term};
use simgap_sim::Effect;

#[test]
fn viscous_and_coulomb_friction_are_recovered_without_trading_one_for_the_other() {
    let (b, fc) = ([2.288, 0.175], [7.17, 1.734]);
    let (_, data, _, _) = paper_arm_data(&[Effect::ViscousFriction { b: b.to_vec() }, Effect::CoulombFriction { fc: fc.to_vec(), w: vec![0.01; 2] }]);
    let p = Problem::new(&data);
    let terms = [Term::Viscous(0), Term::Viscous(1), Term::Coulomb { joint: 0, w: 0.01 }, Term::Coulomb { joint: 1, w: 0.01 }];
    let (_, _, f) = fit_terms(&p, &data, &terms);
    let truth = [b[0], b[1], fc[0], fc[1]];
    let err: Vec<f64> = f.theta.iter().zip(truth).map(|(found, truth)| found / truth - 1.0).collect();
    // columns of the smoothed velocity (not filtered like the torque) gave b +2.8 % and fc −1.0 %
    // on the shoulder, whose friction dominates its residual; the elbow's small viscous friction
    // (2 % of its torque) carries the smoothing's other approximations at the percent level
    assert!(err[0].abs() < 0.005 && err[2].abs() < 0.005, "shoulder b, fc off by {:.2} %, {:.2} %", 100.0 * err[0], 100.0 * err[2]);
    assert!(err[1].abs() < 0.03 && err[3].abs() < 0.005, "elbow b, fc off by {:.2} %, {:.2} %", 100.0 * err[1], 100.0 * err[3]);
}

#[test]
fn a_velocity_filtered_like_the_torque_does_not_lag_the_smoothed_velocity() {
    // the kernel holds each value over its sample interval: fed the velocity at the sample
    // instead of the interval's midpoint, the column lags by half a period (T/2 q̈). The two
    // filters differ in shape, not in time: their difference is smallest unshifted.
    let (_, data, _, _) = paper_arm_data(&[]);
    let (period, d) = (0.0025, &data[0]);
    for j in 0..d.dof {
        let filtered = d.filtered_velocity_map(j, |v| v);
        let gap = |shift: f64| {
            let e = (0..d.len()).map(|s| (filtered[s] + shift * period * d.qdd[s * d.dof + j] - d.qd[s * d.dof + j]).powi(2));
            (e.sum::<f64>() / d.len() as f64).sqrt()
        };
        let (early, on_time, late) = (gap(-0.5), gap(0.0), gap(0.5));
        assert!(on_time < early && on_time < late, "joint {j}: RMS gap {on_time:.3e} rad/s, {late:.3e} with half a period's lag removed, {early:.3e} with one added");
    }
}
