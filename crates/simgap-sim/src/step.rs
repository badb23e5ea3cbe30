//! One sample interval of the sampled closed loop: the step the simulator repeats, and that
//! k-step prediction restarts from measured states.
//!
//! At sample `k` (time `t_k`) a [`Stepper`]
//! 1. forms the command `τ_cmd,k`: either the controller's, from the sensors' measurement of the
//!    true state plus the reference's feed-forward torque ([`Stepper::command`]), or one given
//!    by the caller, e.g. a logged torque ([`Stepper::set_command`]);
//! 2. puts it into the delay line (a ring of the last `m + 2` commands, see
//!    [`crate::delay`]) and forms the delayed command held over the sample;
//! 3. turns it into the applied torque ([`applied_torque`]: saturation, gain, offset; then the
//!    model's effort limits when [`SimParams::torque_limits_from_model`]), held constant
//!    (zero-order hold) over `[t_k, t_k + Δt]`;
//! 4. integrates the plant over that interval: `substeps` RK4 steps of `Δt / substeps` (for an
//!    interval of the sample period; where a dry friction raised them, fewer while no joint is
//!    near rest), or the adaptive integrator ([`Stepper::advance`]).
//!
//! Drives whose torque depends on the motion within the interval are evaluated at every stage
//! instead of held ([`drive_torque`]): a servo's back-EMF (`−en kt²/R q̇`, reported by
//! [`Controller::drive`]), [`Effect::BackEmf`](crate::Effect::BackEmf), the load friction of
//! [`Effect::LoadFriction`](crate::Effect::LoadFriction), and a drive disabled (`en = 0`: no
//! torque at all). Dry frictions of width `w = 0` are integrated as stick–slip: at the start of
//! each RK4 step the friction is the torque that would stop the joint within the step,
//! `τ_stop = M_ii (q̇_i / h + q̈_i)` (`M_ii` the joint's own inertia, `q̈_i` without that friction),
//! clipped to the friction level and held over the step, so a joint whose driving torque is
//! below the level stays at rest (the scheme of Rhoban BAM's servo simulator).
//!
//! A drive whose back-EMF is too stiff for RK4 within [`STIFF_DRIVE_SUBSTEPS`] steps per sample
//! (or, with the frictions' bands, within [`STIFF_DRIVE_FRICTION_SUBSTEPS`])
//! (a servo's back-EMF `kt²/R` against a light wrist link relaxes its speed in a tenth of a
//! millisecond) is integrated by the linearly implicit ROS2 instead ([`Ros2`]), with the
//! Jacobian of the velocity-dependent torques: `J = [[0, I], [0, −(H + diag(ia))⁻¹ D]]`, `D`
//! the slope `−∂(τ_drive + τ_friction)_i/∂q̇_i` of the drive torque (back-EMF, load friction)
//! and the smooth frictions at the start of each step (a forward difference, so a saturated
//! drive has none). The steps are then the ones asked for ([`SimParams::substeps`]; at least
//! [`IMPLICIT_DRY_SUBSTEPS`] with a smooth dry or load friction), not raised for the frictions'
//! bands, whose stiffness the implicit step takes too; the stick–slip
//! friction's stopping torque counts the damping implicitly
//! (`τ_stop = M_ii (q̇_i / h + q̈_i) + D_i q̇_i`).
//!
//! A state diverged when it is not finite or `|q̇|` exceeds [`SimParams::divergence_bound`]
//! ([`Stepper::diverged`]). The step never allocates.

use crate::backlash::{DriveSides, BACKLASH_SUBSTEPS};
use crate::controller::Controller;
use crate::delay::DelayLine;
use crate::effects::{applied_torque, drive_torque, exact_dry_levels, friction_torque_smooth, has_drive_effects, has_exact_dry_friction, stiff_band};
use crate::error::Result;
use crate::integrate::{Dopri5, Integrator, Rk4, Ros2, ROS2_GAMMA};
use crate::params::SimParams;
use crate::plant::{Plant, PlantWorkspace};
use crate::sensor::Sensor;
use crate::substeps::{drive_substeps, drive_substeps_with, substeps_and_moving_rate, substeps_for_rate};

/// The RK4 steps per sample above which a drive's back-EMF alone is stiff: the drive's damping,
/// with the frictions' slopes, is then integrated implicitly (see the [module docs](self)),
/// since resolving it explicitly would cost more. (A drive stiff only with its frictions keeps
/// RK4 at the steps they ask for: on the real XL330 servo logs, whose diagnosis selects load
/// friction, the implicit step left the corrected held-out closed loop at 0.514 of the nominal
/// error against the 0.5 the explicit one reaches.)
pub const STIFF_DRIVE_SUBSTEPS: usize = 16;

/// The RK4 steps per sample above which a drive's back-EMF with the frictions' slopes is
/// integrated implicitly as well: a servo whose rotor inertia keeps its back-EMF resolvable but
/// whose load friction's band asks for hundreds of steps (an SO-101 wrist). The XL330 logs'
/// candidates ask for at most 27 and keep RK4.
pub const STIFF_DRIVE_FRICTION_SUBSTEPS: usize = 64;

/// The implicit steps per sample at least when a smooth dry friction or a load friction acts:
/// ROS2 is first order at a band's kinks (a servo on a light link with Coulomb friction at 20 ms
/// samples: 11.6 mrad from the adaptive reference at one step per sample, 2.8 mrad at four).
pub const IMPLICIT_DRY_SUBSTEPS: usize = 4;

/// The per-sample step of the closed loop (see the [module docs](self)): sensors, delay ring,
/// held torque and integrator workspace of one run of `plant`.
///
/// Sample indices `k` passed to [`Stepper::advance`] are absolute (sample 0 is the first of the
/// run or log); the delay line takes commands `k − m` and `k − m − 1` from the ring, and
/// sample 0's command before the first sample.
#[derive(Debug)]
pub struct Stepper<'p> {
    plant: &'p Plant,
    pws: PlantWorkspace,
    rk4: Rk4,
    dopri: Option<Dopri5>,
    sensor: Sensor,
    line: DelayLine,
    /// Ring of commands: slot `i mod depth` holds `τ_cmd,i`.
    depth: usize,
    history: Vec<f64>,
    q_meas: Vec<f64>,
    qd_meas: Vec<f64>,
    cmd: Vec<f64>,
    delayed: Vec<f64>,
    applied: Vec<f64>,
    limits: Option<Vec<f64>>,
    /// The drives of the current sample ([`Controller::drive`]): enable and back-EMF.
    enabled: Vec<f64>,
    emf: Vec<f64>,
    /// The back-EMF coefficients [`Stepper::drive_substeps`] was computed for.
    emf_seen: Vec<f64>,
    /// RK4 steps per sample period with the controller's back-EMF: `substeps`, raised so that
    /// the motor's damping `kt²/R` against the link's inertia keeps RK4 stable (a servo's light
    /// wrist link: hundreds of steps per 20 ms sample).
    drive_substeps: usize,
    /// The same for the back-EMF alone: above [`STIFF_DRIVE_SUBSTEPS`], the drive is stiff
    /// and its step implicit.
    emf_substeps: usize,
    /// The plant has back-EMF or load friction; it has dry friction of width 0.
    drive_effects: bool,
    exact_dry: bool,
    /// Scratch of the drive path: command less back-EMF, drive torque, stick–slip friction,
    /// levels, inertia diagonal, acceleration.
    scratch: [Vec<f64>; 7],
    /// The implicit drive step: its integrator, `H + diag(ia)`, `W = H + γh diag(D)` and its
    /// factor; scratch of the damping's difference (perturbed speed, two drive torques, `D`)
    /// and of the solve.
    ros2: Ros2,
    inertia: [nalgebra::DMatrix<f64>; 3],
    implicit_scratch: [Vec<f64>; 7],
    adds_ff: bool,
    period: f64,
    substeps: usize,
    /// The substeps asked for by `params` before friction raises them.
    base_substeps: usize,
    /// The friction's rate while every joint moves ([`substeps_and_moving_rate`]; `None`:
    /// `substeps` throughout).
    moving_rate: Option<f64>,
    /// Per joint, the speed below which its dry friction is stiff ([`stiff_band`]).
    band: Vec<f64>,
    /// The drive sides of the joints with backlash ([`crate::backlash`]), and the speeds at the
    /// start of the current step.
    sides: Option<DriveSides>,
    qd_start: Vec<f64>,
    /// Integration steps taken so far.
    steps_taken: u64,
    divergence_bound: f64,
}

impl<'p> Stepper<'p> {
    /// A stepper of `plant` under `params` (sample period, substeps raised by
    /// [`effective_substeps`](crate::effective_substeps), integrator, sensors, effort limits,
    /// divergence bound) for runs of at most `samples` samples (which bounds the delay ring: a delay longer
    /// than the run holds the first command throughout and allocates nothing more).
    ///
    /// # Errors
    /// [`Error::Invalid`](crate::Error::Invalid) for parameters outside their ranges
    /// ([`SimParams::validate`]).
    pub fn new(plant: &'p Plant, params: &SimParams, samples: usize) -> Result<Stepper<'p>> {
        let n = plant.dof();
        params.validate(n)?;
        let sensor = Sensor::new(&params.sensor, plant.model(), params.sample_period)?;
        let line = DelayLine::new(plant.delay(), params.sample_period);
        let depth = line.whole().min(samples) + 2;
        let (substeps, moving_rate) = substeps_and_moving_rate(plant, params);
        let mut band = vec![0.0; n];
        stiff_band(plant.effects(), &mut band);
        let sides = DriveSides::new(plant);
        if sides.is_some() && matches!(params.integrator, Integrator::Adaptive { .. }) {
            return Err(crate::Error::Invalid {
                what: "backlash".into(),
                message: "the drive side's impacts are integrated with fixed RK4 steps; the adaptive integrator does not take them (use the default integrator)".into(),
            });
        }
        Ok(Stepper {
            plant,
            pws: plant.workspace(),
            rk4: Rk4::new(2 * n),
            dopri: match params.integrator {
                Integrator::Adaptive { rtol, atol } => Some(Dopri5::new(2 * n, rtol, atol)),
                Integrator::Rk4 => None,
            },
            sensor,
            line,
            depth,
            history: vec![0.0; depth * n],
            q_meas: vec![0.0; n],
            qd_meas: vec![0.0; n],
            cmd: vec![0.0; n],
            delayed: vec![0.0; n],
            applied: vec![0.0; n],
            limits: params.torque_limits_from_model.then(|| plant.effort_limits().to_vec()),
            enabled: vec![1.0; n],
            emf: vec![0.0; n],
            emf_seen: vec![0.0; n],
            drive_substeps: substeps,
            emf_substeps: 1,
            drive_effects: has_drive_effects(plant.effects()),
            exact_dry: has_exact_dry_friction(plant.effects()),
            scratch: std::array::from_fn(|_| vec![0.0; n]),
            ros2: Ros2::new(2 * n),
            inertia: std::array::from_fn(|_| nalgebra::DMatrix::zeros(n, n)),
            implicit_scratch: std::array::from_fn(|_| vec![0.0; n]),
            adds_ff: true,
            period: params.sample_period,
            substeps,
            base_substeps: params.substeps,
            moving_rate,
            band,
            sides,
            qd_start: vec![0.0; n],
            steps_taken: 0,
            divergence_bound: params.divergence_bound,
        })
    }

    /// Number of degrees of freedom.
    pub fn dof(&self) -> usize {
        self.plant.dof()
    }

    /// Integration steps taken so far (RK4 steps; one per sample interval for the adaptive
    /// integrator): the cost of the run.
    pub fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    /// RK4 steps per sample period at most (after
    /// [`effective_substeps`](crate::effective_substeps)): near rest, where a dry friction is
    /// stiff; fewer while every joint moves ([`Stepper::advance`]).
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// Restarts at sample `k0` of a log: the sensors continue from `q_meas_prev`, the position
    /// measured at sample `k0 − 1` (none: they keep their state), and the delay line holds the
    /// commands `past(i)` of the samples `i < k0` it can still apply (rows of length
    /// [`Stepper::dof`]).
    ///
    /// # Panics
    /// If a row is shorter than the number of joints.
    pub fn restart<'a>(&mut self, k0: usize, q_meas_prev: Option<&[f64]>, past: impl Fn(usize) -> &'a [f64]) {
        let n = self.dof();
        if let Some(q) = q_meas_prev {
            self.sensor.restart(q);
        }
        if let Some(sides) = &mut self.sides {
            sides.reset(&mut self.pws);
        }
        // the taps from k0 on reach back at most depth − 1 samples (or to sample 0); without
        // a delay they reach nothing before k0
        if self.line.is_zero() {
            return;
        }
        for i in k0.saturating_sub(self.depth - 1)..k0 {
            let slot = i % self.depth;
            self.history[slot * n..(slot + 1) * n].copy_from_slice(&past(i)[..n]);
        }
    }

    /// The command of sample `k` at time `t` from the true state `y = [q; q̇]`: the sensors
    /// measure `y`, `controller` computes its torque from the measurement and the reference
    /// `(q_ref, q̇_ref)`, plus `tau_ff` (the reference's feed-forward torque; empty = none) for a
    /// controller that adds it ([`Controller::adds_feed_forward`]). Read them back with
    /// [`Stepper::measured`] and [`Stepper::command_torque`].
    ///
    /// Returns the first joint whose measurement or command is not finite (the run diverged).
    ///
    /// # Panics
    /// If a length does not match the model.
    pub fn command(&mut self, controller: &mut dyn Controller, t: f64, y: &[f64], q_ref: &[f64], qd_ref: &[f64], tau_ff: &[f64]) -> Option<usize> {
        let n = self.dof();
        let (q, qd) = y.split_at(n);
        self.sensor.measure(q, qd, &mut self.q_meas, &mut self.qd_meas);
        controller.torque(t, &self.q_meas, &self.qd_meas, q_ref, qd_ref, &mut self.cmd);
        controller.drive(&mut self.enabled, &mut self.emf);
        if self.emf != self.emf_seen {
            // the motor's damping is stiff against a light link: the steps resolve its rate
            self.emf_seen.copy_from_slice(&self.emf);
            self.drive_substeps = drive_substeps(self.plant, q, &self.emf, self.period, self.substeps);
            self.emf_substeps = drive_substeps_with(self.plant, q, &self.emf, self.period, 1, false);
        }
        self.adds_ff = controller.adds_feed_forward();
        if self.adds_ff && !tau_ff.is_empty() {
            for i in 0..n {
                self.cmd[i] += tau_ff[i];
            }
        }
        (0..n).find(|&j| !self.cmd[j].is_finite() || !self.q_meas[j].is_finite() || !self.qd_meas[j].is_finite())
    }

    /// Sets the command of the next [`Stepper::advance`] to `tau` [N·m or N], model order (e.g.
    /// a logged torque replayed open loop).
    ///
    /// # Panics
    /// If `tau.len()` is not the number of joints.
    pub fn set_command(&mut self, tau: &[f64]) {
        self.cmd.copy_from_slice(tau);
        self.enabled.fill(1.0);
        self.emf.fill(0.0);
    }

    /// The positions and velocities the sensors measured at the last [`Stepper::command`].
    pub fn measured(&self) -> (&[f64], &[f64]) {
        (&self.q_meas, &self.qd_meas)
    }

    /// The command of the current sample [N·m or N].
    pub fn command_torque(&self) -> &[f64] {
        &self.cmd
    }

    /// The torque applied (held) over the last interval [N·m or N]: the delayed command after
    /// the actuator effects and limits.
    pub fn applied(&self) -> &[f64] {
        &self.applied
    }

    /// Advances the state `y = [q; q̇]` (length `2 · dof`) from `t` over one sample interval of
    /// `dt` seconds with the current command as the command of sample `k`: delay line, held
    /// applied torque, then the integrator. An interval of the sample period takes `substeps`
    /// RK4 steps; another (rounded log stamps) `⌈dt / h⌉` steps of at most the same size
    /// `h = T / substeps` (1 to 10,000).
    ///
    /// Where the substeps were raised for a dry friction's stiffness near rest, an interval in
    /// which every joint stays clear of its stiff band takes only the steps the friction's rate
    /// while moving asks for (`substeps_and_moving_rate`); an interval with a joint near rest
    /// takes them all, so the friction's transitions are integrated as finely as before. (Raising the steps only
    /// for the joints near rest, by a bound of their own rates, stayed stable but shifted
    /// multiple shooting's answer on a real double pendulum enough to predict 12 % worse.)
    ///
    /// # Panics
    /// If `y.len() != 2 · dof`.
    pub fn advance(&mut self, k: usize, t: f64, dt: f64, y: &mut [f64]) {
        let n = self.dof();
        assert_eq!(y.len(), 2 * n, "Stepper::advance: y must hold q and q̇");
        // delay line: slot k mod depth holds τ_cmd,k (the taps of sample k are at most
        // depth − 1 samples old, or sample 0, whose slot is not yet overwritten then)
        if self.line.is_zero() {
            self.delayed.copy_from_slice(&self.cmd);
        } else {
            let (depth, history) = (self.depth, &mut self.history);
            let slot = k % depth;
            history[slot * n..(slot + 1) * n].copy_from_slice(&self.cmd);
            let history = &*history;
            self.line.delayed_row(k, |i| &history[(i % depth) * n..(i % depth + 1) * n], &mut self.delayed);
        }
        let steps = steps_over(self.period, dt, self.substeps);
        let drive = self.drive_effects || self.exact_dry || self.sides.is_some() || self.emf.iter().any(|e| *e != 0.0) || self.enabled.iter().any(|e| *e != 1.0);
        if !drive {
            // actuators: saturation, gain, offset, then the model's effort limits, held
            applied_torque(self.plant.effects(), &self.delayed, &mut self.applied);
            if let Some(limits) = &self.limits {
                for i in 0..n {
                    self.applied[i] = self.applied[i].clamp(-limits[i], limits[i]);
                }
            }
            // integrate the plant over the interval with the held torque
            let (plant, pws, applied) = (self.plant, &mut self.pws, &self.applied);
            let mut f = |_t: f64, y: &[f64], dy: &mut [f64]| {
                let (q, qd) = y.split_at(n);
                let (dq, ddq) = dy.split_at_mut(n);
                dq.copy_from_slice(qd);
                plant.acceleration(pws, q, qd, applied, ddq);
            };
            match self.dopri.as_mut() {
                Some(d) => {
                    d.integrate(&mut f, t, t + dt, y);
                    self.steps_taken += 1;
                }
                None => {
                    // the first stage tells whether the interval keeps every joint clear of its
                    // dry friction's stiff band (its speed, less twice the change its
                    // acceleration makes over the interval, above the band); then the steps
                    // need only resolve the moving rate, else all of them are taken
                    let d = self.rk4.derivative(&mut f, t, y);
                    let steps = match self.moving_rate {
                        Some(lambda) if (0..n).all(|i| self.band[i] == 0.0 || y[n + i].abs() - 2.0 * d[n + i].abs() * dt > self.band[i]) => {
                            substeps_for_rate(dt, lambda, steps_over(self.period, dt, self.base_substeps)).min(steps)
                        }
                        _ => steps,
                    };
                    self.steps_taken += steps as u64;
                    let h = dt / steps as f64;
                    self.rk4.step_from_derivative(&mut f, t, h, y);
                    for s in 1..steps {
                        self.rk4.step(&mut f, t + s as f64 * h, h, y);
                    }
                }
            }
            return;
        }
        // drives evaluated at every stage (back-EMF, load friction, enable), dry frictions of
        // width 0 as stick–slip held over each step; the RK4 steps also resolve the back-EMF,
        // or ROS2 takes its damping implicitly where that would cost too many
        let emf = self.emf.iter().any(|e| *e != 0.0);
        let stiff_drive = emf && (self.emf_substeps > STIFF_DRIVE_SUBSTEPS.max(self.base_substeps) || self.drive_substeps > STIFF_DRIVE_FRICTION_SUBSTEPS.max(self.base_substeps));
        let steps = if stiff_drive {
            let dry = self.drive_effects || self.band.iter().any(|b| *b > 0.0);
            steps_over(self.period, dt, self.base_substeps.max(if dry { IMPLICIT_DRY_SUBSTEPS } else { 1 }))
        } else if emf {
            steps_over(self.period, dt, self.drive_substeps.max(self.substeps))
        } else {
            steps
        };
        let steps = if self.sides.is_some() { steps.max(steps_over(self.period, dt, BACKLASH_SUBSTEPS)) } else { steps };
        let (plant, limits) = (self.plant, self.limits.as_deref());
        let (delayed, emf, enabled) = (&self.delayed, &self.emf, &self.enabled);
        let [minus_emf, tau_drive, stick, pos, neg, m_diag, acc] = &mut self.scratch;
        let pws = &mut self.pws;
        let torque = |qd: &[f64], minus_emf: &mut [f64], tau_drive: &mut [f64], out: &mut [f64]| {
            drive_torque(plant.effects(), limits, delayed, emf, enabled, qd, minus_emf, tau_drive, out);
        };
        match self.dopri.as_mut() {
            Some(d) => {
                let applied = &mut self.applied;
                let mut f = |_t: f64, y: &[f64], dy: &mut [f64]| {
                    let (q, qd) = y.split_at(n);
                    let (dq, ddq) = dy.split_at_mut(n);
                    dq.copy_from_slice(qd);
                    torque(qd, minus_emf, tau_drive, applied);
                    plant.acceleration(pws, q, qd, applied, ddq);
                };
                d.integrate(&mut f, t, t + dt, y);
                self.steps_taken += 1;
            }
            None => {
                self.steps_taken += steps as u64;
                let h = dt / steps as f64;
                let exact = self.exact_dry;
                stick.fill(0.0);
                let [qd_step, drive_at, drive_step, friction_at, friction_step, damping, solved] = &mut self.implicit_scratch;
                let [inertia, w, factor] = &mut self.inertia;
                damping.fill(0.0);
                for s in 0..steps {
                    if let Some(sides) = &mut self.sides {
                        // the gaps that open at the start of the step (the contact would pull)
                        let (q, qd) = y.split_at(n);
                        self.qd_start.copy_from_slice(qd);
                        torque(qd, minus_emf, tau_drive, &mut self.applied);
                        sides.uncouple(&mut self.applied);
                        plant.acceleration(pws, q, qd, &self.applied, acc);
                        sides.open_where_pulling(pws, &self.applied, acc, qd);
                    }
                    if stiff_drive {
                        // the damping D_i = −∂(τ_drive + τ_friction)_i/∂q̇_i (a forward
                        // difference, per joint: a joint's drive torque and friction depend on
                        // its own speed only), and W = H + γh D, with which ROS2 solves
                        let (q, qd) = y.split_at(n);
                        for i in 0..n {
                            qd_step[i] = qd[i] + 1e-6 * qd[i].abs().max(1.0);
                        }
                        torque(qd, minus_emf, tau_drive, drive_at);
                        torque(qd_step, minus_emf, tau_drive, drive_step);
                        friction_torque_smooth(plant.effects(), q, qd, friction_at);
                        friction_torque_smooth(plant.effects(), q, qd_step, friction_step);
                        if let Some(sides) = &self.sides {
                            // an open gap's drive damps its rotor, not its link
                            sides.uncouple(drive_at);
                            sides.uncouple(drive_step);
                        }
                        for i in 0..n {
                            let d = (drive_at[i] + friction_at[i] - drive_step[i] - friction_step[i]) / (qd_step[i] - qd[i]);
                            damping[i] = if d.is_finite() { d.max(0.0) } else { 0.0 };
                        }
                        plant.inertia_matrix(pws, q, inertia);
                        w.copy_from(inertia);
                        for i in 0..n {
                            w[(i, i)] += ROS2_GAMMA * h * damping[i];
                        }
                    }
                    if exact {
                        // the friction that stops each joint within the step, clipped to its level
                        // (with the implicit damping's share where ROS2 steps)
                        let (q, qd) = y.split_at(n);
                        torque(qd, minus_emf, tau_drive, &mut self.applied);
                        if let Some(sides) = &self.sides {
                            sides.uncouple(&mut self.applied);
                        }
                        plant.acceleration_smooth(pws, q, qd, &self.applied, acc);
                        plant.inertia_diagonal(pws, q, m_diag);
                        exact_dry_levels(plant.effects(), qd, tau_drive, pos, neg);
                        for i in 0..n {
                            let stop = m_diag[i] * (qd[i] / h + acc[i]) + damping[i] * qd[i];
                            let level = if stop > 0.0 { pos[i] } else { neg[i] };
                            stick[i] = if stop.is_finite() { -stop.signum() * stop.abs().min(level) } else { 0.0 };
                        }
                    }
                    let applied = &mut self.applied;
                    let stick = &*stick;
                    let sides = self.sides.as_ref();
                    let mut f = |_t: f64, y: &[f64], dy: &mut [f64]| {
                        let (q, qd) = y.split_at(n);
                        let (dq, ddq) = dy.split_at_mut(n);
                        dq.copy_from_slice(qd);
                        torque(qd, minus_emf, tau_drive, applied);
                        if let Some(sides) = sides {
                            sides.uncouple(applied);
                        }
                        if exact {
                            for i in 0..n {
                                applied[i] += stick[i];
                            }
                            plant.acceleration_smooth(pws, q, qd, applied, ddq);
                        } else {
                            plant.acceleration(pws, q, qd, applied, ddq);
                        }
                    };
                    if stiff_drive {
                        // (I − γhJ)⁻¹ [r₁; r₂] = [r₁ + γh b; b] with b = W⁻¹ H r₂
                        let (inertia, w) = (&*inertia, &*w);
                        let mut solve = |r: &mut [f64]| {
                            let (r1, r2) = r.split_at_mut(n);
                            for i in 0..n {
                                solved[i] = (0..n).map(|j| inertia[(i, j)] * r2[j]).sum();
                            }
                            factor.copy_from(w);
                            if !simgap_core::try_solve_spd_in_place(factor, solved) {
                                solved.fill(f64::NAN);
                            }
                            r2.copy_from_slice(solved);
                            for i in 0..n {
                                r1[i] += ROS2_GAMMA * h * solved[i];
                            }
                        };
                        self.ros2.step(&mut f, &mut solve, t + s as f64 * h, h, y);
                    } else {
                        self.rk4.step(&mut f, t + s as f64 * h, h, y);
                    }
                    if let Some(sides) = &mut self.sides {
                        // the open rotors under the drive's torque, and their impacts
                        sides.advance(plant, pws, h, &self.qd_start, y, m_diag, &torque);
                    }
                }
            }
        }
    }

    /// The diverged joint of state `y = [q; q̇]`: the first with a non-finite state, else the
    /// fastest with `|q̇|` above the divergence bound; `None` while the state is sound.
    pub fn diverged(&self, y: &[f64]) -> Option<usize> {
        let (q, qd) = y.split_at(self.dof());
        diverged_joint(q, qd, self.divergence_bound)
    }
}

/// The diverged joint: the first with a non-finite state, else the fastest beyond the bound.
fn diverged_joint(q: &[f64], qd: &[f64], bound: f64) -> Option<usize> {
    if let Some(j) = (0..q.len()).find(|&j| !q[j].is_finite() || !qd[j].is_finite()) {
        return Some(j);
    }
    let (j, v) = qd.iter().map(|v| v.abs()).enumerate().fold((0, 0.0), |acc, (j, v)| if v > acc.1 { (j, v) } else { acc });
    (v > bound).then_some(j)
}

/// RK4 steps over an interval of `dt` seconds at `per_period` steps per sample `period`:
/// `per_period` for the period itself, else `⌈dt / h⌉` steps of at most `h = period / per_period`
/// (1 to 10,000; an interval that differs from the period by rounding of the stamps).
fn steps_over(period: f64, dt: f64, per_period: usize) -> usize {
    if dt == period {
        per_period
    } else {
        ((dt * per_period as f64 / period * (1.0 - 1e-9)).ceil() as usize).clamp(1, 10_000)
    }
}
