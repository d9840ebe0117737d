//! What a new user trips over (issue 20): outputs checked before rendering, exit codes,
//! strict command-line values, `info` as a scene check, exposure, parser messages.

mod common;
use common::{cli_dir as dir, penumbra, stderr};
use std::path::Path;
use std::process::Command;

/// A tiny scene: 8×8 film writing `filename`, a point light, one triangle with `indices`.
fn scene(filename: &str, indices: &str) -> String {
    format!(
        "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\n\
         Film \"image\" \"integer xresolution\" 8 \"integer yresolution\" 8 \"string filename\" \"{filename}\"\n\
         Sampler \"random\" \"integer pixelsamples\" 1\n\
         WorldBegin\nLightSource \"point\" \"point from\" [0 0 -3] \"rgb I\" [9 9 9]\n\
         Shape \"trianglemesh\" \"integer indices\" [{indices}] \"point P\" [-4 -4 0 4 -4 0 0 4 0]\nWorldEnd\n"
    )
}

#[test]
fn output_into_a_missing_directory_fails_before_the_scene_is_built() {
    let d = dir("missing-o");
    // The scene would fail in the build (vertex index 7 of 3): the output is checked first.
    std::fs::write(d.join("bad.pbrt"), scene("out.exr", "0 1 7")).unwrap();
    let o = penumbra(&d, &["render", "bad.pbrt", "-o", "nodir/x.exr", "-q"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("nodir/x.exr: directory nodir does not exist"), "{e}");
    assert!(!e.contains("vertex index"), "{e}");
    assert!(!d.join("nodir").exists());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn the_scenes_own_film_filename_gets_its_directories() {
    let d = dir("film-dir");
    std::fs::write(d.join("s.pbrt"), scene("sub/dir/out.png", "0 1 2")).unwrap();
    let o = penumbra(&d, &["render", "s.pbrt", "-q"]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("created directory sub/dir"), "{e}");
    // No Integrator line: path, with no warning about it (nothing at `<default>`).
    assert!(!e.contains("<default>") && !e.contains("warning"), "{e}");
    let img = penumbra_core::image::read(d.join("sub/dir/out.png")).unwrap();
    assert_eq!((img.width, img.height), (8, 8));
    assert!(d.join("sub/dir/out.stats.json").is_file());
    std::fs::remove_dir_all(&d).ok();
}

/// Starts `penumbra args…`, sends SIGINT after `after` seconds and returns its exit code.
fn interrupted(cwd: &Path, args: &[&str], after: f64) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .current_dir(cwd)
        .args(args)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run penumbra");
    std::thread::sleep(std::time::Duration::from_secs_f64(after));
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let t0 = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed().as_secs() > 120 {
            child.kill().ok();
            panic!("penumbra {args:?} did not stop within 120 s of SIGINT");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn ctrl_c_exits_130_from_render_and_sweep() {
    let d = dir("sigint");
    // Seconds of small tiles (each stops the render within milliseconds): the interrupt lands
    // mid-render.
    let (code, e) = interrupted(&d, &["render", "--spp", "16", "--resolution", "2048x2048", "-q", "-o", "x.exr"], 1.5);
    assert_eq!(code, Some(130), "{e}");
    assert!(e.contains("interrupted: nothing was written"), "{e}");
    assert!(!d.join("x.exr").exists());
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/suite/ltc/quad-cube.pbrt");
    let args = ["sweep", scene, "--reference-spp", "64", "--resolution", "1024x1024", "-i", "ltc", "-o", "sw"];
    let (code, e) = interrupted(&d, &args, 1.5);
    assert_eq!(code, Some(130), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn usage_errors_exit_64_distinct_from_diff_verdicts() {
    let d = dir("usage");
    for args in [
        &["diff", "--bogus", "a.exr", "b.exr"][..],
        &["diff", "a.exr"],
        &["diff", "--fail", "abc", "a.exr", "b.exr"],
        &["render", "--spp", "many"],
        &["sweep"],
        &["nosuchcommand"],
    ] {
        let o = penumbra(&d, args);
        assert_eq!(o.status.code(), Some(64), "penumbra {args:?}: {}", stderr(&o));
    }
    for args in [&["--help"][..], &["diff", "--help"], &["--version"]] {
        let o = penumbra(&d, args);
        assert_eq!(o.status.code(), Some(0), "penumbra {args:?}: {}", stderr(&o));
    }
    // The help documents the scheme, and that no subcommand renders the default scene.
    let help = String::from_utf8_lossy(&penumbra(&d, &["--help"]).stdout).into_owned();
    assert!(help.contains("64 command-line usage error") && help.contains("130 interrupted"), "{help}");
    assert!(help.contains("With no subcommand, `penumbra` renders the embedded default scene"), "{help}");
    let dhelp = String::from_utf8_lossy(&penumbra(&d, &["diff", "--help"]).stdout).into_owned();
    assert!(dhelp.contains("64 command-line usage error"), "{dhelp}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn out_of_range_crops_are_errors_and_ignored_flags_are_said() {
    let d = dir("strict");
    std::fs::write(d.join("s.pbrt"), scene("out.exr", "0 1 2")).unwrap();
    for (crop, says) in [
        ("0,9,0,4", "--crop 0,9,0,4 is outside the 8x8 image"),
        ("4,4,0,8", "is outside the 8x8 image"),
        ("-1,4,0,8", "is outside the 8x8 image"),
        ("0.0,1.5,0,1", "fractions need 0 <= x0 < x1 <= 1"),
    ] {
        let o = penumbra(&d, &["render", "s.pbrt", "-q", "--crop", crop, "-o", "c.exr"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "--crop {crop}: {e}");
        assert!(e.contains(says), "--crop {crop}: {e}");
    }
    // sweep checks the same, before anything renders.
    let o = penumbra(
        &d,
        &["sweep", "s.pbrt", "--reference-spp", "4", "-i", "ambientocclusion", "--crop", "0,16,0,8", "-o", "sw"],
    );
    assert!(stderr(&o).contains("is outside the 8x8 image"), "{}", stderr(&o));
    assert!(!d.join("sw").exists());
    // --variance with a PNG is said, not silently dropped.
    let o = penumbra(&d, &["render", "s.pbrt", "-q", "--variance", "-o", "v.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("--variance: v.png has no room for the variance channels"), "{}", stderr(&o));
    // --threads beyond the machine's cores is clamped with a warning.
    let o = penumbra(&d, &["render", "s.pbrt", "-q", "--threads", "100000", "-o", "t.exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning: --threads 100000 is more than this machine's"), "{}", stderr(&o));
    let stats: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("t.stats.json")).unwrap()).unwrap();
    let cores = std::thread::available_parallelism().unwrap().get() as u64;
    assert!(stats["threads"].as_u64().unwrap() <= cores, "{stats}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn diff_heatmap_honours_the_extension() {
    use penumbra_core::image::{self, channel_names, Image};
    let d = dir("heat-ext");
    let a = Image::from_data(4, 2, channel_names(&["R", "G", "B"]), vec![0.5; 24]).unwrap();
    let mut b = a.clone();
    b.set(3, 1, 1, 0.75);
    image::write(&a, d.join("a.exr")).unwrap();
    image::write(&b, d.join("b.exr")).unwrap();
    for name in ["h.exr", "h.pfm"] {
        let o = penumbra(&d, &["diff", "a.exr", "b.exr", "--heatmap", name]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        // The error values themselves, at the image's size (no legend band).
        let h = image::read(d.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((h.width, h.height), (4, 2), "{name}");
        assert_eq!(h.pixel(3, 1), &[0.25, 0.25, 0.25][..], "{name}");
        assert_eq!(h.pixel(0, 0), &[0.0, 0.0, 0.0][..], "{name}");
    }
    let o = penumbra(&d, &["diff", "a.exr", "b.exr", "--heatmap", "h.tiff"]);
    assert_eq!(o.status.code(), Some(4), "{}", stderr(&o));
    assert!(stderr(&o).contains("must end in .png, .exr or .pfm"), "{}", stderr(&o));
    std::fs::remove_dir_all(&d).ok();
}

/// `info` reports what `render` reports before rendering — the same text on stderr, the same
/// exit status — for build-time errors and warnings the parser cannot see.
#[test]
fn info_checks_the_scene_as_render_does() {
    let d = dir("info-check");
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0\n1 -1 0\n";
    std::fs::write(d.join("short.ply"), ply).unwrap();
    let head = "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\n\
                Film \"image\" \"integer xresolution\" 8 \"integer yresolution\" 8\n\
                Sampler \"random\" \"integer pixelsamples\" 1\nWorldBegin\nLightSource \"point\" \"rgb I\" [1 1 1]\n";
    let cases = [
        (
            "index",
            "Shape \"trianglemesh\" \"integer indices\" [0 1 7] \"point P\" [-1 -1 0 1 -1 0 0 1 0]",
            1,
            "vertex index 7",
        ),
        (
            "shortp",
            "Shape \"trianglemesh\" \"integer indices\" [0 1 2] \"point P\" [-1 -1 0 1 -1 0 0 1]",
            1,
            "multiple of 3",
        ),
        ("ply", "Shape \"plymesh\" \"string filename\" \"short.ply\"", 1, "short.ply"),
        ("misspelled", "Shape \"sphere\" \"float radiuss\" 2", 0, "\"float radiuss\" unused"),
        ("unknown", "Shape \"blob\"", 0, "blob"),
        ("light", "LightSource \"spot\" \"float conedelta\" 5 \"float coneangel\" 30", 0, "coneangel"),
    ];
    for (name, body, code, says) in cases {
        let file = format!("{name}.pbrt");
        std::fs::write(d.join(&file), format!("{head}{body}\nWorldEnd\n")).unwrap();
        let render = penumbra(&d, &["render", &file, "-q", "-o", "r.exr"]);
        let info = penumbra(&d, &["info", &file]);
        let (re, ie) = (stderr(&render), stderr(&info));
        assert!(ie.contains(says), "{name}: info says\n{ie}");
        assert_eq!(ie, re, "{name}: info and render differ");
        assert_eq!(info.status.code(), Some(code), "{name}: {ie}");
        assert_eq!(render.status.code(), Some(code), "{name}: {re}");
    }
    // -i NAME: that integrator's parameters and what it would build; a misspelled `--param` is
    // a usage error, as for `render`.
    let o = penumbra(&d, &["info", "misspelled.pbrt", "-i", "ambientocclusion", "--param", "nsample=4"]);
    assert_eq!(o.status.code(), Some(64), "{}", stderr(&o));
    assert!(stderr(&o).contains("no parameter \"nsample\""), "{}", stderr(&o));
    let o = penumbra(&d, &["info", "misspelled.pbrt", "-i", "ambientocclusion", "--param", "nsamples=4"]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("ambientocclusion builds: bvh (1 spp)") && out.contains("bvh: not built by info"), "{out}");
    let o = penumbra(&d, &["info", "misspelled.pbrt", "-i", "ltc"]);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("ltc builds: bvh, lights, materials"), "{out}");
    assert!(out.contains("lights: 0.") && out.contains("(1 lights)"), "{out}");
    // A usage error (64), found before the scene is read: no summary on stdout (issue 41).
    let o = penumbra(&d, &["info", "misspelled.pbrt", "-i", "nosuch"]);
    assert_eq!(o.status.code(), Some(64));
    assert!(stderr(&o).contains("unknown integrator \"nosuch\""), "{}", stderr(&o));
    assert!(o.stdout.is_empty(), "{}", String::from_utf8_lossy(&o.stdout));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn exposure_for_render_png_and_convert() {
    use penumbra_core::image;
    let d = dir("exposure");
    std::fs::write(d.join("s.pbrt"), scene("out.exr", "0 1 2")).unwrap();
    for (out, stops) in [("a.exr", "0"), ("dark.png", "-1"), ("plain.png", "0")] {
        let o = penumbra(&d, &["render", "s.pbrt", "-q", "--exposure", stops, "-o", out]);
        assert!(o.status.success(), "{out}: {}", stderr(&o));
    }
    // Said when it does not apply.
    let o = penumbra(&d, &["render", "s.pbrt", "-q", "--exposure", "2", "-o", "b.exr"]);
    assert!(stderr(&o).contains("--exposure applies to PNG output"), "{}", stderr(&o));
    // convert EXR → PNG at the same exposure gives the render's own PNG, byte for byte.
    let o = penumbra(&d, &["convert", "a.exr", "conv.png", "--exposure", "-1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.join("conv.png")).unwrap(), std::fs::read(d.join("dark.png")).unwrap());
    let (dark, plain) = (image::read(d.join("dark.png")).unwrap(), image::read(d.join("plain.png")).unwrap());
    let sum = |i: &image::Image| i.data.iter().map(|&v| v as f64).sum::<f64>();
    assert!(sum(&plain) > 0.0 && sum(&dark) < 0.9 * sum(&plain), "{} {}", sum(&dark), sum(&plain));
    // convert to a float format scales the values by 2^S exactly.
    let o = penumbra(&d, &["convert", "a.exr", "twice.pfm", "--exposure", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, twice) = (image::read(d.join("a.exr")).unwrap(), image::read(d.join("twice.pfm")).unwrap());
    let a = a.select_channels(&["R", "G", "B"]).unwrap();
    assert_eq!(twice.data, a.data.iter().map(|v| v * 2.0).collect::<Vec<_>>());
    let o = penumbra(&d, &["convert", "a.exr", "x.tga"]);
    assert_eq!(o.status.code(), Some(1));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn parser_messages_point_at_the_cause_and_escape_bytes() {
    let d = dir("parser-msgs");
    let cases: [(&str, &[u8], &str); 3] = [
        // An unclosed '[' is reported at the bracket, not at the directive the list runs into.
        (
            "bracket",
            b"WorldBegin\nShape \"sphere\" \"float radius\" [ 1\nShape \"sphere\"\nWorldEnd\n",
            "error: unclosed '[' in the value of parameter \"float radius\": the list runs into \"Shape\" at bracket.pbrt:3:1\n --> bracket.pbrt:2:31",
        ),
        // A missing closing quote runs on to the next string: said at the string, not as a bad number.
        (
            "quote",
            b"WorldBegin\nShape \"sphere\" \"float radius 2 Shape \"sphere\"\nWorldEnd\n",
            "a closing quote is probably missing (the string runs on to the next '\"')\n --> quote.pbrt:2:16",
        ),
        // A NUL and an invalid UTF-8 byte are escaped, never printed raw.
        ("bytes", b"WorldBegin\nShape \"sph\x00\xffere\"\nWorldEnd\n", "warning: shape \"sph\\x00\\xffere\" unknown; skipped"),
    ];
    for (name, text, says) in cases {
        let file = format!("{name}.pbrt");
        std::fs::write(d.join(&file), text).unwrap();
        let o = penumbra(&d, &["info", &file]);
        let e = stderr(&o);
        assert!(e.contains(says), "{name}:\n{e}");
        assert!(!o.stderr.contains(&0) && !e.contains('\u{fffd}'), "{name}: raw bytes in\n{e}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// What penumbra writes by default is ignored by git (a render in a clone leaves `git status` clean).
#[test]
fn default_outputs_are_gitignored() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let ignore = std::fs::read_to_string(root.join(".gitignore")).unwrap();
    for pattern in ["/penumbra.exr", "*.stats.json", "/sweep-out/", "/stability-out/"] {
        assert!(ignore.lines().any(|l| l.trim() == pattern), "{pattern} missing from .gitignore");
    }
    // Where git is at hand, ask it (the patterns above are what it matches).
    let asked = Command::new("git")
        .current_dir(root)
        .args([
            "check-ignore",
            "-q",
            "penumbra.exr",
            "penumbra.stats.json",
            "sweep-out/sweep.csv",
            "stability-out/stability.json",
            "scenes/x.stats.json",
        ])
        .status();
    if let Ok(status) = asked {
        if status.code() != Some(128) {
            assert!(status.success(), "git check-ignore: {status}");
        }
    }
}

#[test]
fn phases_count_what_the_render_counts() {
    // `--phases` records one camera ray per camera sample, one shadow query per shadow ray and
    // one closest-hit query (the camera ray's first or another) per ray; without it, nothing.
    let d = dir("phases");
    let s = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/suite/ltc/two-lights-metal.pbrt");
    let s = s.to_str().unwrap();
    let stats = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec!["render", s, "--spp", "4", "--resolution", "16x16", "--threads", "2", "-q", "-o", "t.pfm"];
        args.extend_from_slice(extra);
        let o = penumbra(&d, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice(&std::fs::read(d.join("t.stats.json")).unwrap()).unwrap()
    };
    assert_eq!(stats(&[])["stats"]["phases"], serde_json::json!({}));
    let st = &stats(&["--phases"])["stats"];
    let (p, calls) = (&st["phases"], |k: &str| st["phases"][k]["calls"].as_f64().unwrap_or(0.0));
    assert_eq!(calls("camera_ray"), st["camera_samples"].as_f64().unwrap(), "{p}");
    assert_eq!(calls("camera_hit"), st["camera_samples"].as_f64().unwrap(), "{p}");
    assert_eq!(calls("camera_hit") + calls("closest_hit"), st["rays"].as_f64().unwrap(), "{p}");
    assert_eq!(calls("shadow"), st["shadow_rays"].as_f64().unwrap(), "{p}");
    assert!(calls("shading") > 0.0 && calls("light_sampling") > 0.0, "{p}");
    for k in ["camera_hit", "closest_hit", "shadow", "shading", "light_sampling"] {
        let sec = p[k]["seconds"].as_f64().unwrap();
        assert!(sec > 0.0 && sec < 2.0 * st["render_seconds"].as_f64().unwrap() * 2.0, "{k}: {p}");
    }
}
