//! The shooting stage, for open-loop fit runs: candidate sets fitted by multiple shooting and
//! kept when their two-fold cross-validated prediction of the fit runs says so.
//!
//! One file per job: a set's two-fold cross-validation ([`cross_validation`]), the servo's sets
//! ([`servo_sets`]), the chosen set's fit on all fit runs and its spread ([`final_fit`]), a refit
//! after a term left ([`refit`](mod@refit)), and the drive in place of an inertial correction
//! ([`drive_in_place_of_inertia`](mod@drive_in_place_of_inertia)).

mod cross_validation;
mod drive_in_place_of_inertia;
mod final_fit;
mod refit;
mod servo_sets;

use simgap_sim::ControllerKind;

use crate::error::Result;
use crate::options::{check_stop, DiagnoseOptions, Progress};
use crate::prediction::kstep;
use crate::prepare::servo;
use crate::select::prediction::{ADD_GAIN, PRUNE_TOLERANCE};
use crate::select::scorer::Scorer;
use crate::select::shooting;
use crate::vocabulary::{Term, TermDesign};

use cross_validation::{shooting_options, transfer, try_set, Tried};
pub(crate) use drive_in_place_of_inertia::drive_in_place_of_inertia;
use final_fit::finish;
pub(crate) use final_fit::Refined;
pub(crate) use refit::{refit, shooting_errors};
use servo_sets::{load_friction_at_rest, servo_limit};
// (the scorer caches the stalled joints and names them by this path)
pub(super) use servo_sets::stalled_joints;

// the crate's tests check the jackknife variance by the stage's path
#[cfg(test)]
pub(crate) use final_fit::jackknife_variance;

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
/// all fit runs. A set with more parameters than the selected set (as shooting fits it) takes
/// its place only when it predicts the fit runs better than it by [`ADD_GAIN`] and in every part
/// of them (the fold test of [`kstep::FoldTest::holds`], as an effect joins in the prune stage);
/// the best set that does, or that has no more parameters, is taken. Returns it (or none) and
/// notes saying what was tried.
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
    // the play the search by prediction found goes with every set holding its rotor inertia
    // (shooting fits no width: the play is the drive's structure, as the rotor is)
    for (name, terms) in &mut sets {
        let play: Vec<Term> =
            selected.iter().filter(|t| matches!(t, Term::Backlash { joint, .. } if terms.contains(&Term::Armature(*joint)))).filter(|t| !terms.contains(t)).cloned().collect();
        if !play.is_empty() {
            terms.extend(play);
            name.push_str(", with the selected backlash");
        }
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
    let (searched, fitted, all) = shoot_runs.counts();
    if searched < all {
        notes.push(format!(
            "multiple shooting: the fit runs hold {all} consecutive windows of {} s; the sets were fitted and cross-validated on {searched} of them spread evenly over every run (the search takes {} in all, {} s of logs, each run's share rounded up), and the chosen set's final fit on {}",
            sopts.window,
            shooting::SEARCH_WINDOWS,
            shooting::SEARCH_WINDOWS as f64 * sopts.window,
            if fitted < all { format!("{fitted} (it takes {} in all)", shooting::MAX_WINDOWS) } else { format!("all {all}") }
        ));
    }
    // the sets, best score first
    let mut order: Vec<usize> = (0..tried.len()).collect();
    order.sort_by(|a, b| tried[*a].score.total_cmp(&tried[*b].score));
    let Some(&(mut bi)) = order.first() else { return Ok((None, notes)) };
    // a set with more parameters than the selected set (as shooting fits it) earns its place as
    // an effect added by the prune stage does: better by ADD_GAIN, in every part of the fit runs;
    // the best set that does (or that has no more parameters) is taken
    let columns = |t: &Tried| t.designs.iter().map(|d| d.cols.len()).sum::<usize>();
    if let Some(si) = tried.iter().position(|t| t.terms == selected) {
        let simpler = &tried[si];
        bi = si;
        for &i in order.iter().take_while(|&&i| i != si) {
            let larger = &tried[i];
            let gain = larger.score < simpler.score * (1.0 - ADD_GAIN);
            let test = kstep::FoldTest::of(&kstep::fold_ratios(&larger.errors, &simpler.errors, &scorer.folds));
            if columns(larger) <= columns(simpler) || (gain && test.holds(PRUNE_TOLERANCE, ADD_GAIN)) {
                bi = i;
                break;
            }
            notes.push(format!(
                "multiple shooting: {} predicts the fit runs at {:.4} of the nominal model's k-step error against {:.4} with the selected set's fewer parameters, {}: it does not replace the selected set",
                larger.name,
                larger.score,
                simpler.score,
                if gain {
                    format!("but not in every part of them (fold by fold, the upper 2-standard-error bound of the ratio with/without its extra terms is {:.3}, the worst fold's {:.3})", test.bound, test.worst)
                } else {
                    format!("not better by {:.0} %", 100.0 * ADD_GAIN)
                }
            ));
        }
    }
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
    let (refined, more) = finish(scorer, &shoot_runs, &sopts, best, "the parameters of the selected effects are fitted", options)?;
    notes.extend(more);
    Ok((Some(refined), notes))
}
