//! End-to-end: `penumbra info` on a suite scene and on a broken file.

use std::process::Command;

#[test]
fn info_on_suite_scene() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/suite/ltc/quad-cube.pbrt");
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra")).args(["info", scene]).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("shapes: 3 (trianglemesh x3)"), "{stdout}");
    // 2 + 12 + 2 triangles.
    assert!(stdout.contains("triangles (from the text): 16"), "{stdout}");
    assert!(stdout.contains("area lights: 1 (diffuse x1), on 1 shape(s)"), "{stdout}");
    assert!(stdout.contains("camera: perspective (fov 40)"), "{stdout}");
    assert!(stdout.contains("film: image 256x256"), "{stdout}");
    assert!(stdout.contains("integrator: directlighting"), "{stdout}");
}

#[test]
fn info_on_broken_file_fails_with_location() {
    let dir = std::env::temp_dir().join(format!("penumbra-cli-info-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.pbrt");
    std::fs::write(&path, "WorldBegin\nShape \"sphere\" \"float radius\" [ 1 \"x\" ]\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra")).arg("info").arg(&path).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains(&format!("{}:2:35", path.display())), "{stderr}");
    assert!(stderr.contains('^'), "{stderr}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn info_with_shexp_reports_sphere_sets() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/suite/ao/spheres-on-plane.pbrt");
    let out = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args(["info", scene, "-i", "shexp", "--param", "spheres=4"])
        .env("PENUMBRA_CACHE_DIR", "")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("shexp builds: bvh, lights, materials, sphere sets"), "{stdout}");
    assert!(stdout.contains("2 leaf spheres: 2 exact, 0 fitted"), "{stdout}");
    assert!(stdout.contains("object 0 (sphere at"), "{stdout}");
    assert!(stdout.contains("Exact, 1 spheres"), "{stdout}");
    assert!(stdout.contains("object 2 (ground plane)"), "{stdout}");
}

/// `silhouette`'s cost estimate (issue 37 item 3): `info` prints it, and warns on a heavy mesh
/// (killeroo-simple, 79k triangles: ~6 000 contour edges per point, every camera sample
/// integrated with `shading=sample`, 8 per pixel: measured 28–31× the estimated
/// `ambientocclusion` time at 0.41–0.45 ms per point; with the default pixel shading, 2.9
/// integrations per pixel, it is now ~9×, under the threshold) but not on the 134-triangle
/// blinds (measured 0.3–0.8×). The warning's threshold is 10×, so the margins are about 3× and
/// more than tenfold; the estimate's two times are measured on the same machine, so load moves
/// both. Mutations: a threshold of 1e9 fails the first, of 0 the second.
#[test]
fn info_estimates_silhouette_cost_and_warns_on_a_heavy_mesh() {
    let root = env!("CARGO_MANIFEST_DIR");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_penumbra")).args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let killeroo = format!("{root}/scenes/public/mmp-pbrt-v3/scenes/killeroo-simple.pbrt");
    let (out, _) = run(&["info", &killeroo, "-i", "silhouette", "--param", "mode=ao", "--param", "shading=sample"]);
    assert!(out.contains("silhouette cost estimate: ") && out.contains("contour edges per shading point"), "{out}");
    assert!(out.contains("points to integrate (490000 px"), "{out}");
    assert!(out.contains("warning: silhouette will be about") && out.contains("-i ambientocclusion"), "{out}");
    let blinds = format!("{root}/scenes/suite/ao/blinds.pbrt");
    let (out, err) = run(&["info", &blinds, "-i", "silhouette"]);
    assert!(out.contains("silhouette cost estimate: "), "{out}");
    assert!(!out.contains("warning: silhouette will be") && !err.contains("slower than"), "{out}{err}");
    // Other integrators estimate nothing (and info still skips their BVH).
    let (out, _) = run(&["info", &blinds, "-i", "ambientocclusion"]);
    assert!(!out.contains("cost estimate") && out.contains("bvh: not built by info"), "{out}");
}

/// The start of `penumbra render -i silhouette` states the estimate and the warning (before
/// the render: stderr's first lines after the build); `-q` keeps only the warning.
#[test]
fn render_states_silhouette_estimate_before_rendering() {
    let root = env!("CARGO_MANIFEST_DIR");
    let dir = std::env::temp_dir().join(format!("penumbra-cli-info-cost-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let killeroo = format!("{root}/scenes/public/mmp-pbrt-v3/scenes/killeroo-simple.pbrt");
    let img = dir.join("k.exr");
    let img = img.to_str().unwrap();
    let base = ["render", &killeroo, "-i", "silhouette", "--param", "mode=ao", "--resolution", "8x8", "--spp", "1"];
    for quiet in [false, true] {
        let mut args = base.to_vec();
        args.extend(["-o", img]);
        if quiet {
            args.push("-q");
        }
        let out = Command::new(env!("CARGO_BIN_EXE_penumbra")).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        let (estimate, warning) =
            (err.find("silhouette cost estimate:"), err.find("warning: silhouette will be about"));
        assert!(warning.is_some(), "{err}");
        if quiet {
            assert!(estimate.is_none(), "{err}");
        } else {
            let done = err.find("k.exr: silhouette at 1 spp").expect("the render's summary");
            assert!(estimate.unwrap() < done && warning.unwrap() < done, "{err}");
            assert!(err.contains("64 points to integrate (64 px × 1.00: every camera sample"), "{err}");
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
