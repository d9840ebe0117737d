//! `import penumbra`: the Python API over the renderer's crates (issue 40). Scenes parse once
//! ([`scene::Scene`]) and render with the CLI's pipeline into numpy arrays handed over without
//! a copy; `diff`, `check`, `sweep` and `relight` call the library functions the CLI's commands
//! call, with their options checked as the command line checks them. Renders and sweeps run
//! with the GIL released and stop on Ctrl-C ([`run`]).

mod convert;
mod errors;
mod run;
mod scene;
mod tools;

use pyo3::prelude::*;

/// The Python module `penumbra`.
#[pymodule]
fn penumbra(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SceneError", py.get_type::<errors::SceneError>())?;
    m.add("ParamError", py.get_type::<errors::ParamError>())?;
    m.add("SceneWarning", py.get_type::<errors::SceneWarning>())?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<scene::Render>()?;
    m.add_function(wrap_pyfunction!(scene::load, m)?)?;
    m.add_function(wrap_pyfunction!(scene::load_string, m)?)?;
    m.add_function(wrap_pyfunction!(tools::integrators, m)?)?;
    m.add_function(wrap_pyfunction!(tools::diff, m)?)?;
    m.add_function(wrap_pyfunction!(tools::check, m)?)?;
    m.add_function(wrap_pyfunction!(tools::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(tools::relight, m)?)?;
    m.add_function(wrap_pyfunction!(convert::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(convert::write_image, m)?)?;
    Ok(())
}
