//! The search for backlash: on each actuated joint, with the rotor inertia the selected set holds
//! there or with one added beside it, the play of
//! [`WIDTH_GRID`](crate::vocabulary::backlash::WIDTH_GRID) that predicts the fit runs best
//! (refined halfway, in ratio, toward the grid's neighbours), kept when it predicts them
//! better by [`ADD_GAIN`]; the terms that stood in for the play (a friction, a payload, cogging
//! absorbing its lost motion) are then dropped where the set predicts as well without them.
//!
//! Play has no column in the torque residual (see [`crate::vocabulary::backlash`]): it is judged by
//! the cross-validated k-step prediction of the fit runs alone, through the simulator that
//! integrates the drive side. Play without a rotor inertia cannot change the link's motion (the
//! drive side crosses the gap at once): it is tried with the rotor. Where the effort was measured
//! on the link side of the gearbox, no rotor inertia is seen at all and play is not tried.

use simgap_core::JointKind;

use super::prediction::{ADD_GAIN, PRUNE_TOLERANCE};
use super::scorer::Scorer;
use super::Step;
use crate::vocabulary::backlash::{WIDTH_GRID, WIDTH_GRID_LINEAR};
use crate::vocabulary::Term;

/// What the search did: the set's new score and the notes for the report.
pub(crate) struct Searched {
    /// The set's cross-validated k-step score after the search.
    pub(crate) score: f64,
    /// What was tried and skipped, in words.
    pub(crate) notes: Vec<String>,
}

/// Tries play on each actuated joint (joint kinds `kinds`, names `joints`, `passive` joints
/// skipped) with the rotor inertia of `terms` there, or with one added beside it, adding the best
/// width (and the rotor) where it beats `score` by [`ADD_GAIN`], then dropping the terms that
/// stood in for it; logs every change in `log`. `stop` is checked between widths.
///
/// # Errors
/// [`crate::Error::Interrupted`] when `stop` says so.
pub(crate) fn search(
    scorer: &Scorer<'_>,
    terms: &mut Vec<Term>,
    mut score: f64,
    log: &mut Vec<Step>,
    (joints, kinds, passive): (&[String], &[JointKind], &[bool]),
    stop: &dyn Fn() -> crate::Result<()>,
) -> crate::Result<Searched> {
    let mut notes = Vec::new();
    let mut skipped: Vec<Option<String>> = vec![None; joints.len()];
    let mut open: Vec<usize> = (0..joints.len()).filter(|&j| !passive[j]).collect();
    // the link inertia each joint moves, against which a rotor's is weighed
    let h_mean = crate::report::pitfalls::mean_mass_diagonal(scorer.model, scorer.ctx.data);
    // forward: the joint whose play predicts best joins first, then the others are tried again
    while !open.is_empty() {
        let mut tried: Vec<Tried> = Vec::new();
        for &j in &open {
            let t = Tried::on(scorer, terms, score, j, kinds[j], h_mean[j], stop)?;
            if t.width.is_some() {
                skipped[j] = None;
                tried.push(t);
            } else if let Some(why) = t.skipped {
                // (one note per joint: the reason of the last pass that skipped it)
                skipped[j] = Some(format!("backlash not tried on {}: {why}", joints[j]));
            }
        }
        let Some(bi) = (0..tried.len()).min_by(|a, b| tried[*a].score.total_cmp(&tried[*b].score)) else { break };
        let best = tried.swap_remove(bi).refined(scorer, stop)?;
        let j = best.joint;
        open.retain(|&k| k != j);
        let with_rotor = if best.rotor_added { " with a rotor inertia" } else { "" };
        let width = best.width.unwrap_or(f64::NAN);
        // the play must predict better than the set without it and than the same set with the
        // rotor alone, and lie inside the widths tried (not at the edge of the search)
        let rotor_alone = best.rotor_alone;
        // (or one refinement step past the widest, √2 times it: play as wide as the widest width
        // tried predicts best a little wider, as the search's widths come out wide; never
        // narrower than the narrowest, below which the logs do not resolve play)
        let (narrowest, widest_tried) = (best.grid[0], best.grid[best.grid.len() - 1]);
        let widest = widest_tried * 2f64.sqrt();
        let inside = best.width.is_some_and(|w| w >= narrowest * (1.0 - 1e-9) && w <= widest * (1.0 + 1e-9));
        // and the typical fold of the fit runs must not be worse with it: a pooled gain carried by
        // a few folds' large errors (trajectories that diverge) is no play
        let gains = best.score < score.min(rotor_alone) * (1.0 - ADD_GAIN) && inside;
        let with_play = || best.base.iter().cloned().chain([Term::Backlash { joint: j, width }]).collect::<Vec<_>>();
        let contradicted = gains.then(|| scorer.gain_test(&with_play(), terms)).filter(crate::select::plausible::typical_fold_contradicts);
        if let Some(test) = contradicted {
            notes.push(format!(
                "backlash on {}{with_rotor}: a width of {width:.4} predicts the fit runs at {:.4} of the nominal error against {score:.4} without it, but the typical fold is worse with it (the geometric mean of the fold ratios with/without is {:.3}): the gain is carried by a few folds' large errors, and the play is not kept",
                joints[j], best.score, test.mean
            ));
            break;
        }
        if !gains {
            // neither it nor any other joint's play predicts better: say so for each
            for t in std::iter::once(&best).chain(&tried) {
                notes.push(format!(
                    "backlash tried on {}{} (widths {:?} and between): the best, {:.4}, predicts the fit runs at {:.4} of the nominal error against {score:.4} without it{}, not better by {:.0} % inside the widths tried",
                    joints[t.joint],
                    if t.rotor_added { " with a rotor inertia" } else { "" },
                    t.grid,
                    t.width.unwrap_or(f64::NAN),
                    t.score,
                    if t.joint == best.joint && best.rotor_added { format!(" and {rotor_alone:.4} with the rotor alone") } else { String::new() },
                    100.0 * ADD_GAIN
                ));
            }
            break;
        }
        let term = Term::Backlash { joint: j, width };
        let why = format!(
            "play of {width:.4}{with_rotor} predicts the fit runs better (cross-validated k-step score {:.4} against {score:.4}; widths tried {:?} and between)",
            best.score, best.grid
        );
        // how precise the width is: the search's step, and an end of the widths searched
        let end = if width >= widest_tried * (1.0 - 1e-9) {
            format!(" It lies at or past the widest width searched ({widest_tried:.4}): the play may be wider.")
        } else if width <= narrowest * (1.0 + 1e-9) {
            format!(" It lies at the narrowest width searched ({narrowest:.4}), below which these logs do not resolve play: the play may be narrower.")
        } else {
            String::new()
        };
        notes.push(format!(
            "backlash on {}: a width of {width:.4}, chosen among widths a factor of √2 apart by the fit runs' prediction, so known to that factor at best (read it as the play's order, not its measure).{end}",
            joints[j]
        ));
        for t in terms.iter().filter(|t| !best.base.contains(t)) {
            log.push(Step { term: t.clone(), cv_mse: f64::NAN, accepted: false, reason: format!("stood in for the play on {}: {why}", joints[j]) });
        }
        if best.rotor_added {
            log.push(Step { term: Term::Armature(j), cv_mse: f64::NAN, accepted: true, reason: format!("the drive side of the play: {why}") });
        }
        log.push(Step { term: term.clone(), cv_mse: f64::NAN, accepted: true, reason: why.clone() });
        *terms = best.base.clone();
        terms.push(term);
        // the effects the set held in the play's stead (a friction or an inertia that absorbed its
        // lost motion) leave where the set predicts as well without them
        score = prune_stand_ins(scorer, terms, best.score, log, stop)?;
    }
    let notes = skipped.into_iter().flatten().chain(notes).collect();
    Ok(Searched { score, notes })
}

/// The play searched on one joint.
struct Tried {
    joint: usize,
    /// The rotor inertia is added with the play (the set has none there).
    rotor_added: bool,
    grid: &'static [f64],
    /// The best width so far (`None`: no width predicted at all) and its score.
    width: Option<f64>,
    score: f64,
    /// The set with the rotor inertia, without the play (and without the terms that stood in for
    /// it, where that predicted better).
    base: Vec<Term>,
    /// The score of `base`: the set with the rotor alone.
    rotor_alone: f64,
    /// Why no width was tried (the rotor's fitted inertia too small for play to move the link).
    skipped: Option<String>,
}

impl Tried {
    /// The widths of the grid on joint `j` of type `kind` (mean link inertia `h_jj`) with `terms`,
    /// whose score is `current`.
    fn on(scorer: &Scorer<'_>, terms: &[Term], current: f64, j: usize, kind: JointKind, h_jj: f64, stop: &dyn Fn() -> crate::Result<()>) -> crate::Result<Tried> {
        // the play needs the rotor's inertia on its drive side: the set's, or one added with it
        let mut base = terms.to_vec();
        let rotor_added = !base.contains(&Term::Armature(j));
        if rotor_added {
            base.push(Term::Armature(j));
        }
        let grid: &'static [f64] = if kind == JointKind::Prismatic { &WIDTH_GRID_LINEAR } else { &WIDTH_GRID };
        // the set as it is, and without the terms that stand in for a rotor inertia and its lost
        // motion (a drive gain, a payload or an inertial correction, cogging, a spring or an
        // offset on the joint), which otherwise keep the rotor's fitted inertia near zero
        let lean: Vec<Term> = base.iter().filter(|t| !stands_in(t, j)).cloned().collect();
        let bases = if lean.len() < base.len() { vec![base, lean] } else { vec![base] };
        let mut t = Tried { joint: j, rotor_added, grid, width: None, score: f64::INFINITY, base: Vec::new(), rotor_alone: f64::INFINITY, skipped: None };
        let mut reasons = Vec::new();
        for (bi, base) in bases.into_iter().enumerate() {
            let which = if bi == 0 { "with the set's terms" } else { "without the terms that could stand in for it" };
            // the link's lead after a reversal is w·ia/(H_jj + ia): a rotor of less than
            // ROTOR_SHARE of the link's inertia leaves the play nothing to show
            let share = rotor_share(scorer, &base, j, h_jj);
            if !(share >= ROTOR_SHARE) {
                reasons.push(format!(
                    "{which}, the rotor inertia fitted there is {:.1} % of the link inertia the joint moves, below the {:.0} % at which play could move the link (its lead after a reversal is the width times ia/(H_jj + ia))",
                    100.0 * share,
                    100.0 * ROTOR_SHARE
                ));
                continue;
            }
            // a base the rotor alone leaves far worse than the set (a stand-in that was a real
            // effect) is not one play could rescue
            let alone = scorer.score(&base);
            if !(alone < FAR_WORSE * current) {
                reasons.push(format!(
                    "{which}, the set with the rotor alone predicts the fit runs at {alone:.4} of the nominal error, more than {FAR_WORSE} times the set's {current:.4}"
                ));
                continue;
            }
            let mut alt = Tried { base, rotor_alone: alone, ..t.blank() };
            for &w in grid {
                stop()?;
                alt.try_width(scorer, w);
            }
            if alt.score < t.score {
                t = alt;
            }
        }
        if t.width.is_none() {
            t.skipped = Some(reasons.join("; "));
        }
        Ok(t)
    }

    /// The same joint and grid with nothing tried yet.
    fn blank(&self) -> Tried {
        Tried { base: Vec::new(), skipped: None, width: None, score: f64::INFINITY, rotor_alone: f64::INFINITY, ..*self }
    }

    /// Scores `width` and keeps it if it predicts better.
    fn try_width(&mut self, scorer: &Scorer<'_>, width: f64) {
        let mut with = self.base.clone();
        with.push(Term::Backlash { joint: self.joint, width });
        let s = scorer.score(&with);
        if s.is_finite() && s < self.score {
            (self.width, self.score) = (Some(width), s);
        }
    }

    /// Refined between the grid's neighbours: the width halfway (in ratio) toward each.
    fn refined(mut self, scorer: &Scorer<'_>, stop: &dyn Fn() -> crate::Result<()>) -> crate::Result<Tried> {
        if let Some(centre) = self.width {
            for w in [centre / 2f64.sqrt(), centre * 2f64.sqrt()] {
                stop()?;
                self.try_width(scorer, w);
            }
        }
        Ok(self)
    }
}

/// The rotor inertia, as a share of the joint's mean link inertia `h_jj`, below which play is not
/// tried on it.
const ROTOR_SHARE: f64 = 0.1;

/// How much worse than the set a base with the rotor alone may predict and still be searched.
const FAR_WORSE: f64 = 3.0;

/// The rotor inertia `terms` fit on joint `j` by the torque residual, as a share of `h_jj`.
fn rotor_share(scorer: &Scorer<'_>, terms: &[Term], j: usize, h_jj: f64) -> f64 {
    let (designs, _, fit) = scorer.ctx.fit_terms(terms);
    crate::vocabulary::rotor::fitted(terms, &designs, &fit.theta, j).map_or(0.0, |ia| ia / h_jj)
}

/// Whether `t` can stand in for a rotor inertia with play on joint `j`: a drive gain, a payload
/// or an inertial correction (all scale with the acceleration a servo's command follows), or
/// cogging, a spring, an offset or a limit on the joint.
fn stands_in(t: &Term, j: usize) -> bool {
    match t {
        Term::Gain(_) | Term::Payload { .. } | Term::InertialError { .. } => true,
        Term::Cogging { joint, .. } | Term::Saturation { joint, .. } => *joint == j,
        Term::Spring(k) | Term::Offset(k) => *k == j,
        _ => false,
    }
}

/// Drops, one at a time, the terms of `terms` (other than the play and the rotor inertias it
/// drives)
/// whose removal leaves the set's score within [`PRUNE_TOLERANCE`] of `score`, the least missed
/// first; logs each. Returns the set's new score.
fn prune_stand_ins(scorer: &Scorer<'_>, terms: &mut Vec<Term>, mut score: f64, log: &mut Vec<Step>, stop: &dyn Fn() -> crate::Result<()>) -> crate::Result<f64> {
    loop {
        let mut best: Option<(usize, f64)> = None;
        let drives: Vec<usize> = terms.iter().filter_map(|t| if let Term::Backlash { joint, .. } = t { Some(*joint) } else { None }).collect();
        for (i, t) in terms.iter().enumerate() {
            if matches!(t, Term::Backlash { .. }) || matches!(t, Term::Armature(j) if drives.contains(j)) {
                continue;
            }
            stop()?;
            let mut without = terms.clone();
            without.remove(i);
            let s = scorer.score(&without);
            if s.is_finite() && s <= score * (1.0 + PRUNE_TOLERANCE) && best.is_none_or(|(_, b)| s < b) {
                best = Some((i, s));
            }
        }
        let Some((i, s)) = best else { return Ok(score) };
        let t = terms.remove(i);
        log.push(Step {
            term: t,
            cv_mse: f64::NAN,
            accepted: false,
            reason: format!("dropped once the play joined: the set predicts the fit runs as well without it (cross-validated k-step score {s:.4} against {score:.4})"),
        });
        score = s.min(score);
    }
}
