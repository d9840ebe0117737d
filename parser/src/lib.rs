//! pbrt-v3 scene text to a flat, fully resolved [`SceneDescription`].
//!
//! Nothing here knows about rays or rendering: the output is plain data
//! (entities with their [`ParamSet`] and [`FileLoc`]), which `penumbra-core`
//! turns into a renderable scene.

pub mod diag;
pub mod params;
pub mod scene;
pub mod transform;

pub use diag::{DiagSink, Diagnostic, FileLoc, Severity};
pub use params::{Param, ParamSet, ParamValue, SpectrumValue, TextureRef};
pub use scene::*;
pub use transform::{AnimatedTransform, Matrix4, Transform};

use std::path::Path;

/// The result of a successful parse: the scene and every warning raised while parsing.
#[derive(Debug)]
pub struct ParseOutput {
    pub scene: SceneDescription,
    pub warnings: Vec<Diagnostic>,
}

/// Parse a pbrt-v3 scene file (and everything it `Include`s).
pub fn parse_file(path: &Path) -> Result<ParseOutput, Diagnostic> {
    let _ = path;
    Err(Diagnostic::error(None, "parser not implemented yet"))
}

/// Parse scene text held in memory. `name` is used in diagnostics; relative
/// `Include` and asset paths resolve against `base_dir` (the current directory if `None`).
pub fn parse_str(text: &str, name: &str, base_dir: Option<&Path>) -> Result<ParseOutput, Diagnostic> {
    let _ = (text, name, base_dir);
    Err(Diagnostic::error(None, "parser not implemented yet"))
}
