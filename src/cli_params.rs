//! `--param key=value` on the command line, with the value's type inferred.

use penumbra_parser::{Diagnostic, FileLoc, Param, ParamSet, ParamValue};
use std::sync::Arc;

/// Parses `key=value`: `true`/`false` → bool, an integer → integer, a number → float,
/// comma-separated numbers → floats, anything else → string. Values inferred as
/// integers are also accepted where a float is asked for.
pub fn parse_param(arg: &str) -> Result<Param, Diagnostic> {
    let (k, v) = arg
        .split_once('=')
        .ok_or_else(|| Diagnostic::error(None, format!("--param expects key=value, got \"{arg}\"")))?;
    let k = k.trim();
    if k.is_empty() {
        return Err(Diagnostic::error(None, format!("--param has an empty key in \"{arg}\"")));
    }
    let v = v.trim();
    let loc = FileLoc::new(Arc::from("<command line>"), 1, 1);
    let value = if v == "true" || v == "false" {
        ParamValue::Bool(vec![v == "true"])
    } else if let Ok(i) = v.parse::<i32>() {
        ParamValue::Int(vec![i])
    } else if let Ok(f) = v.parse::<f32>() {
        ParamValue::Float(vec![f])
    } else if v.contains(',') && v.split(',').all(|s| s.trim().parse::<f32>().is_ok()) {
        ParamValue::Float(v.split(',').map(|s| s.trim().parse::<f32>().unwrap_or(0.0)).collect())
    } else {
        ParamValue::String(vec![v.to_string()])
    };
    let mut p = Param::new(k, value, loc);
    p.loose = true;
    Ok(p)
}

/// `--threads N` (0: all cores). More threads than the machine has cores add nothing (images
/// are bit-identical whatever the count): clamped, with the warning to print.
pub fn thread_count(requested: usize) -> (usize, Option<String>) {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    if requested > cores {
        let w = format!("warning: --threads {requested} is more than this machine's {cores} cores: using {cores}");
        (cores, Some(w))
    } else {
        (requested, None)
    }
}

/// `-i a,b,c`: the names trimmed, without repeats, each one `penumbra_integrators::find` knows.
pub fn integrator_list(names: &[String]) -> Result<Vec<String>, String> {
    let mut out: Vec<String> = Vec::new();
    for n in names.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        if penumbra_integrators::find(n).is_none() {
            return Err(format!(
                "unknown integrator \"{n}\"; valid names: {}",
                penumbra_integrators::names().join(", ")
            ));
        }
        if !out.iter().any(|m| m == n) {
            out.push(n.to_string());
        }
    }
    if out.is_empty() {
        return Err("-i: no integrator given".into());
    }
    Ok(out)
}

/// Prints a command's final error on stderr (with an `error: ` prefix unless it has one) and
/// exits with `code`.
pub fn exit_with_error(code: u8, message: &str) -> std::process::ExitCode {
    let m = message.trim_end();
    if m.starts_with("error") || m.contains(": error") {
        eprintln!("{m}");
    } else {
        eprintln!("error: {m}");
    }
    std::process::ExitCode::from(code)
}

/// `--threads N` clamped by [`thread_count`], its warning printed.
pub fn threads_or_warn(requested: usize) -> usize {
    let (threads, warning) = thread_count(requested);
    if let Some(w) = warning {
        eprintln!("{w}");
    }
    threads
}

/// `base` with every command-line parameter added (replacing same-named ones).
pub fn merge(base: &ParamSet, cli: &[Param]) -> ParamSet {
    let mut ps = base.clone();
    for p in cli {
        ps.add(p.clone());
    }
    ps
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn infers_types() {
        assert_eq!(parse_param("nsamples=4").unwrap().value, ParamValue::Int(vec![4]));
        assert_eq!(parse_param("maxdistance=0.5").unwrap().value, ParamValue::Float(vec![0.5]));
        assert_eq!(parse_param("cossample=false").unwrap().value, ParamValue::Bool(vec![false]));
        assert_eq!(parse_param("mode=silhouette").unwrap().value, ParamValue::String(vec!["silhouette".into()]));
        assert!(parse_param("novalue").is_err());
        assert!(parse_param("=3").is_err());
    }
}
