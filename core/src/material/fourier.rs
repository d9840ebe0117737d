//! `fourier`: pbrt-v3's `FourierMaterial` — the tabulated BSDF of `"string bsdffile"` (path
//! relative to the scene file, read once per process: [`FourierTable::cached`]) and a bump map.
//! A file that cannot be read or is malformed is an error located at the parameter, naming the
//! byte offset and what was expected there (pbrt-v3 prints an error and renders the surface
//! black).

use super::{FloatParam, Lobes};
use crate::bxdf::{Bsdf, Bxdf, FourierBxdf, FourierTable};
use crate::texture::Textures;
use penumbra_parser::{DiagSink, Diagnostic, FileLoc, ParamSet};
use std::path::{Path, PathBuf};

/// The parameters of `fourier`.
#[derive(Clone, Debug, PartialEq)]
pub struct Fourier {
    pub table: &'static FourierTable,
    pub bump: Option<FloatParam>,
}

impl Fourier {
    pub fn create(
        tx: &mut Textures,
        p: &ParamSet,
        w: &DiagSink,
        loc: &FileLoc,
        base_dir: &Path,
    ) -> Result<Fourier, Diagnostic> {
        let name = p.get_one_string("bsdffile", "");
        let at = p.loc_of("bsdffile").cloned().unwrap_or_else(|| loc.clone());
        if name.is_empty() {
            return Err(Diagnostic::error(Some(at), "fourier material needs a \"string bsdffile\""));
        }
        let path = PathBuf::from(&name);
        let path = if path.is_absolute() { path } else { base_dir.join(path) };
        let table = FourierTable::cached(&path).map_err(|e| Diagnostic::error(Some(at), e.to_string()))?;
        Ok(Fourier { table, bump: tx.get_float_param_opt(p, "bumpmap", w)? })
    }

    /// One [`FourierBxdf`]; the BSDF's own index is 1 (pbrt-v3's `BSDF(*si)`).
    pub(super) fn scatter(&self, l: &Lobes) -> Bsdf {
        let mut b = l.bsdf(1.0);
        let _ = b.add(Bxdf::Fourier(FourierBxdf::new(self.table, l.opts.mode)));
        b
    }
}
