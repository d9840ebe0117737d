//! What a new user still tripped over (issue 41): each case failed before its fix.

mod common;
use common::{cli_dir as dir, penumbra, stderr};
use std::os::unix::fs::PermissionsExt;

/// A tiny scene (8×8, one spp) with the given Integrator line and ending.
fn scene(integrator: &str, end: &str) -> String {
    format!(
        "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\n{integrator}\n\
         Film \"image\" \"integer xresolution\" 8 \"integer yresolution\" 8 \"string filename\" \"out.exr\"\n\
         Sampler \"random\" \"integer pixelsamples\" 1\n\
         WorldBegin\nLightSource \"point\" \"point from\" [0 0 -3] \"rgb I\" [9 9 9]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2] \"point P\" [-4 -4 0 4 -4 0 0 4 0]\n{end}"
    )
}

#[test]
fn a_read_only_output_is_refused_before_rendering_and_kept() {
    let d = dir("readonly");
    std::fs::write(d.join("s.pbrt"), scene("", "WorldEnd\n")).unwrap();
    std::fs::write(d.join("prot.exr"), b"a protected reference").unwrap();
    std::fs::set_permissions(d.join("prot.exr"), std::fs::Permissions::from_mode(0o444)).unwrap();
    let o = penumbra(&d, &["render", "s.pbrt", "-o", "prot.exr", "-q"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("prot.exr") && e.contains("read-only"), "{e}");
    assert_eq!(std::fs::read(d.join("prot.exr")).unwrap(), b"a protected reference");
    assert_eq!(std::fs::metadata(d.join("prot.exr")).unwrap().permissions().mode() & 0o777, 0o444);
    // Nothing else was written (no stats, no temporary file).
    let mut names: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
    names.sort();
    assert_eq!(names, ["prot.exr", "s.pbrt"]);
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_scene_as_the_first_argument_renders_it_as_pbrt_does() {
    let d = dir("pbrt-habit");
    std::fs::write(d.join("s.pbrt"), scene("", "WorldEnd\n")).unwrap();
    let o = penumbra(&d, &["s.pbrt", "-o", "habit.exr", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("habit.exr").is_file());
    // A name that is neither a subcommand nor a file is still a usage error.
    let o = penumbra(&d, &["nosuch", "-q"]);
    assert_eq!(o.status.code(), Some(64), "{}", stderr(&o));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn an_unknown_scene_integrator_is_an_error_and_a_missing_world_end_a_warning() {
    let d = dir("strict");
    std::fs::write(d.join("foo.pbrt"), scene("Integrator \"directlightin\"", "WorldEnd\n")).unwrap();
    let o = penumbra(&d, &["render", "foo.pbrt", "-q"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("foo.pbrt:3:") && e.contains("did you mean \"directlighting\""), "{e}");
    assert!(!d.join("out.exr").exists());
    // pbrt-v3's own integrators penumbra lacks still render with the fallback, and say so.
    std::fs::write(d.join("bdpt.pbrt"), scene("Integrator \"bdpt\"", "WorldEnd\n")).unwrap();
    let o = penumbra(&d, &["render", "bdpt.pbrt", "-o", "bdpt.exr", "-q"]);
    assert!(o.status.success() && stderr(&o).contains("not implemented by penumbra"), "{}", stderr(&o));
    std::fs::write(d.join("open.pbrt"), scene("", "")).unwrap();
    let o = penumbra(&d, &["render", "open.pbrt", "-o", "open.exr", "-q"]);
    assert!(o.status.success() && stderr(&o).contains("missing WorldEnd"), "{}", stderr(&o));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn a_misspelt_integrator_is_a_usage_error_with_a_suggestion_everywhere() {
    let d = dir("misspelt");
    std::fs::write(d.join("s.pbrt"), scene("", "WorldEnd\n")).unwrap();
    for args in [
        &["render", "s.pbrt", "-i", "ltcc", "-q"][..],
        &["info", "s.pbrt", "-i", "ltcc"],
        &["sweep", "s.pbrt", "-i", "directlighting,ltcc"],
        &["stability", "s.pbrt", "-i", "ltcc"],
    ] {
        let o = penumbra(&d, args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(64), "{args:?}: {e}");
        assert!(e.contains("did you mean \"ltc\""), "{args:?}: {e}");
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn info_without_a_scene_describes_the_embedded_one_as_render_renders_it() {
    let d = dir("info-default");
    let o = penumbra(&d, &["info"]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.contains("builds:"), "{out}");
    std::fs::remove_dir_all(&d).ok();
}

/// Item 1: a value that cannot be parsed is a usage error (64, as `penumbra --help` documents),
/// in every subcommand that takes the flag, with a message naming the flag and its form.
#[test]
fn malformed_resolution_crop_and_tile_are_usage_errors_everywhere() {
    let d = dir("malformed");
    std::fs::write(d.join("s.pbrt"), scene("", "WorldEnd\n")).unwrap();
    let cases: &[(&[&str], &str, &str)] = &[
        (&["--resolution", "128"], "--resolution", "WxH"),
        (&["--resolution", "128x"], "--resolution", "WxH"),
        (&["--resolution", "0x8"], "--resolution", "WxH"),
        (&["--crop", "1,2,3"], "--crop", "x0,x1,y0,y1"),
        (&["--crop", "a,b,c,d"], "--crop", "x0,x1,y0,y1"),
    ];
    let shard: &[(&[&str], &str, &str)] = &[
        (&["--tile", "7/7", "-o", "x.shard"], "--tile", "I/N"),
        (&["--tile", "0/0", "-o", "x.shard"], "--tile", "I/N"),
        (&["--tile", "1", "-o", "x.shard"], "--tile", "I/N"),
        (&["--tile", "0/2", "--tile-layout", "cols", "-o", "x.shard"], "--tile-layout", "rows"),
    ];
    let mut runs: Vec<(Vec<&str>, &str, &str)> = Vec::new();
    for &(flag, name, form) in cases.iter().chain(shard) {
        runs.push(([&["render", "s.pbrt", "-q"][..], flag].concat(), name, form));
    }
    for &(flag, name, form) in cases {
        runs.push(([&["sweep", "s.pbrt", "-i", "path", "--budgets", "1"][..], flag].concat(), name, form));
        if name != "--crop" {
            // (`stability` has no --crop.)
            runs.push(([&["stability", "s.pbrt", "-i", "path"][..], flag].concat(), name, form));
        }
    }
    for (args, name, form) in runs {
        let o = penumbra(&d, &args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(64), "{args:?}: {e}");
        assert!(e.contains(name) && e.contains(form), "{args:?} must name {name} and {form}: {e}");
    }
    assert!(!d.join("x.shard").exists(), "nothing written");
    std::fs::remove_dir_all(&d).ok();
}

/// Item 6: `convert` decodes a PNG input from sRGB (so PNG -> EXR -> PNG is exact; the PNGs
/// penumbra writes are sRGB-encoded), says so in its help, and `--linear` takes the code values
/// as linear instead (then the EXR holds code/255).
#[test]
fn convert_decodes_png_from_srgb_and_linear_overrides_it() {
    let d = dir("convert-srgb");
    let o = penumbra(&d, &["render", "-q", "--resolution", "8x8", "--spp", "1", "-o", "a.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    for args in [&["convert", "a.png", "b.exr"][..], &["convert", "b.exr", "c.png"]] {
        let o = penumbra(&d, args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    let (a, c) = (std::fs::read(d.join("a.png")).unwrap(), std::fs::read(d.join("c.png")).unwrap());
    assert_eq!(a, c, "PNG -> EXR -> PNG must be byte-identical with the default (sRGB)");
    // --linear: the EXR holds code/255, so converting it back (sRGB-encoding) brightens it.
    let o = penumbra(&d, &["convert", "--linear", "a.png", "lin.exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = penumbra(&d, &["convert", "--srgb", "a.png", "s.exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = penumbra(&d, &["diff", "s.exr", "b.exr"]);
    assert_eq!(o.status.code(), Some(0), "--srgb is the default: {}", stderr(&o));
    let o = penumbra(&d, &["diff", "lin.exr", "b.exr"]);
    assert_ne!(o.status.code(), Some(0), "--linear must change the values");
    let o = penumbra(&d, &["convert", "--linear", "--srgb", "a.png", "x.exr"]);
    assert_eq!(o.status.code(), Some(64), "{}", stderr(&o));
    let help = String::from_utf8_lossy(&penumbra(&d, &["convert", "--help"]).stdout).into_owned();
    assert!(help.contains("decoded from sRGB") && help.contains("--linear"), "{help}");
    std::fs::remove_dir_all(&d).ok();
}
