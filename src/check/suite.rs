//! `penumbra check --suite`: (placeholder until the suite runner lands).

use super::CheckArgs;
use std::path::Path;
use std::process::ExitCode;

pub fn run(_args: &CheckArgs, suite: &Path) -> ExitCode {
    eprintln!("penumbra check: --suite {}: not implemented yet", suite.display());
    ExitCode::from(super::EXIT_FILE)
}
