//! The switches of a diagnosis: the one table of yes/no options that every front end reads.
//!
//! The CLI's flags (`simgap diagnose --directional-friction`), Python's keywords
//! (`simgap.diagnose(..., directional_friction=True)`), the type stub and the fleet's options
//! are all built from, or checked against, [`SWITCHES`]: a new switch is one entry here.

use simgap_sim::EffectKind;

use crate::options::DiagnoseOptions;

/// A yes/no option of [`crate::diagnose`], as every front end spells it.
#[derive(Clone, Copy, Debug)]
pub struct Switch {
    /// Its name: the Python keyword and the fleet's option key (`directional_friction`).
    pub name: &'static str,
    /// The CLI flag without its dashes: `name` with `-` for `_` (`directional-friction`).
    pub flag: &'static str,
    /// What turning it on does (the CLI's help and the Python docs).
    pub help: &'static str,
    /// Its value when it is not given.
    pub default: bool,
    /// Sets it in a diagnosis' options.
    pub set: fn(&mut DiagnoseOptions, bool),
    /// Reads it from a diagnosis' options.
    pub get: fn(&DiagnoseOptions) -> bool,
}

/// Every switch of a diagnosis, in the order front ends list them.
pub const SWITCHES: &[Switch] = &[
    Switch {
        name: EffectKind::DirectionalFriction.as_str(),
        flag: "directional-friction",
        help: "Also try friction that differs with the direction of motion (levels and slopes per direction) in place of the \
               Coulomb and viscous friction of turning joints (worn gearboxes); on linear axes (ball screws) it is tried without it",
        default: false,
        set: |o, v| o.directional_friction = v,
        get: |o| o.directional_friction,
    },
    Switch {
        name: EffectKind::LoadStribeckFriction.as_str(),
        flag: "load-stribeck-friction",
        help: "On servo logs, also try the load friction rising at rest (a breakaway level above the moving one, both growing \
               with the drive's torque): for a servo that stops short of its goal and stays there while its duty rises",
        default: false,
        set: |o, v| o.load_stribeck_friction = v,
        get: |o| o.load_stribeck_friction,
    },
    Switch {
        name: "link_side_torque",
        flag: "link-side-torque",
        help: "The logged effort is measured on the link side of the gearbox (joint-torque sensors, as on torque-sensing \
               arms): no rotor inertia or back-EMF is tried, since both act before such a sensor",
        default: false,
        set: |o, v| o.prepare.link_side_torque = v,
        get: |o| o.prepare.link_side_torque,
    },
];

/// The switch named `name` (its Python keyword), if there is one.
pub fn switch(name: &str) -> Option<&'static Switch> {
    SWITCHES.iter().find(|s| s.name == name)
}

/// The options of a diagnosis with the switches `on` set (by name) and every other switch at
/// its default.
///
/// # Errors
/// The name of a switch that does not exist, with the names that do.
pub fn options_with(on: &[(&str, bool)]) -> Result<DiagnoseOptions, String> {
    // every switch starts at its default (the table's defaults are the options', a test checks)
    let mut options = DiagnoseOptions::default();
    for (name, value) in on {
        let s = switch(name).ok_or_else(|| format!("no diagnosis option '{name}'; expected one of {:?}", SWITCHES.iter().map(|s| s.name).collect::<Vec<_>>()))?;
        (s.set)(&mut options, *value);
    }
    Ok(options)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_switch_sets_what_it_reads_and_its_flag_is_its_name() {
        for s in SWITCHES {
            assert_eq!(s.flag, s.name.replace('_', "-"), "{}", s.name);
            for v in [true, false] {
                let mut o = DiagnoseOptions::default();
                (s.set)(&mut o, v);
                assert_eq!((s.get)(&o), v, "{}", s.name);
                // setting one switch leaves every other at its value
                for other in SWITCHES.iter().filter(|t| t.name != s.name) {
                    assert_eq!((other.get)(&o), (other.get)(&DiagnoseOptions::default()), "{} moved {}", s.name, other.name);
                }
            }
            assert_eq!((s.get)(&DiagnoseOptions::default()), s.default, "{}: the table's default is the options' default", s.name);
        }
    }

    #[test]
    fn an_unknown_switch_is_refused_by_name() {
        let e = options_with(&[("directional_frictoin", true)]).unwrap_err();
        assert!(e.contains("directional_frictoin") && e.contains(EffectKind::DirectionalFriction.as_str()), "{e}");
        assert!(options_with(&[("link_side_torque", true)]).unwrap().prepare.link_side_torque);
    }
}
