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
