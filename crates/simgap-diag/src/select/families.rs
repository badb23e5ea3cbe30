//! The candidate families of the selection ([`families`]) and the search of each family's
//! nonlinear parameter: its grid, the best member against the current residual and its
//! refinement around it ([`Context::best_of`]).

use super::context::Context;
use super::residual::screen_best;
use crate::prepare::dataset::FitData;
use crate::vocabulary::{Column, Term, TermDesign};

/// Widths a Coulomb friction's grid tries on a joint (then refined within its range).
const DRY_WIDTH_GRID: usize = 8;

/// Widths a Stribeck friction's grid tries with each Stribeck velocity (one: the top of the
/// joint's range; its hump below vs shapes the sign near rest).
const STRIBECK_WIDTH_GRID: usize = 1;

/// A family of terms sharing an effect and a joint; nonlinear parameters are searched on a grid.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Family {
    /// A fixed term.
    Fixed(Term),
    /// Coulomb friction, its width `w` searched within the joint's
    /// [`DryWidth`](crate::prepare::width::DryWidth).
    Coulomb(usize),
    /// Stribeck velocity searched, and its width `w` within the joint's
    /// [`DryWidth`](crate::prepare::width::DryWidth).
    Stribeck(usize),
    /// Load-dependent friction, its width `w` searched like Coulomb friction's.
    LoadFriction(usize),
    /// Saturation limit searched.
    Saturation(usize),
    /// Cogging periods searched.
    Cogging(usize),
    /// Delay searched.
    Delay,
    /// Payload centre of mass re-linearised.
    Payload,
}

impl Family {
    /// A member of the family: every member occupies the same slot (see [`Term::slot`]).
    pub(super) fn member(&self) -> Term {
        match *self {
            Family::Fixed(ref t) => t.clone(),
            Family::Coulomb(joint) => Term::Coulomb { joint, w: 1.0 },
            Family::Stribeck(joint) => Term::Stribeck { joint, vs: 1.0, w: 1.0 },
            Family::LoadFriction(joint) => Term::LoadFriction { joint, w: 1.0 },
            Family::Saturation(joint) => Term::Saturation { joint, limit: 1.0 },
            Family::Cogging(joint) => Term::Cogging { joint, periods: 1.0 },
            Family::Delay => Term::Delay { delay: 0.0 },
            Family::Payload => Term::Payload { com: [0.0; 3], max_mass: f64::INFINITY },
        }
    }
}

/// All candidate families for the fit runs `data` (back-EMF only on joints whose drive some
/// run disables: elsewhere it is viscous friction; a torque saturation only where no fit run was
/// low-pass filtered by its recorder; a rotor inertia only where the effort was not measured on
/// the link side of the gearbox).
pub(crate) fn families(data: &[FitData]) -> Vec<Family> {
    let dof = data.first().map_or(0, |d| d.dof);
    // a recorder's low-pass filter flattens the torque's peaks as a limit would: on such logs a
    // torque saturation cannot be told from it (`prepare::lowpass`)
    let saturation = !crate::prepare::lowpass::any_filtered(data);
    let rotor = crate::vocabulary::rotor::visible(data);
    let mut f = Vec::new();
    for j in 0..dof {
        f.push(Family::Fixed(Term::Viscous(j)));
        f.push(Family::Coulomb(j));
        f.push(Family::Stribeck(j));
        f.push(Family::LoadFriction(j));
        if crate::vocabulary::back_emf::separable(j, data) {
            f.push(Family::Fixed(Term::BackEmf(j)));
        }
        if rotor {
            f.push(Family::Fixed(Term::Armature(j)));
        }
        f.push(Family::Fixed(Term::Gain(j)));
        f.push(Family::Fixed(Term::Offset(j)));
        if saturation {
            f.push(Family::Saturation(j));
        }
        f.push(Family::Cogging(j));
        f.push(Family::Fixed(Term::Spring(j)));
        f.push(Family::Fixed(Term::EncoderOffset(j)));
    }
    f.push(Family::Delay);
    f.push(Family::Fixed(Term::CoriolisStructure));
    f.push(Family::Payload);
    f
}

/// Whether directional friction is tried on a joint of type `kind`: on every linear axis (ball
/// screws, belts and guides, whose friction commonly differs by direction) and, when asked for
/// (`options.directional_friction`), on every joint.
pub(crate) fn directional_tried(kind: simgap_core::JointKind, options: &crate::DiagnoseOptions) -> bool {
    options.directional_friction || kind == simgap_core::JointKind::Prismatic
}

/// The families of the vocabulary a diagnosis with `options` does not try on these runs, each
/// with why and how to ask for it, for the report's notes: directional friction on turning
/// joints (`kinds`; it is tried on linear axes) and, on servo logs (`servo`), the load friction
/// rising at rest.
pub(crate) fn not_tried(kinds: &[simgap_core::JointKind], joints: &[String], servo: bool, options: &crate::DiagnoseOptions) -> Vec<String> {
    use simgap_sim::EffectKind;
    let mut out = Vec::new();
    let turning: Vec<&str> = kinds.iter().zip(joints).filter(|(k, _)| !directional_tried(**k, options)).map(|(_, j)| j.as_str()).collect();
    if !turning.is_empty() {
        out.push(format!(
            "not tried: {} on the turning joints ({}): it is tried on linear axes only unless asked for (--directional-friction, Python directional_friction=True), since on turning joints a near-tie between it and the symmetric pair can pick the worse",
            EffectKind::DirectionalFriction,
            turning.join(", ")
        ));
    }
    if servo && !options.load_stribeck_friction {
        out.push(format!(
            "not tried: {} (a load friction rising at rest) on these servo logs: it is tried when asked for (--load-stribeck-friction, Python load_stribeck_friction=True), at up to twice the time",
            EffectKind::LoadStribeckFriction
        ));
    }
    out
}

impl Context<'_> {
    /// The members of `family` the search tries: its grid over the nonlinear parameter.
    fn grid(&self, family: &Family) -> Vec<Term> {
        match *family {
            Family::Fixed(ref t) => vec![t.clone()],
            Family::Coulomb(j) => self.dry_width[j].grid(DRY_WIDTH_GRID).into_iter().map(|w| Term::Coulomb { joint: j, w }).collect(),
            Family::LoadFriction(j) => self.dry_width[j].grid(DRY_WIDTH_GRID).into_iter().map(|w| Term::LoadFriction { joint: j, w }).collect(),
            Family::Stribeck(j) => {
                let widths = self.dry_width[j].grid(STRIBECK_WIDTH_GRID);
                let terms = (0..12).flat_map(|i| widths.iter().map(move |&w| Term::Stribeck { joint: j, vs: 0.01 * 1.6f64.powi(i), w }));
                terms.filter(|t| matches!(*t, Term::Stribeck { vs, w, .. } if crate::vocabulary::stribeck_resolvable(vs, w))).collect()
            }
            Family::Saturation(j) => {
                let max = self.max_command(j);
                let floor = self.saturation_floor[j];
                (1..=24)
                    .map(|i| Term::Saturation { joint: j, limit: max * (0.2 + 0.8 * (1.0 - (i as f64 / 25.0))) })
                    .filter(|t| matches!(t, Term::Saturation { limit, .. } if *limit >= floor))
                    .collect()
            }
            Family::Cogging(j) => (3..=64).map(|n| Term::Cogging { joint: j, periods: n as f64 }).collect(),
            Family::Delay => {
                let t = self.sample_period;
                [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0].iter().map(|m| Term::Delay { delay: m * t }).collect()
            }
            Family::Payload => vec![Term::Payload { com: [0.0; 3], max_mass: self.max_payload() }],
        }
    }
    /// `best` refined on a finer grid around it (the payload's centre of mass searched).
    fn refine(&self, best: &Term, resid: &Column) -> Term {
        match *best {
            Term::Saturation { joint, limit } => {
                // coarse (±20 % in 2 % steps), then fine (±2 % in 0.2 % steps)
                // (only limits the data allow; the current one is among them)
                let allowed = |t: &Term| *t == *best || self.saturation_plausible(t, resid);
                let coarse: Vec<Term> = (-10..=10).map(|i| Term::Saturation { joint, limit: limit * (1.0 + 0.02 * i as f64) }).filter(allowed).collect();
                let Term::Saturation { limit, .. } = screen_best(self, &coarse, resid).0 else { unreachable!() };
                let at = Term::Saturation { joint, limit };
                let allowed = |t: &Term| *t == at || self.saturation_plausible(t, resid);
                let fine: Vec<Term> = (-10..=10).map(|i| Term::Saturation { joint, limit: limit * (1.0 + 0.002 * i as f64) }).filter(allowed).collect();
                screen_best(self, &fine, resid).0
            }
            Term::Delay { delay } => {
                let cands: Vec<Term> = (-8..=8).map(|i| Term::Delay { delay: (delay * (1.0 + 0.05 * i as f64)).max(1e-6) }).collect();
                screen_best(self, &cands, resid).0
            }
            Term::Coulomb { joint, w } => {
                // ±60 % in 10 % steps, within the range the data allow
                let range = self.dry_width[joint];
                let mut cands: Vec<Term> = (-5..=5).map(|i| Term::Coulomb { joint, w: range.clamp(w * 1.1f64.powi(i)) }).collect();
                cands.dedup();
                screen_best(self, &cands, resid).0
            }
            Term::Stribeck { joint, vs, w } => {
                let near = (-5..=5).map(|i| vs * 1.1f64.powi(i));
                let cands: Vec<Term> = near.filter(|&v| v == vs || crate::vocabulary::stribeck_resolvable(v, w)).map(|vs| Term::Stribeck { joint, vs, w }).collect();
                screen_best(self, &cands, resid).0
            }
            Term::LoadFriction { joint, w } => {
                let range = self.dry_width[joint];
                let mut cands: Vec<Term> = (-5..=5).map(|i| Term::LoadFriction { joint, w: range.clamp(w * 1.1f64.powi(i)) }).collect();
                cands.dedup();
                screen_best(self, &cands, resid).0
            }
            Term::Payload { .. } => self.payload_search(resid, &[]),
            ref other => other.clone(),
        }
    }

    /// The best member of a family against the current residual.
    pub(crate) fn best_of(&self, family: &Family, resid: &Column) -> Term {
        let mut cands = self.grid(family);
        if let Family::Saturation(j) = *family {
            // limits the logs contradict are not candidates; with none left, a limit that
            // clamps nothing
            cands.retain(|t| self.saturation_plausible(t, resid));
            if cands.is_empty() {
                return Term::Saturation { joint: j, limit: self.max_command(j).max(self.saturation_floor[j]) };
            }
        }
        let (best, _) = screen_best(self, &cands, resid);
        self.refine(&best, resid)
    }

    /// [`Context::best_of`]; the payload's centre of mass is searched jointly with the other
    /// selected terms `rest` (so they cannot absorb part of it first).
    pub(crate) fn best_of_with(&self, family: &Family, resid: &Column, rest: &[TermDesign]) -> Term {
        match family {
            Family::Payload => self.payload_search(resid, rest),
            _ => self.best_of(family, resid),
        }
    }
}
