//! The prepare stage: every log aligned to the model by joint name, checked (experiment, sample
//! period, a held-out run that repeats a fit run), glitches repaired, sensors inferred, passive
//! joints found, and each fit run smoothed once into the [`FitData`] every later stage shares.

pub(crate) mod dataset;
pub(crate) mod differentiate;
pub(crate) mod locked;
pub(crate) mod lowpass;
pub(crate) mod robust;
pub(crate) mod sensors;
pub(crate) mod servo;
pub(crate) mod width;
pub(crate) mod windows;

use simgap_core::{Formulation, Model};
use simgap_sim::Run;

use crate::error::{Error, Result};
use crate::prepare::sensors::{infer_sensors, InferredSensors};
use crate::prepare::windows::{median_spacing, PredictionRun, DEFAULT_HORIZONS, FIT_WINDOWS_PER_RUN, FOLDS_PER_RUN, MAX_WINDOWS_PER_RUN};
pub(crate) use dataset::align_run;
pub use dataset::{FitData, PrepareOptions};
pub use width::DryWidth;

/// What the prepare stage hands to every later stage: the runs aligned to the model, the fit
/// data smoothed once, the prediction windows, and what the logs showed.
pub(crate) struct Prepared {
    /// The model's joint names, in model order.
    pub(crate) joints: Vec<String>,
    /// The fit runs, aligned to the model (glitches repaired).
    pub(crate) fit_runs: Vec<Run>,
    /// The held-out runs, aligned to the model (glitches repaired).
    pub(crate) hold_runs: Vec<Run>,
    /// Each fit run smoothed and differentiated once, with its nominal residual.
    pub(crate) data: Vec<FitData>,
    /// The fit runs cut into k-step prediction windows (numbered in folds).
    pub(crate) fit_pred: Vec<PredictionRun>,
    /// The held-out runs cut into k-step prediction windows.
    pub(crate) hold_pred: Vec<PredictionRun>,
    /// Prediction horizons [s].
    pub(crate) horizons: Vec<f64>,
    /// Notes on the logs for the report.
    pub(crate) notes: Vec<String>,
    /// The sensors each run shows (fit runs, then held-out runs).
    pub(crate) sensors: Vec<InferredSensors>,
    /// Per joint, whether nothing drives it.
    pub(crate) passive: Vec<bool>,
    /// Whether the fit runs move (some smoothed velocity above 1e-3 rad/s or m/s): without
    /// motion no effect can be told apart.
    pub(crate) moving: bool,
    pub(crate) servo: Option<servo::Constants>,
}

/// The controller sample period of the fit runs [s].
pub(crate) fn sample_period(runs: &[Run]) -> f64 {
    runs.iter()
        .find_map(|r| r.experiment.as_ref().map(|e| e.sample_period))
        .filter(|t| t.is_finite() && *t > 0.0)
        .unwrap_or_else(|| runs.first().map_or(0.0025, |r| median_spacing(&r.t)))
}

/// The prepare stage: align, check, repair glitches, infer sensors, smooth.
pub(crate) fn prepare(model: &Model, formulation: Formulation, fit: &[Run], holdout: &[Run], options: &PrepareOptions, horizons: &[f64]) -> Result<Prepared> {
    if fit.is_empty() {
        return Err(Error::Input("no fit log given; expected at least one".into()));
    }
    // what the readers noted about the logs (a LeRobot dataset's nominal timing), once per note
    let mut notes = reader_notes(fit.iter().chain(holdout));
    // one recording is the common case: without held-out logs each fit log is split in time
    let (split_fit, split_hold);
    let (fit, holdout) = if holdout.is_empty() {
        (split_fit, split_hold) = split_in_time(fit, FIT_SHARE);
        notes.push(format!(
            "no held-out log given: each fit log is split in time, the first {:.0} % fits and the rest is held out ({})",
            100.0 * FIT_SHARE,
            split_hold.iter().map(|r| r.source.as_str()).collect::<Vec<_>>().join(", ")
        ));
        (&split_fit[..], &split_hold[..])
    } else {
        (fit, holdout)
    };
    let mut fit_runs: Vec<Run> = fit.iter().map(|r| align_run(model, r)).collect::<Result<_>>()?;
    let mut hold_runs: Vec<Run> = holdout.iter().map(|r| align_run(model, r)).collect::<Result<_>>()?;
    // every run carries its experiment, with a sample period its stamps allow
    for r in fit_runs.iter().chain(&hold_runs) {
        let Some(exp) = &r.experiment else {
            return Err(Error::Log {
                log: r.source.clone(),
                message: "no experiment (controller, joints, kp, kv, sample_period) in its metadata, sidecar or the call; expected one to predict and re-simulate it (use controller 'replay' for open-loop runs or an unknown controller)".into(),
            });
        };
        if r.len() < 3 {
            return Err(Error::Log { log: r.source.clone(), message: format!("{} samples; expected a log of at least a few seconds", r.len()) });
        }
        let spacing = median_spacing(&r.t);
        let ratio = exp.sample_period / spacing;
        if !(exp.sample_period.is_finite() && exp.sample_period > 0.0 && (0.02..=50.0).contains(&ratio)) {
            return Err(Error::Log {
                log: r.source.clone(),
                message: format!(
                    "sample_period {} s, but the log's stamps are {:.6} s apart (median); expected a period within a factor 50 of the stamp spacing",
                    exp.sample_period, spacing
                ),
            });
        }
        if (ratio - 1.0).abs() > 0.05 {
            notes.push(format!(
                "{}: the experiment's sample period {} s differs from the median stamp spacing {:.6} s; the controller is simulated at the experiment's period",
                r.source, exp.sample_period, spacing
            ));
        }
    }
    // servo runs: the drive's torque from the duty (or the firmware's law on the goal), with
    // the motor constants the experiments give or the fit runs show
    let servo = servo_commands(model, &mut fit_runs, &mut hold_runs, options, &mut notes)?;
    // a held-out run must be one the fit never saw (a robot at rest logs the same samples twice:
    // that is no copy, and the answer will be that nothing can be told)
    for h in hold_runs.iter().filter(|h| h.q.chunks(h.dof().max(1)).any(|row| row != &h.q[..h.dof()])) {
        if let Some(f) = fit_runs.iter().find(|f| robust::same_content(f, h)) {
            return Err(Error::Input(format!("held-out log {} holds the same samples as fit log {}; a held-out run must be one the fit never saw", h.source, f.source)));
        }
    }
    // glitches: found, replaced, reported
    for r in fit_runs.iter_mut().chain(hold_runs.iter_mut()) {
        let found = robust::repair_glitches(r);
        for g in found.iter().take(5) {
            notes.push(g.to_string());
        }
        if found.len() > 5 {
            notes.push(format!("{}: {} more glitch samples replaced (the first five are listed)", r.source, found.len() - 5));
        }
    }
    // sensors as the logs show them
    let sensors: Vec<InferredSensors> = fit_runs.iter().chain(&hold_runs).map(infer_sensors).collect();
    let mut kinds: Vec<(String, Vec<&str>)> = Vec::new();
    for s in sensors.iter().filter(|s| s.velocity == "backward_difference" || s.counts_per_rev.is_some()) {
        let kind = format!("velocity {}{}", s.velocity.replace('_', " "), s.counts_per_rev.map_or(String::new(), |c| format!(", encoder {c} counts per revolution")));
        match kinds.iter_mut().find(|k| k.0 == kind) {
            Some(k) => k.1.push(&s.log),
            None => kinds.push((kind, vec![&s.log])),
        }
    }
    for (kind, logs) in kinds {
        notes.push(format!("sensors inferred from the logs ({}): {kind}; the re-simulated controller sees the same", logs.join(", ")));
    }
    // passive joints: commanded effort always zero in every run
    let n = model.dof();
    let passive: Vec<bool> = (0..n).map(|j| fit_runs.iter().chain(&hold_runs).all(|r| r.tau.iter().skip(j).step_by(n).all(|v| *v == 0.0))).collect();
    for (j, p) in passive.iter().enumerate() {
        if *p {
            notes.push(format!("joint {} is passive (commanded effort always 0): actuator effects (gain, offset, saturation) are not tried on it", model.joint_names()[j]));
        }
    }
    if options.link_side_torque {
        notes.push(
            "the logged effort is measured on the link side of the gearbox (as told): the rotor's inertia and the motor's back-EMF act before such a sensor, so neither is tried"
                .into(),
        );
    }
    let mut data: Vec<FitData> = fit_runs.iter().map(|r| FitData::new(model, formulation, r.clone(), options)).collect::<Result<_>>()?;
    for (d, s) in data.iter_mut().zip(&sensors) {
        d.recorder_bandwidth = s.recorder_lowpass_hz;
    }
    // fit runs whose positions a recorder low-pass filtered (no measurement noise above a few Hz)
    let filtered: Vec<(&str, f64)> = data.iter().filter_map(|d| d.recorder_bandwidth.map(|b| (d.name.as_str(), b))).collect();
    if let Some(top) = filtered.iter().map(|f| f.1).reduce(f64::max) {
        notes.push(format!(
            "the positions of {} carry no measurement noise above about {top:.0} Hz: their recorder low-pass filtered them (and, as a rule, the torques alike), or they were simulated without sensor noise. Such a filter flattens the torque's peaks as a torque limit would, so a torque saturation cannot be told from it and is not tried; nothing faster than the filter passes can be seen in these logs",
            filtered.iter().map(|f| f.0).collect::<Vec<_>>().join(", ")
        ));
    }
    // the dry-friction widths each joint's data allow, from every fit run (the width a term
    // takes within them is its column, the corrected model's and the report's)
    let velocities: Vec<&[f64]> = data.iter().map(|d| &d.qd[..]).collect();
    let kinds: Vec<simgap_core::JointKind> = model.joints().iter().map(|j| j.kind).collect();
    let widths = width::dry_friction_widths(&kinds, &velocities);
    for d in &mut data {
        d.dry_width = widths.clone();
    }
    let horizons = self::horizons(horizons)?;
    let sensor_of = |r: &Run| sensors.iter().find(|s| s.log == r.source).map(|s| s.params()).unwrap_or_else(simgap_sim::SensorParams::exact);
    let fit_pred: Vec<PredictionRun> =
        fit_runs.iter().enumerate().map(|(i, r)| PredictionRun::new(r.clone(), &horizons, options.window, sensor_of(r), i * FOLDS_PER_RUN, FIT_WINDOWS_PER_RUN)).collect();
    let hold_pred: Vec<PredictionRun> = hold_runs.iter().map(|r| PredictionRun::new(r.clone(), &horizons, options.window, sensor_of(r), 0, MAX_WINDOWS_PER_RUN)).collect();
    if let Some(pr) = hold_pred.iter().find(|p| p.windows() == 0) {
        return Err(Error::Log {
            log: pr.run.source.clone(),
            message: format!("too short to predict: {:.3} s; expected at least the shortest horizon ({} s) plus the smoothing window", pr.run.duration(), horizons[0]),
        });
    }
    let joints = model.joint_names().iter().map(|s| s.to_string()).collect();
    let moving = data.iter().any(|d| d.qd.iter().any(|v| v.abs() > 1e-3));
    Ok(Prepared { joints, fit_runs, hold_runs, data, fit_pred, hold_pred, horizons, notes, sensors, passive, moving, servo })
}

/// The notes the log readers left on the runs ([`Run::notes`]), each once, after the runs it
/// concerns (the first three named, then how many more).
fn reader_notes<'a>(runs: impl Iterator<Item = &'a Run>) -> Vec<String> {
    let mut by_note: Vec<(&str, Vec<&str>)> = Vec::new();
    for r in runs {
        for n in &r.notes {
            match by_note.iter_mut().find(|(m, _)| m == n) {
                Some((_, logs)) => logs.push(&r.source),
                None => by_note.push((n, vec![&r.source])),
            }
        }
    }
    by_note
        .into_iter()
        .map(|(note, logs)| {
            let named = logs.iter().take(3).copied().collect::<Vec<_>>().join(", ");
            let more = if logs.len() > 3 { format!(" and {} more", logs.len() - 3) } else { String::new() };
            format!("{named}{more}: {note}")
        })
        .collect()
}

/// Writes every servo run's drive command `en (kt/R) V duty` as its effort (see
/// [`servo`]), and the motor constants into its experiment: the experiment's priors, else
/// fitted on the fit runs (the same constants for every run of a diagnosis).
fn servo_commands(model: &Model, fit_runs: &mut [Run], hold_runs: &mut [Run], options: &PrepareOptions, notes: &mut Vec<String>) -> Result<Option<servo::Constants>> {
    if !fit_runs.iter().chain(hold_runs.iter()).any(servo::is_servo) {
        return Ok(None);
    }
    let n = model.dof();
    let mut params = Vec::new();
    let mut volts = Vec::new();
    for r in fit_runs.iter().chain(hold_runs.iter()) {
        if servo::is_servo(r) {
            let p = servo::params(model, r)?;
            volts.push(servo::volts(r, &p)?);
            params.push(Some(p));
        } else {
            volts.push(Vec::new());
            params.push(None);
        }
    }
    // the priors the servo runs give (every run that gives them the same), else the fit runs'
    // constants
    let runs: Vec<&Run> = fit_runs.iter().chain(hold_runs.iter()).collect();
    // (run, (kt, R)) of every servo run that gives priors
    type Priors = (Vec<f64>, Vec<f64>);
    let given: Vec<(&Run, Priors)> = runs.iter().zip(&params).filter_map(|(r, p)| Some((*r, p.as_ref()?.kt.clone().zip(p.as_ref()?.r.clone())?))).collect();
    if let Some((other, (kt, r))) = given.iter().find(|(_, c)| *c != given[0].1) {
        let (first, (kt0, r0)) = &given[0];
        let list = |v: &[f64]| v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(",");
        return Err(Error::Log {
            log: other.source.clone(),
            message: format!(
                "its servo motor constants kt = {} N·m/A, R = {} Ω differ from kt = {}, R = {} of {}; expected the same priors in every log of one diagnosis (or none, to fit them)",
                list(kt),
                list(r),
                list(kt0),
                list(r0),
                first.source
            ),
        });
    }
    let without: Vec<&str> = runs.iter().zip(&params).filter(|(_, p)| p.as_ref().is_some_and(|p| p.kt.is_none())).map(|(r, _)| r.source.as_str()).collect();
    if let (Some((first, _)), false) = (given.first(), without.is_empty()) {
        notes.push(format!("servo motor constants: the priors of {} apply to every log, also to those that give none ({})", first.source, without.join(", ")));
    }
    let constants = match given.into_iter().next().map(|(_, c)| c) {
        Some((kt, r)) => servo::Constants { kt, r, source: "prior", notes: Vec::new(), clamp: Vec::new() },
        None => {
            let fit: Vec<(&Run, Vec<f64>)> = fit_runs.iter().zip(&volts).filter(|(r, _)| servo::is_servo(r)).map(|(r, v)| (r, v.clone())).collect();
            if fit.is_empty() {
                return Err(Error::Input(
                    "held-out servo logs without motor constants ('kt', 'R') and no servo fit log to fit them on; expected the priors or a servo fit log".into(),
                ));
            }
            let c = servo::fit_constants(model, &fit, options.window);
            notes.push(format!(
                "servo motor constants fitted on the fit logs (no kt, R priors given): {}",
                model.joint_names().iter().enumerate().map(|(j, name)| format!("{name}: kt = {:.4} N·m/A, R = {:.4} Ω", c.kt[j], c.r[j])).collect::<Vec<_>>().join("; ")
            ));
            notes.extend(c.notes.iter().cloned());
            c
        }
    };
    let names: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    for ((r, v), p) in fit_runs.iter_mut().chain(hold_runs.iter_mut()).zip(&volts).zip(params) {
        let Some(mut p) = p else { continue };
        r.tau = (0..v.len()).map(|i| constants.kt[i % n] / constants.r[i % n] * v[i]).collect();
        p.kt = Some(constants.kt.clone());
        p.r = Some(constants.r.clone());
        if let Some(e) = r.experiment.as_mut() {
            e.joints = names.clone();
            p.write_to(e);
        }
    }
    Ok(Some(constants))
}

/// Without held-out logs, the share of each fit log (from its start) that fits; the rest is
/// held out.
pub(crate) const FIT_SHARE: f64 = 0.6;

/// Each run cut in time: its first `share` fits, the rest is held out (named after the run,
/// with the time it starts at).
fn split_in_time(runs: &[Run], share: f64) -> (Vec<Run>, Vec<Run>) {
    let mut fit = Vec::with_capacity(runs.len());
    let mut hold = Vec::with_capacity(runs.len());
    for r in runs {
        let k = ((r.len() as f64) * share).round() as usize;
        let mut a = r.slice(0..k);
        let mut b = r.slice(k..r.len());
        let at = b.t.first().map_or(0.0, |t| t - r.t.first().copied().unwrap_or(0.0));
        a.source = format!("{} (first {:.0} %)", r.source, 100.0 * share);
        b.source = format!("{} (from {at:.3} s)", r.source);
        fit.push(a);
        hold.push(b);
    }
    (fit, hold)
}

/// The prediction horizons [s]: `given`, or [`DEFAULT_HORIZONS`] when empty.
///
/// # Errors
/// [`Error::Input`] for a horizon that is not a positive number.
pub(crate) fn horizons(given: &[f64]) -> Result<Vec<f64>> {
    let horizons = if given.is_empty() { DEFAULT_HORIZONS.to_vec() } else { given.to_vec() };
    if let Some(h) = horizons.iter().find(|h| !(h.is_finite() && **h > 0.0)) {
        return Err(Error::Input(format!("prediction horizon {h} s; expected positive numbers")));
    }
    Ok(horizons)
}

/// Runs prepared for k-step prediction only, as held-out runs are: aligned to the model,
/// glitches repaired, sensors inferred, windows laid.
///
/// # Errors
/// [`Error::Log`] for a run without experiment or too short for one window.
pub(crate) fn prediction_runs(model: &Model, runs: &[Run], horizons: &[f64], window: f64) -> Result<Vec<PredictionRun>> {
    let mut prepared = Vec::with_capacity(runs.len());
    for r in runs {
        let mut run = align_run(model, r)?;
        if run.experiment.is_none() {
            return Err(Error::Log { log: run.source.clone(), message: "no experiment (controller, joints, kp, kv, sample_period); expected one to predict the run".into() });
        }
        robust::repair_glitches(&mut run);
        let sensor = infer_sensors(&run).params();
        let pr = PredictionRun::new(run, horizons, window, sensor, 0, MAX_WINDOWS_PER_RUN);
        if pr.windows() == 0 {
            return Err(Error::Log {
                log: pr.run.source.clone(),
                message: format!("too short to predict: {:.3} s; expected at least the shortest horizon plus the smoothing window", pr.run.duration()),
            });
        }
        prepared.push(pr);
    }
    Ok(prepared)
}
