//! One file per subcommand.

pub(crate) mod demo;
pub(crate) mod diagnose;
pub(crate) mod paper;
pub(crate) mod predict;
pub(crate) mod selfcheck;
pub(crate) mod simulate;
pub(crate) mod terms;

use std::path::PathBuf;

use simgap::core::{Formulation, Model, UrdfOptions};

/// The model options shared by subcommands that default to the built-in paper arm.
#[derive(clap::Args)]
pub(crate) struct ModelArgs {
    /// URDF of the robot (default: the built-in paper arm).
    #[arg(long)]
    pub(crate) urdf: Option<PathBuf>,
    /// Tip link of the chain when the tree branches.
    #[arg(long)]
    pub(crate) tip: Option<String>,
    /// Formulation of C: euler-lagrange or simplified.
    #[arg(long, default_value = "euler-lagrange")]
    pub(crate) formulation: Formulation,
}

impl ModelArgs {
    /// Loads the model these options name (see [`load_model`]).
    pub(crate) fn load(&self) -> anyhow::Result<Model> {
        load_model(self.urdf.as_deref(), self.tip.as_deref())
    }
}

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
