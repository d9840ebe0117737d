//! `penumbra diff A B`.

use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct DiffArgs {
    pub a: PathBuf,
    pub b: PathBuf,
}

pub fn run(args: DiffArgs) -> ExitCode {
    let _ = (args.a, args.b);
    eprintln!("penumbra diff: not implemented yet");
    ExitCode::from(4)
}
