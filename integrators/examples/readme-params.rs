//! Rewrites the README's integrator parameter list (between its marker comments) from the
//! registry: `cargo run -p penumbra-integrators --example readme-params [README.md]`.
//! `tests/cli_params.rs` checks that the README is up to date.

fn main() -> std::process::ExitCode {
    let path = std::env::args().nth(1).unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md").into());
    let result = std::fs::read_to_string(&path)
        .map_err(|e| format!("{path}: {e}"))
        .and_then(|text| penumbra_integrators::with_generated_params(&text))
        .and_then(|text| std::fs::write(&path, text).map_err(|e| format!("{path}: {e}")));
    match result {
        Ok(()) => {
            eprintln!("{path}: integrator parameters rewritten");
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
