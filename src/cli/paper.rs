//! `simgap paper`.

/// Arguments of `simgap paper`.
#[derive(clap::Args)]
pub(crate) struct Args {}

pub(crate) fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`simgap paper` is not built yet")
}
