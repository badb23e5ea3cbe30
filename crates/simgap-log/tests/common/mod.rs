//! Shared by simgap-log's integration tests: [`tmp`], a test's own file path in a folder that is
//! removed with what the test wrote when the test ends, also when it fails.

use std::ops::Deref;
use std::path::{Path, PathBuf};

/// A file path `name` in a fresh temporary folder (`tempfile`), which is removed when this is
/// dropped. Derefs to the path.
#[allow(dead_code)] // not every test file that includes this module makes one
pub(crate) struct Scratch {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

/// A temporary folder of a test's own, `<temp>/simgap-log-<random>/`, removed when dropped: for
/// files that must sit side by side (a log and its sidecar).
#[allow(dead_code)] // not every test file that includes this module makes one
pub(crate) fn folder() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("simgap-log-").tempdir().expect("a temporary folder")
}

/// A path for a file `name` in a temporary folder of its own, `<temp>/simgap-log-<random>/`.
#[allow(dead_code)] // not every test file that includes this module makes one
pub(crate) fn tmp(name: &str) -> Scratch {
    let dir = folder();
    let path = dir.path().join(name);
    Scratch { _dir: dir, path }
}
