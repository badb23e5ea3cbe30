//! `meta/info.json`: the version, frame rate, file layout and features of a LeRobot dataset,
//! checked before anything is read by them.
//!
//! Every number is checked against a bound before it is used: a frame rate must be a positive
//! finite number of at most [`MAX_FPS`], counts non-negative integers of at most
//! [`MAX_EPISODES`], a feature's shape at most [`MAX_WIDTH`] numbers; the file layout is a
//! template with LeRobot's placeholders only, and the paths it gives stay inside the folder.

use std::path::{Component, Path, PathBuf};

use serde_json::Value;

/// The highest frame rate accepted [Hz] (LeRobot records at 30–200 Hz).
pub(crate) const MAX_FPS: f64 = 100_000.0;
/// The most episodes a dataset may declare (LeRobot's largest hold about 10⁵).
pub(crate) const MAX_EPISODES: i64 = 100_000_000;
/// The most numbers one state or action vector may hold.
pub(crate) const MAX_WIDTH: usize = 4096;
/// The largest `meta/info.json` read [bytes].
const MAX_INFO_BYTES: u64 = 16 << 20;

/// The two layouts simgap reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Version {
    /// v2.0 and v2.1: one Parquet file per episode, `meta/episodes.jsonl`.
    V2,
    /// v3.0: many episodes per file, `meta/episodes/chunk-*/file-*.parquet`.
    V3,
}

/// A vector feature (`observation.state`, `action`): its element type and per-element names.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Feature {
    /// `float32`, `float64`, ….
    pub(crate) dtype: String,
    /// One name per element (`shoulder_pan.pos`, …).
    pub(crate) names: Vec<String>,
}

/// What `meta/info.json` says.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Info {
    /// `codebase_version` as written (`v2.1`, `v3.0`).
    pub(crate) codebase_version: String,
    /// The layout.
    pub(crate) version: Version,
    /// Frames per second [Hz].
    pub(crate) fps: f64,
    /// `total_episodes`, when given.
    pub(crate) total_episodes: Option<i64>,
    /// `chunks_size`: episodes (v2) or files (v3) per chunk folder.
    pub(crate) chunks_size: i64,
    /// `data_path`, the template of a data file's path.
    pub(crate) data_path: String,
    /// `robot_type`, when given.
    pub(crate) robot_type: Option<String>,
    /// `observation.state`.
    pub(crate) state: Feature,
    /// `action`, when the dataset has one.
    pub(crate) action: Option<Feature>,
}

/// The default `data_path` of each layout.
fn default_data_path(version: Version) -> &'static str {
    match version {
        Version::V2 => "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
        Version::V3 => "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
    }
}

/// Reads and checks `meta/info.json` of the dataset `folder`.
///
/// # Errors
/// A message (the caller names the file): missing or unreadable, not JSON, a version simgap
/// does not read, a missing or out-of-range key, no `observation.state`, a feature whose type
/// is not a float or whose names do not match its shape.
pub(crate) fn read_info(folder: &Path) -> Result<Info, String> {
    let path = folder.join("meta").join("info.json");
    let len = std::fs::metadata(&path).map_err(|e| format!("cannot read meta/info.json: {e} (a LeRobot dataset folder holds meta/info.json and data/)"))?.len();
    if len > MAX_INFO_BYTES {
        return Err(format!("meta/info.json is {len} bytes; expected at most {MAX_INFO_BYTES}"));
    }
    let text = std::fs::read_to_string(&path).map_err(|e| format!("cannot read meta/info.json: {e}"))?;
    parse_info(&text).map_err(|m| format!("meta/info.json: {m}"))
}

/// Parses the text of `meta/info.json` (see [`read_info`]).
pub(crate) fn parse_info(text: &str) -> Result<Info, String> {
    let value: Value = serde_json::from_str(text).map_err(|e| format!("not valid JSON: {e}"))?;
    let obj = value.as_object().ok_or("expected a JSON object")?;
    // the version
    let codebase_version = obj.get("codebase_version").and_then(Value::as_str).ok_or("key 'codebase_version' is missing or not a string")?.to_string();
    let version = match codebase_version.trim_start_matches('v').split('.').next() {
        Some("2") => Version::V2,
        Some("3") => Version::V3,
        _ => return Err(format!("codebase_version '{codebase_version}': simgap reads LeRobotDataset v2.0, v2.1 and v3.0 (convert older ones with LeRobot's conversion scripts)")),
    };
    // the frame rate
    let fps = obj.get("fps").and_then(Value::as_f64).ok_or("key 'fps' is missing or not a number")?;
    if !(fps.is_finite() && fps > 0.0 && fps <= MAX_FPS) {
        return Err(format!("fps is {fps}; expected a frame rate in (0, {MAX_FPS}] Hz"));
    }
    // counts
    let count = |key: &str, lo: i64| -> Result<Option<i64>, String> {
        match obj.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => match v.as_i64() {
                Some(n) if (lo..=MAX_EPISODES).contains(&n) => Ok(Some(n)),
                _ => Err(format!("{key} is {v}; expected an integer in [{lo}, {MAX_EPISODES}]")),
            },
        }
    };
    let total_episodes = count("total_episodes", 0)?;
    let chunks_size = count("chunks_size", 1)?.unwrap_or(1000);
    count("total_frames", 0)?;
    count("total_chunks", 0)?;
    // the layout
    let data_path = match obj.get("data_path") {
        None | Some(Value::Null) => default_data_path(version).to_string(),
        Some(Value::String(s)) => s.clone(),
        Some(other) => return Err(format!("data_path is {other}; expected a path template")),
    };
    check_template(&data_path, version)?;
    let robot_type = obj.get("robot_type").and_then(Value::as_str).map(str::to_string);
    // the features read
    let features = obj.get("features").and_then(Value::as_object).ok_or("key 'features' is missing or not an object")?;
    let state = feature(features, "observation.state")?.ok_or("no feature 'observation.state': simgap reads the measured joint positions from it")?;
    let action = feature(features, "action")?;
    Ok(Info { codebase_version, version, fps, total_episodes, chunks_size, data_path, robot_type, state, action })
}

/// A vector feature of `features`: float elements, a shape of at most [`MAX_WIDTH`] numbers,
/// one name each (`names` a list, or LeRobot v2.0's `{"motors": [...]}`).
fn feature(features: &serde_json::Map<String, Value>, key: &str) -> Result<Option<Feature>, String> {
    let Some(f) = features.get(key) else { return Ok(None) };
    let f = f.as_object().ok_or_else(|| format!("feature '{key}' is not an object"))?;
    let dtype = f.get("dtype").and_then(Value::as_str).ok_or_else(|| format!("feature '{key}' has no dtype"))?.to_string();
    if !matches!(dtype.as_str(), "float32" | "float64" | "float16" | "float") {
        return Err(format!("feature '{key}' has dtype '{dtype}'; expected float32 or float64 (joint positions)"));
    }
    let shape = f.get("shape").and_then(Value::as_array).ok_or_else(|| format!("feature '{key}' has no shape"))?;
    let width = match shape.as_slice() {
        [n] => n.as_u64().filter(|n| (1..=MAX_WIDTH as u64).contains(n)).ok_or_else(|| format!("feature '{key}' has shape [{n}]; expected [N] with 1 ≤ N ≤ {MAX_WIDTH}"))? as usize,
        other => return Err(format!("feature '{key}' has shape {other:?}; expected a vector [N]")),
    };
    let names = match f.get("names") {
        Some(Value::Array(a)) => a.clone(),
        // LeRobot v2.0: {"motors": [...]} (one list under any one key)
        Some(Value::Object(o)) if o.len() == 1 => o.values().next().and_then(Value::as_array).cloned().ok_or_else(|| format!("feature '{key}': names is not a list"))?,
        Some(other) => return Err(format!("feature '{key}': names is {other}; expected a list of {width} names")),
        None => return Err(format!("feature '{key}' has no names; simgap maps its entries to joints by name")),
    };
    if names.len() != width {
        return Err(format!("feature '{key}' has shape [{width}] but {} names", names.len()));
    }
    let names = names.iter().map(|n| n.as_str().map(str::to_string).ok_or_else(|| format!("feature '{key}': name {n} is not a string"))).collect::<Result<Vec<_>, _>>()?;
    Ok(Some(Feature { dtype, names }))
}

/// The placeholders a `data_path` of each layout may hold.
fn placeholders(version: Version) -> &'static [&'static str] {
    match version {
        Version::V2 => &["episode_chunk", "episode_index"],
        Version::V3 => &["chunk_index", "file_index"],
    }
}

/// Checks a path template: LeRobot's placeholders only, a relative path inside the folder.
fn check_template(template: &str, version: Version) -> Result<(), String> {
    let probe = format_path(template, &|_| Some(0)).map_err(|m| format!("data_path '{template}': {m}"))?;
    let bad = |m: &str| Err(format!("data_path '{template}': {m}"));
    if Path::new(&probe).components().any(|c| !matches!(c, Component::Normal(_))) {
        return bad("expected a relative path inside the dataset folder");
    }
    let allowed = placeholders(version);
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        let close = rest[open..].find('}').map(|c| open + c).ok_or("unclosed '{'")?;
        let name = rest[open + 1..close].split(':').next().unwrap_or("");
        if !allowed.contains(&name) {
            return bad(&format!("placeholder '{name}'; expected {}", allowed.join(" and ")));
        }
        rest = &rest[close + 1..];
    }
    Ok(())
}

/// Fills a path template's `{name}` and `{name:0Nd}` placeholders with `value(name)`.
///
/// # Errors
/// A message for an unknown placeholder, a malformed one or an unclosed brace.
pub(crate) fn format_path(template: &str, value: &dyn Fn(&str) -> Option<i64>) -> Result<String, String> {
    let mut out = String::new();
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let close = rest[open..].find('}').map(|c| open + c).ok_or("unclosed '{'")?;
        let spec = &rest[open + 1..close];
        let (name, format) = spec.split_once(':').unwrap_or((spec, ""));
        let v = value(name).ok_or_else(|| format!("unknown placeholder '{name}'"))?;
        let digits = match format {
            "" | "d" => 0,
            f => f
                .strip_prefix('0')
                .and_then(|f| f.strip_suffix('d'))
                .and_then(|w| w.parse::<usize>().ok())
                .filter(|w| *w <= 20)
                .ok_or_else(|| format!("placeholder format '{f}'; expected 0Nd"))?,
        };
        out.push_str(&format!("{v:0digits$}"));
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// The path of a data file: `folder` joined with the template filled with `value`.
pub(crate) fn data_file(folder: &Path, template: &str, value: &dyn Fn(&str) -> Option<i64>) -> Result<PathBuf, String> {
    Ok(folder.join(format_path(template, value)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    const V3: &str = r#"{"codebase_version": "v3.0", "fps": 50, "total_episodes": 2, "chunks_size": 1000,
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "features": {"observation.state": {"dtype": "float32", "shape": [2], "names": ["a.pos", "gripper.pos"]},
                     "action": {"dtype": "float32", "shape": [2], "names": ["a.pos", "gripper.pos"]}}}"#;

    #[test]
    fn a_v3_info_reads_and_fills_its_path_template() {
        let info = parse_info(V3).unwrap();
        assert_eq!(info.version, Version::V3);
        assert_eq!(info.fps, 50.0);
        assert_eq!(info.state.names, vec!["a.pos", "gripper.pos"]);
        let v = |k: &str| match k {
            "chunk_index" => Some(0),
            "file_index" => Some(7),
            _ => None,
        };
        assert_eq!(format_path(&info.data_path, &v).unwrap(), "data/chunk-000/file-007.parquet");
    }

    #[test]
    fn hostile_values_are_refused_with_the_key() {
        for (from, to, what) in [
            ("\"fps\": 50", "\"fps\": 0", "fps"),
            ("\"fps\": 50", "\"fps\": -3", "fps"),
            ("\"fps\": 50", "\"fps\": 1e300", "fps"),
            ("\"total_episodes\": 2", "\"total_episodes\": -1", "total_episodes"),
            ("\"chunks_size\": 1000", "\"chunks_size\": 0", "chunks_size"),
            ("\"observation.state\": {\"dtype\": \"float32\", \"shape\": [2]", "\"observation.state\": {\"dtype\": \"float32\", \"shape\": [4000000000]", "shape"),
            ("\"observation.state\": {\"dtype\": \"float32\"", "\"observation.state\": {\"dtype\": \"string\"", "dtype"),
            ("file-{file_index:03d}", "../../etc/{file_index}", "data_path"),
            ("file-{file_index:03d}", "file-{evil}", "placeholder"),
        ] {
            let text = V3.replace(from, to);
            assert_ne!(text, V3, "{from}");
            let e = parse_info(&text).unwrap_err();
            assert!(e.contains(what), "{e}");
        }
    }
}
