//! What a new user trips over (issue 20): outputs checked before rendering, exit codes,
//! strict command-line values, `info` as a scene check, exposure, parser messages.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-ux-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn penumbra(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_penumbra")).current_dir(cwd).args(args).output().expect("run penumbra")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A tiny scene: 8×8 film writing `filename`, a point light, one triangle with `indices`.
fn scene(filename: &str, indices: &str) -> String {
    format!(
        "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\n\
         Film \"image\" \"integer xresolution\" 8 \"integer yresolution\" 8 \"string filename\" \"{filename}\"\n\
         Sampler \"random\" \"integer pixelsamples\" 1\n\
         WorldBegin\nLightSource \"point\" \"rgb I\" [1 1 1]\n\
         Shape \"trianglemesh\" \"integer indices\" [{indices}] \"point P\" [-1 -1 0 1 -1 0 0 1 0]\nWorldEnd\n"
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
    let img = penumbra_core::image::read(d.join("sub/dir/out.png")).unwrap();
    assert_eq!((img.width, img.height), (8, 8));
    assert!(d.join("sub/dir/out.stats.json").is_file());
    std::fs::remove_dir_all(&d).ok();
}
