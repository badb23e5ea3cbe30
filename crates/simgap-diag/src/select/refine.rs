//! The shooting stage, for open-loop fit runs: candidate sets fitted by multiple shooting and
//! kept when their two-fold cross-validated prediction of the fit runs says so.

use rayon::prelude::*;
use simgap_sim::ControllerKind;

use crate::error::Result;
use crate::lsq;
use crate::options::{check_stop, DiagnoseOptions, Progress};
use crate::prediction::kstep::{self, FOLDS_PER_RUN};
use crate::prepare::servo;
use crate::select::prediction::{ADD_GAIN, PRUNE_TOLERANCE};
use crate::select::scorer::Scorer;
use crate::select::shooting;
use crate::vocabulary::fitted_terms;
use crate::vocabulary::{effects, Term, TermDesign};

/// A set of terms whose parameters multiple shooting fitted.
pub(crate) struct Refined {
    /// What the set is, in words.
    pub(crate) name: String,
    pub(crate) terms: Vec<Term>,
    pub(crate) designs: Vec<TermDesign>,
    /// The fit on all fit runs; its `std` is the reported spread (shooting's own, the halves'
    /// disagreement and the torque-residual fit's, combined).
    pub(crate) shot: shooting::Shot,
    /// Shooting's own standard deviations, `σ² (JᵀJ)⁻¹` alone.
    pub(crate) own_std: nalgebra::DVector<f64>,
    /// Cross-validated k-step RMS per horizon on the fit runs [rad].
    pub(crate) cv: Vec<f64>,
    /// Its score against the nominal model ([`kstep::score`]).
    pub(crate) score: f64,
    /// Whether `score` is still the score of `terms` (false once a term left or was replaced
    /// without a refit).
    pub(crate) scored_as_is: bool,
    /// The set as its two-fold cross-validation fitted it (terms, designs, each half's answer):
    /// the leak-free starts of a set with a term more or less.
    pub(crate) halves: (Vec<Term>, Vec<TermDesign>, Vec<nalgebra::DVector<f64>>),
    /// The fit runs cut into shooting windows, as it was fitted on (shared with its refits).
    pub(crate) runs: std::sync::Arc<Vec<kstep::PredictionRun>>,
}

/// A set tried by the shooting stage: its two-fold cross-validation.
pub(crate) struct Tried {
    pub(crate) name: String,
    pub(crate) terms: Vec<Term>,
    pub(crate) designs: Vec<TermDesign>,
    /// The fits on each half of the fit runs.
    pub(crate) halves: Vec<nalgebra::DVector<f64>>,
    pub(crate) cv: Vec<f64>,
    /// Cross-validated k-step RMS per horizon of each fit run [rad] (empty where not kept).
    pub(crate) cv_per_run: Vec<Vec<f64>>,
    pub(crate) score: f64,
    /// Whether its gain over the nominal model holds fold by fold.
    pub(crate) test: kstep::FoldTest,
}

/// The shooting stage, for open-loop fit runs: the selected set, the selected set with an
/// inertial correction in place of a payload, and the physically natural set of a system-
/// identification run (inertial error of every link, Coulomb and viscous friction and rotor
/// inertia on every joint), on servo logs the servo's own set (its motor constants, rotor
/// inertia, load-dependent and viscous friction) and, where a fit log shows the servo stalled
/// ([`stalled_joints`]) or its motor constants were fitted clamped ([`servo::Clamp`]), the
/// servo's set with a limit ([`servo_limit`]), each fitted by
/// multiple shooting ([`shooting`]) from the start of lowest cost among its torque-residual
/// fit, the same with the URDF's inertia, and the answers of the sets tried before it (shared
/// terms kept, the others at 0).
///
/// Feedback runs keep the torque-residual fit: their torque residual is well conditioned (the
/// controller keeps the motion near its reference, accelerations are smooth), while in a k-step
/// window the controller corrects the model's errors, so prediction constrains the parameters
/// less. (On the synthetic demo, shooting predicted the held-out run better but moved the
/// elbow's viscous friction from 2.3 % to 3.7 % off the hidden value.)
///
/// Each set is scored by two-fold cross-validated k-step prediction of the fit runs: the fit runs'
/// folds are split into even and odd ones (alternate fifths of every run); each half is fitted
/// (torque-residual start and shooting) on the other half alone and predicted with it. The set of
/// lowest score replaces the selection when it beats `current` (the selected set's score with its
/// torque-residual fit, cross-validated over every fold) by [`ADD_GAIN`]; it is then refitted on
/// all fit runs. Returns it (or none) and notes saying what was tried.
pub(crate) fn refine_by_shooting(
    scorer: &Scorer<'_>,
    selected: &[Term],
    current: f64,
    progress: &mut dyn FnMut(Progress),
    options: &DiagnoseOptions,
) -> Result<(Option<Refined>, Vec<String>)> {
    let (model, ctx, prep) = (scorer.model, scorer.ctx, scorer.prep);
    let n = model.dof();
    let has_inertial = ctx.inertial_basis.ncols() > 0;
    // open-loop replays, and servos (their firmware loop is known exactly: its prediction
    // restarted from the measured state is the drive's, not a tracking controller's)
    let open_loop = prep.fit_runs.iter().all(|r| r.experiment.as_ref().is_none_or(|e| matches!(e.controller, ControllerKind::Replay | ControllerKind::Servo)));
    if !open_loop {
        return Ok((None, Vec::new()));
    }
    let servo = prep.servo.is_some();
    let mut sets: Vec<(String, Vec<Term>)> = Vec::new();
    let fitted_columns = |terms: &[Term]| terms.iter().any(|t| !matches!(t, Term::Saturation { .. } | Term::Delay { .. } | Term::CoriolisStructure));
    if fitted_columns(selected) {
        sets.push(("the selected set".into(), selected.to_vec()));
    }
    if has_inertial && selected.iter().any(|t| matches!(t, Term::Payload { .. })) {
        let mut with: Vec<Term> = selected.iter().filter(|t| !matches!(t, Term::Payload { .. })).cloned().collect();
        with.push(ctx.inertial_term());
        sets.push(("the selected set with an inertial correction of every link in place of the payload".into(), with));
    }
    if has_inertial {
        let rotor = crate::vocabulary::rotor::visible(ctx.data);
        let mut natural = vec![ctx.inertial_term()];
        for j in 0..n {
            natural.push(Term::Coulomb { joint: j, w: ctx.dry_width[j].mid() });
            natural.push(Term::Viscous(j));
            if rotor && !prep.passive[j] {
                natural.push(Term::Armature(j));
            }
        }
        let name = if rotor {
            "an inertial correction of every link with Coulomb and viscous friction and rotor inertia on every joint"
        } else {
            "an inertial correction of every link with Coulomb and viscous friction on every joint"
        };
        sets.push((name.into(), natural));
    }
    if servo {
        // a servo's own structure: its motor constants (drive gain kt/R, back-EMF kt²/R where a
        // drop with torque off tells it from viscous friction), rotor inertia, load-dependent and
        // viscous friction
        let mut drive = Vec::new();
        for j in (0..n).filter(|&j| !prep.passive[j]) {
            drive.push(Term::Gain(j));
            if crate::vocabulary::back_emf::separable(j, ctx.data) {
                drive.push(Term::BackEmf(j));
            }
            drive.push(Term::Armature(j));
            drive.push(Term::LoadFriction { joint: j, w: ctx.dry_width[j].mid() });
            drive.push(Term::Viscous(j));
        }
        sets.push(("the servo's motor constants with rotor inertia, load-dependent and viscous friction".into(), drive));
    }
    if sets.is_empty() {
        return Ok((None, Vec::new()));
    }
    let sopts = shooting_options(scorer);
    let shoot_runs = std::sync::Arc::new(shooting::shooting_runs(&prep.fit_pred, options.prepare.window, &sopts));
    let stop = options.stop.as_deref();
    let mut tried: Vec<Tried> = Vec::new();
    // the sets, the servo's set with a torque limit, with friction rising at rest, the chosen
    // set on all fit runs
    let total = sets.len() + usize::from(servo) * (1 + usize::from(options.load_stribeck_friction)) + 1;
    for (si, (name, terms)) in sets.iter().enumerate() {
        progress(Progress { stage: "refining by multiple shooting", done: si, total });
        check_stop(options)?;
        // a larger set starts where the smaller ones tried before it ended
        let earlier = |half: usize, designs: &[TermDesign]| -> Vec<nalgebra::DVector<f64>> { tried.iter().map(|t| transfer(t, &t.halves[half], terms, designs)).collect() };
        let t = try_set(scorer, &shoot_runs, &sopts, name, terms, &earlier, stop)?;
        tried.push(t);
    }
    let mut limit_notes = Vec::new();
    if servo {
        progress(Progress { stage: "refining by multiple shooting", done: sets.len(), total });
        // the joints a fit log shows stalled, and those whose motor constants were fitted
        // with their torque clamped
        let mut limited_joints = stalled_joints(scorer).to_vec();
        let clamped = scorer.prep.servo.as_ref().map(|c| c.clamp.iter().enumerate().filter(|(_, c)| c.is_some()).map(|(j, _)| j).collect::<Vec<_>>()).unwrap_or_default();
        limited_joints.extend(clamped);
        limited_joints.sort_unstable();
        limited_joints.dedup();
        if limited_joints.is_empty() {
            limit_notes.push(format!(
                "no fit log shows the servo stalled (at full duty for {} s or more with its joint at rest), and its motor law fits unclamped: the servo's set is not tried with a torque limit",
                servo::MIN_STALL
            ));
        } else if let Some(drive) = tried.last() {
            // (on servo logs the servo's set is the last set tried)
            let (limited, note) = servo_limit(scorer, &shoot_runs, &sopts, drive, &limited_joints, stop)?;
            tried.extend(limited);
            limit_notes.push(note);
        }
        // the servo's set (with its limit, if that predicts better) with its load friction
        // rising at rest, when asked for
        let of_servo = |t: &&Tried| t.terms.iter().any(|x| matches!(x, Term::LoadFriction { .. })) && t.terms.iter().any(|x| matches!(x, Term::Gain(_)));
        let base = tried.iter().skip(sets.len() - 1).filter(of_servo).min_by(|a, b| a.score.total_cmp(&b.score));
        if let (Some(base), true) = (base, options.load_stribeck_friction) {
            progress(Progress { stage: "refining by multiple shooting", done: sets.len() + 1, total });
            let (risen, note) = load_friction_at_rest(scorer, &shoot_runs, &sopts, base, stop)?;
            tried.extend(risen);
            limit_notes.push(note);
        }
    }
    let mut notes: Vec<String> = tried
        .iter()
        .map(|r| {
            format!(
                "multiple shooting ({} s windows restarted from the measured state, errors at {} instants per window; two-fold cross-validation over alternate fifths of every fit run): {} predicts the fit runs at {:.4} of the nominal model's k-step error (fold by fold: upper 2-standard-error bound {:.3}, worst fold {:.3}; torque-residual fit of the selected set: {current:.4})",
                sopts.window, sopts.points, r.name, r.score, r.test.bound, r.test.worst
            )
        })
        .collect();
    notes.extend(limit_notes);
    let Some(bi) = (0..tried.len()).min_by(|a, b| tried[*a].score.total_cmp(&tried[*b].score)) else { return Ok((None, notes)) };
    if tried[bi].score < current * (1.0 - ADD_GAIN) && !tried[bi].test.holds(PRUNE_TOLERANCE, ADD_GAIN) {
        notes.push(format!(
            "multiple shooting: {} predicts the fit runs at {:.4} of the nominal model's k-step error, but not in every part of them (fold by fold, the upper 2-standard-error bound of that ratio is {:.3} and the worst fold's {:.3}): the torque-residual answer is kept",
            tried[bi].name, tried[bi].score, tried[bi].test.bound, tried[bi].test.worst
        ));
        return Ok((None, notes));
    }
    if !(tried[bi].score < current * (1.0 - ADD_GAIN)) {
        notes.push(format!(
            "multiple shooting does not predict the fit runs better than the torque-residual fit by {:.0} %: the torque-residual parameters are kept",
            100.0 * ADD_GAIN
        ));
        return Ok((None, notes));
    }
    // the chosen set on all fit runs
    progress(Progress { stage: "refining by multiple shooting", done: total - 1, total });
    let best = tried.swap_remove(bi);
    let (refined, more) = finish(scorer, &shoot_runs, &sopts, best, "the parameters of the selected effects are fitted", stop)?;
    notes.extend(more);
    Ok((Some(refined), notes))
}

/// Levenberg–Marquardt iterations at most of a shooting fit on servo logs (10 elsewhere,
/// [`shooting::Options`]). A servo's drive gain, torque limit and load-dependent friction trade
/// with one another, and their fits were still descending at 10: on the Rhoban XL330 logs the
/// final fits of two folds of four stopped there, and 25 took the held-out `sin_time_square`
/// logs' 0.5 s k-step error from 51.4 to 38.8 mrad. (For every set on every log, it changed the
/// DFKI case study in the third digit and, on one synthetic double-pendulum replay, let a set
/// with an inertial correction beat the torque-residual fit on the fit runs by 2.3 % and predict
/// the held-out run five times worse.)
const SERVO_ITERATIONS: usize = 25;

/// The options of the shooting fits of these logs: [`SERVO_ITERATIONS`] on servo logs.
fn shooting_options(scorer: &Scorer<'_>) -> shooting::Options {
    let mut o = shooting::Options::default();
    if scorer.prep.servo.is_some() {
        o.max_iterations = SERVO_ITERATIONS;
    }
    o
}

/// The driven servo joints that some fit log shows stalled ([`servo::stalls`]): at full duty
/// for [`servo::MIN_STALL`] or more, at rest. Only there is a torque limit evidenced.
/// Computed once per scorer (the fit logs do not change).
fn stalled_joints<'s>(scorer: &'s Scorer<'_>) -> &'s [usize] {
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
fn servo_limit(
    scorer: &Scorer<'_>,
    shoot_runs: &[kstep::PredictionRun],
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
/// [`DiagnoseOptions::load_stribeck_friction`] asks (see there why it is off by default).
///
/// On the Rhoban XL330 logs the arm lifting towards a goal stops short of it and stays there
/// for seconds while the P loop's duty rises by up to 29 % (the `up_and_down` trajectory): a
/// friction that grows with the drive's torque and brakes the arm in motion cannot also hold
/// it, unless its level at rest is higher.
fn load_friction_at_rest(
    scorer: &Scorer<'_>,
    shoot_runs: &[kstep::PredictionRun],
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
    let tries: Vec<Tried> = grid.iter().map(|&r| try_vs(r)).collect::<Result<_>>()?;
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

/// θ of the set `to` from the answer `theta` of the set `from`: shared terms keep their values,
/// the others start at 0 (no friction, no rotor inertia, the URDF's inertia), so that a larger
/// set starts where a smaller one ended.
fn transfer(from: &Tried, theta: &nalgebra::DVector<f64>, to: &[Term], to_designs: &[TermDesign]) -> nalgebra::DVector<f64> {
    let k: usize = to_designs.iter().map(|d| d.cols.len()).sum();
    let mut out = nalgebra::DVector::zeros(k);
    let mut c = 0;
    for (t, d) in to.iter().zip(to_designs) {
        let mut cf = 0;
        for (tf, df) in from.terms.iter().zip(&from.designs) {
            if tf == t && df.cols.len() == d.cols.len() {
                out.rows_mut(c, d.cols.len()).copy_from(&theta.rows(cf, d.cols.len()));
            }
            cf += df.cols.len();
        }
        c += d.cols.len();
    }
    out
}

/// The starts [`starts`] gives, in words, in its order.
const START_NAMES: [&str; 2] = ["the torque-residual fit", "the torque-residual fit with the URDF's inertia"];

/// Starts of a shooting fit: the torque-residual fit `theta`, and the same with the URDF's
/// inertia where the set corrects it.
fn starts(designs: &[TermDesign], theta: nalgebra::DVector<f64>) -> Vec<nalgebra::DVector<f64>> {
    let mut c = 0;
    let mut urdf = theta.clone();
    let mut inertial = false;
    for d in designs {
        if d.inertial.is_some() {
            urdf.rows_mut(c, d.cols.len()).fill(0.0);
            inertial = true;
        }
        c += d.cols.len();
    }
    if inertial {
        vec![theta, urdf]
    } else {
        vec![theta]
    }
}

/// Extra starts of a half's shooting fit (the half, the set's designs): answers of other sets on
/// the same half.
type EarlierStarts<'a> = dyn Fn(usize, &[TermDesign]) -> Vec<nalgebra::DVector<f64>> + 'a;

/// The answers of [`try_set`]'s halves, in words, in its order: half `h` holds out the folds
/// (fifths of every run) whose index has parity `h`, and is fitted on the others.
const HALF_NAMES: [&str; 2] = ["the answer fitted on the 2nd and 4th fifths of every fit run", "the answer fitted on the 1st, 3rd and 5th fifths"];

/// One set's two-fold cross-validation by multiple shooting: each half of the fit runs' folds
/// (alternate fifths of every run) fitted on the other half alone, from its torque-residual fit
/// and `earlier(half, designs)`, and predicted with it.
fn try_set(
    scorer: &Scorer<'_>,
    shoot_runs: &[kstep::PredictionRun],
    sopts: &shooting::Options,
    name: &str,
    terms: &[Term],
    earlier: &EarlierStarts<'_>,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<Tried> {
    let (model, formulation, ctx, prep) = (scorer.model, scorer.formulation, scorer.ctx, scorer.prep);
    let n = model.dof();
    let (designs, gr, _) = ctx.fit_terms(terms);
    let mut merged: Vec<kstep::Errors> =
        prep.fit_pred.iter().map(|pr| kstep::Errors { horizons: prep.horizons.len(), dof: n, sq: vec![f64::NAN; pr.windows() * prep.horizons.len() * n] }).collect();
    let mut halves = Vec::new();
    for half in 0..2 {
        let held = |f: usize| (f % FOLDS_PER_RUN) % 2 == half;
        let keep = |r: usize, w: usize| !held(shoot_runs[r].fold[w]);
        let problem = shooting::Problem { model, formulation, terms, designs: &designs, runs: shoot_runs, keep: &keep, options: sopts };
        let mut from = starts(&designs, lsq::theta_without(&gr, &held));
        from.extend(earlier(half, &designs));
        let shot = shooting::fit(&problem, &from, stop)?;
        let eff = effects::to_effects(model, &fitted_terms(terms, &designs, &shot.theta, None));
        let errs: Vec<kstep::Errors> =
            prep.fit_pred.par_iter().map(|pr| kstep::predict(model, formulation, &eff, pr, &prep.horizons, &|w| held(pr.fold[w]))).collect::<Result<_>>()?;
        for (m, e) in merged.iter_mut().zip(&errs) {
            for (a, v) in m.sq.iter_mut().zip(&e.sq) {
                if v.is_finite() {
                    *a = *v;
                }
            }
        }
        halves.push(shot.theta);
    }
    let mut all = kstep::Errors { horizons: prep.horizons.len(), dof: n, sq: Vec::new() };
    for m in &merged {
        all.sq.extend_from_slice(&m.sq);
    }
    let cv = all.rms();
    let score = kstep::score(&cv, &scorer.nominal);
    let test = scorer.against_nominal(&all);
    let cv_per_run = merged.iter().map(kstep::Errors::rms).collect();
    Ok(Tried { name: name.to_string(), terms: terms.to_vec(), designs, halves, cv, cv_per_run, score, test })
}

/// The set `best` fitted on all fit runs (from its torque-residual fit and its halves' answers),
/// with the reported spread; terms fitted at their lower bound 0 are left out. Returns it and a
/// note of what was done.
fn finish(
    scorer: &Scorer<'_>,
    shoot_runs: &std::sync::Arc<Vec<kstep::PredictionRun>>,
    sopts: &shooting::Options,
    best: Tried,
    what: &str,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<(Refined, Vec<String>)> {
    let (model, formulation, ctx) = (scorer.model, scorer.formulation, scorer.ctx);
    let mut notes = Vec::new();
    let keep = |_: usize, _: usize| true;
    let (_, _, f) = ctx.fit_terms(&best.terms);
    let problem = shooting::Problem { model, formulation, terms: &best.terms, designs: &best.designs, runs: shoot_runs, keep: &keep, options: sopts };
    // starts: the torque-residual fit (and with the URDF's inertia), the two halves' answers
    let mut from = starts(&best.designs, f.theta.clone());
    let mut start_names: Vec<&str> = START_NAMES[..from.len()].to_vec();
    from.extend(best.halves.iter().cloned());
    start_names.extend(&HALF_NAMES[..best.halves.len()]);
    let mut shot = shooting::fit(&problem, &from, stop)?;
    // where the fit began, and whether it moved from there (on rough costs, e.g. a servo's
    // stalls and clipped duty, no step may lower it: the answer is then that start's)
    let began = start_names.get(shot.start).copied().unwrap_or("a start");
    let moved = if shot.cost < shot.cost_start {
        format!("from {began}, the start of lowest cost")
    } else {
        format!("from {began}, the start of lowest cost, which no step improved: the answer is that start's")
    };
    // the other method's answer, where it estimates the same thing: on logs their recorder
    // low-pass filtered, the torque-residual fit is distorted where the filter flattened the
    // torque's peaks (`prepare::lowpass`): its disagreement measures that distortion, not the
    // error of the shooting answer. On both seeds' self-check, the filtered and link-side
    // scenarios' intervals held 202 of 216 true values without it (206 with it, at a median 3.2
    // times the width: a link-side viscous friction of 0.81 N·m·s/rad was reported ± 0.96, its
    // shooting spread ± 0.005)
    let filtered = crate::prepare::lowpass::any_filtered(ctx.data);
    // on servo logs that show the servo stalled, the torque-residual fit reads the stalled
    // drive's full command as torque and a joint held at rest by dry friction as unexplained:
    // on the Rhoban XL330 logs (`sin_time_square` held out) it fitted no load-dependent friction
    // where shooting fits 0.38 × |τ|, and its disagreement made the gain's, the rotor inertia's
    // and the load friction's intervals hold the value of no effect (k = 2.12 ± 1.49). There
    // the spread between fit logs stands in for it (`run_jackknife`; k = 2.17 ± 0.14, and
    // across the three folds that select a gain, fitted on different trajectory kinds,
    // k = 1.72–2.34). With fewer fit logs than [`MIN_JACKKNIFE_RUNS`] the disagreement stays
    // (wide, not understated)
    let stalled = scorer.prep.servo.is_some() && !stalled_joints(scorer).is_empty();
    // (a leave-one-out fit that fails, e.g. a simulation that diverges without one log, keeps
    // the disagreement instead; only a stop request ends the diagnosis)
    let jackknife = if stalled && !filtered && shoot_runs.len() >= MIN_JACKKNIFE_RUNS {
        match run_jackknife(&problem, &shot.theta, stop) {
            Ok(answers) => Some(answers),
            Err(crate::error::Error::Interrupted) => return Err(crate::error::Error::Interrupted),
            Err(_) => None,
        }
    } else {
        None
    };
    let method_term = if filtered {
        " (not the difference from the torque-residual fit of the same set: these logs were low-pass filtered by their recorder, which distorts that fit)".to_string()
    } else if let Some(j) = &jackknife {
        format!(
            ", and the delete-one-log jackknife variance of the answers fitted with each of the {} fit logs left out (not the difference from the torque-residual fit of the same set: a fit log shows the servo stalled, which that fit reads as torque)",
            j.len()
        )
    } else {
        ", and the squared difference from the torque-residual fit of the same set (the disagreement of two methods bounds the error either makes)".to_string()
    };
    notes.push(format!(
        "{what} by multiple shooting on all fit runs {moved} (normalised k-step cost {:.3e} → {:.3e} in {} iterations); their 95 % intervals are 1.96 σ with σ² the sum of σ² (JᵀJ)⁻¹ of the shooting residuals and a quarter of the squared difference of the two halves' answers (each half fitted again from its answer and from the answer on all fit runs, the lower cost on it kept){method_term}",
        shot.cost_start, shot.cost, shot.iterations
    ));
    // the reported spread: σ² (JᵀJ)⁻¹ alone treats the errors along a window as independent
    // and misses what the whole record shares (the self-check found 38 % coverage with it);
    // the two halves' disagreement (σ of a full-data answer ≈ |θ₁ − θ₂| / 2) and the other
    // method's answer or the jackknife over fit logs add what it misses (shooting's own σ is
    // kept as an interval variant)
    let shot_std = shot.std.clone();
    // each half's answer again, started also from the answer on all fit runs, the lower cost
    // on that half kept: two halves that ended in different basins measure where their fits
    // began, not the data's scatter. (On the Rhoban XL330 logs with the `sin_sin` logs held
    // out, one half's answer had no inertial correction and a load friction of 0.04 × |τ|
    // against 0.46 on all fit runs; started from that answer, its own half's cost fell from
    // above 7.10e-2 to 6.11e-2, and the halves' disagreement, which had made the viscous, load
    // and cogging frictions' intervals hold no effect, shrank to the jackknife's size)
    let halves_again: Vec<nalgebra::DVector<f64>> = best
        .halves
        .iter()
        .enumerate()
        .map(|(half, own)| {
            let held = |f: usize| (f % FOLDS_PER_RUN) % 2 == half;
            let keep = |r: usize, w: usize| !held(shoot_runs[r].fold[w]);
            let p = shooting::Problem { keep: &keep, ..problem };
            Ok(shooting::fit(&p, &[own.clone(), shot.theta.clone()], stop)?.theta)
        })
        .collect::<Result<_>>()?;
    let halves = match (halves_again.first(), halves_again.get(1)) {
        (Some(a), Some(b)) if a.len() == shot.theta.len() && b.len() == shot.theta.len() => Some((a, b)),
        _ => None,
    };
    let jack_var = jackknife.as_deref().map(jackknife_variance);
    for i in 0..shot.theta.len() {
        let half = halves.map_or(0.0, |(a, b)| 0.5 * (a[i] - b[i]));
        let disagreement = || f.theta.get(i).map_or(0.0, |t| (shot.theta[i] - t).powi(2));
        let other = match &jack_var {
            Some(v) => v.get(i).copied().filter(|x| x.is_finite()).unwrap_or_else(disagreement),
            None if filtered => 0.0,
            None => disagreement(),
        };
        let total = (shot.std[i].powi(2) + half.powi(2) + other).sqrt();
        shot.std[i] = if total.is_finite() { total } else { shot.std[i] };
    }
    // a friction, rotor inertia or payload at its lower bound 0 is no effect: left out
    let (mut terms, mut designs, mut theta, mut std, mut own_std) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut none: Vec<String> = Vec::new();
    let mut c = 0;
    for (t, d) in best.terms.iter().zip(&best.designs) {
        let k = d.cols.len();
        let zero = d.inertial.is_none() && k > 0 && (0..k).all(|a| shot.theta[c + a] == 0.0 && d.lo.get(a) == Some(&0.0));
        if zero {
            none.push(t.describe(&scorer.model.joint_names().iter().map(|s| s.to_string()).collect::<Vec<_>>()));
        } else {
            terms.push(t.clone());
            designs.push(d.clone());
            theta.extend_from_slice(&shot.theta.as_slice()[c..c + k]);
            std.extend_from_slice(&shot.std.as_slice()[c..c + k]);
            own_std.extend_from_slice(&shot_std.as_slice()[c..c + k]);
        }
        c += k;
    }
    if !none.is_empty() {
        notes.push(format!("fitted by multiple shooting at their bound 0, so left out: {}", none.join(", ")));
    }
    let shot = shooting::Shot { theta: nalgebra::DVector::from_vec(theta), std: nalgebra::DVector::from_vec(std), ..shot };
    let halves = (best.terms, best.designs, best.halves);
    Ok((
        Refined {
            name: best.name,
            terms,
            designs,
            shot,
            own_std: nalgebra::DVector::from_vec(own_std),
            cv: best.cv,
            score: best.score,
            scored_as_is: true,
            halves,
            runs: shoot_runs.clone(),
        },
        notes,
    ))
}

/// Fewest fit logs for a jackknife over them ([`run_jackknife`]).
const MIN_JACKKNIFE_RUNS: usize = 3;

/// The delete-one-log jackknife of a shooting fit: the answers fitted with each fit log left
/// out in turn, each started from `theta`, the answer on all of them.
fn run_jackknife(problem: &shooting::Problem<'_>, theta: &nalgebra::DVector<f64>, stop: Option<&std::sync::atomic::AtomicBool>) -> Result<Vec<nalgebra::DVector<f64>>> {
    (0..problem.runs.len())
        .map(|out| {
            let keep = move |r: usize, _: usize| r != out;
            let p = shooting::Problem { keep: &keep, ..*problem };
            Ok(shooting::fit(&p, std::slice::from_ref(theta), stop)?.theta)
        })
        .collect()
}

/// The jackknife variance of every parameter, `(g − 1)/g Σ (θ₍ᵢ₎ − θ̄)²` over the `g` answers
/// with one group left out (Efron & Tibshirani, *An Introduction to the Bootstrap*, §11.2).
pub(crate) fn jackknife_variance(answers: &[nalgebra::DVector<f64>]) -> Vec<f64> {
    let g = answers.len();
    let Some(k) = answers.first().map(|a| a.len()) else { return Vec::new() };
    if g < 2 {
        return vec![0.0; k];
    }
    (0..k)
        .map(|c| {
            let mean = answers.iter().map(|a| a[c]).sum::<f64>() / g as f64;
            (g as f64 - 1.0) / g as f64 * answers.iter().map(|a| (a[c] - mean).powi(2)).sum::<f64>()
        })
        .collect()
}

/// The set of `r` fitted again by multiple shooting after a term left it with a value the others
/// were fitted beside (a partner it traded with, or a term at the edge of its range): its
/// two-fold cross-validation and its fit on all fit runs, each half started from the
/// torque-residual fit and from `r`'s answer on that half.
/// `None` when nothing is left to fit.
///
/// # Errors
/// As [`refine_by_shooting`].
pub(crate) fn refit(scorer: &Scorer<'_>, r: &Refined, options: &DiagnoseOptions) -> Result<Option<(Refined, Vec<String>)>> {
    if r.terms.is_empty() {
        return Ok(None);
    }
    let sopts = shooting_options(scorer);
    let tried = try_from(scorer, &sopts, r, &r.terms, options)?;
    let what = "after a term that is no finding left the set, the parameters of the others are fitted again";
    finish(scorer, &r.runs, &sopts, tried, what, options.stop.as_deref()).map(Some)
}

/// The two-fold cross-validated k-step score ([`kstep::score`]) of `terms` fitted by multiple
/// shooting as the shooting stage scores its sets, each half started from the torque-residual
/// fit and from `r`'s answer on the same half (shared terms; never from an answer that saw the
/// held half): what the fit runs say of `r`'s set with a term more or less, on the same footing
/// as the model the report states.
///
/// # Errors
/// As [`refine_by_shooting`].
pub(crate) fn shooting_score(scorer: &Scorer<'_>, r: &Refined, terms: &[Term], options: &DiagnoseOptions) -> Result<f64> {
    if terms.is_empty() {
        // the nominal model, whose score is 1 by definition
        return Ok(scorer.score(terms));
    }
    Ok(try_from(scorer, &shooting_options(scorer), r, terms, options)?.score)
}

/// [`try_set`] of `terms`, each half started also from `r`'s answer on that half where they
/// share terms.
fn try_from(scorer: &Scorer<'_>, sopts: &shooting::Options, r: &Refined, terms: &[Term], options: &DiagnoseOptions) -> Result<Tried> {
    let before = as_tried(r);
    let earlier = |half: usize, designs: &[TermDesign]| before.halves.get(half).map(|h| transfer(&before, h, terms, designs)).into_iter().collect::<Vec<_>>();
    try_set(scorer, &r.runs, sopts, &r.name, terms, &earlier, options.stop.as_deref())
}

/// The set of `r` as its two-fold cross-validation fitted it (terms, designs, each half's
/// answer), the starts of a set with a term more or less ([`transfer`]).
fn as_tried(r: &Refined) -> Tried {
    let (terms, designs, halves) = &r.halves;
    Tried {
        name: r.name.clone(),
        terms: terms.clone(),
        designs: designs.clone(),
        halves: halves.clone(),
        cv: r.cv.clone(),
        cv_per_run: Vec::new(),
        score: r.score,
        test: kstep::FoldTest::of(&[]),
    }
}

/// On a one-joint servo arm, the set of `r` with the drive's torque gain and rotor inertia in
/// place of its inertial correction, fitted by multiple shooting, when it predicts the fit runs
/// as well (its two-fold cross-validated score within [`PRUNE_TOLERANCE`] of `r`'s). On one
/// turning joint the two are the same dynamics up to friction and a turn of the weight's
/// direction ([`crate::select::alternatives::one_joint_equivalent`]); on a servo the drive's
/// terms are the likelier story: its motor constants were fitted from the logs (or taken from a
/// datasheet), while the URDF's mass and inertia were measured or computed. Each half starts
/// also from the gain and rotor inertia its own answer's inertial correction is, with that
/// answer's other parameters. Returns the swapped set, or none (another arm, no servo, no
/// inertial correction, a rotor inertia that would be negative, or a swap that predicts worse),
/// and notes of what was tried.
///
/// On the Rhoban XL330 logs with the `sin_sin` logs held out, the inertial correction (the
/// weight's moment about the axis ×0.53) simulated as its equivalent gain 1.886 and rotor
/// inertia 0.00174 kg·m², without a refit, predicted the held-out logs as well (k-step 13.4 /
/// 31.5 / 39.5 mrad against 13.4 / 31.9 / 38.3); fitted, the swapped set predicts the fit runs
/// at 0.3172 against 0.3065 (the 1.2° turn of the weight it cannot hold), so the inertial
/// correction stays there. In the test suite's servo scenario 3 (`tests/selfcheck_small.rs`)
/// the drive's terms take the place of an inertial correction that was a gain of 1.018.
///
/// # Errors
/// As [`refine_by_shooting`].
pub(crate) fn drive_in_place_of_inertia(scorer: &Scorer<'_>, r: &Refined, options: &DiagnoseOptions) -> Result<(Option<Refined>, Vec<String>)> {
    let model = scorer.model;
    let is_inertial = |t: &Term| matches!(t, Term::InertialError { .. });
    if scorer.prep.servo.is_none() || model.dof() != 1 || scorer.prep.passive.first().copied().unwrap_or(true) || !r.terms.iter().any(is_inertial) {
        return Ok((None, Vec::new()));
    }
    let equivalent = |terms: &[Term], designs: &[TermDesign], theta: &nalgebra::DVector<f64>| {
        crate::select::alternatives::one_joint_equivalent(model, &effects::to_effects(model, &fitted_terms(terms, designs, theta, None)))
    };
    let Some(whole) = equivalent(&r.terms, &r.designs, &r.shot.theta) else { return Ok((None, Vec::new())) };
    let mut terms: Vec<Term> = r.terms.iter().filter(|t| !is_inertial(t)).cloned().collect();
    for t in [Term::Gain(0), Term::Armature(0)] {
        if !terms.contains(&t) {
            terms.push(t);
        }
    }
    // each half also from its own answer's equivalent: the gain and rotor inertia set, the
    // other shared terms at that answer's values
    let before = as_tried(r);
    let earlier = |half: usize, designs: &[TermDesign]| -> Vec<nalgebra::DVector<f64>> {
        let Some(answer) = before.halves.get(half) else { return Vec::new() };
        let mut start = transfer(&before, answer, &terms, designs);
        let mut from = vec![start.clone()];
        if let Some(e) = equivalent(&before.terms, &before.designs, answer) {
            // `k τ = (H + ia) q̈ + g + k F`: the torques that act beside the drive (frictions,
            // cogging) scale by k; a load friction's share of the drive's torque and the
            // drive's own back-EMF do not
            let mut c = 0;
            for (t, d) in terms.iter().zip(designs) {
                let k = d.cols.len();
                match t {
                    Term::Gain(_) if k == 1 => start[c] = 1.0 - e.k,
                    Term::Armature(_) if k == 1 => start[c] = e.k * start[c] + e.ia,
                    Term::LoadFriction { .. } if k >= 1 => start[c] *= e.k,
                    // (fc, mu, fs − fc, mus − mu): the load-independent levels
                    Term::LoadStribeck { .. } if k == 4 => [c, c + 2].into_iter().for_each(|i| start[i] *= e.k),
                    Term::BackEmf(_) | Term::LoadFriction { .. } | Term::LoadStribeck { .. } => {}
                    _ => (c..c + k).for_each(|i| start[i] *= e.k),
                }
                c += k;
            }
            from.push(start);
        }
        from
    };
    let sopts = shooting_options(scorer);
    let name = "the selected set with the drive's torque gain and rotor inertia in place of the inertial correction";
    let tried = try_set(scorer, &r.runs, &sopts, name, &terms, &earlier, options.stop.as_deref())?;
    let head = format!(
        "on this one-joint servo arm the inertial correction is a torque gain k = {:.3} with a rotor inertia of {} kg·m² (the same dynamics up to friction): {name}, fitted by multiple shooting, predicts the fit runs at {:.4} of the nominal model's k-step error against {:.4}",
        whole.k,
        crate::vocabulary::effects::sig3(whole.ia),
        tried.score,
        r.score
    );
    if !(tried.score <= r.score * (1.0 + PRUNE_TOLERANCE)) {
        return Ok((None, vec![format!("{head}: worse by more than {:.0} %, so the inertial correction is kept", 100.0 * PRUNE_TOLERANCE)]));
    }
    let what =
        "the drive's torque gain and rotor inertia in place of the inertial correction (the motor constants were fitted, the URDF's inertia is as published), the parameters";
    let (refined, mut notes) = finish(scorer, &r.runs, &sopts, tried, what, options.stop.as_deref())?;
    notes.insert(0, format!("{head}: within {:.0} %, so the drive's terms are selected", 100.0 * PRUNE_TOLERANCE));
    Ok((Some(refined), notes))
}
