//! pbrt-v3 scene text to a flat, fully resolved [`SceneDescription`].
//!
//! Nothing here knows about rays or rendering: the output is plain data
//! (entities with their [`ParamSet`] and [`FileLoc`]), which `penumbra-core`
//! turns into a renderable scene.

pub mod diag;
mod interp;
mod lexer;
mod number;
pub mod params;
pub mod scene;
pub mod transform;

pub use diag::{DiagSink, Diagnostic, FileLoc, Severity};
pub use params::{Param, ParamSet, ParamValue, SpectrumValue, TextureRef};
pub use scene::*;
pub use transform::{AnimatedTransform, Matrix4, Transform};

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, Weak};

/// Deepest `Include` nesting accepted.
pub const MAX_INCLUDE_DEPTH: usize = interp::MAX_INCLUDE_DEPTH;
/// Deepest `AttributeBegin`/`TransformBegin`/`ObjectBegin` nesting accepted.
pub const MAX_NESTING: usize = interp::MAX_NESTING;

/// The result of a successful parse: the scene and every warning raised while parsing.
#[derive(Debug)]
pub struct ParseOutput {
    pub scene: SceneDescription,
    pub warnings: Vec<Diagnostic>,
}

/// Parse a pbrt-v3 scene file (and everything it `Include`s).
///
/// The file is streamed through a 1 MiB window: memory use is the parsed data,
/// not the text. Relative `Include`, `.spd` and asset paths resolve against the
/// directory of this file, as in pbrt-v3.
pub fn parse_file(path: &Path) -> Result<ParseOutput, Diagnostic> {
    parse_file_with_window(path, lexer::CHUNK)
}

/// [`parse_file`] with a chosen read-window size in bytes (tests exercise refills with tiny windows).
#[doc(hidden)]
pub fn parse_file_with_window(path: &Path, window: usize) -> Result<ParseOutput, Diagnostic> {
    let open_err =
        |e: std::io::Error| Diagnostic::error(None, format!("cannot open scene file \"{}\": {e}", path.display()));
    let file = std::fs::File::open(path).map_err(open_err)?;
    if file.metadata().map(|m| m.is_dir()).unwrap_or(false) {
        return Err(Diagnostic::error(None, format!("cannot parse \"{}\": it is a directory", path.display())));
    }
    let base_dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let canon = std::fs::canonicalize(path).ok();
    let lex = lexer::Lexer::from_reader(Box::new(file), Arc::from(path.display().to_string()), window);
    let (scene, warnings) = interp::Interp::new(lex, canon, base_dir, Some(path.to_path_buf())).run()?;
    Ok(ParseOutput { scene, warnings })
}

/// Parse scene text held in memory. `name` is used in diagnostics; relative
/// `Include` and asset paths resolve against `base_dir` (the current directory if `None`).
pub fn parse_str(text: &str, name: &str, base_dir: Option<&Path>) -> Result<ParseOutput, Diagnostic> {
    let base_dir = base_dir.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    let name: Arc<str> = Arc::from(name);
    register_source(&name, text);
    let lex = lexer::Lexer::from_bytes(text.as_bytes().to_vec(), name);
    let (scene, warnings) = interp::Interp::new(lex, None, base_dir, None).run()?;
    Ok(ParseOutput { scene, warnings })
}

/// The texts given to [`parse_str`], so that diagnostics raised later (unused parameters…)
/// can quote them. Each is keyed by the identity of its name's `Arc`, which every [`FileLoc`]
/// of that parse shares, not by the name: two parses under one name (tests in parallel, a
/// server) each quote their own text. An entry lives while any location of its parse does.
static SOURCES: Mutex<Vec<(Weak<str>, Arc<str>)>> = Mutex::new(Vec::new());

fn register_source(name: &Arc<str>, text: &str) {
    let mut g = SOURCES.lock().unwrap_or_else(|e| e.into_inner());
    g.retain(|(n, _)| n.strong_count() > 0);
    g.push((Arc::downgrade(name), Arc::from(text)));
}

fn registered_source(file: &Arc<str>) -> Option<Arc<str>> {
    let g = SOURCES.lock().unwrap_or_else(|e| e.into_inner());
    // A live `Weak` keeps its allocation, so an address match is the same `Arc`.
    g.iter().find(|(n, _)| std::ptr::addr_eq(n.as_ptr(), Arc::as_ptr(file))).map(|(_, t)| t.clone())
}

/// Very long lines are cut a little after the column.
fn cut_line(line: &str, loc: &FileLoc) -> String {
    let cut = loc.column as usize + 200;
    let mut s: String = line.chars().take(cut).collect();
    if s.ends_with('\r') {
        s.pop();
    }
    s
}

/// The text of the line at `loc` (without its line terminator): from the text given to the
/// [`parse_str`] call `loc` came from, otherwise read from the file.
/// Very long lines are cut a little after the column.
pub fn source_line(loc: &FileLoc) -> Option<String> {
    if loc.is_builtin() || loc.line == 0 {
        return None;
    }
    if let Some(text) = registered_source(&loc.file) {
        return text.split('\n').nth(loc.line as usize - 1).map(|l| cut_line(l, loc));
    }
    let f = std::fs::File::open(&*loc.file).ok()?;
    let mut r = BufReader::new(f);
    let mut buf = Vec::new();
    for _ in 1..loc.line {
        buf.clear();
        if r.read_until(b'\n', &mut buf).ok()? == 0 {
            return None;
        }
    }
    buf.clear();
    // Bound what is read for absurdly long lines.
    let limit = (loc.column as u64 + 200) * 4;
    Read::take(&mut r, limit).read_until(b'\n', &mut buf).ok()?;
    if buf.last() == Some(&b'\n') {
        buf.pop();
    }
    Some(cut_line(&String::from_utf8_lossy(&buf), loc))
}

#[cfg(test)]
mod tests;
