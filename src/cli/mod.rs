//! One file per subcommand.

pub(crate) mod demo;
pub(crate) mod diagnose;
pub(crate) mod paper;
pub(crate) mod selfcheck;
pub(crate) mod simulate;
pub(crate) mod terms;

use simgap::core::{Model, UrdfOptions};

/// Loads the model named on the command line (`None` = the built-in paper arm), printing its
/// loading warnings to stderr.
pub(crate) fn load_model(urdf: Option<&std::path::Path>, tip: Option<&str>) -> anyhow::Result<Model> {
    let model = match urdf {
        Some(p) => Model::from_urdf_file_with(p, &UrdfOptions { tip: tip.map(str::to_string) })?,
        None => Model::paper_arm(),
    };
    for w in model.warnings() {
        eprintln!("warning: {w}");
    }
    Ok(model)
}
