//! `penumbra info SCENE`.

use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct InfoArgs {
    /// The pbrt-v3 scene file.
    pub scene: PathBuf,
}

pub fn run(args: InfoArgs) -> ExitCode {
    match penumbra_parser::parse_file(&args.scene) {
        Ok(out) => {
            for w in &out.warnings {
                eprint!("{w}");
            }
            println!("shapes: {}", out.scene.shapes.len());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprint!("{e}");
            ExitCode::FAILURE
        }
    }
}
