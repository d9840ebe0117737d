//! The exceptions: `SceneError` (a scene that cannot be used, with its `file:line:column`),
//! `ParamError` (an option the command line would refuse as a usage error), `SceneWarning`.

use penumbra_parser::{DiagSink, Diagnostic};
use pyo3::exceptions::{PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    penumbra,
    SceneError,
    pyo3::exceptions::PyException,
    "A scene that cannot be loaded or rendered. `str(e)` starts with `file:line:column:`; the \
     attributes `file`, `line`, `column`, `message` and `diagnostic` (the CLI's full report, with \
     the source line) say where and what."
);
pyo3::create_exception!(
    penumbra,
    ParamError,
    PyValueError,
    "An option or integrator parameter the command line would refuse (a usage error): an \
     unknown name (the message names the valid ones), a value of the wrong type or out of range."
);
pyo3::create_exception!(
    penumbra,
    SceneWarning,
    PyRuntimeWarning,
    "A warning the CLI prints about a scene (an unsupported feature and what was done instead, an unused parameter)."
);

/// A located diagnostic as a `SceneError`.
pub fn scene_error(py: Python<'_>, d: &Diagnostic) -> PyErr {
    let head = match &d.loc {
        Some(l) => format!("{}:{}:{}: {}", l.file, l.line, l.column, d.message),
        None => d.message.clone(),
    };
    let err = SceneError::new_err(head);
    let value = err.value(py);
    let (file, line, column) = match &d.loc {
        Some(l) => (Some(l.file.to_string()), Some(l.line), Some(l.column)),
        None => (None, None, None),
    };
    // Attributes on a fresh exception instance cannot fail in practice; if one did, the
    // message still says it all.
    let _ = value.setattr("file", file);
    let _ = value.setattr("line", line);
    let _ = value.setattr("column", column);
    let _ = value.setattr("message", d.message.clone());
    let _ = value.setattr("diagnostic", d.to_string());
    err
}

/// A command-line-level error (a bad parameter or option) as a `ParamError`.
pub fn param_error(d: &Diagnostic) -> PyErr {
    ParamError::new_err(d.message.clone())
}

/// Emits every collected diagnostic as a Python `SceneWarning` (each once per call).
pub fn emit_warnings(py: Python<'_>, warnings: &DiagSink) -> PyResult<()> {
    let mut seen = std::collections::BTreeSet::new();
    for d in warnings.take() {
        let text = match &d.loc {
            Some(l) => format!("{}:{}:{}: {}", l.file, l.line, l.column, d.message),
            None => d.message.clone(),
        };
        if seen.insert(text.clone()) {
            let category = py.get_type::<SceneWarning>();
            let msg = std::ffi::CString::new(text.replace('\0', " ")).unwrap_or_default();
            PyErr::warn(py, &category, &msg, 1)?;
        }
    }
    Ok(())
}
