//! `simgap diagnose`.

/// Arguments of `simgap diagnose`.
#[derive(clap::Args)]
pub(crate) struct Args {}

pub(crate) fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`simgap diagnose` is not built yet")
}
