//! The name of a CSV log still being written (`run.partial.csv`): the sink writes under it
//! and renames when finished, and the sidecar lookup sees through it. A leaf of the crate.

use std::path::{Path, PathBuf};

/// What a CSV log's name holds before its extension while it is being written.
pub const PARTIAL: &str = ".partial";

/// The name a CSV log has while it is being written: `run.csv` → `run.partial.csv`,
/// `run.csv.gz` → `run.partial.csv.gz` (other names get `.partial` before their extension).
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    let lower = name.to_lowercase();
    let ext = [".csv.gz", ".csv"].iter().find(|e| lower.ends_with(*e)).map_or(name.rfind('.').map_or(0, |i| name.len() - i), |e| e.len());
    let (stem, ext) = name.split_at(name.len() - ext);
    path.with_file_name(format!("{stem}{PARTIAL}{ext}"))
}

/// Whether `path` names a CSV log whose writer had not finished (`*.partial.csv[.gz]`).
pub fn is_partial(path: &Path) -> bool {
    let name = path.file_name().map(|s| s.to_string_lossy().to_lowercase()).unwrap_or_default();
    name.ends_with(".partial.csv") || name.ends_with(".partial.csv.gz")
}
