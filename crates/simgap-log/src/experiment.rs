//! Experiment files: the `simgap.experiment` keys in a JSON object (or `key = value` lines),
//! and the sidecar file `NAME.experiment.json` that gives a log without a metadata record its
//! experiment.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use simgap_sim::{experiment_from_map, experiment_to_map, Experiment};

use crate::error::{read_error as log_error, write_error, Result};

/// The sidecar experiment file of a log: `run.mcap`, `run.csv`, `run.csv.gz` and the bag
/// folder `run/` → `run.experiment.json` beside it.
pub fn sidecar_path(log_path: &Path) -> PathBuf {
    sidecar_candidates(log_path).swap_remove(0)
}

/// Sidecar files looked for, in order: `<stem>.experiment.json`, `<stem>.experiment` beside
/// the log, for a CSV log still being written (`<name>.partial.csv[.gz]`, see
/// [`crate::CsvSink`]) also those of `<name>`, and for a bag folder `experiment.json` inside it.
pub(crate) fn sidecar_candidates(log_path: &Path) -> Vec<PathBuf> {
    let trimmed: PathBuf = log_path.components().collect();
    let name = trimmed.file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    let lower = name.to_lowercase();
    let stem_len = [".csv.gz", ".csv", ".mcap"].iter().find(|ext| lower.ends_with(*ext)).map_or(name.len(), |ext| name.len() - ext.len());
    let stem = &name[..stem_len];
    let mut out = vec![trimmed.with_file_name(format!("{stem}.experiment.json")), trimmed.with_file_name(format!("{stem}.experiment"))];
    if stem.to_lowercase().ends_with(crate::partial::PARTIAL) {
        let whole = &stem[..stem.len() - crate::partial::PARTIAL.len()];
        out.extend([trimmed.with_file_name(format!("{whole}.experiment.json")), trimmed.with_file_name(format!("{whole}.experiment"))]);
    }
    if log_path.is_dir() {
        out.push(log_path.join("experiment.json"));
    }
    out
}

/// The experiment of the first sidecar file that exists, if any.
///
/// # Errors
/// [`Error::Read`](crate::Error::Read) when that file is malformed.
pub fn read_sidecar(log_path: &Path) -> Result<Option<Experiment>> {
    for sidecar in sidecar_candidates(log_path) {
        if sidecar.is_file() {
            return read_experiment_file(&sidecar).map(Some);
        }
    }
    Ok(None)
}

/// Reads an experiment file: a JSON object or `key = value` lines (`#` comments), with the keys
/// of the `simgap.experiment` metadata (`controller`, `joints`, `kp`, `kv`, `sample_period`;
/// others kept in `extra`). In JSON, lists may be arrays or comma-separated strings.
///
/// # Errors
/// [`Error::Log`] naming the file: unreadable, not JSON / `key = value`, a missing or malformed
/// key.
pub fn read_experiment_file(path: &Path) -> Result<Experiment> {
    let err = |m: String| log_error(path, m);
    let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
    let mut map = BTreeMap::new();
    if text.trim_start().starts_with('{') {
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| err(format!("not valid JSON: {e}")))?;
        let obj = value.as_object().ok_or_else(|| err("expected a JSON object".into()))?;
        for (k, v) in obj {
            let s = match v {
                serde_json::Value::String(s) => s.clone(),
                serde_json::Value::Number(n) => n.to_string(),
                serde_json::Value::Array(items) => items
                    .iter()
                    .map(|x| match x {
                        serde_json::Value::String(s) => Ok(s.clone()),
                        serde_json::Value::Number(n) => Ok(n.to_string()),
                        other => Err(err(format!("key '{k}': unexpected list item {other}"))),
                    })
                    .collect::<Result<Vec<_>>>()?
                    .join(","),
                other => return Err(err(format!("key '{k}': expected a string, number or list, got {other}"))),
            };
            map.insert(k.clone(), s);
        }
    } else {
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (k, v) = line.split_once('=').ok_or_else(|| err(format!("line {}: expected 'key = value', got '{line}'", i + 1)))?;
            map.insert(k.trim().to_string(), v.trim().to_string());
        }
    }
    experiment_from_map(&map).map_err(|m| err(format!("malformed experiment: {m}")))
}

/// Writes an experiment file as a JSON object of strings (the `simgap.experiment` map).
///
/// # Errors
/// [`Error::Write`] when the file cannot be written.
pub fn write_experiment_file(experiment: &Experiment, path: &Path) -> Result<()> {
    let map = experiment_to_map(experiment);
    let text = serde_json::to_string_pretty(&map).map_err(|e| write_error(path, e))?;
    std::fs::write(path, text + "\n").map_err(|e| write_error(path, e))
}
