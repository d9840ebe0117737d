//! Rewrites the documentation generated from the registry: the integrator table in README.md
//! and the parameter table in each docs/integrators/NAME.md (between their marker comments):
//! `cargo run -p penumbra-integrators --example generate-docs`. `tests/cli_params.rs` checks
//! that they are up to date.

use penumbra_integrators::{doc_page, with_generated_params, with_generated_table, REGISTRY};

fn rewrite(path: &str, generate: impl Fn(&str) -> Result<String, String>) -> Result<(), String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{path}: {e}"))?;
    let new = generate(&text)?;
    if new != text {
        std::fs::write(path, new).map_err(|e| format!("{path}: {e}"))?;
        eprintln!("{path}: rewritten");
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let mut result = rewrite(&format!("{root}/README.md"), with_generated_table);
    for e in REGISTRY {
        result =
            result.and_then(|()| rewrite(&format!("{root}/{}", doc_page(e.name)), |t| with_generated_params(e, t)));
    }
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
