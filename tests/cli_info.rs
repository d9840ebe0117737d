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
