//! `simgap simulate`.

/// Arguments of `simgap simulate`.
#[derive(clap::Args)]
pub(crate) struct Args {}

pub(crate) fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`simgap simulate` is not built yet")
}
