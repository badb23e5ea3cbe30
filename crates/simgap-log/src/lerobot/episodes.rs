//! Which episodes a LeRobot dataset holds and where each one's frames are.
//!
//! - **v2.0 / v2.1**: `meta/episodes.jsonl`, one JSON object per line with `episode_index`
//!   and `length` (and `tasks`); the frames of episode `e` are the whole file `data_path`
//!   filled with `episode_chunk = e / chunks_size` and `episode_index = e`
//!   (`data/chunk-000/episode_000003.parquet`). Without `episodes.jsonl`, the episodes are
//!   `0 … total_episodes − 1`.
//! - **v3.0**: `meta/episodes/chunk-*/file-*.parquet`, one row per episode with
//!   `episode_index`, `data/chunk_index`, `data/file_index` and `dataset_from_index`,
//!   `dataset_to_index` (the episode's rows are those of global `index` in
//!   `[from, to)`); its frames are the rows of `data_path` filled with `chunk_index` and
//!   `file_index` whose `episode_index` is `e` (many episodes share one file).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::info::{data_file, Info, Version, MAX_EPISODES};
use super::table::{read_columns, RowGroups};

/// The largest `meta/episodes.jsonl` read [bytes] (about 10⁶ episodes).
const MAX_JSONL_BYTES: u64 = 256 << 20;
/// The most episode metadata files of a v3.0 dataset.
const MAX_EPISODE_FILES: usize = 100_000;

/// One episode: its index, the data file holding its frames and its length when known.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Episode {
    /// `episode_index`.
    pub(crate) index: i64,
    /// The Parquet file holding its frames.
    pub(crate) file: PathBuf,
    /// Frames, as the metadata says (`length`, or `dataset_to_index − dataset_from_index`).
    pub(crate) length: Option<i64>,
    /// Whether the file holds other episodes too (v3.0): its rows are picked by
    /// `episode_index`.
    pub(crate) shared_file: bool,
}

/// The episodes of a dataset, in index order.
///
/// # Errors
/// A message naming the metadata file and the problem: unreadable, malformed, an index out of
/// range or repeated.
pub(crate) fn list_episodes(folder: &Path, info: &Info) -> Result<Vec<Episode>, String> {
    let mut episodes = match info.version {
        Version::V2 => v2_episodes(folder, info)?,
        Version::V3 => v3_episodes(folder, info)?,
    };
    episodes.sort_by_key(|e| e.index);
    if let Some(w) = episodes.windows(2).find(|w| w[0].index == w[1].index) {
        return Err(format!("the episode metadata lists episode {} twice", w[0].index));
    }
    Ok(episodes)
}

/// An episode index or count from JSON or a Parquet number, checked.
fn index_of(v: f64, what: &str) -> Result<i64, String> {
    if v.fract() == 0.0 && (0.0..=MAX_EPISODES as f64).contains(&v) {
        Ok(v as i64)
    } else {
        Err(format!("{what} is {v}; expected an integer in [0, {MAX_EPISODES}]"))
    }
}

fn v2_episodes(folder: &Path, info: &Info) -> Result<Vec<Episode>, String> {
    let file_of = |e: i64| {
        data_file(folder, &info.data_path, &|k| match k {
            "episode_chunk" => Some(e / info.chunks_size),
            "episode_index" => Some(e),
            _ => None,
        })
    };
    let jsonl = folder.join("meta").join("episodes.jsonl");
    if !jsonl.is_file() {
        // no episode list: every index below total_episodes
        let total = info.total_episodes.ok_or("has neither meta/episodes.jsonl nor total_episodes in meta/info.json: cannot tell its episodes")?;
        return (0..total).map(|e| Ok(Episode { index: e, file: file_of(e)?, length: None, shared_file: false })).collect();
    }
    let len = std::fs::metadata(&jsonl).map_err(|e| format!("meta/episodes.jsonl: cannot read: {e}"))?.len();
    if len > MAX_JSONL_BYTES {
        return Err(format!("meta/episodes.jsonl is {len} bytes; expected at most {MAX_JSONL_BYTES}"));
    }
    let text = std::fs::read_to_string(&jsonl).map_err(|e| format!("meta/episodes.jsonl: cannot read: {e}"))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let at = |m: String| format!("meta/episodes.jsonl, line {}: {m}", i + 1);
        let v: Value = serde_json::from_str(line).map_err(|e| at(format!("not valid JSON: {e}")))?;
        let number = |key: &str| -> Result<Option<i64>, String> {
            match v.get(key) {
                None | Some(Value::Null) => Ok(None),
                Some(x) => x.as_f64().ok_or_else(|| at(format!("{key} is {x}; expected a number"))).and_then(|f| index_of(f, key).map_err(at)).map(Some),
            }
        };
        let index = number("episode_index")?.ok_or_else(|| at("no episode_index".into()))?;
        out.push(Episode { index, file: file_of(index)?, length: number("length")?, shared_file: false });
    }
    Ok(out)
}

/// The episode metadata files of a v3.0 dataset, `meta/episodes/*/*.parquet` in name order.
fn v3_episode_files(folder: &Path) -> Result<Vec<PathBuf>, String> {
    let dir = folder.join("meta").join("episodes");
    let chunks = std::fs::read_dir(&dir).map_err(|e| format!("cannot list meta/episodes/: {e} (a v3.0 dataset keeps its episode index there)"))?;
    let mut files = Vec::new();
    for chunk in chunks.flatten().map(|e| e.path()).filter(|p| p.is_dir()) {
        for f in std::fs::read_dir(&chunk).map_err(|e| format!("cannot list {}: {e}", chunk.display()))?.flatten() {
            let p = f.path();
            if p.extension().is_some_and(|x| x == "parquet") && p.is_file() {
                files.push(p);
            }
            if files.len() > MAX_EPISODE_FILES {
                return Err(format!("meta/episodes/ holds more than {MAX_EPISODE_FILES} files"));
            }
        }
    }
    files.sort();
    if files.is_empty() {
        return Err("meta/episodes/ holds no chunk-*/file-*.parquet".into());
    }
    Ok(files)
}

fn v3_episodes(folder: &Path, info: &Info) -> Result<Vec<Episode>, String> {
    let mut out = Vec::new();
    for file in v3_episode_files(folder)? {
        let name = file.strip_prefix(folder).unwrap_or(&file).display().to_string();
        let columns = ["episode_index", "data/chunk_index", "data/file_index", "dataset_from_index", "dataset_to_index", "length"];
        let t = read_columns(&file, &columns, &["dataset_from_index", "dataset_to_index", "length"], &RowGroups::All).map_err(|m| format!("{name}: {m}"))?;
        let col = |c: &str| -> Result<Option<&[f64]>, String> {
            match t.column(c) {
                None => Ok(None),
                Some(c2) if c2.width == 1 || t.rows == 0 => Ok(Some(&c2.values)),
                Some(_) => Err(format!("{name}: column '{c}' holds lists; expected one number per episode")),
            }
        };
        let (episode, chunk, file_index) = (col("episode_index")?.unwrap_or(&[]), col("data/chunk_index")?.unwrap_or(&[]), col("data/file_index")?.unwrap_or(&[]));
        let (from, to, length) = (col("dataset_from_index")?, col("dataset_to_index")?, col("length")?);
        for r in 0..t.rows {
            let at = |m: String| format!("{name}, row {r}: {m}");
            let index = index_of(episode[r], "episode_index").map_err(at)?;
            let (c, f) = (index_of(chunk[r], "data/chunk_index").map_err(at)?, index_of(file_index[r], "data/file_index").map_err(at)?);
            let length = match (from, to, length) {
                (Some(a), Some(b), _) => {
                    let (a, b) = (index_of(a[r], "dataset_from_index").map_err(at)?, index_of(b[r], "dataset_to_index").map_err(at)?);
                    if b < a {
                        return Err(at(format!("dataset_to_index {b} is below dataset_from_index {a}")));
                    }
                    Some(b - a)
                }
                (_, _, Some(l)) => Some(index_of(l[r], "length").map_err(at)?),
                _ => None,
            };
            let path = data_file(folder, &info.data_path, &|k| match k {
                "chunk_index" => Some(c),
                "file_index" => Some(f),
                _ => None,
            })?;
            out.push(Episode { index, file: path, length, shared_file: true });
        }
    }
    Ok(out)
}

/// Parses an episode selection: comma-separated indices and inclusive ranges (`0,3-5`), each
/// checked against the episodes `have` (in index order) before any range is expanded.
///
/// # Errors
/// A message for an empty or malformed selection, a reversed range, or an index the dataset
/// does not have (naming the indices it has).
pub(crate) fn parse_selection(sel: &str, have: &[i64]) -> Result<Vec<i64>, String> {
    let have_set: BTreeSet<i64> = have.iter().copied().collect();
    let span = || match (have.first(), have.last()) {
        (Some(a), Some(b)) if a == b => format!("it has episode {a} only"),
        (Some(a), Some(b)) if (b - a) as usize + 1 == have.len() => format!("it has episodes {a} to {b}"),
        (Some(_), Some(_)) => format!("it has {} episodes between {} and {}", have.len(), have[0], have[have.len() - 1]),
        _ => "it has no episode".into(),
    };
    if sel.trim().is_empty() {
        return Err(format!("empty episode selection after '#'; expected indices and ranges such as '#0,3-5' ({})", span()));
    }
    let number = |s: &str| -> Result<i64, String> { s.trim().parse::<i64>().map_err(|_| format!("episode selection '{sel}': '{}' is not an episode index", s.trim())) };
    let mut out = Vec::new();
    let mut seen = BTreeSet::new();
    for part in sel.split(',') {
        let (a, b) = match part.trim().split_once('-') {
            Some((a, b)) if !a.trim().is_empty() => (number(a)?, number(b)?),
            _ => {
                let n = number(part)?;
                (n, n)
            }
        };
        if b < a {
            return Err(format!("episode selection '{sel}': range {a}-{b} runs backwards"));
        }
        for e in [a, b] {
            if !have_set.contains(&e) {
                return Err(format!("the dataset has no episode {e} ({})", span()));
            }
        }
        // only indices the dataset has: a range never expands beyond its episodes
        for &e in have_set.range(a..=b) {
            if seen.insert(e) {
                out.push(e);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_selection_is_indices_and_inclusive_ranges_in_the_order_given() {
        let have: Vec<i64> = (0..10).collect();
        assert_eq!(parse_selection("0,3-5", &have).unwrap(), vec![0, 3, 4, 5]);
        assert_eq!(parse_selection("7, 2-3,3", &have).unwrap(), vec![7, 2, 3]);
        assert!(parse_selection("12", &have).unwrap_err().contains("no episode 12"));
        assert!(parse_selection("5-3", &have).unwrap_err().contains("backwards"));
        assert!(parse_selection("", &have).unwrap_err().contains("empty"));
        assert!(parse_selection("a", &have).unwrap_err().contains("not an episode index"));
        // a huge range is checked against the dataset before it is expanded
        assert!(parse_selection("0-9000000000000000000", &have).unwrap_err().contains("no episode"));
    }
}
