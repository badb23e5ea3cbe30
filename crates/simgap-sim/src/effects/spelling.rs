//! The command-line spelling of an effect's parameters, `param=v1,v2,...;param=...`, as each
//! effect's file reads it ([`Effect::parse`](super::Effect::parse)).

use super::invalid;
use crate::error::Result;

/// The parameters of one spelled effect, read as numbers, with what a per-joint value and a
/// left-out width resolve to.
pub(super) struct Spelling<'a> {
    /// The effect's name as spelled (for the messages).
    name: &'a str,
    /// Each parameter given, in order, with its numbers.
    params: Vec<(String, Vec<f64>)>,
    /// Joints of the model.
    dof: usize,
    /// Widths of a dry friction whose spelling leaves `w` out, one per joint (or a single
    /// value, refused as not a width where one is needed).
    default_w: &'a [f64],
}

impl<'a> Spelling<'a> {
    /// Reads `rest`, the part after `name:`, into numbers (`inf` and `+inf` for `+∞`).
    ///
    /// # Errors
    /// [`Error::Invalid`](crate::Error::Invalid) for a part that is not `param=values` or a
    /// value that is not a number.
    pub(super) fn read(name: &'a str, rest: &str, dof: usize, default_w: &'a [f64]) -> Result<Spelling<'a>> {
        let mut params: Vec<(String, Vec<f64>)> = Vec::new();
        for part in rest.split(';').map(str::trim).filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').ok_or_else(|| invalid(name, format!("'{part}' is not param=values")))?;
            let vals = v
                .split(',')
                .map(|x| {
                    let x = x.trim();
                    match x {
                        "inf" | "+inf" => Ok(f64::INFINITY),
                        _ => x.parse::<f64>().map_err(|_| invalid(name, format!("'{x}' in parameter '{}' is not a number", k.trim()))),
                    }
                })
                .collect::<Result<Vec<f64>>>()?;
            params.push((k.trim().to_string(), vals));
        }
        Ok(Spelling { name, params, dof, default_w })
    }

    /// Refuses a parameter not in `known`.
    ///
    /// # Errors
    /// [`Error::Invalid`](crate::Error::Invalid) naming the first unknown parameter and the
    /// known ones.
    pub(super) fn only(&self, known: &[&str]) -> Result<()> {
        if let Some((k, _)) = self.params.iter().find(|(k, _)| !known.contains(&k.as_str())) {
            return Err(invalid(self.name, format!("unknown parameter '{k}'; expected {}", if known.is_empty() { "none".into() } else { known.join(", ") })));
        }
        Ok(())
    }

    /// The numbers of parameter `k` as given.
    ///
    /// # Errors
    /// [`Error::Invalid`](crate::Error::Invalid) when it is missing.
    pub(super) fn get(&self, k: &str) -> Result<Vec<f64>> {
        self.params.iter().find(|(p, _)| p == k).map(|(_, v)| v.clone()).ok_or_else(|| invalid(self.name, format!("missing parameter '{k}'")))
    }

    /// A per-joint parameter: `dof` numbers, or one for every joint.
    ///
    /// # Errors
    /// As [`Spelling::get`]; also for another count.
    pub(super) fn per_joint(&self, k: &str) -> Result<Vec<f64>> {
        let v = self.get(k)?;
        match v.len() {
            1 => Ok(vec![v[0]; self.dof]),
            n if n == self.dof => Ok(v),
            n => Err(invalid(self.name, format!("parameter '{k}' has {n} values; expected {} (one per joint) or 1", self.dof))),
        }
    }

    /// A dry friction's width [rad/s or m/s]: given (as [`Spelling::per_joint`]), or the
    /// caller's default on every joint.
    ///
    /// # Errors
    /// As [`Spelling::per_joint`]; also for a default that is not a finite number `>= 0` or
    /// not one per joint.
    pub(super) fn width(&self, k: &str) -> Result<Vec<f64>> {
        if self.params.iter().any(|(p, _)| p == k) {
            return self.per_joint(k);
        }
        if let Some(w) = self.default_w.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
            return Err(invalid(self.name, format!("default width w = {w}; expected a finite number >= 0 [rad/s or m/s] (0: the exact sign)")));
        }
        if self.default_w.len() != self.dof {
            return Err(invalid(self.name, format!("{} default widths for {} joints", self.default_w.len(), self.dof)));
        }
        Ok(self.default_w.to_vec())
    }

    /// A parameter of one number.
    ///
    /// # Errors
    /// As [`Spelling::get`]; also for another count.
    pub(super) fn scalar(&self, k: &str) -> Result<f64> {
        let v = self.get(k)?;
        if v.len() != 1 {
            return Err(invalid(self.name, format!("parameter '{k}' takes one number, got {}", v.len())));
        }
        Ok(v[0])
    }

    /// A parameter of three numbers (a vector in a link frame).
    ///
    /// # Errors
    /// As [`Spelling::get`]; also for another count.
    pub(super) fn triple(&self, k: &str) -> Result<[f64; 3]> {
        let v = self.get(k)?;
        <[f64; 3]>::try_from(v.as_slice()).map_err(|_| invalid(self.name, format!("parameter '{k}' takes 3 numbers, got {}", v.len())))
    }

    /// The effect's name as spelled (for a file's own messages).
    pub(super) fn name(&self) -> &str {
        self.name
    }
}
