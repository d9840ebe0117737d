//! One identity for a scene, used wherever renders of "the same scene" must be recognised:
//! shard files (`merge` refuses a shard of another scene) and `sweep`'s cached references (a
//! cached reference is reused only for the same scene). It covers every file a render reads:
//! the scene file, its `Include`s and `.spd` spectra (what the parser read), and the assets its
//! entities name (PLY meshes, image textures and environment maps: [`SceneDescription::asset_files`]),
//! so editing any of them changes it.

use crate::pipeline;
use penumbra_core::fnv::Fnv1a;
use penumbra_parser::SceneDescription;

/// FNV-1a of every file the scene reads, contents only (so a scene copied elsewhere keeps its
/// identity), each as its length and bytes: the parsed files in reading order, then the
/// assets in the description's order (a missing asset as a marker, so that creating it
/// changes the identity too). The embedded default scene's text when no file was parsed.
pub fn scene_identity(desc: &SceneDescription) -> Result<String, String> {
    let mut h = Fnv1a::new();
    if desc.files_read.is_empty() {
        h.bytes(pipeline::DEFAULT_SCENE.as_bytes());
    }
    for f in &desc.files_read {
        let bytes = std::fs::read(f).map_err(|e| format!("cannot read {} to identify the scene: {e}", f.display()))?;
        h.u64(bytes.len() as u64).bytes(&bytes);
    }
    h.bytes(b"\0assets\0");
    for f in desc.asset_files() {
        match std::fs::read(&f) {
            Ok(bytes) => h.u64(bytes.len() as u64).bytes(&bytes),
            Err(_) => h.u64(u64::MAX),
        };
    }
    Ok(format!("{:016x}", h.finish()))
}
