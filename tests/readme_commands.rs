//! The README's commands run as written on a fresh clone (issue 41 item 4), and docs/commands.md
//! lists every option of every subcommand (its synopsis is generated from the `--help` texts).

mod common;
use common::cli_dir as dir;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The lines of every fenced ```sh block of a Markdown text, with their line numbers.
fn fenced_commands(markdown: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut inside = false;
    for (i, line) in markdown.lines().enumerate() {
        let t = line.trim();
        if t.starts_with("```") {
            inside = !inside && t == "```sh";
            continue;
        }
        if inside && !t.is_empty() && !t.starts_with('#') {
            out.push((i + 1, t.to_string()));
        }
    }
    out
}

/// Every command of the README's ```sh blocks, in order, in one scratch directory that holds only
/// what a fresh clone holds (`scenes/`), with the built `penumbra` first on PATH: each exits 0.
/// The `cargo` lines (install, the test command itself) are the only ones not run; they are
/// checked: the install command, or commands .ci/run runs (each part of an `a && b`).
#[test]
fn every_readme_command_runs_as_written() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let commands = fenced_commands(&readme);
    assert!(commands.len() >= 15, "found only {} README commands", commands.len());
    let d = dir("readme-walk");
    std::os::unix::fs::symlink(root().join("scenes"), d.join("scenes")).unwrap();
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_penumbra"));
    let path = format!("{}:{}", bin.parent().unwrap().display(), std::env::var("PATH").unwrap_or_default());
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    let mut ran = 0;
    for (line, cmd) in &commands {
        assert!(!cmd.contains('…') && !cmd.contains("=R"), "README.md:{line}: a placeholder in {cmd:?}");
        if cmd.starts_with("cargo ") {
            let c = cmd.split('#').next().unwrap().trim();
            let in_ci = |part: &str| ci.lines().any(|l| l.trim() == part.trim());
            assert!(
                c.starts_with("cargo install --path .") || c.split("&&").all(in_ci),
                "README.md:{line}: {c:?} is neither the install command nor a command .ci/run runs"
            );
            continue;
        }
        let o = Command::new("sh").arg("-c").arg(cmd).current_dir(&d).env("PATH", &path).output().unwrap();
        assert!(
            o.status.success(),
            "README.md:{line}: {cmd}\nexit {:?}\n{}{}",
            o.status.code(),
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        ran += 1;
    }
    assert!(ran >= 15, "ran {ran} commands");
    std::fs::remove_dir_all(&d).ok();
}

const SUBCOMMANDS: [&str; 9] = ["render", "info", "diff", "check", "convert", "sweep", "stability", "relight", "merge"];
const BEGIN: &str = "<!-- synopsis:begin (generated from `penumbra SUBCOMMAND --help` by tests/readme_commands.rs; PENUMBRA_BLESS=1 rewrites it) -->";
const END: &str = "<!-- synopsis:end -->";

/// `penumbra SUB --help`'s usage line and option list (what comes before its longer notes).
fn synopsis(bin: &Path, sub: &str) -> String {
    let o = Command::new(bin).args([sub, "--help"]).output().unwrap();
    assert!(o.status.success(), "{sub} --help");
    let help = String::from_utf8(o.stdout).unwrap();
    let mut out = String::new();
    let mut in_options = false;
    for line in help.lines() {
        if line.starts_with("Usage:") {
            out += line;
            out += "\n";
        } else if line == "Options:" {
            in_options = true;
            out += "\n";
        } else if in_options && line.is_empty() {
            break;
        } else if in_options {
            out += line;
            out += "\n";
        }
    }
    format!("### `{sub}`\n\n```text\n{out}```\n")
}

/// docs/commands.md's synopsis is what the binary's `--help` says, so no option goes missing
/// from the documentation (the render synopsis lacked seven of them).
#[test]
fn the_commands_synopsis_is_generated_from_help() {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_penumbra"));
    let mut block = format!("{BEGIN}\n\n");
    for sub in SUBCOMMANDS {
        block += &synopsis(&bin, sub);
        block += "\n";
    }
    block += END;
    let path = root().join("docs/commands.md");
    let doc = std::fs::read_to_string(&path).unwrap();
    let (Some(a), Some(b)) = (doc.find(BEGIN), doc.find(END)) else {
        panic!("docs/commands.md has no synopsis markers")
    };
    let current = &doc[a..b + END.len()];
    if current != block && std::env::var_os("PENUMBRA_BLESS").is_some() {
        std::fs::write(&path, format!("{}{block}{}", &doc[..a], &doc[b + END.len()..])).unwrap();
        return;
    }
    assert!(current == block, "docs/commands.md's synopsis is stale: rerun with PENUMBRA_BLESS=1");
}

/// The features of every dependency as `cargo tree` prints them, for one selection of the graph.
fn tree_features(args: &[&str]) -> std::collections::BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let o = Command::new(cargo)
        .args(["tree", "--locked", "--prefix", "none", "-f", "{p} [{f}]"])
        .args(args)
        .current_dir(root())
        .output()
        .unwrap();
    assert!(o.status.success(), "cargo tree: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| l.trim().trim_end_matches(" (*)").to_string())
        .filter(|l| !l.is_empty())
        .collect()
}

/// The README's install command reuses the test build (issue 41 item 5): every crate the
/// installed binary needs is compiled with the features the test build gives it (the
/// dev-dependencies turn features on; the root Cargo.toml's feature pins ask for the same), so
/// `cargo install --path . --locked` after `cargo test --workspace --release` compiles nothing
/// of the workspace again. Before the pins, bitflags, either and serde differed, and the install
/// compiled core, integrators and the CLI again (1 min 17 s on an idle 2-core machine).
#[test]
fn the_installed_binary_has_the_test_builds_features() {
    let install = tree_features(&["-p", "penumbra", "-e", "normal,build"]);
    let test = tree_features(&["--workspace", "-e", "normal,build,dev"]);
    let missing: Vec<&String> = install.iter().filter(|l| !test.contains(*l)).collect();
    assert!(missing.is_empty(), "crates the install builds with other features than the tests: {missing:?}");
}
