//! The diagnosis report: its JSON keys are a public contract that other scripts read.

pub(crate) mod export_basis;
#[cfg(feature = "html")]
pub mod html;
pub(crate) mod pitfalls;
pub(crate) mod residual;
pub(crate) mod servo;
pub(crate) mod units;
pub(crate) mod verdict;

use crate::locate::Where;
use crate::prediction::resim::RunGap;
use crate::prepare::FitData;
use crate::vocabulary::effects::{EffectReport, Param};
use simgap_sim::{Effect, EffectKind, Run};
use std::collections::BTreeMap;

/// One candidate effect, fitted alone on the nominal model.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Candidate {
    /// Rank (1 = explains most of the cross-validated residual).
    pub rank: usize,
    /// The effect (its contract name in the JSON).
    #[serde(serialize_with = "crate::vocabulary::effects::contract_name")]
    pub effect: EffectKind,
    /// Joints fitted.
    pub joints: Vec<String>,
    /// Fitted parameters (as in `selected_effects`).
    pub parameters: BTreeMap<String, Param>,
    /// 95 % half-widths from resampling alone (the larger of the block bootstrap and the
    /// delete-one-fold jackknife); unlike `selected_effects`, without the pipeline's shared error.
    pub uncertainty: BTreeMap<String, Param>,
    /// The unit of each parameter, by the type of the joints it acts on.
    pub units: BTreeMap<String, String>,
    /// Fraction of the nominal cross-validated torque residual it removes (fit runs).
    pub cv_residual_reduction: f64,
    /// Held-out L² after adding this effect alone [rad]; `null` when its fit is not physical
    /// (see `reason`) or its simulation failed.
    pub holdout_l2_after: f64,
    /// `holdout_l2_after / holdout_l2_before`.
    pub holdout_ratio: f64,
    /// Held-out k-step prediction error after adding this effect alone [rad], aligned with
    /// `gap.kstep.horizons_s`.
    pub holdout_kstep_after: Vec<f64>,
    /// Cross-validated k-step prediction error on the fit runs with this effect alone [rad],
    /// aligned with `gap.kstep.horizons_s`.
    pub fit_kstep_cv: Vec<f64>,
    /// Part of the selected set.
    pub selected: bool,
    /// Why it was (not) selected.
    pub reason: String,
}

/// k-step-ahead prediction error: windows of each run restart the model from the measured
/// (smoothed) state and drive it with the logged torque (open-loop runs) or the logged
/// controller (feedback runs); the error is the RMS position error at the window ends [rad].
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct KStep {
    /// Prediction horizons [s].
    pub horizons_s: Vec<f64>,
    /// Nominal model, one value per horizon, pooled over the held-out runs [rad].
    pub before: Vec<f64>,
    /// With the selected effects [rad].
    pub after: Vec<f64>,
    /// Constant-velocity extrapolation over the same windows [rad]: a model that does not beat
    /// it says nothing about physics.
    pub floor: Vec<f64>,
    /// Per joint (model order), per horizon: nominal [rad].
    pub per_joint_before: Vec<Vec<f64>>,
    /// Per joint, per horizon: with the selected effects [rad].
    pub per_joint_after: Vec<Vec<f64>>,
    /// Per held-out run.
    pub runs: Vec<RunKStep>,
}

/// k-step errors of one held-out run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunKStep {
    /// Log name.
    pub log: String,
    /// Number of prediction windows.
    pub windows: usize,
    /// Nominal, per horizon [rad].
    pub before: Vec<f64>,
    /// Selected effects, per horizon [rad].
    pub after: Vec<f64>,
    /// Constant-velocity floor, per horizon [rad].
    pub floor: Vec<f64>,
    /// Where each window starts and the measured (smoothed) state it restarts from: filled by
    /// [`crate::predict`] (so that another simulator can be scored on the same windows), empty
    /// in a diagnosis report.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub window_starts: Vec<WindowStart>,
    /// Whole-run mean absolute position error of a closed-loop re-simulation from the first
    /// sample, driven by the logged reference (the measure servo identification tools report),
    /// nominal and with the effects [rad]: filled by [`crate::predict`] for feedback runs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub whole_run_mae: Option<(f64, f64)>,
}

/// The start of one k-step window: time [s] and the state the model restarts from.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WindowStart {
    /// Time of the start sample [s].
    pub t0: f64,
    /// Positions [rad or m], model order.
    pub q0: Vec<f64>,
    /// Velocities [rad/s or m/s], model order.
    pub qd0: Vec<f64>,
}

/// Effect sets that explain the fit runs as well as the selected set: what these data cannot
/// tell apart.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Alternative {
    /// Effect names of the alternative set.
    pub effects: Vec<String>,
    /// Why it is an alternative (an exact equivalence, or a tie within the cross-validation
    /// noise, with the figures).
    pub why: String,
}

/// An effect the diagnosis fitted and then dropped as no finding (the report's
/// `dropped_effects`): what it was, by which rule it left, the fit runs' evidence, and what it
/// would have done on the held-out runs, measured after every decision.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DroppedEffect {
    /// The effect as fitted when it was judged: `effect`, `joints`, `parameters`, `uncertainty`
    /// (the 95 % half-widths it was judged by), `units`, `description`.
    #[serde(flatten)]
    pub fitted: EffectReport,
    /// The rule: `too_small` (less than 1 % of its joint's commanded torque), `at_edge_of_range`,
    /// `not_established` (its 95 % interval holds its neutral value and the fit runs are not
    /// predicted worse without it by more than 2 %, or by less than 10 % and not in every part of
    /// them), `set_no_better_than_nominal` (the others left, and the set no longer predicts the
    /// fit runs better than the nominal model by 2 %, in every part of them).
    pub rule: String,
    /// Why, in words, with the figures.
    pub why: String,
    /// The fit runs' cross-validated k-step score (error relative to the nominal model's,
    /// geometric mean over horizons) of the set it was judged in, with it; `null` where the rule
    /// did not need it.
    pub fit_score_with: Option<f64>,
    /// The same without it.
    pub fit_score_without: Option<f64>,
    /// Held-out k-step error of the selected effects with this one added [rad or m], aligned
    /// with `gap.kstep.horizons_s`: what it would have done, measured after the decision (the
    /// held-out runs decide nothing).
    pub holdout_kstep_with: Vec<f64>,
}

/// The gap before and after (the report's `gap`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Gap {
    /// Which figure answers "how far" for these runs: `closed_loop` or `k_step`.
    pub headline: String,
    /// Why that figure.
    pub headline_reason: String,
    /// Held-out k-step prediction error before and after.
    pub kstep: KStep,
    /// Cross-validated k-step error on the fit runs, nominal model, per horizon [rad] (what
    /// selection compares against).
    pub fit_kstep_cv_before: Vec<f64>,
    /// The same with the selected effects.
    pub fit_kstep_cv_after: Vec<f64>,
    /// L² (eq. 127) over the held-out runs, nominal closed-loop simulation vs measured [rad].
    pub holdout_l2_before: f64,
    /// The same with the selected effects added.
    pub holdout_l2_after: f64,
    /// `after / before`.
    pub ratio: f64,
    /// Per joint, before.
    pub per_joint_before: Vec<f64>,
    /// Per joint, after.
    pub per_joint_after: Vec<f64>,
    /// Per held-out run, before.
    pub runs_before: Vec<RunGap>,
    /// Per held-out run, after.
    pub runs_after: Vec<RunGap>,
    /// The same index over the fit runs (before, after), for reference.
    pub fit_l2_before: f64,
    /// Fit runs, after.
    pub fit_l2_after: f64,
}

/// A decision of the stepwise selection.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Decision {
    /// The effect (its contract name in the JSON).
    #[serde(serialize_with = "crate::vocabulary::effects::contract_name")]
    pub effect: EffectKind,
    /// Joint, when per joint.
    pub joint: Option<String>,
    /// Cross-validated weighted MSE with the term.
    pub cv_mse: f64,
    /// Entered or not.
    pub accepted: bool,
    /// Why.
    pub reason: String,
}

/// The whole report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    /// simgap version.
    pub simgap_version: String,
    /// Robot name.
    pub model: String,
    /// Formulation of C under test.
    pub formulation: String,
    /// Joint names, model order.
    pub joints: Vec<String>,
    /// Joint types, model order (`revolute`, `continuous`, `prismatic`): the units of each
    /// joint's figures follow them (rad, rad/s, N·m on a turning joint; m, m/s, N on a linear one).
    pub joint_types: Vec<String>,
    /// Fit logs.
    pub fit_logs: Vec<String>,
    /// Held-out logs.
    pub holdout_logs: Vec<String>,
    /// One-sentence conclusion.
    pub verdict: String,
    /// Effects the tool concludes explain the gap (empty when nothing significant remains).
    pub selected_effects: Vec<EffectReport>,
    /// Effects fitted and then dropped as no finding, with the rule, the fit runs' evidence and
    /// what each would have done on the held-out runs.
    pub dropped_effects: Vec<DroppedEffect>,
    /// Every effect tried, ranked.
    pub candidates: Vec<Candidate>,
    /// Effect sets the data cannot tell apart from the selected set (empty when they decide).
    pub alternatives: Vec<Alternative>,
    /// The sensors the re-simulation and prediction give each run's controller, as inferred
    /// from its samples.
    pub sensors: Vec<crate::prepare::sensors::InferredSensors>,
    /// Warnings about the logs and the answer (glitches removed, sensors inferred, URDF
    /// pitfalls the data reveal, what the residual still holds).
    pub notes: Vec<String>,
    /// What is left: the torque residual after the selected effects on the fit runs, per joint
    /// (noise-like, or structured and following which signal; see [`crate::report::residual`]).
    pub residual: Vec<crate::report::residual::ResidualTest>,
    /// How far the gap shrinks on held-out runs.
    pub gap: Gap,
    /// Where the gap lies.
    #[serde(rename = "where")]
    pub location: Where,
    /// The stepwise selection, step by step.
    pub selection_log: Vec<Decision>,
    /// Cross-validated weighted MSE of the nominal torque residual.
    pub nominal_cv_mse: f64,
    /// The motor constants of servo runs (absent for other drives).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub servo: Option<ServoReport>,
}

/// The motor constants a diagnosis of servo runs simulates with (its `servo` key).
///
/// The corrected model is the servo law `τ = en (kt/R) (V duty − kt q̇)` with `kt` and `R`
/// (the experiment's priors, or fitted by the prepare stage) and the selected effects; a
/// selected `torque_gain` k and `back_emf` kb change the drive to
/// `en (k (kt/R) (V duty − kt q̇) − kb q̇)`, i.e. to the `effective` constants
/// `kt' = (k kt²/R + kb) / (k kt/R)` and `R' = kt' / (k kt/R)`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ServoReport {
    /// Joint names, model order.
    pub joints: Vec<String>,
    /// Torque constants [N·m/A] the corrected model's servo law uses.
    pub kt: Vec<f64>,
    /// Winding resistances [Ω] the corrected model's servo law uses.
    #[serde(rename = "R")]
    pub r: Vec<f64>,
    /// `prior` (the experiment's) or `fitted` (from the fit logs).
    pub source: String,
    /// The constants with the selected torque gain and back-EMF folded in.
    pub effective: EffectiveConstants,
}

/// Motor constants with the selected drive effects folded in (see [`ServoReport`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct EffectiveConstants {
    /// Torque constants [N·m/A].
    pub kt: Vec<f64>,
    /// Winding resistances [Ω].
    #[serde(rename = "R")]
    pub r: Vec<f64>,
}

impl ServoReport {
    /// The servo key of a diagnosis whose servo law has `kt`, `r` and whose selected effects
    /// are `effects`.
    pub(crate) fn new(joints: &[String], kt: &[f64], r: &[f64], source: &str, effects: &[simgap_sim::Effect]) -> ServoReport {
        let n = kt.len();
        let (mut k, mut kb) = (vec![1.0; n], vec![0.0; n]);
        for e in effects {
            match e {
                simgap_sim::Effect::TorqueGain { k: g } => k.iter_mut().zip(g).for_each(|(a, b)| *a *= b),
                simgap_sim::Effect::BackEmf { kb: b } => kb.iter_mut().zip(b).for_each(|(a, b)| *a += b),
                _ => {}
            }
        }
        let a: Vec<f64> = (0..n).map(|j| k[j] * kt[j] / r[j]).collect();
        let kt_eff: Vec<f64> = (0..n).map(|j| (k[j] * kt[j] * kt[j] / r[j] + kb[j]) / a[j]).collect();
        let r_eff: Vec<f64> = (0..n).map(|j| kt_eff[j] / a[j]).collect();
        ServoReport { joints: joints.to_vec(), kt: kt.to_vec(), r: r.to_vec(), source: source.into(), effective: EffectiveConstants { kt: kt_eff, r: r_eff } }
    }
}

impl Report {
    /// The JSON text (pretty-printed; non-finite numbers become `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serialises")
    }

    /// A terminal summary.
    pub fn summary(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "simgap diagnosis of '{}' ({} C), joints {:?}", self.model, self.formulation, self.joints);
        let _ = writeln!(s, "fit logs: {}   held-out logs: {}", self.fit_logs.len(), self.holdout_logs.len());
        let _ = writeln!(s, "\nWHERE");
        let kinds = units::kinds_of(&self.joint_types);
        let joint_units = |name: &str| self.joints.iter().position(|j| j == name).and_then(|i| kinds.get(i)).map_or_else(|| units::Units::of(&kinds), |k| units::Units::joint(*k));
        let all = units::Units::of(&kinds);
        for j in &self.location.per_joint {
            let u = joint_units(&j.joint);
            let _ = writeln!(
                s,
                "  {:<14} sim L2 {:>10.3e} {}  share {:>5.1} %  torque residual L2 {:>9.3e} {}",
                j.joint,
                j.sim_l2,
                u.position,
                100.0 * j.share,
                j.torque_residual_l2,
                u.effort
            );
        }
        for seg in self.location.worst_segments.iter().take(3) {
            let u = joint_units(&seg.joint);
            let _ = writeln!(s, "  worst: {} t = {:.3}–{:.3} s, {} ({}), RMS {:.3e} {}", seg.log, seg.start, seg.end, seg.joint, seg.phase, seg.rms_error, u.position);
        }
        let _ = writeln!(s, "\nWHICH (candidates fitted alone, ranked by cross-validated prediction of the fit runs)");
        let last = self.gap.fit_kstep_cv_before.len().saturating_sub(1);
        let _ = writeln!(s, "  {:<4} {:<20} {:>10} {:>12} {:>12}  selected", "rank", "effect", "cv-resid", "fit k-step", "held k-step");
        for c in &self.candidates {
            // k-step ratios at the longest horizon: fit runs (cross-validated), held-out runs
            let ratio = |v: &[f64], before: &[f64]| v.get(last).zip(before.get(last)).map_or(f64::NAN, |(a, b)| a / b);
            let _ = writeln!(
                s,
                "  {:<4} {:<20} {:>9.1}% {:>12.3} {:>12.3}  {}",
                c.rank,
                c.effect,
                100.0 * c.cv_residual_reduction,
                ratio(&c.fit_kstep_cv, &self.gap.fit_kstep_cv_before),
                ratio(&c.holdout_kstep_after, &self.gap.kstep.before),
                if c.selected { "yes" } else { "" }
            );
        }
        let _ = writeln!(s, "  (k-step columns: error after / before at {} s; below 1 the effect predicts better)", self.gap.kstep.horizons_s.last().copied().unwrap_or(f64::NAN));
        // selected effects in candidate rank order, joints in model order
        let _ = writeln!(s, "\nSELECTED (in rank order)");
        if self.selected_effects.is_empty() {
            let _ = writeln!(s, "  nothing significant");
        }
        for e in verdict::ranked_selection(self) {
            let params: Vec<String> = e
                .parameters
                .iter()
                .map(|(k, v)| {
                    let unit = e.units.get(k).map(String::as_str).unwrap_or("-");
                    let unit = if unit == "-" || unit.is_empty() { String::new() } else { format!(" {unit}") };
                    format!("{k} = {}{unit}", fmt_param(v, e.uncertainty.get(k)))
                })
                .collect();
            let _ = writeln!(s, "  {:<20} joints {:?}  {}", e.effect, e.joints, params.join(", "));
            if !e.description.is_empty() {
                let _ = writeln!(s, "  {:<20} {}", "", e.description);
            }
        }
        if !self.dropped_effects.is_empty() {
            let _ = writeln!(s, "\nDROPPED (fitted, then not a finding; held-out figures measured after the decision)");
            for d in &self.dropped_effects {
                let _ = writeln!(s, "  {}", d.summary_line(&self.gap.kstep));
            }
        }
        if !self.alternatives.is_empty() {
            let _ = writeln!(s, "\nALTERNATIVES (explain the fit runs as well; these data cannot tell them apart)");
            for a in &self.alternatives {
                let _ = writeln!(s, "  {}: {}", a.effects.join(" + "), a.why);
            }
        }
        let k = &self.gap.kstep;
        let headline = |name: &str| if self.gap.headline == name { "  [headline]" } else { "" };
        if !k.horizons_s.is_empty() {
            let _ = writeln!(s, "\nHOW FAR (held-out runs, k-step prediction: RMS position error [{}] after h seconds){}", all.position, headline("k_step"));
            let _ = writeln!(s, "  {:>8} {:>14} {:>14} {:>14} {:>8}", "h [s]", "const. vel.", "nominal", "selected", "ratio");
            for (i, h) in k.horizons_s.iter().enumerate() {
                let get = |v: &Vec<f64>| v.get(i).copied().unwrap_or(f64::NAN);
                let _ = writeln!(s, "  {:>8} {:>14.4e} {:>14.4e} {:>14.4e} {:>8.3}", h, get(&k.floor), get(&k.before), get(&k.after), get(&k.after) / get(&k.before));
            }
        }
        let _ = writeln!(s, "\nHOW FAR (held-out runs, closed loop, eq. 127){}", headline("closed_loop"));
        let _ =
            writeln!(s, "  L2 before {:.4e} {u}   after {:.4e} {u}   after/before {:.3}", self.gap.holdout_l2_before, self.gap.holdout_l2_after, self.gap.ratio, u = all.position);
        for (b, a) in self.gap.runs_before.iter().zip(&self.gap.runs_after) {
            if b.status != "completed" || a.status != "completed" {
                let _ = writeln!(s, "  run {}: nominal {}, selected {}", b.log, b.status, a.status);
            }
        }
        if !self.gap.headline_reason.is_empty() {
            let _ = writeln!(s, "  ({})", self.gap.headline_reason);
        }
        if let Some(sv) = &self.servo {
            let _ = writeln!(s, "\nSERVO (motor constants the corrected model simulates with, {})", sv.source);
            for (j, name) in sv.joints.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "  {name:<14} kt = {:.4} N·m/A, R = {:.4} Ω; with the selected drive effects: kt = {:.4} N·m/A, R = {:.4} Ω",
                    sv.kt[j], sv.r[j], sv.effective.kt[j], sv.effective.r[j]
                );
            }
        }
        if !self.notes.is_empty() {
            let _ = writeln!(s, "\nNOTES");
            for n in &self.notes {
                let _ = writeln!(s, "  - {n}");
            }
        }
        // the conclusion from the figures above, so it cannot contradict them
        let a = verdict::assess(self);
        let _ = writeln!(s, "\n{}", a.text);
        s
    }
}

impl DroppedEffect {
    /// One line of the terminal summary: the effect with its values and 95 % intervals, why it
    /// left, and what it would have done at the longest held-out horizon (`kstep`, the report's
    /// held-out figures), e.g. `coulomb_friction on shoulder: fc = 0.1270 [-0.05300, 0.3070]
    /// N·m; not a finding: …; held-out k-step at 0.5 s with it 4.0500e-1 (selected 4.4600e-1)`.
    pub fn summary_line(&self, kstep: &KStep) -> String {
        let e = &self.fitted;
        let on = if e.joints.is_empty() { String::new() } else { format!(" on {}", e.joints.join(", ")) };
        let params: Vec<String> = e
            .parameters
            .iter()
            .filter(|(_, v)| !matches!(v, Param::PerLink(_)))
            .map(|(k, v)| {
                let unit = e.units.get(k).map(String::as_str).filter(|u| *u != "-" && !u.is_empty()).map_or(String::new(), |u| format!(" {u}"));
                format!("{k} = {}{unit}", fmt_interval(v, e.uncertainty.get(k)))
            })
            .collect();
        let last = kstep.horizons_s.len().checked_sub(1);
        let held = match last.and_then(|i| Some((kstep.horizons_s[i], *self.holdout_kstep_with.get(i)?, *kstep.after.get(i)?))) {
            Some((h, with, after)) if with.is_finite() => format!("; held-out k-step at {h} s with it {with:.4e} (selected {after:.4e})"),
            _ => String::new(),
        };
        format!("{}{on}: {}; {}{held}", e.effect.as_str(), params.join(", "), self.why)
    }
}

/// A parameter, each value with its 95 % interval `[lo, hi]` where `half_width` gives a finite
/// half-width of the same layout: `0.127 [-0.052, 0.306]`, per joint `[0.0176 [..], 0.0100]`.
fn fmt_interval(p: &Param, half_width: Option<&Param>) -> String {
    let halves: &[f64] = match (p, half_width) {
        (Param::Number(_), Some(Param::Number(u))) => std::slice::from_ref(u),
        (Param::PerJoint(v), Some(Param::PerJoint(u))) | (Param::Vector(v), Some(Param::Vector(u))) if u.len() == v.len() => u,
        _ => &[],
    };
    let one = |i: usize, x: f64| match halves.get(i).filter(|u| u.is_finite()) {
        Some(u) => format!("{} [{}, {}]", sig4(x), sig4(x - u), sig4(x + u)),
        None => sig4(x),
    };
    match p {
        Param::Number(x) => one(0, *x),
        Param::PerJoint(v) | Param::Vector(v) => {
            let all: Vec<String> = v.iter().enumerate().map(|(i, x)| one(i, *x)).collect();
            if all.len() == 1 {
                all.into_iter().next().unwrap_or_default()
            } else {
                format!("[{}]", all.join(", "))
            }
        }
        Param::PerLink(v) => format!("{} links", v.len()),
    }
}

/// `x` with four significant digits.
fn sig4(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if !(1e-3..1e4).contains(&a) {
        return format!("{x:.3e}");
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    format!("{x:.decimals$}")
}

/// A parameter, each value with its 95 % half-width where `half_width` gives a finite one of
/// the same layout: `2.1243 ± 1.4920`, per joint `[0.0176 ± 0.0230, 0.0100]`; links by count.
fn fmt_param(p: &Param, half_width: Option<&Param>) -> String {
    let halves: &[f64] = match (p, half_width) {
        (Param::Number(_), Some(Param::Number(u))) => std::slice::from_ref(u),
        (Param::PerJoint(v), Some(Param::PerJoint(u))) | (Param::Vector(v), Some(Param::Vector(u))) if u.len() == v.len() => u,
        _ => &[],
    };
    let one = |i: usize, x: f64| match halves.get(i).filter(|u| u.is_finite()) {
        Some(u) => format!("{x:.4} ± {u:.4}"),
        None => format!("{x:.4}"),
    };
    match p {
        Param::Number(x) => one(0, *x),
        Param::PerJoint(v) | Param::Vector(v) => format!("[{}]", v.iter().enumerate().map(|(i, x)| one(i, *x)).collect::<Vec<_>>().join(", ")),
        Param::PerLink(v) => format!("{} links", v.len()),
    }
}

/// Everything [`crate::diagnose`] produced: the report and the runs behind its figures.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The report (see [`Report`]).
    pub report: Report,
    /// The selected effects, as simulator effects.
    pub effects: Vec<Effect>,
    /// Held-out runs as measured (model-aligned, glitches repaired).
    pub holdout: Vec<Run>,
    /// Their nominal closed-loop simulations.
    pub holdout_nominal: Vec<Option<Run>>,
    /// Their simulations with the selected effects.
    pub holdout_corrected: Vec<Option<Run>>,
    /// Fit data (smoothed states and residuals), for plots.
    pub fit_data: Vec<FitData>,
    /// The selected effects with the 95 % half-widths of each interval method on its own, for
    /// the self-check's coverage comparison: for a torque-residual fit `block_bootstrap`,
    /// `fold_jackknife`, `resampling` (the larger of the two, 1.96 σ), `pipeline_error` (1.96 |b|,
    /// the pipeline's measured error), `noise_resampling` (1.96 σ_n, the scatter that error does
    /// not make), `pipeline_error_change` (1.96 |δ|, how far `b` moves measured again from the
    /// corrected values): the report's half-width is `|b| + 1.96 sqrt(σ_n² + δ²)`, see
    /// [`crate::select::uncertainty`]; `spread_or_bias` (1.96 max(σ, |b|), the rule before) and
    /// `bias_corrected` (the values less `b`, with the `resampling` half-widths: a parametric
    /// bootstrap's bias correction, measured beside the reported intervals, not reported); for a
    /// fit by multiple shooting `multiple_shooting`.
    pub interval_variants: Vec<(&'static str, Vec<EffectReport>)>,
    /// What the export takes from the logs (time step, passive joints, a servo's firmware),
    /// decided once from the runs the diagnosis prepared, so that every front end writes the
    /// same files (see [`crate::export`]); not in the JSON report.
    pub export: export_basis::ExportBasis,
}

impl Diagnosis {
    /// [`Diagnosis::interval_variants`] as a JSON object: per method, the selected effects with
    /// that method's 95 % half-widths in `uncertainty`.
    pub fn interval_variants_json(&self) -> String {
        let map: serde_json::Map<String, serde_json::Value> =
            self.interval_variants.iter().map(|(name, reports)| (name.to_string(), serde_json::to_value(reports).unwrap_or(serde_json::Value::Null))).collect();
        serde_json::Value::Object(map).to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_effect_says_its_values_intervals_rule_and_what_it_would_have_done() {
        let mut fitted = EffectReport::new(EffectKind::CoulombFriction);
        fitted.joints = vec!["shoulder".into()];
        fitted.parameters.insert("fc".into(), Param::PerJoint(vec![0.127]));
        fitted.uncertainty.insert("fc".into(), Param::PerJoint(vec![0.18]));
        fitted.units.insert("fc".into(), "N·m".into());
        let d = DroppedEffect {
            fitted,
            rule: "not_established".into(),
            why: "not a finding: the 95 % interval holds its neutral value".into(),
            fit_score_with: Some(0.94),
            fit_score_without: Some(0.95),
            holdout_kstep_with: vec![0.0238, 0.405],
        };
        let kstep = KStep { horizons_s: vec![0.1, 0.5], after: vec![0.0246, 0.446], ..Default::default() };
        let line = d.summary_line(&kstep);
        let name = EffectKind::CoulombFriction.as_str();
        assert!(line.starts_with(&format!("{name} on shoulder: fc = 0.1270 [-0.05300, 0.3070] N·m; not a finding")), "{line}");
        assert!(line.ends_with("held-out k-step at 0.5 s with it 4.0500e-1 (selected 4.4600e-1)"), "{line}");
        let json = serde_json::to_value(&d).unwrap();
        assert_eq!(json["effect"], name, "the entry's fields are flattened: {json}");
        assert_eq!(json["rule"], "not_established");
        assert_eq!(json["parameters"]["fc"][0], 0.127);
    }
}
