//! The drive side of a joint with backlash ([`Effect::Backlash`](crate::Effect::Backlash)):
//! its hidden state, and when the play is taken up or opens.
//!
//! A joint `i` with play of total width `w` and rotor inertia `ia` (its armature) has a drive
//! side at `θ = q_i + s`, `|s| ≤ w/2`. While the play is taken up on side `σ = ±1` (`s = σ w/2`)
//! the rotor moves with the link: the plant holds `ia` on the joint's diagonal and the drive's
//! torque `τ_i` on the link, and the rotor pushes on the link with the contact torque
//! `λ = τ_i − ia q̈_i` (the rotor's equation `ia θ̈ = τ_i − λ` with `θ̈ = q̈_i`). When `σ λ < 0`
//! the contact would pull: the gap opens. Inside the gap the link moves without the drive's
//! torque and without `ia`, and the rotor alone, `ia θ̈ = τ_i(θ̇)`, with the drive's torque at
//! the rotor's speed (its back-EMF damps the rotor, not the link): an implicit Euler step per
//! integration step, `θ̇⁺ = θ̇ + h τ_i(θ̇) / (ia + h D)`, `D = −∂τ_i/∂θ̇`. When `s` reaches
//! `±w/2` moving outward the drive takes the link along in a plastic impact that keeps the
//! joint's momentum, `q̇_i⁺ = (M_ii q̇_i + ia θ̇) / (M_ii + ia)` (`M_ii` the link's own inertia
//! on the joint; the other joints' speeds are kept).
//!
//! A run or a restarted window starts with the play taken up on the side its first contact
//! torque pushes (the side the drive's torque holds at rest). The state is checked once per
//! integration step, which the stepper takes at least [`BACKLASH_SUBSTEPS`] times per sample.

use crate::plant::{Plant, PlantWorkspace};

/// Integration steps per sample at least while a joint has backlash: the drive side crosses a
/// gap of a degree in a few milliseconds.
pub const BACKLASH_SUBSTEPS: usize = 8;

/// The drive's torque at given speeds: `(speeds, scratch, drive torque, out)`, as
/// [`crate::effects::drive_torque`] computes it for the stepper's current command.
pub type DriveTorque<'a> = dyn Fn(&[f64], &mut [f64], &mut [f64], &mut [f64]) + 'a;

/// One joint's drive side.
#[derive(Clone, Debug)]
struct Gap {
    joint: usize,
    /// Half the play, `w/2` [rad or m].
    half: f64,
    /// Rotor inertia [kg·m² or kg].
    ia: f64,
    /// The side the play is taken up on (`±1`; 0 before the first contact is known).
    side: f64,
    /// The gap is open: the drive side moves alone.
    open: bool,
    /// Drive side minus link [rad or m].
    s: f64,
    /// The drive side's speed [rad/s or m/s].
    speed: f64,
}

/// The drive sides of every joint with backlash and a rotor inertia, with their scratch.
#[derive(Clone, Debug)]
pub struct DriveSides {
    gaps: Vec<Gap>,
    /// Speeds with the open joints' drive sides in place of their links' [rad/s or m/s].
    speeds: Vec<f64>,
    /// The drive's torque at those speeds, and at those speeds nudged [N·m or N].
    torque: [Vec<f64>; 2],
    /// Scratch of the drive's torque (command less back-EMF, drive torque).
    scratch: [Vec<f64>; 2],
}

impl DriveSides {
    /// The drive sides of `plant`'s joints with play (`None` without any: see
    /// [`Plant::backlash`]).
    pub fn new(plant: &Plant) -> Option<DriveSides> {
        let widths = plant.backlash()?;
        let n = plant.dof();
        let gaps = (0..n)
            .filter(|&i| widths[i] > 0.0 && plant.armature()[i] > 0.0)
            .map(|i| Gap { joint: i, half: 0.5 * widths[i], ia: plant.armature()[i], side: 0.0, open: false, s: 0.0, speed: 0.0 })
            .collect();
        Some(DriveSides { gaps, speeds: vec![0.0; n], torque: [vec![0.0; n], vec![0.0; n]], scratch: [vec![0.0; n], vec![0.0; n]] })
    }

    /// Starts over (a new run or window): every play taken up, on the side the next contact
    /// torque pushes; every rotor coupled to its link in `pws`.
    pub fn reset(&mut self, pws: &mut PlantWorkspace) {
        for g in &mut self.gaps {
            g.side = 0.0;
            g.open = false;
            pws.couple_rotor(g.joint, g.ia);
        }
    }

    /// Removes from `applied` the drive's torque of the joints whose gap is open: it moves their
    /// rotors, not their links.
    pub fn uncouple(&self, applied: &mut [f64]) {
        for g in self.gaps.iter().filter(|g| g.open) {
            applied[g.joint] = 0.0;
        }
    }

    /// At the start of a step: opens the gap of each joint whose contact torque
    /// `λ = τ_i − ia q̈_i` would pull, with `applied` the drive's torques (the open joints'
    /// already removed) and `acc` the accelerations they give at speeds `qd`.
    pub fn open_where_pulling(&mut self, pws: &mut PlantWorkspace, applied: &[f64], acc: &[f64], qd: &[f64]) {
        for g in self.gaps.iter_mut().filter(|g| !g.open) {
            let i = g.joint;
            let contact = applied[i] - g.ia * acc[i];
            if g.side == 0.0 {
                g.side = if contact < 0.0 { -1.0 } else { 1.0 };
                g.s = g.side * g.half;
            } else if g.side * contact < 0.0 && contact.is_finite() {
                g.open = true;
                g.s = g.side * g.half;
                g.speed = qd[i];
                pws.couple_rotor(i, 0.0);
            }
        }
    }

    /// Whether some gap is open.
    pub fn any_open(&self) -> bool {
        self.gaps.iter().any(|g| g.open)
    }

    /// At the end of a step of `h` seconds from speeds `qd_start` to the state `y = [q; q̇]`:
    /// moves each open joint's drive side under `torque` (the drive's torque at given speeds,
    /// see [`crate::effects::drive_torque`]), and where it reaches the other side of its gap,
    /// takes the link along (the plastic impact of the module docs, `m_diag` scratch for the
    /// links' own inertias).
    #[allow(clippy::too_many_arguments)]
    pub fn advance(&mut self, plant: &Plant, pws: &mut PlantWorkspace, h: f64, qd_start: &[f64], y: &mut [f64], m_diag: &mut [f64], torque: &DriveTorque<'_>) {
        if !self.any_open() {
            return;
        }
        let n = plant.dof();
        // the drive's torque at the rotors' speeds, and its slope there
        self.speeds.copy_from_slice(qd_start);
        for g in self.gaps.iter().filter(|g| g.open) {
            self.speeds[g.joint] = g.speed;
        }
        let [minus_emf, drive] = &mut self.scratch;
        let [at, nudged] = &mut self.torque;
        torque(&self.speeds, minus_emf, drive, at);
        for g in self.gaps.iter().filter(|g| g.open) {
            self.speeds[g.joint] = g.speed + nudge(g.speed);
        }
        torque(&self.speeds, minus_emf, drive, nudged);
        let mut impact = false;
        for g in self.gaps.iter_mut().filter(|g| g.open) {
            let i = g.joint;
            let damping = ((at[i] - nudged[i]) / nudge(g.speed)).max(0.0);
            let damping = if damping.is_finite() { damping } else { 0.0 };
            g.speed += h * at[i] / (g.ia + h * damping);
            g.s += h * (g.speed - y[n + i]);
            let relative = g.speed - y[n + i];
            if g.s.abs() >= g.half && g.s * relative >= 0.0 {
                impact = true;
            }
        }
        if !impact {
            return;
        }
        // the links' own inertias (the open rotors uncoupled), then the impacts
        let (q, _) = y.split_at(n);
        plant.inertia_diagonal(pws, q, m_diag);
        for g in self.gaps.iter_mut().filter(|g| g.open) {
            let i = g.joint;
            let relative = g.speed - y[n + i];
            if g.s.abs() >= g.half && g.s * relative >= 0.0 {
                g.side = g.s.signum();
                g.s = g.side * g.half;
                g.open = false;
                let m = m_diag[i];
                y[n + i] = (m * y[n + i] + g.ia * g.speed) / (m + g.ia);
                pws.couple_rotor(i, g.ia);
            }
        }
    }
}

/// The step of the forward difference of the drive's torque in a rotor's speed [rad/s or m/s].
fn nudge(speed: f64) -> f64 {
    1e-6 * speed.abs().max(1.0)
}
