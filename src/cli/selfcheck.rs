//! `simgap selfcheck`.

/// Arguments of `simgap selfcheck`.
#[derive(clap::Args)]
pub(crate) struct Args {}

pub(crate) fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`simgap selfcheck` is not built yet")
}
