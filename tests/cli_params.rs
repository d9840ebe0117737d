//! Strict `--param` (issue 20 item 5), command-line locations, and the integrator parameter
//! lists of `render --help` and docs/integrators/, generated from the registry (issue 14 item 5).

mod common;
use common::{cli_dir as dir, penumbra, stderr};
use std::path::Path;
use std::process::Output;

/// An 8×8 scene with a quad light over a floor, written to `s.pbrt` in `d`.
fn scene(d: &Path) {
    let text = "LookAt 0 3 -6 0 0 0 0 1 0\nCamera \"perspective\"\n\
        Film \"image\" \"integer xresolution\" 8 \"integer yresolution\" 8 \"string filename\" \"out.exr\"\n\
        Sampler \"random\" \"integer pixelsamples\" 1\nIntegrator \"ltc\"\nWorldBegin\n\
        AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [4 4 4]\n\
        Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-1 2 -1 1 2 -1 1 2 1 -1 2 1]\nAttributeEnd\n\
        Material \"matte\"\n\
        Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [-4 0 -4 -4 0 4 4 0 4 4 0 -4]\nWorldEnd\n";
    std::fs::write(d.join("s.pbrt"), text).unwrap();
}

/// `render s.pbrt` with `args` after it.
fn render(d: &Path, args: &[&str]) -> Output {
    let mut all = vec!["render", "s.pbrt", "-q", "-o", "r.exr"];
    all.extend_from_slice(args);
    penumbra(d, &all)
}

const USAGE: i32 = 64;

#[test]
fn an_unknown_param_is_a_usage_error_naming_the_parameters() {
    let d = dir("unknown");
    scene(&d);
    // The scene's integrator (ltc) and one chosen with -i.
    for args in [&["--param", "shadow=false"][..], &["-i", "ltc", "--param", "shadow=false"]] {
        let o = render(&d, args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(USAGE), "{e}");
        assert!(e.contains("integrator \"ltc\" has no parameter \"shadow\""), "{e}");
        assert!(e.contains("shadows (bool)") && e.contains("coveragesamples (integer)"), "{e}");
        assert!(e.contains("--> <command line>") && !e.contains("s.pbrt"), "{e}");
        assert!(!d.join("r.exr").exists());
    }
    // sweep and info too (sweep: every integrator of the sweep must declare it).
    let o = penumbra(&d, &["info", "s.pbrt", "--param", "shadow=false"]);
    assert_eq!(o.status.code(), Some(USAGE), "{}", stderr(&o));
    let o = penumbra(
        &d,
        &["sweep", "s.pbrt", "--reference-spp", "1", "-i", "ltc,ratio", "--param", "shadows=false", "-o", "sw"],
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(USAGE), "{e}");
    assert!(e.contains("integrator \"ratio\" has no parameter \"shadows\""), "{e}");
    assert!(!d.join("sw").exists(), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn an_ill_typed_param_says_what_was_expected() {
    let d = dir("typed");
    scene(&d);
    let cases = [
        (&["--param", "shadows=flase"][..], "ltc: \"shadows\" expects a bool (true or false), got \"flase\""),
        (&["-i", "ambientocclusion", "--param", "nsamples=2.5"], "\"nsamples\" expects an integer, got \"2.5\""),
        (&["--param", "mode=fast"], "\"mode\" expects one of auto, silhouette, per-triangle, pertriangle"),
        (&["-i", "ambientocclusion", "--param", "nsamples=0"], "\"nsamples\" must be in 1..=1048576, got 0"),
        (&["-i", "path", "--param", "pixelbounds=0,4"], "\"pixelbounds\" expects 4 comma-separated integers"),
    ];
    for (args, says) in cases {
        let o = render(&d, args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(USAGE), "{args:?}: {e}");
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!e.contains("unused"), "{args:?}: {e}");
        assert!(e.contains("its parameters:"), "{args:?}: {e}");
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_convertible_param_is_accepted_without_a_warning() {
    let d = dir("convert");
    scene(&d);
    // An integer where a float is declared, a word for an enumeration, 4 integers.
    for args in [
        &["-i", "ambientocclusion", "--param", "maxdistance=1", "--param", "cossample=false"][..],
        &["--param", "mode=per-triangle", "--param", "coveragesamples=1"],
        &["-i", "path", "--param", "pixelbounds=0,4,0,4", "--param", "rrthreshold=1"],
    ] {
        let o = render(&d, args);
        let e = stderr(&o);
        assert!(o.status.success(), "{args:?}: {e}");
        assert!(!e.contains("warning: parameter"), "{args:?}: {e}");
    }
    // maxdistance=1 really is the float 1: the same image as maxdistance=1.0.
    let ao = |out: &str, params: &[&str]| {
        let mut args = vec!["render", "s.pbrt", "-q", "-i", "ambientocclusion", "-o", out];
        args.extend_from_slice(params);
        let o = penumbra(&d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    ao("a.pfm", &["--param", "maxdistance=1"]);
    ao("b.pfm", &["--param", "maxdistance=1.0"]);
    ao("c.pfm", &[]);
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    assert_eq!(read("a.pfm"), read("b.pfm"));
    assert_ne!(read("a.pfm"), read("c.pfm"), "maxdistance=1 should cut the floor's occlusion by the light");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn command_line_values_never_point_into_the_scene() {
    let d = dir("spp");
    scene(&d);
    for args in [&["--spp", "0"][..], &["--spp", "99999999"]] {
        let o = render(&d, args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(USAGE), "{args:?}: {e}");
        assert!(e.contains("--spp"), "{args:?}: {e}");
        assert!(!e.contains("s.pbrt"), "{args:?}: {e}");
    }
    // The scene file's own values stay located in the scene.
    std::fs::write(
        d.join("bad.pbrt"),
        std::fs::read_to_string(d.join("s.pbrt")).unwrap().replace("\"ltc\"", "\"ltc\" \"integer coveragesamples\" 0"),
    )
    .unwrap();
    let o = penumbra(&d, &["render", "bad.pbrt", "-q", "-o", "r.exr"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("\"coveragesamples\" must be in 1..=1024, got 0") && e.contains("--> bad.pbrt:5:"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn render_help_lists_every_integrator_and_its_parameters() {
    let o = penumbra(Path::new("."), &["render", "--help"]);
    assert!(o.status.success());
    let help = String::from_utf8_lossy(&o.stdout).into_owned();
    for e in penumbra_integrators::REGISTRY {
        assert!(help.contains(&format!("  {}: {}", e.name, e.method)), "{}: not in\n{help}", e.name);
        for s in e.params {
            let line = format!("{}: {} = {}", s.name, s.kind.describe(), s.default);
            assert!(help.contains(&line), "{}: \"{line}\" not in\n{help}", e.name);
            assert!(help.contains(s.doc), "{}: doc of {} not in\n{help}", e.name, s.name);
        }
    }
    assert!(help.contains("nsamples: integer = 64, in 1..=1048576. occlusion rays per camera sample"), "{help}");
}

/// The README's integrator table and every integrator's page with its parameter table are
/// generated from the registry and up to date (a newly registered integrator fails here
/// until its page exists).
#[test]
fn docs_generated_from_the_registry_are_up_to_date() {
    let root = env!("CARGO_MANIFEST_DIR");
    let fix = "run `cargo run -p penumbra-integrators --example generate-docs`";
    let readme = std::fs::read_to_string(format!("{root}/README.md")).unwrap();
    assert!(
        penumbra_integrators::with_generated_table(&readme).unwrap() == readme,
        "README.md's integrator table is out of date: {fix}"
    );
    for e in penumbra_integrators::REGISTRY {
        let page_path = penumbra_integrators::doc_page(e.name);
        assert!(readme.contains(&format!("| [`{}`]({page_path}) |", e.name)), "{}", e.name);
        let page = std::fs::read_to_string(format!("{root}/{page_path}")).unwrap_or_else(|err| {
            panic!("{page_path}: {err} (every registered integrator has a page; see CONTRIBUTING.md)")
        });
        let generated = penumbra_integrators::with_generated_params(e, &page).unwrap();
        assert!(generated == page, "{page_path}: the parameter table is out of date: {fix}");
    }
    let ltc = std::fs::read_to_string(format!("{root}/docs/integrators/ltc.md")).unwrap();
    assert!(ltc.contains("| `\"bool shadows\"` | true |"));
}

/// README.md stays a front door (issue 33): the details live in docs/.
#[test]
fn readme_is_short() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(lines <= 300, "README.md has {lines} lines; move details to docs/ (at most 300)");
}
