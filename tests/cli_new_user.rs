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

/// Item 6: a cropped render keeps its place in the full frame, as pbrt-v3 writes a crop
/// (src/core/imageio.cpp, WriteImageEXR: display window the full resolution, data window the
/// crop); `merge` of cropped shards keeps it, and `diff` compares a crop with the same pixels of
/// the whole image (it refused the sizes before, exit 3).
#[test]
fn a_cropped_exr_keeps_its_place_in_the_frame_and_diff_and_merge_honour_it() {
    let d = dir("crop-frame");
    std::fs::write(d.join("s.pbrt"), scene("", "WorldEnd\n")).unwrap();
    let base = ["render", "s.pbrt", "-i", "directlighting", "--spp", "2", "--resolution", "16x12", "-q"];
    let run = |extra: &[&str]| {
        let args: Vec<&str> = base.iter().chain(extra).copied().collect();
        let o = penumbra(&d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    run(&["-o", "full.exr"]);
    run(&["--crop", "4,12,2,9", "-o", "crop.exr"]);
    for i in 0..2 {
        run(&["--crop", "4,12,2,9", "--tile", &format!("{i}/2"), "-o", &format!("p{i}.shard")]);
    }
    let o = penumbra(&d, &["merge", "p0.shard", "p1.shard", "-o", "merged.exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let full = penumbra_core::image::read(d.join("full.exr")).unwrap();
    assert_eq!(full.frame, None);
    let want = Some(penumbra_core::image::Frame { full: (16, 12), origin: (4, 2) });
    for name in ["crop.exr", "merged.exr"] {
        let crop = penumbra_core::image::read(d.join(name)).unwrap();
        assert_eq!((crop.width, crop.height, crop.frame), (8, 7, want), "{name}");
        // The pixels are the whole render's at the same place.
        assert_eq!(crop.data, full.crop(4, 12, 2, 9).unwrap().data, "{name}");
    }
    for (a, b) in [("crop.exr", "full.exr"), ("full.exr", "merged.exr")] {
        let o = penumbra(&d, &["diff", a, b, "--no-flip"]);
        let out = String::from_utf8_lossy(&o.stdout).to_string();
        assert_eq!(o.status.code(), Some(0), "{a} {b}: {out}{}", stderr(&o));
        assert!(out.contains("pixels [4,12)×[2,9) of the 16×12 frame"), "{out}");
    }
    // A crop that shares no pixel with the other image's data window is "different sizes" (3).
    run(&["--crop", "0,4,0,2", "-o", "corner.exr"]);
    let o = penumbra(&d, &["diff", "corner.exr", "crop.exr", "--no-flip"]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    std::fs::remove_dir_all(&d).ok();
}

/// Item 6 for `check`: a cropped render (pbrt-v3's frame: the crop as the data window in the
/// full display window) is judged against the same pixels of a whole reference. Before, `check`
/// compared the data windows' sizes and refused (exit 3, "the images differ in size").
#[test]
fn check_judges_a_cropped_render_on_the_pixels_of_the_whole_reference() {
    let d = dir("check-crop-frame");
    std::fs::write(d.join("s.pbrt"), scene("", "WorldEnd\n")).unwrap();
    let base = ["render", "s.pbrt", "-i", "directlighting", "--variance", "-q"];
    let run = |extra: &[&str]| {
        let args: Vec<&str> = base.iter().chain(extra).copied().collect();
        let o = penumbra(&d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    run(&["--resolution", "16x12", "--spp", "64", "--seed", "1", "-o", "ref.exr"]);
    run(&["--resolution", "16x12", "--spp", "16", "--crop", "4,12,2,9", "-o", "crop.exr"]);
    let o = penumbra(&d, &["check", "crop.exr", "ref.exr", "--json"]);
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert_eq!(o.status.code(), Some(0), "{out}{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    // The 8×7 crop's pixels were judged.
    assert_eq!((v["width"].as_u64(), v["height"].as_u64()), (Some(8), Some(7)), "{v}");
    // The crop's pixels differ from the reference's at another place: a wrong alignment fails.
    let shifted = penumbra_core::image::read(d.join("crop.exr")).unwrap().with_frame((16, 12), (0, 0));
    penumbra_core::image::write(&shifted, d.join("shifted.exr")).unwrap();
    std::fs::copy(d.join("crop.stats.json"), d.join("shifted.stats.json")).unwrap();
    let o = penumbra(&d, &["check", "shifted.exr", "ref.exr"]);
    assert_eq!(o.status.code(), Some(2), "{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    // Crops that share no pixel, or frames of different sizes, are a size mismatch (3).
    run(&["--resolution", "16x12", "--spp", "16", "--crop", "0,4,0,2", "-o", "corner.exr"]);
    assert_eq!(penumbra(&d, &["check", "corner.exr", "crop.exr"]).status.code(), Some(3));
    run(&["--spp", "16", "--resolution", "8x6", "-o", "small.exr"]);
    assert_eq!(penumbra(&d, &["check", "crop.exr", "small.exr"]).status.code(), Some(3));
    std::fs::remove_dir_all(&d).ok();
}

/// Item 9: the 219-byte scene that subdivides a tetrahedron 9 times (2^20 triangles from 4
/// faces, 5 s and 330 MB to render before) is refused under the default budget at once, at its
/// `nlevels`, with exit 1, naming the variable that allows it, and nothing written.
#[test]
fn a_few_bytes_subdivided_nine_times_are_refused_by_the_default_budget() {
    let d = dir("amplified");
    let text = "LookAt 0 0 5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\nLightSource \"point\"\n\
                Shape \"loopsubdiv\" \"integer nlevels\" [ 9 ] \"integer indices\" [ 0 1 2 0 3 1 0 2 3 1 3 2 ] \
                \"point P\" [ 1 1 1 1 -1 -1 -1 1 -1 -1 -1 1 ]\nWorldEnd\n";
    assert!(text.len() < 260, "{}", text.len());
    std::fs::write(d.join("s.pbrt"), text).unwrap();
    let t0 = std::time::Instant::now();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .current_dir(&d)
        .env_remove("PENUMBRA_MAX_TRIANGLES")
        .args(["render", "s.pbrt", "-q", "-o", "out.exr"])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(t0.elapsed().as_secs_f64() < 5.0, "{:?}", t0.elapsed());
    assert!(err.contains("s.pbrt:5:20") && err.contains("1048576 triangles"), "{err}");
    assert!(err.contains("PENUMBRA_MAX_TRIANGLES"), "{err}");
    assert!(!d.join("out.exr").exists());
    std::fs::remove_dir_all(&d).ok();
}

/// Item 9: a scene that asks for minutes of tessellation is refused at once with a located
/// error. The scene's triangle budget (PENUMBRA_MAX_TRIANGLES, default 2^26) is charged by
/// loopsubdiv with 4^nlevels × faces before it subdivides, and by every other shape (each object
/// instance counted) as it is built. Before, nothing bounded the sum: this scene rendered.
#[test]
fn a_scene_over_the_triangle_budget_is_a_located_error() {
    let d = dir("triangle-budget");
    let subdiv = "AttributeBegin\n  Shape \"loopsubdiv\" \"integer nlevels\" [ 6 ] \"integer indices\" [ 0 1 2 0 3 1 0 2 3 1 3 2 ]\n\
                  \"point P\" [ 1 1 1 1 -1 -1 -1 1 -1 -1 -1 1 ]\nAttributeEnd\nWorldEnd\n";
    std::fs::write(d.join("s.pbrt"), scene("", subdiv)).unwrap();
    let render = |budget: Option<&str>| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_penumbra"));
        c.current_dir(&d).args(["render", "s.pbrt", "-q", "-o", "out.exr"]);
        if let Some(b) = budget {
            c.env("PENUMBRA_MAX_TRIANGLES", b);
        }
        c.output().unwrap()
    };
    // 4 × 4^6 = 16384 triangles: within the default budget, over a budget of 10000.
    let o = render(None);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = render(Some("10000"));
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    // At the nlevels parameter: line 10 of the file, column 22.
    assert!(err.contains("s.pbrt:10:22"), "{err}");
    assert!(err.contains("16384 triangles") && err.contains("triangle budget of 10000"), "{err}");
    // A malformed budget is an error, not the default.
    let o = render(Some("lots"));
    assert!(!o.status.success() && stderr(&o).contains("PENUMBRA_MAX_TRIANGLES"), "{}", stderr(&o));
    std::fs::remove_dir_all(&d).ok();
}
