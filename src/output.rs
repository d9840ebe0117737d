//! Checking, before any work is done, that an output file can be created where it is asked for.

use std::path::{Path, PathBuf};

/// What to do when the output's directory does not exist.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MissingDir {
    /// Fail: the user named the path (`-o`), a missing directory is most likely a typo.
    Fail,
    /// Create it (and its parents): the path comes from the scene file (`Film "filename"`).
    Create,
}

/// Checks that `path` can be written (atomically, through a temporary file beside it, as
/// `penumbra_core::image::write_atomic` does): its directory exists (or is created, per
/// `missing`) and is writable, and `path` is not a directory or an existing file the user may
/// not write (a read-only reference image is refused before any work, not replaced). Returns the
/// directories created.
pub fn prepare(path: &Path, missing: MissingDir) -> Result<Vec<PathBuf>, String> {
    if path.file_name().is_none() {
        return Err(format!("{}: not a file name", path.display()));
    }
    if path.is_dir() {
        return Err(format!("{}: is a directory", path.display()));
    }
    penumbra_core::image::existing_writable(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut created = Vec::new();
    if !dir.exists() {
        match missing {
            MissingDir::Fail => {
                return Err(format!("{}: directory {} does not exist", path.display(), dir.display()));
            }
            MissingDir::Create => {
                let mut d = dir.as_path();
                while !d.as_os_str().is_empty() && !d.exists() {
                    created.push(d.to_path_buf());
                    d = d.parent().unwrap_or(Path::new(""));
                }
                created.reverse();
                std::fs::create_dir_all(&dir)
                    .map_err(|e| format!("{}: cannot create {}: {e}", path.display(), dir.display()))?;
            }
        }
    } else if !dir.is_dir() {
        return Err(format!("{}: {} is not a directory", path.display(), dir.display()));
    }
    let probe = dir.join(format!(".penumbra-probe-{}", std::process::id()));
    std::fs::File::options()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| format!("{}: cannot write in {}: {e}", path.display(), dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(created)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_directory_fails_or_is_created() {
        let base = std::env::temp_dir().join(format!("penumbra-output-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        std::fs::create_dir_all(&base).unwrap();
        let out = base.join("a/b/img.exr");
        let e = prepare(&out, MissingDir::Fail).unwrap_err();
        assert!(e.contains("does not exist"), "{e}");
        assert!(!base.join("a").exists());
        assert_eq!(prepare(&out, MissingDir::Create).unwrap(), vec![base.join("a"), base.join("a/b")]);
        assert!(base.join("a/b").is_dir());
        assert_eq!(prepare(&out, MissingDir::Fail).unwrap(), Vec::<PathBuf>::new());
        // The probe file is gone; a directory is not an output file.
        assert_eq!(std::fs::read_dir(base.join("a/b")).unwrap().count(), 0);
        assert!(prepare(&base.join("a"), MissingDir::Fail).unwrap_err().contains("is a directory"));
        std::fs::remove_dir_all(&base).ok();
    }
}
