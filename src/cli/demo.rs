//! `simgap demo`.

/// Arguments of `simgap demo`.
#[derive(clap::Args)]
pub(crate) struct Args {}

pub(crate) fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`simgap demo` is not built yet")
}
