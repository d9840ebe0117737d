//! One set of render flags (issue 33 item 3): `--spp` (and `--reference-spp`) take 1..=2^24 in
//! every subcommand, with one message, as a usage error (exit 64) before anything is read;
//! `--param`, `--threads`, `--seed` and `--resolution` are accepted by `render`, `sweep` and
//! `stability` alike.

mod common;
use common::{cli_dir, penumbra, stderr};

/// Every samples-per-pixel flag with `value` (the scene need not exist: clap refuses first).
fn spp_commands(value: &str) -> Vec<Vec<String>> {
    let v = value.to_string();
    [
        vec!["render", "s.pbrt", "--spp", &v],
        vec!["sweep", "s.pbrt", "-i", "ambientocclusion", "--reference-spp", &v],
        vec![
            "sweep",
            "s.pbrt",
            "-i",
            "ambientocclusion",
            "--reference-spp",
            "4",
            "--budget-param",
            "nsamples",
            "--spp",
            &v,
        ],
        vec!["stability", "s.pbrt", "-i", "ambientocclusion", "--spp", &v],
    ]
    .into_iter()
    .map(|c| c.into_iter().map(String::from).collect())
    .collect()
}

#[test]
fn spp_is_1_to_2_pow_24_everywhere_with_one_message() {
    let d = cli_dir("cli-flags-spp");
    for bad in ["0", "16777217"] {
        let mut messages = Vec::new();
        for cmd in spp_commands(bad) {
            let args: Vec<&str> = cmd.iter().map(String::as_str).collect();
            let o = penumbra(&d, &args);
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(64), "{args:?}: {e}");
            assert!(e.contains(&format!("{bad} is not in 1..=16777216")), "{args:?}: {e}");
            // The message after the flag's name and value name (`--spp <SPP>`, `--reference-spp <N>`).
            let first_line = e.lines().next().unwrap_or_default();
            messages.push(first_line.rsplit("': ").next().unwrap_or_default().to_string());
        }
        let first = &messages[0];
        assert!(messages.iter().all(|m| m == first), "different messages for --spp {bad}: {messages:?}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// The largest value passes clap: what fails then is the missing scene (exit 1), not the range.
#[test]
fn spp_2_pow_24_is_accepted_everywhere() {
    let d = cli_dir("cli-flags-spp-max");
    for cmd in spp_commands("16777216") {
        let args: Vec<&str> = cmd.iter().map(String::as_str).collect();
        let o = penumbra(&d, &args);
        let e = stderr(&o);
        assert_ne!(o.status.code(), Some(64), "{args:?}: {e}");
        assert!(!e.contains("is not in"), "{args:?}: {e}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// The shared flags have one help text in every subcommand that renders.
#[test]
fn render_flags_are_the_same_in_every_subcommand() {
    let d = cli_dir("cli-flags-help");
    let help = |sub: &str| String::from_utf8_lossy(&penumbra(&d, &[sub, "--help"]).stdout).into_owned();
    // The flag's help line, whitespace normalised (each subcommand aligns its own columns).
    let flag_help = |text: &str, flag: &str| -> String {
        let line = text.lines().find(|l| l.trim_start().starts_with(&format!("{flag} ")));
        line.unwrap_or_else(|| panic!("{flag} missing in\n{text}")).split_whitespace().collect::<Vec<_>>().join(" ")
    };
    let (render, sweep, stability) = (help("render"), help("sweep"), help("stability"));
    for flag in ["--param", "--threads", "--seed", "--resolution"] {
        let r = flag_help(&render, flag);
        assert_eq!(r, flag_help(&sweep, flag), "{flag}: render and sweep differ");
        assert_eq!(r, flag_help(&stability, flag), "{flag}: render and stability differ");
    }
    std::fs::remove_dir_all(&d).ok();
}
