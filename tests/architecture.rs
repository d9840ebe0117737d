//! ARCHITECTURE.md names every folder of the code (issue 33): a folder added to `core/src/`,
//! `integrators/src/` or `src/` without a line in the map fails here.

#[test]
fn architecture_names_every_source_folder() {
    let root = env!("CARGO_MANIFEST_DIR");
    let text = std::fs::read_to_string(format!("{root}/ARCHITECTURE.md")).unwrap();
    let mut missing = Vec::new();
    for base in ["core/src", "integrators/src", "src"] {
        for entry in std::fs::read_dir(format!("{root}/{base}")).unwrap() {
            let entry = entry.unwrap();
            if entry.file_type().unwrap().is_dir() {
                let name = format!("{base}/{}/", entry.file_name().to_string_lossy());
                if !text.contains(&format!("`{name}`")) {
                    missing.push(name);
                }
            }
        }
    }
    missing.sort();
    assert!(missing.is_empty(), "ARCHITECTURE.md does not name these folders (as `path/`): {missing:?}");
}
