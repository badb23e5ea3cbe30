//! The chosen set fitted by multiple shooting on all fit runs ([`finish`]), with its reported
//! spread: shooting's own, the two halves' disagreement, and the torque-residual fit's or the
//! delete-one-log jackknife's ([`jackknife_variance`]).

use crate::error::Result;
use crate::options::DiagnoseOptions;
use crate::prediction::kstep::{self, FOLDS_PER_RUN};
use crate::select::scorer::Scorer;
use crate::select::shooting;
use crate::vocabulary::{Term, TermDesign};

use super::cross_validation::{starts, Tried, HALF_NAMES, START_NAMES};
use super::servo_sets::stalled_joints;

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
    /// The cross-validated errors of every fit window behind `score`.
    pub(crate) errors: kstep::Errors,
    /// The set as its two-fold cross-validation fitted it (terms, designs, each half's answer):
    /// the leak-free starts of a set with a term more or less.
    pub(crate) halves: (Vec<Term>, Vec<TermDesign>, Vec<nalgebra::DVector<f64>>),
    /// The fit runs cut into shooting windows, as it was fitted on (shared with its refits).
    pub(crate) runs: std::sync::Arc<shooting::Windows>,
}

/// The set `best` fitted on all fit runs (from its torque-residual fit and its halves' answers),
/// with the reported spread; terms fitted at their lower bound 0 are left out. Returns it and a
/// note of what was done.
pub(super) fn finish(
    scorer: &Scorer<'_>,
    shoot_runs: &std::sync::Arc<shooting::Windows>,
    sopts: &shooting::Options,
    best: Tried,
    what: &str,
    options: &DiagnoseOptions,
) -> Result<(Refined, Vec<String>)> {
    let stop = options.stop.as_deref();
    let (model, formulation, ctx) = (scorer.model, scorer.formulation, scorer.ctx);
    let mut notes = Vec::new();
    let keep = |_: usize, _: usize| true;
    let (_, _, f) = ctx.fit_terms(&best.terms);
    // the final fit on every window of the fit runs (up to `shooting::MAX_WINDOWS`), the
    // halves again and the jackknife on the search's
    let problem = shooting::Problem { model, formulation, terms: &best.terms, designs: &best.designs, runs: shoot_runs, keep: &keep, options: sopts };
    let whole = shooting::Problem { runs: shoot_runs.whole(), ..problem };
    // starts: the torque-residual fit (and with the URDF's inertia), the two halves' answers
    let mut from = starts(&best.designs, f.theta.clone());
    let mut start_names: Vec<&str> = START_NAMES[..from.len()].to_vec();
    from.extend(best.halves.iter().cloned());
    start_names.extend(&HALF_NAMES[..best.halves.len()]);
    let mut shot = shooting::fit(&whole, &from, stop)?;
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
        ", and the squared difference from the torque-residual fit of the same set (the disagreement of two methods bounds the error either makes), up to what that fit's own error on the fit runs re-simulated with the answer and 1.96 times the spread above explain (the rest is model mismatch the two methods read differently)".to_string()
    };
    notes.push(format!(
        "{what} by multiple shooting on all fit runs ({} windows of {} s) {moved} (normalised k-step cost {:.3e} → {:.3e} in {} iterations); their 95 % intervals are 1.96 σ with σ² the sum of σ² (JᵀJ)⁻¹ of the shooting residuals and a quarter of the squared difference of the two halves' answers (each half fitted again from its answer and from the answer on all fit runs, the lower cost on it kept){method_term}",
        shoot_runs.counts().1,
        sopts.window,
        shot.cost_start,
        shot.cost,
        shot.iterations
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
    // the torque-residual fit's own error on runs that follow the shooting answer: what of its
    // disagreement with that answer the data can make (`uncertainty::method_disagreement`)
    let method_error = if jack_var.is_none() && !filtered {
        crate::select::uncertainty::torque_residual_error(model, formulation, &scorer.prep.fit_runs, &best.terms, &best.designs, &shot.theta, &options.prepare)
    } else {
        None
    };
    for i in 0..shot.theta.len() {
        let half = halves.map_or(0.0, |(a, b)| 0.5 * (a[i] - b[i]));
        let scatter = shot.std[i].hypot(half);
        let disagreement = || {
            f.theta
                .get(i)
                .map_or(0.0, |t| crate::select::uncertainty::method_disagreement(shot.theta[i] - t, method_error.as_ref().and_then(|b| b.get(i).copied()), scatter).powi(2))
        };
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
            errors: best.errors,
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
