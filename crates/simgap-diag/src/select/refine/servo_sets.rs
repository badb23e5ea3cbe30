//! The servo's sets of the shooting stage: its set with a torque limit on the joints a fit log
//! shows stalled or whose motor constants were fitted clamped ([`servo_limit`]), and with its
//! load friction rising at rest ([`load_friction_at_rest`]).

use rayon::prelude::*;

use crate::error::Result;
use crate::prediction::kstep;
use crate::prepare::servo;
use crate::select::prediction::ADD_GAIN;
use crate::select::scorer::Scorer;
use crate::select::shooting;
use crate::vocabulary::{Term, TermDesign};

use super::cross_validation::{transfer, try_set, Tried};

/// The driven servo joints that some fit log shows stalled ([`servo::stalls`]): at full duty
/// for [`servo::MIN_STALL`] or more, at rest. Only there is a torque limit evidenced.
/// Computed once per scorer (the fit logs do not change).
pub(in crate::select) fn stalled_joints<'s>(scorer: &'s Scorer<'_>) -> &'s [usize] {
    scorer.stalled.get_or_init(|| stalled_joints_of(scorer))
}

fn stalled_joints_of(scorer: &Scorer<'_>) -> Vec<usize> {
    let (model, ctx, prep) = (scorer.model, scorer.ctx, scorer.prep);
    let n = model.dof();
    let rest: Vec<f64> = (0..n).map(|j| servo::REST_WIDTHS * ctx.dry_width[j].mid()).collect();
    let mut stalled = vec![false; n];
    for run in prep.fit_runs.iter().filter(|r| servo::is_servo(r)) {
        let Ok(p) = servo::params(model, run) else { continue };
        for (s, now) in stalled.iter_mut().zip(servo::stalls(run, &p, &rest, servo::MIN_STALL)) {
            *s |= now;
        }
    }
    (0..n).filter(|&j| stalled[j] && !prep.passive[j]).collect()
}

/// Shares of a driven joint's largest command at which the servo set is tried with a torque
/// limit, coarse then around the best ([`servo_limit`]).
const LIMIT_SHARES: [f64; 4] = [0.45, 0.6, 0.75, 0.9];

/// Ratio either side of the clamp the motor constants were fitted with ([`servo::Clamp`]) at
/// which the servo set is also tried.
const CLAMP_STEP: f64 = 1.15;

/// The servo's set `drive` with a torque limit on its driven joints that stalled or whose
/// motor constants were fitted clamped (`limited`), fitted by multiple shooting: the limit (a
/// share of each joint's largest command, the same share on every joint) searched over
/// [`LIMIT_SHARES`] and then half a step either side of the best; and, where the motor
/// constants were fitted clamped ([`servo::Clamp`]), the set with the limit at that clamp and
/// [`CLAMP_STEP`] either side. A servo stops where its drive can give no more (a current
/// limit, a stall), which a load-dependent friction also explains: the friction that stalls
/// the drive at full duty then brakes it at every duty, and a servo held with a low gain, whose
/// duty is small, is predicted too stiff. The limited set is returned when it predicts the fit runs
/// better than `drive` by [`ADD_GAIN`] (a limit is one more parameter) and than `drive` fitted
/// again from the limited set's answer (where the limit only led the fit to a better answer of
/// the others, that set is returned instead); the note says what was found either way.
///
/// On the Rhoban XL330 logs, with the `sin_time_square` logs held out, the set without a limit
/// had been selected (load friction 0.45 × |τ|, torque gain 1.66): whole-run error 66.5 mrad on
/// the held-out Kp 100 log. With a limit at 45 % of the largest command (load friction 0.50 ×
/// |τ|, gain 2.53) it is 40.0 mrad; BAM's best published model has 19.1. On simulated servos
/// with a limit at a sixth to a quarter of their stall torque (`examples/servo_limit.rs`) the
/// grid alone, whose lowest share is far above such a limit, settled on a torque gain twice
/// the truth with the limit half of it, and wrong mechanics beside them; with constants fitted
/// clamped and the search at the clamp, the most torque came within 15 % of the limit in each
/// of the 5 that stalled.
pub(super) fn servo_limit(
    scorer: &Scorer<'_>,
    shoot_runs: &shooting::Windows,
    sopts: &shooting::Options,
    drive: &Tried,
    limited: &[usize],
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<(Option<Tried>, String)> {
    let ctx = scorer.ctx;
    let joints: Vec<usize> = drive.terms.iter().filter_map(|t| if let Term::Gain(j) = t { Some(*j) } else { None }).filter(|j| limited.contains(j)).collect();
    if joints.is_empty() {
        return Ok((None, "no driven servo joint stalled or was fitted clamped: no torque limit tried".into()));
    }
    let unit = |j: usize| simgap_sim::Quantity::Effort.unit(scorer.model.joints()[j].kind);
    // the set with a limit `limits[i]` on `joints[i]`, each half started where the set without
    // a limit ended on it
    let try_limits = |limits: &[f64], what: String| -> Result<Tried> {
        let mut terms = drive.terms.clone();
        terms.extend(joints.iter().zip(limits).map(|(&j, &l)| Term::Saturation { joint: j, limit: l.max(ctx.saturation_floor[j]) }));
        let earlier = |half: usize, designs: &[TermDesign]| vec![transfer(drive, &drive.halves[half], &terms, designs)];
        let name = format!("the servo's motor constants with rotor inertia, load-dependent and viscous friction and a torque limit {what}");
        try_set(scorer, shoot_runs, sopts, &name, &terms, &earlier, stop)
    };
    // (the share, for the grid's tries; what was tried, in words; the fit)
    let try_share = |share: f64| -> Result<(Option<f64>, String, Tried)> {
        let limits: Vec<f64> = joints.iter().map(|&j| share * ctx.max_command(j)).collect();
        let what = format!("at {:.1} % of each joint's largest command", 100.0 * share);
        Ok((Some(share), what.clone(), try_limits(&limits, what)?))
    };
    let best_of = |tries: Vec<(Option<f64>, String, Tried)>| tries.into_iter().min_by(|a, b| a.2.score.total_cmp(&b.2.score));
    let coarse = best_of(LIMIT_SHARES.into_iter().map(try_share).collect::<Result<_>>()?);
    let step = 0.5 * (LIMIT_SHARES[1] - LIMIT_SHARES[0]);
    let at = coarse.as_ref().and_then(|c| c.0).unwrap_or(LIMIT_SHARES[0]);
    let near: Vec<(Option<f64>, String, Tried)> = [at - step, at + step].into_iter().filter(|s| *s > 0.0 && *s < 1.0).map(try_share).collect::<Result<_>>()?;
    let grid_best = best_of(coarse.into_iter().chain(near).collect());
    // at the clamp the motor constants were fitted with, and a step either side, on the joints
    // fitted clamped; the others at the grid's best share
    let grid = grid_best.as_ref().and_then(|b| b.0).unwrap_or(at);
    let clamps: Vec<Option<servo::Clamp>> = joints.iter().map(|&j| scorer.prep.servo.as_ref().and_then(|c| c.clamp.get(j).copied().flatten())).collect();
    let clamped = clamps.iter().any(Option::is_some);
    let mut from_clamp = Vec::new();
    if clamped {
        for f in [1.0, 1.0 / CLAMP_STEP, CLAMP_STEP] {
            let limits: Vec<f64> = joints.iter().zip(&clamps).map(|(&j, c)| c.map_or(grid * ctx.max_command(j), |c| f * c.limit)).collect();
            let what = format!(
                "at {}the clamp the motor constants were fitted with ({})",
                if f == 1.0 { String::new() } else { format!("{f:.3} times ") },
                joints
                    .iter()
                    .zip(&limits)
                    .zip(&clamps)
                    .map(|((&j, l), c)| format!("{l:.3} {} on {}{}", unit(j), scorer.model.joint_names()[j], if c.is_some() { "" } else { " at the grid's best share" }))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            from_clamp.push((None, what.clone(), try_limits(&limits, what)?));
        }
    }
    let Some((_, what, limited)) = best_of(grid_best.into_iter().chain(from_clamp).collect()) else { return Ok((None, String::new())) };
    let shares: Vec<String> = LIMIT_SHARES.iter().map(|s| format!("{:.0}", 100.0 * s)).collect();
    let head = format!(
        "multiple shooting: the servo's set with a torque limit on its stalled or clamped joints {what} (the best of {} % of each joint's largest command, half a step either side of the best{}) predicts the fit runs at {:.4} of the nominal model's k-step error, against {:.4} without it",
        shares.join(", "),
        if clamped { format!(", and the clamp the motor constants were fitted with and {CLAMP_STEP} times either side") } else { String::new() },
        limited.score,
        drive.score
    );
    if !(limited.score < drive.score * (1.0 - ADD_GAIN)) {
        return Ok((None, format!("{head}: not better by {:.0} %, so not tried further", 100.0 * ADD_GAIN)));
    }
    // the limit may only have led the shooting fit to a better answer of the other parameters
    // (on the self-check's servos without one, limits at 82–98 % of the largest command "won"
    // so): the set without it, started where the limited set ended, must do worse
    let earlier = |half: usize, designs: &[TermDesign]| vec![transfer(&limited, &limited.halves[half], &drive.terms, designs)];
    let name = format!("{} (started where the set with a torque limit ended)", drive.name);
    let unlimited = try_set(scorer, shoot_runs, sopts, &name, &drive.terms, &earlier, stop)?;
    if limited.score < unlimited.score * (1.0 - ADD_GAIN) {
        Ok((Some(limited), format!("{head}, and {:.4} without the limit when started from its answer: tried as a set of its own", unlimited.score)))
    } else {
        let note = format!(
            "{head}, but without the limit, started from its answer, the set predicts them at {:.4}: the limit only led the fit elsewhere, and the set without it is tried",
            unlimited.score
        );
        Ok((Some(unlimited), note))
    }
}

/// The servo's set `base` (the lower-scoring of its set with and without a torque limit) with
/// each load friction replaced by a load Stribeck friction (`load_stribeck_friction`: its
/// level rises at rest, `fs + mus |τ|` above `fc + mu |τ|`), the Stribeck velocity searched
/// over [`load_stribeck::VS_GRID`](crate::vocabulary::LOAD_STRIBECK_VS_GRID) times each
/// joint's width, each fitted by multiple shooting, each half started where `base` ended on it
/// (the moving levels as `base` fitted them, no rise). Returned when it predicts the fit runs
/// better than `base` by [`ADD_GAIN`] (two parameters more per joint); the note says what was
/// found either way, with the ratio of its error to `base`'s on each fit run. Tried only when
/// [`DiagnoseOptions::load_stribeck_friction`](crate::options::DiagnoseOptions::load_stribeck_friction)
/// asks (see there why it is off by default).
///
/// On the Rhoban XL330 logs the arm lifting towards a goal stops short of it and stays there
/// for seconds while the P loop's duty rises by up to 29 % (the `up_and_down` trajectory): a
/// friction that grows with the drive's torque and brakes the arm in motion cannot also hold
/// it, unless its level at rest is higher.
pub(super) fn load_friction_at_rest(
    scorer: &Scorer<'_>,
    shoot_runs: &shooting::Windows,
    sopts: &shooting::Options,
    base: &Tried,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<(Option<Tried>, String)> {
    let grid = crate::vocabulary::LOAD_STRIBECK_VS_GRID;
    let try_vs = |ratio: f64| -> Result<Tried> {
        let terms: Vec<Term> =
            base.terms.iter().map(|t| if let Term::LoadFriction { joint, w } = *t { Term::LoadStribeck { joint, vs: ratio * w, w } } else { t.clone() }).collect();
        // each half from `base`'s answer on it, the load Stribeck friction's moving levels
        // from its load friction and no rise
        let earlier = |half: usize, designs: &[TermDesign]| {
            let mut theta = transfer(base, &base.halves[half], &terms, designs);
            let at: Vec<usize> = base.designs.iter().scan(0, |c, d| Some(std::mem::replace(c, *c + d.cols.len()))).collect();
            let mut c = 0;
            for (t, d) in terms.iter().zip(designs) {
                if let Term::LoadStribeck { joint, w, .. } = *t {
                    if let Some(i) = base.terms.iter().position(|b| *b == Term::LoadFriction { joint, w }) {
                        theta[c] = base.halves[half][at[i]];
                        theta[c + 1] = base.halves[half][at[i] + 1];
                    }
                }
                c += d.cols.len();
            }
            vec![theta]
        };
        let name = format!("{} with its load friction rising at rest (load Stribeck friction, vs = {ratio} w)", base.name);
        try_set(scorer, shoot_runs, sopts, &name, &terms, &earlier, stop)
    };
    // (the velocities' fits are independent: on as many cores as there are)
    let tries: Vec<Tried> = grid.par_iter().map(|&r| try_vs(r)).collect::<Result<_>>()?;
    let scores: Vec<String> = grid.iter().zip(&tries).map(|(r, t)| format!("{:.4} at vs = {r} w", t.score)).collect();
    let Some(best) = tries.into_iter().min_by(|a, b| a.score.total_cmp(&b.score)) else { return Ok((None, String::new())) };
    let head = format!(
        "multiple shooting: {} with its load friction rising at rest (a load Stribeck friction, vs searched over {} times the joint's width w) predicts the fit runs at {}, against {:.4} without the rise",
        base.name,
        grid.map(|r| r.to_string()).join(", "),
        scores.join(", "),
        base.score
    );
    let ratios: Vec<String> = best.cv_per_run.iter().zip(&base.cv_per_run).map(|(a, b)| format!("{:.3}", kstep::score(a, b))).collect();
    let head = format!("{head} (fit run by fit run, against the set without the rise: {})", ratios.join(", "));
    if best.score < base.score * (1.0 - ADD_GAIN) {
        Ok((Some(best), format!("{head}: tried as a set of its own")))
    } else {
        Ok((None, format!("{head}: not better by {:.0} %, so not tried further", 100.0 * ADD_GAIN)))
    }
}
