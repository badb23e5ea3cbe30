//! The sidecar `PATH.effects.json`: the selected effects an exported file does not hold, in the
//! report's `selected_effects` form, each with how to apply it, and where the others went.

use std::collections::BTreeMap;

use simgap_sim::EffectKind;

use crate::{EffectReport, Param};

/// One selected effect the exported format does not hold: the report's entry (`effect`,
/// `joints`, `parameters` with `w` where the report has it, `units`) and one sentence on how
/// to apply it in a simulator.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SidecarEntry {
    /// The effect (its contract name in the JSON, e.g. `time_delay`).
    #[serde(serialize_with = "crate::vocabulary::effects::contract_name")]
    pub effect: EffectKind,
    /// Joints it acts on (names); empty for whole-robot effects.
    pub joints: Vec<String>,
    /// Parameters, as in the report's `selected_effects` (per-joint lists aligned with
    /// `joints`, whole-robot numbers).
    pub parameters: BTreeMap<String, Param>,
    /// The unit of each parameter, as the report states it (empty where it states none).
    pub units: BTreeMap<String, String>,
    /// How to apply it, in one sentence.
    pub apply: String,
}

/// One selected effect the exported file does hold, and where it was written.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HeldEntry {
    /// The effect (its contract name in the JSON).
    #[serde(serialize_with = "crate::vocabulary::effects::contract_name")]
    pub effect: EffectKind,
    /// Joints it acts on.
    pub joints: Vec<String>,
    /// Its parameters as the report states them (`w` included for dry friction).
    pub parameters: BTreeMap<String, Param>,
    /// Where the file holds it (e.g. `joint damping`, `<inertial> of link 'forearm'`).
    pub written_as: String,
    /// How the file's version differs from the model simgap simulated, when it does (empty
    /// when it is exact).
    pub approximation: String,
}

/// The sidecar of one exported file.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Sidecar {
    /// `urdf` or `mjcf`.
    pub format: String,
    /// Selected effects the file does not hold, in the report's `selected_effects` form.
    pub selected_effects: Vec<SidecarEntry>,
    /// Selected effects the file holds, and where.
    pub held: Vec<HeldEntry>,
    /// Anything else a user of the file must know (e.g. URDF values simgap's model ignores).
    pub notes: Vec<String>,
}

impl Sidecar {
    /// An empty sidecar for `format` (`urdf` or `mjcf`).
    pub(super) fn new(format: &str) -> Self {
        Sidecar { format: format.into(), ..Sidecar::default() }
    }

    /// The JSON text (pretty-printed; non-finite numbers become `null`).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }

    /// Records `e` as held by the file.
    pub(super) fn hold(&mut self, e: &EffectReport, written_as: impl Into<String>, approximation: impl Into<String>) {
        self.held.push(HeldEntry {
            effect: e.effect,
            joints: e.joints.clone(),
            parameters: e.parameters.clone(),
            written_as: written_as.into(),
            approximation: approximation.into(),
        });
    }

    /// Records `e` as not held, with how to apply it in a simulator.
    pub(super) fn defer(&mut self, e: &EffectReport, format: Format) {
        let units = e.parameters.keys().map(|k| (k.clone(), e.units.get(k).cloned().unwrap_or_default())).collect();
        self.selected_effects.push(SidecarEntry { effect: e.effect, joints: e.joints.clone(), parameters: e.parameters.clone(), units, apply: how_to_apply(e.effect, format) });
    }
}

/// The exported format, for the sentences that differ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Format {
    Urdf,
    Mjcf,
}

/// How to apply an effect the file does not hold, in one sentence.
pub(super) fn how_to_apply(effect: EffectKind, format: Format) -> String {
    let each_step = "to the joint's generalised force at every step (MuJoCo: qfrc_applied before mj_step; Pinocchio: to τ before aba)";
    match (effect, format) {
        (EffectKind::Armature, _) => "Add ia to the joint's diagonal of the mass matrix: Pinocchio model.armature[v] = ia (v the joint's velocity index), MJCF joint armature; it is the rotor inertia reflected through the gearbox.".into(),
        (EffectKind::TorqueGain, _) => "Multiply the commanded torque by k before it reaches the joint (τ_applied = k·clamp(τ_cmd, ±limit) + offset); in MJCF it is the motor's gear.".into(),
        (EffectKind::TorqueSaturation, _) => {
            "Clamp the commanded torque to ±limit before the gain (MJCF: motor forcerange with forcelimited=\"true\"; Gazebo enforces <limit effort>, Pinocchio does not).".into()
        }
        (EffectKind::TorqueOffset, _) => "Add offset to the torque the drive applies, after the saturation and the gain: τ_applied = k·clamp(τ_cmd, ±limit) + offset.".into(),
        (EffectKind::TimeDelay, _) => {
            "Apply each command delay seconds late, for the whole robot: a buffer of delay / sample period samples between the controller and the actuators (τ_applied(t) = τ_cmd(t − delay)), or the simulator's actuator delay where it has one.".into()
        }
        (EffectKind::StribeckFriction, _) => format!(
            "Add −(fc + (fs − fc)·exp(−(q̇/vs)²))·tanh(q̇/w) {each_step}; a constant dry friction (URDF friction, MJCF frictionloss) cannot hold the breakaway hump, so it is not approximated by one."
        ),
        (EffectKind::Cogging, _) => format!("Add −amplitude·sin(periods_per_rev·q) {each_step}."),
        (EffectKind::DirectionalFriction, _) => format!("Add −(fc_pos·tanh(q̇/w) + b_pos·q̇) while q̇ > 0 and (fc_neg·tanh(−q̇/w) − b_neg·q̇) while q̇ < 0 {each_step}: friction that differs with the direction of motion."),
        (EffectKind::LoadFriction, _) => format!(
            "Add −(fc + mu·|τ_drive|)·tanh(q̇/w), τ_drive the torque the drive applies at the joint, {each_step}: dry friction that grows with the drive torque, which no joint attribute sees."
        ),
        (EffectKind::LoadStribeckFriction, _) => format!(
            "Add −(fc + mu·|τ_drive| + ((fs − fc) + (mus − mu)·|τ_drive|)·exp(−(q̇/vs)²))·tanh(q̇/w), τ_drive the torque the drive applies at the joint, {each_step}: dry friction that grows with the drive torque and is higher at rest (w = 0: hold the joint while the torque that would move it is below fs + mus·|τ_drive|)."
        ),
        (EffectKind::BackEmf, _) => "Add −kb·q̇ while the drive is enabled (torque on) and nothing with torque off; a robot whose torque is always on may add kb to the joint's damping instead.".into(),
        (EffectKind::EncoderOffset, _) => "Add offset to the measured position before the model sees it (the joint is at q_measured + offset: gravity, inertia and limits act there), and keep the controller on the measured one; MJCF: joint ref = −offset.".into(),
        (EffectKind::Backlash, _) => "Give the joint a drive side carrying its rotor inertia (armature) with free play of total width `width` to the link: the drive's torque reaches the link only while the play is taken up; inside the gap the rotor moves alone under the drive's torque, and where it reaches the other side it takes the link along in a plastic impact (momentum kept). MJCF: a second joint '<name>_backlash' of the same body and axis, range ±width/2.".into(),
        (EffectKind::JointSpring, Format::Urdf) => format!("Add −k·(q − q0) {each_step} (MJCF: joint stiffness = k, springref = q0)."),
        (EffectKind::CoriolisStructure, _) => "Pinocchio and MuJoCo compute the true (Euler–Lagrange) Coriolis torque: with the simplified C under test that is already the correction; with the Euler–Lagrange C under test the robot behaves as the simplified C = Ḣ/2, which neither can simulate.".into(),
        (_, _) => "Apply it as its entry in the report's selected_effects states it: this exporter does not map it onto the format.".into(),
    }
}
