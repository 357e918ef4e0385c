//! `lightpath completions SHELL` and `lightpath man`: generated from the clap
//! definition, printed to stdout.

use anyhow::Result;
use std::io::Write;

#[derive(clap::Args)]
pub struct CompletionsArgs {
    /// The shell to complete for.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

/// Prints the completion script for `args.shell`, e.g.
/// `lightpath completions bash > ~/.local/share/bash-completion/completions/lightpath`.
pub fn completions(args: CompletionsArgs, mut cmd: clap::Command) -> Result<()> {
    let mut out = std::io::stdout().lock();
    clap_complete::generate(args.shell, &mut cmd, "lightpath", &mut out);
    out.flush()?;
    Ok(())
}

/// Prints the man page (roff), e.g. `lightpath man > lightpath.1`.
pub fn man(cmd: clap::Command) -> Result<()> {
    let mut buffer = Vec::new();
    clap_mangen::Man::new(cmd).render(&mut buffer)?;
    let mut out = std::io::stdout().lock();
    out.write_all(&buffer)?;
    out.flush()?;
    Ok(())
}
