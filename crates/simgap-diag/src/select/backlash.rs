//! The search for backlash: on each actuated joint whose rotor inertia the selected set holds,
//! the play of [`WIDTH_GRID`](crate::vocabulary::backlash::WIDTH_GRID) that predicts the fit runs
//! best (refined between the grid's neighbours to a ratio of 2^(1/4)), kept when it predicts them
//! better by [`ADD_GAIN`].
//!
//! Play has no column in the torque residual (see [`crate::vocabulary::backlash`]): it is judged by
//! the cross-validated k-step prediction of the fit runs alone, through the simulator that
//! integrates the drive side. Where the set holds no rotor inertia on a joint, its play cannot
//! change the link's motion (the drive side crosses the gap at once) and is not tried; where the
//! effort was measured on the link side of the gearbox, no rotor inertia is seen at all.

use simgap_core::JointKind;

use super::prediction::ADD_GAIN;
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

/// Tries play on each actuated joint of `terms` with a rotor inertia (joint kinds `kinds`, names
/// `joints`, `passive` joints skipped), adding the best width where it beats `score` by
/// [`ADD_GAIN`]; logs every width kept in `log`. `stop` is checked between widths.
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
    let with_rotor: Vec<usize> = (0..joints.len()).filter(|&j| !passive[j] && terms.contains(&Term::Armature(j))).collect();
    let without: Vec<&str> = (0..joints.len()).filter(|&j| !passive[j] && !with_rotor.contains(&j)).map(|j| joints[j].as_str()).collect();
    if !without.is_empty() {
        notes.push(format!(
            "not tried: backlash on {}: the selected set holds no rotor inertia there, and play without a rotor's inertia does not change the link's motion (the drive side crosses the gap at once)",
            without.join(", ")
        ));
    }
    for j in with_rotor {
        let grid: &[f64] = if kinds[j] == JointKind::Prismatic { &WIDTH_GRID_LINEAR } else { &WIDTH_GRID };
        let mut best: Option<(f64, f64)> = None;
        for &width in grid {
            stop()?;
            let mut with = terms.clone();
            with.push(Term::Backlash { joint: j, width });
            let s = scorer.score(&with);
            if s.is_finite() && best.is_none_or(|(_, b)| s < b) {
                best = Some((width, s));
            }
        }
        // refined between the grid's neighbours: the width halfway (in ratio) toward each, twice
        if let Some((mut width, mut best_score)) = best {
            for step in [2f64.sqrt(), 2f64.powf(0.25)] {
                let centre = width;
                for w in [centre / step, centre * step] {
                    stop()?;
                    let mut with = terms.clone();
                    with.push(Term::Backlash { joint: j, width: w });
                    let s = scorer.score(&with);
                    if s.is_finite() && s < best_score {
                        (width, best_score) = (w, s);
                    }
                }
            }
            best = Some((width, best_score));
        }
        match best {
            Some((width, s)) if s < score * (1.0 - ADD_GAIN) => {
                let term = Term::Backlash { joint: j, width };
                log.push(Step {
                    term: term.clone(),
                    cv_mse: f64::NAN,
                    accepted: true,
                    reason: format!("play of {width:.4} predicts the fit runs better (cross-validated k-step score {s:.4} against {score:.4}; widths tried {grid:?})"),
                });
                terms.push(term);
                score = s;
            }
            Some((width, s)) => notes.push(format!(
                "backlash tried on {} (widths {grid:?}): the best, {width:.4}, predicts the fit runs at {s:.4} of the nominal error against {score:.4} without it, not better by {:.0} %",
                joints[j],
                100.0 * ADD_GAIN
            )),
            None => {}
        }
    }
    Ok(Searched { score, notes })
}
