//! Servo runs: the torque a position-controlled servo applied, which its log does not hold.
//!
//! A `servo` experiment's drive is the DC-motor law `τ = en (kt/R) (V duty − kt q̇)` (see
//! [`simgap_sim::Servo`]). Its command is the voltage part `τ_V = en (kt/R) V duty`, with the
//! duty the log holds (the servo's *present PWM*) or, without one, the firmware's
//! `clip(duty_gain (goal − q), ±max_duty)`, and `V` the logged supply voltage or the
//! experiment's `supply_voltage`. The prepare stage writes `τ_V` as the run's commanded effort,
//! so that every later stage (residual, actuator columns, delay line) reads a servo like any
//! drive; the back-EMF `en kt²/R q̇` is subtracted from the residual's torque by the fit data
//! ([`FitData::new`](super::FitData::new)).
//!
//! The motor constants are the experiment's priors `kt` and `R` when it gives them. Without
//! them they are fitted here, per joint, by least squares of the model's inverse dynamics on
//! the drive's two signals over every fit run:
//!
//! ```text
//! (H q̈ + C q̇ + g)_j ≈ a (en V duty)_j − b (en q̇)_j − c q̇_j − f sign(q̇_j) − ia q̈_j
//! ```
//!
//! with `a = kt/R`, `b = kt²/R` (so `kt = b/a`, `R = kt/a`), all five ≥ 0; the friction and
//! rotor-inertia columns keep those effects out of the constants, and are left for the
//! diagnosis to find. Runs that move the joint with its drive disabled (a drop with torque off)
//! tell the back-EMF `b` from viscous friction `c`; without any (no drop, or a joint its
//! friction holds through the drop), `b` and `c` are one column and the report says the
//! constants could not be separated. A drive held below the law by a limit is fitted with
//! the law clamped where that explains most of the residual ([`fit_constants`]).

use simgap_core::{inverse_dynamics_into, Model, Workspace};
use simgap_sim::{ControllerKind, Run, ServoParams};

use crate::error::{Error, Result};
use crate::lsq::bounded::solve_bounded;
use crate::prepare::differentiate::Smoother;
use nalgebra::{DMatrix, DVector};

/// Whether a run is logged by a position-controlled servo.
pub(crate) fn is_servo(run: &Run) -> bool {
    run.experiment.as_ref().is_some_and(|e| e.controller == ControllerKind::Servo)
}

/// The servo constants of a (model-aligned) servo run, in model joint order.
///
/// # Errors
/// [`Error::Log`] naming the run and the missing or malformed key.
pub(crate) fn params(model: &Model, run: &Run) -> Result<ServoParams> {
    let exp = run.experiment.as_ref().ok_or_else(|| Error::Log { log: run.source.clone(), message: "no experiment".into() })?;
    let p = ServoParams::from_experiment(exp).map_err(|m| Error::Log { log: run.source.clone(), message: format!("servo experiment: {m}") })?;
    let map: Vec<usize> = model
        .joint_names()
        .iter()
        .map(|j| {
            exp.joints.iter().position(|e| e == j).ok_or_else(|| Error::Log {
                log: run.source.clone(),
                message: format!("servo experiment names joints {}; expected every model joint (missing '{j}')", exp.joints.join(",")),
            })
        })
        .collect::<Result<_>>()?;
    let pick = |v: &[f64]| map.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    Ok(ServoParams {
        duty_gain: pick(&p.duty_gain),
        max_duty: pick(&p.max_duty),
        supply_voltage: p.supply_voltage,
        kt: p.kt.as_deref().map(pick),
        r: p.r.as_deref().map(pick),
        goal_rate_limit: p.goal_rate_limit,
    })
}

/// The drive's voltage signal `en V duty` [V] of every sample (row-major, model order): the
/// logged duty, else the firmware's P law on the logged goal.
///
/// # Errors
/// [`Error::Log`] for a servo log without goal positions, without a voltage (logged or
/// `supply_voltage`), or with its drive disabled throughout and no motion.
pub(crate) fn volts(run: &Run, p: &ServoParams) -> Result<Vec<f64>> {
    let (n, len) = (run.dof(), run.len());
    let fail = |message: String| Error::Log { log: run.source.clone(), message };
    let logged_duty = run.drive.duty.len() == len * n && len > 0;
    if run.q_ref.len() != len * n {
        return Err(fail(
            "a servo log without goal positions (q_ref_<joint> columns or the reference topic); expected the goal the firmware tracked (the servo's prediction is driven by it)"
                .into(),
        ));
    }
    let logged_v = run.drive.voltage.len() == len && len > 0;
    if !logged_v && !p.supply_voltage.is_finite() {
        return Err(fail("a servo log without a voltage column and an experiment without 'supply_voltage'; expected one of them".into()));
    }
    let enabled_anywhere = (0..len).any(|k| (0..n).any(|j| run.drive.enabled(k, j, n)));
    let moves = run.q.chunks(n.max(1)).any(|row| row.iter().zip(&run.q[..n]).any(|(a, b)| (a - b).abs() > 1e-9));
    if !enabled_anywhere && !moves {
        return Err(fail(
            "the servo's torque is off throughout and the joint never moves: nothing in this log tells the drive or the mechanics; expected motion or an enabled drive".into(),
        ));
    }
    let mut out = vec![0.0; len * n];
    for k in 0..len {
        let v = if logged_v { run.drive.voltage[k] } else { p.supply_voltage };
        for j in 0..n {
            if !run.drive.enabled(k, j, n) {
                continue;
            }
            out[k * n + j] = v * duty(run, p, logged_duty, k, j);
        }
    }
    Ok(out)
}

/// The duty of joint `j` at sample `k`: the logged one (`logged`), else the firmware's P law on
/// the logged goal, `clip(duty_gain (goal − q), ±max_duty)`.
fn duty(run: &Run, p: &ServoParams, logged: bool, k: usize, j: usize) -> f64 {
    let n = run.dof();
    if logged {
        run.drive.duty[k * n + j]
    } else {
        (p.duty_gain[j] * (run.q_ref[k * n + j] - run.q[k * n + j])).clamp(-p.max_duty[j], p.max_duty[j])
    }
}

/// Whether `runs` (model-aligned) move joint `j` with its drive disabled for [`MIN_STALL`] or
/// more, faster than [`REST_WIDTHS`] typical dry-friction widths: only then do they tell a
/// servo's back-EMF from its viscous friction, which act alike while the drive is enabled. The
/// speed is the logged position's change over [`MOTION_SPAN`] or more (a count's flicker on a
/// 4096-count encoder moves it 0.03 rad/s there, below the 0.05 rad/s of a turning joint).
pub(crate) fn moves_with_drive_off<'a>(model: &Model, runs: impl IntoIterator<Item = &'a Run>, j: usize) -> bool {
    let rest = REST_WIDTHS * super::width::typical(model.joints()[j].kind);
    let mut moving = 0.0;
    for run in runs {
        let (n, len) = (run.dof(), run.len());
        // `end`: the first sample at least MOTION_SPAN after `k`
        let mut end = 0;
        for k in 0..len.saturating_sub(1) {
            end = end.max(k + 1);
            while end < len - 1 && run.t[end] - run.t[k] < MOTION_SPAN {
                end += 1;
            }
            let off = (k..=end).all(|i| !run.drive.enabled(i, j, n));
            let dt = run.t[end] - run.t[k];
            if off && dt >= MOTION_SPAN && (run.q[end * n + j] - run.q[k * n + j]).abs() >= rest * dt {
                moving += run.t[k + 1] - run.t[k];
            }
        }
    }
    moving >= MIN_STALL
}

/// The span [s] over which [`moves_with_drive_off`] measures a joint's speed.
const MOTION_SPAN: f64 = 0.05;

/// Share of `max_duty` from which a duty counts as full.
const FULL_DUTY: f64 = 0.99;

/// Per joint, whether the servo of `run` stalls: it drives at full duty (at least
/// [`FULL_DUTY`] of `max_duty`, one sign, enabled) for `duration` seconds or more while its
/// joint moves by no more than `rest_speed[j] · duration` (joint units per second). Such a log
/// shows the most torque the drive gives; a drive that never stalls shows none.
pub(crate) fn stalls(run: &Run, p: &ServoParams, rest_speed: &[f64], duration: f64) -> Vec<bool> {
    let (n, len) = (run.dof(), run.len());
    let logged = run.drive.duty.len() == len * n && len > 0;
    (0..n)
        .map(|j| {
            // the sign of a full duty at each sample, 0 where the duty is not full or the drive off
            let full: Vec<f64> = (0..len)
                .map(|k| {
                    let d = duty(run, p, logged, k, j);
                    if run.drive.enabled(k, j, n) && d.abs() >= FULL_DUTY * p.max_duty[j] {
                        d.signum()
                    } else {
                        0.0
                    }
                })
                .collect();
            // two pointers over each stretch of full duty of one sign
            let mut start = 0;
            for end in 0..len {
                if full[end] == 0.0 || full[end] != full[start] {
                    start = end;
                }
                while start < end && run.t[end] - run.t[start + 1] >= duration {
                    start += 1;
                }
                let dt = run.t[end] - run.t[start];
                if full[end] != 0.0 && dt >= duration && (run.q[end * n + j] - run.q[start * n + j]).abs() <= rest_speed[j] * dt {
                    return true;
                }
            }
            false
        })
        .collect()
}

/// The torque constant [N·m/A] of a servo whose fit logs show no back-EMF: small enough that
/// `kt²/R` is nothing, so that `kt/R` alone is the drive.
const NO_BACK_EMF_KT: f64 = 1e-6;

/// Where the motor constants of a diagnosis of servo runs came from.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Constants {
    /// Torque constants [N·m/A], model order.
    pub kt: Vec<f64>,
    /// Winding resistances [Ω], model order.
    pub r: Vec<f64>,
    /// `prior` (the experiment's) or `fitted` (by [`fit_constants`]).
    pub source: &'static str,
    /// What could not be separated, per joint (empty when everything could).
    pub notes: Vec<String>,
    /// Per joint, the clamp the constants were fitted with, where it explains at least half of
    /// the unclamped law's residual (empty for priors): a limit the diagnosis's torque-limit
    /// search tries.
    pub clamp: Vec<Option<Clamp>>,
}

/// A clamp on a servo's torque that the constants fit found and took ([`fit_constants`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Clamp {
    /// The most torque the drive delivers [N·m or N].
    pub limit: f64,
}

/// Fits `kt` and `R` per joint (see the [module docs](self)) from servo runs (model-aligned,
/// with `volts` their [`volts`] signals), smoothing with a window of `window` seconds.
///
/// A servo's drive may be held below its law by a limit (a current limit, a weak supply), in a
/// stall or while it moves, which read as the law biases the constants (simulated limits at a
/// sixth to a quarter of the stall torque gave `kt/R` 3.4–7 times too small and `kt²/R` a
/// hundredth of the truth or none; the diagnosis's torque gain and back-EMF cannot mend the
/// latter, which the simulated drive clamps with the command). So the law is also fitted with
/// its torque clamped, `clamp(a V duty − b q̇, ±L)`, for `L` on [`CLAMP_SHARES`] of the largest
/// unclamped command, each fitted by reclassifying the samples the clamp holds until none
/// changes. The best clamp is taken, and noted, where it explains at least [`CLAMP_GAIN`] of the residual the
/// unclamped law leaves; the clamp itself is returned as [`Constants::clamp`], where the
/// diagnosis's torque-limit search also looks. A smaller gain is noted and not taken: a
/// load-dependent friction, which brakes the drive in proportion to its torque, is partly
/// mimicked by a clamp. (On the Rhoban XL330 logs, whose servo shows load-dependent friction,
/// clamps gained 20–29 %; taken there, the held-out whole-run error with the `sin_time_square`
/// logs held out rose from 28.2 to 67.1 mrad. On simulated limits they gained 88–98 %.)
pub(crate) fn fit_constants(model: &Model, runs: &[(&Run, Vec<f64>)], window: f64) -> Constants {
    let n = model.dof();
    let names = model.joint_names();
    // per joint: the samples' columns and inverse dynamics
    let mut rows: Vec<Vec<Row>> = vec![Vec::new(); n];
    let mut ws = Workspace::new(model);
    let mut id = vec![0.0; n];
    for (run, volts) in runs {
        let smoother = Smoother::new(&run.t, window);
        let valid = smoother.valid();
        if valid.len() < 20 {
            continue;
        }
        let q = smoother.apply(&run.q, n, 0);
        let qd = smoother.apply(&run.q, n, 1);
        let qdd = smoother.apply(&run.q, n, 2);
        let vs = smoother.apply_zoh(volts, n);
        let en: Vec<f64> = (0..run.len()).flat_map(|k| (0..n).map(move |j| (k, j))).map(|(k, j)| if run.drive.enabled(k, j, n) { 1.0 } else { 0.0 }).collect();
        let ens = smoother.apply_zoh(&en, n);
        for k in valid {
            let row = k * n..(k + 1) * n;
            inverse_dynamics_into(model, &mut ws, &q[row.clone()], &qd[row.clone()], &qdd[row.clone()], &mut id);
            for j in 0..n {
                let (v, e, w, a) = (vs[k * n + j], ens[k * n + j], qd[k * n + j], qdd[k * n + j]);
                rows[j].push(Row { x: [v, -e * w, -w, -w.signum(), -a], y: id[j], enabled: e });
            }
        }
    }
    let (mut kt, mut r, mut notes) = (vec![f64::NAN; n], vec![f64::NAN; n], Vec::new());
    let mut clamp = vec![None; n];
    for j in 0..n {
        let mut theta = clamped_fit(&rows[j], f64::INFINITY, None);
        // (a servo that never stalls can still be held by a limit while it moves)
        if !rows[j].is_empty() {
            let free = theta.clone();
            let free_cost = clamped_cost(&rows[j], &free, f64::INFINITY);
            let largest = rows[j].iter().map(|row| command(row, &free).abs()).fold(0.0, f64::max);
            let best = CLAMP_SHARES
                .iter()
                .map(|share| {
                    let limit = share * largest;
                    let th = clamped_fit(&rows[j], limit, Some(&free));
                    (limit, clamped_cost(&rows[j], &th, limit), th)
                })
                .filter(|(_, c, _)| c.is_finite())
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((limit, cost, th)) = best.filter(|(_, c, _)| *c < free_cost) {
                let unit = simgap_sim::Quantity::Effort.unit(model.joints()[j].kind);
                let gain = 1.0 - cost / free_cost;
                let head = format!(
                    "{}: the motor law clamped at ±{limit:.3} {unit} fits the logs with {:.0} % less residual (kt/R = {:.4}, kt²/R = {:.4}, against {:.4} and {:.4} unclamped)",
                    names[j],
                    100.0 * gain,
                    th[0],
                    th[1],
                    free[0],
                    free[1]
                );
                if gain >= CLAMP_GAIN {
                    notes.push(format!("{head}: the clamped law's constants are taken, and the diagnosis's torque-limit search also tries that clamp"));
                    clamp[j] = Some(Clamp { limit });
                    theta = th;
                } else {
                    notes.push(format!("{head}: less than {:.0} %, which a load-dependent friction also gives, so the unclamped constants are kept", 100.0 * CLAMP_GAIN));
                }
            }
        }
        let (a, b) = (theta[0], theta[1]);
        if !moves_with_drive_off(model, runs.iter().map(|(r, _)| *r), j) {
            let why = if rows[j].iter().any(|row| row.enabled < 0.5) {
                "the joint hardly moves while its drive is disabled in the fit logs"
            } else {
                "the drive is never disabled in the fit logs"
            };
            notes.push(format!(
                "{}: {why}, so its back-EMF kt²/R and viscous friction act alike; the fitted kt and R split them as the least-squares fit does, not as the data decide",
                names[j]
            ));
        }
        if a > 1e-9 && b > 1e-12 {
            kt[j] = b / a;
            r[j] = kt[j] / a;
        } else {
            // no back-EMF seen: a torque constant near 0 leaves the law without one, and R
            // carries the fitted drive gain kt/R
            notes.push(format!(
                "{}: no back-EMF is seen in the fit logs; kt is set to {NO_BACK_EMF_KT:e} N·m/A (no back-EMF) and R = kt / (kt/R) carries the fitted drive gain",
                names[j]
            ));
            kt[j] = NO_BACK_EMF_KT;
            r[j] = NO_BACK_EMF_KT / a.max(1e-9);
        }
    }
    Constants { kt, r, source: "fitted", notes, clamp }
}

/// Shares of the largest unclamped command at which [`fit_constants`] tries a clamp: a
/// geometric grid from 90 % down to 12.5 % (a servo's current limit may lie far below its
/// stall torque).
const CLAMP_SHARES: [f64; 12] = [0.9, 0.75, 0.63, 0.53, 0.44, 0.37, 0.31, 0.26, 0.22, 0.18, 0.15, 0.125];

/// Share of the unclamped law's residual sum of squares a clamp must explain to be taken.
const CLAMP_GAIN: f64 = 0.5;

/// How long a servo must drive at full duty with its joint at rest for its log to show a stall
/// [s] (a reversal at full duty passes through rest in a few milliseconds; the Rhoban XL330's
/// stalls at firmware Kp 800 last 0.24 and 2.9 s).
pub(crate) const MIN_STALL: f64 = 0.1;

/// The joint's speed below which a stalled joint counts as at rest: this many times its
/// dry-friction width (0.05 rad/s, 10 mm/s for the typical widths).
pub(crate) const REST_WIDTHS: f64 = 5.0;

/// One sample of a joint in the constants fit: the columns `[en V duty, −en q̇, −q̇, −sign q̇,
/// −q̈]`, the inverse dynamics `y` and whether the drive was enabled.
#[derive(Clone, Copy, Debug)]
struct Row {
    x: [f64; 5],
    y: f64,
    enabled: f64,
}

/// The drive's torque `a en V duty − b en q̇` of a sample under `theta`.
fn command(row: &Row, theta: &DVector<f64>) -> f64 {
    theta[0] * row.x[0] + theta[1] * row.x[1]
}

/// The samples' residual sum of squares with the drive's torque clamped at `±limit`.
fn clamped_cost(rows: &[Row], theta: &DVector<f64>, limit: f64) -> f64 {
    rows.iter()
        .map(|row| {
            let mech: f64 = (2..5).map(|i| theta[i] * row.x[i]).sum();
            let e = row.y - command(row, theta).clamp(-limit, limit) - mech;
            e * e
        })
        .sum()
}

/// The bounded least-squares fit of the five constants with the drive's torque clamped at
/// `±limit`, from `start` (or unclamped): a sample the clamp holds gives `y ∓ limit` to the
/// mechanical columns alone; repeated until no sample changes side (at most 20 times).
fn clamped_fit(rows: &[Row], limit: f64, start: Option<&DVector<f64>>) -> DVector<f64> {
    let lo = [1e-9, 0.0, 0.0, 0.0, 0.0];
    let hi = [f64::INFINITY; 5];
    let mut held: Vec<f64> = match start {
        Some(th) => rows.iter().map(|row| side(command(row, th), limit)).collect(),
        None => vec![0.0; rows.len()],
    };
    let mut theta = DVector::zeros(5);
    for _ in 0..20 {
        let mut g = DMatrix::<f64>::zeros(5, 5);
        let mut c = DVector::<f64>::zeros(5);
        for (row, h) in rows.iter().zip(&held) {
            let (x, y) = if *h == 0.0 { (row.x, row.y) } else { ([0.0, 0.0, row.x[2], row.x[3], row.x[4]], row.y - h * limit) };
            for a in 0..5 {
                c[a] += x[a] * y;
                for b in 0..5 {
                    g[(a, b)] += x[a] * x[b];
                }
            }
        }
        theta = solve_bounded(&g, &c, &lo, &hi).0;
        let next: Vec<f64> = rows.iter().map(|row| side(command(row, &theta), limit)).collect();
        if next == held {
            return theta;
        }
        held = next;
    }
    theta
}

/// The side on which a clamp at `±limit` holds a torque: `±1`, or 0 inside.
fn side(torque: f64, limit: f64) -> f64 {
    if torque > limit {
        1.0
    } else if torque < -limit {
        -1.0
    } else {
        0.0
    }
}
