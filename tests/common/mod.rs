//! Shared by the CLI integration tests: which `simgap` binary to run.
//!
//! `$SIMGAP_BIN` when set; else `target/release/simgap` when it is newer than every source file
//! (as after `make test`'s release build; the diagnosis tests are far slower in a debug build);
//! else the debug binary cargo built for the test. And [`Scratch`], a test's own folder under
//! the system's temporary one, removed when the test ends.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The `simgap` binary the tests run.
pub(crate) fn bin() -> PathBuf {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(b) = std::env::var_os("SIMGAP_BIN").filter(|b| !b.is_empty()) {
            return PathBuf::from(b);
        }
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let release = root.join("target/release/simgap");
        let built = std::fs::metadata(&release).and_then(|m| m.modified()).ok();
        let newest_source = [root.join("src"), root.join("crates"), root.join("Cargo.toml"), root.join("Cargo.lock")].iter().filter_map(|p| newest(p)).max();
        match (built, newest_source) {
            (Some(b), Some(s)) if b > s => release,
            _ => PathBuf::from(env!("CARGO_BIN_EXE_simgap")),
        }
    })
    .clone()
}

/// Newest modification time of a file or of the `.rs`, `.toml` and `.urdf` files under a folder.
fn newest(path: &Path) -> Option<std::time::SystemTime> {
    let meta = std::fs::metadata(path).ok()?;
    if meta.is_file() {
        return meta.modified().ok();
    }
    std::fs::read_dir(path)
        .ok()?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let p = e.path();
            let name = e.file_name().to_string_lossy().to_string();
            if p.is_dir() {
                if name == "target" || name.starts_with('.') {
                    None
                } else {
                    newest(&p)
                }
            } else if name.ends_with(".rs") || name.ends_with(".toml") || name.ends_with(".urdf") {
                e.metadata().ok()?.modified().ok()
            } else {
                None
            }
        })
        .max()
}

/// A test's scratch folder, `<temp>/simgap-<test>-<name>-<random>` (`tempfile`), empty when
/// made and removed (with what the test wrote) when dropped, also when the test fails.
#[allow(dead_code)] // not every test crate that includes this module makes one
pub(crate) struct Scratch(tempfile::TempDir);

#[allow(dead_code)]
impl Scratch {
    /// An empty folder for `test`'s `name`.
    pub(crate) fn new(test: &str, name: &str) -> Scratch {
        Scratch(tempfile::Builder::new().prefix(&format!("simgap-{test}-{name}-")).tempdir().expect("a temporary folder"))
    }

    /// The folder, kept after the test (for one shared by tests through a `static`, which is
    /// never dropped).
    pub(crate) fn keep(self) -> PathBuf {
        self.0.keep()
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        self.0.path()
    }
}
