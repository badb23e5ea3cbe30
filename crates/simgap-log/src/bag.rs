//! rosbag2 bag folders: `metadata.yaml` and one or more `.mcap` files (split by size or
//! duration), read in the order the metadata lists them.

use std::path::{Path, PathBuf};

use crate::error::{read_error, Result};

/// The MCAP files of a bag folder, in recording order: the `relative_file_paths` of its
/// `metadata.yaml`, else every `.mcap` file of the folder in name order.
///
/// # Errors
/// [`Error::Read`](crate::Error::Read) naming the folder: a bag in another storage format
/// (sqlite3), a listed file that is missing, or no `.mcap` file at all.
pub fn bag_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let err = |m: String| read_error(dir, m);
    let metadata = dir.join("metadata.yaml");
    let mut files = Vec::new();
    if metadata.is_file() {
        let text = std::fs::read_to_string(&metadata).map_err(|e| err(format!("cannot read metadata.yaml: {e}")))?;
        if let Some(storage) = yaml_scalar(&text, "storage_identifier") {
            if storage != "mcap" {
                return Err(err(format!("the bag is stored as '{storage}'; simgap reads MCAP bags (convert with `ros2 bag convert` or `rosbags-convert --dst-storage mcap`)")));
            }
        }
        for name in yaml_list(&text, "relative_file_paths") {
            let path = dir.join(&name);
            if !path.is_file() {
                return Err(err(format!("metadata.yaml lists '{name}', which is not in the folder")));
            }
            files.push(path);
        }
    }
    if files.is_empty() {
        let entries = std::fs::read_dir(dir).map_err(|e| err(format!("cannot list the folder: {e}")))?;
        for entry in entries.flatten() {
            let p = entry.path();
            if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap")) && p.is_file() {
                files.push(p);
            }
        }
        files.sort();
    }
    if files.is_empty() {
        let db3 = std::fs::read_dir(dir).ok().into_iter().flatten().flatten().any(|e| e.path().extension().is_some_and(|x| x == "db3"));
        return Err(err(if db3 {
            "the bag is stored as sqlite3 (.db3); simgap reads MCAP bags (convert with `ros2 bag convert` or `rosbags-convert --dst-storage mcap`)".into()
        } else {
            "no .mcap file in the folder (a rosbag2 bag folder holds metadata.yaml and .mcap files)".into()
        }));
    }
    Ok(files)
}

/// The first `key: value` scalar anywhere in a YAML text (quotes removed).
fn yaml_scalar(text: &str, key: &str) -> Option<String> {
    text.lines().find_map(|l| {
        let rest = l.trim().strip_prefix(key)?.trim_start().strip_prefix(':')?;
        let v = rest.trim().trim_matches(|c| c == '"' || c == '\'');
        (!v.is_empty()).then(|| v.to_string())
    })
}

/// The items of the first block list `key:` followed by `- item` lines (or a flow list
/// `key: [a, b]`).
fn yaml_list(text: &str, key: &str) -> Vec<String> {
    let unquote = |s: &str| s.trim().trim_matches(|c| c == '"' || c == '\'').to_string();
    let mut lines = text.lines();
    while let Some(l) = lines.next() {
        let Some(rest) = l.trim().strip_prefix(key).and_then(|r| r.trim_start().strip_prefix(':')) else { continue };
        let rest = rest.trim();
        if let Some(flow) = rest.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
            return flow.split(',').map(unquote).filter(|s| !s.is_empty()).collect();
        }
        let mut out = Vec::new();
        for item in lines.by_ref() {
            match item.trim().strip_prefix("- ") {
                Some(v) => out.push(unquote(v)),
                None if item.trim().is_empty() => continue,
                None => break,
            }
        }
        return out;
    }
    Vec::new()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_yaml_lists_the_files_and_the_storage() {
        let text = "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  relative_file_paths:\n    - bag_0.mcap\n    - \"bag_1.mcap\"\n  duration:\n    nanoseconds: 3\n";
        assert_eq!(yaml_scalar(text, "storage_identifier").as_deref(), Some("mcap"));
        assert_eq!(yaml_list(text, "relative_file_paths"), vec!["bag_0.mcap".to_string(), "bag_1.mcap".to_string()]);
        assert_eq!(yaml_list("relative_file_paths: [a.mcap, 'b.mcap']", "relative_file_paths"), vec!["a.mcap".to_string(), "b.mcap".to_string()]);
    }
}
