//! `--param key=value` on the command line, with the value's type inferred.

use penumbra_integrators::common::params::listing;
use penumbra_integrators::Entry;
use penumbra_parser::{Diagnostic, FileLoc, Param, ParamSet, ParamValue};

/// Parses `key=value`: `true`/`false` → bool, an integer → integer, a number → float,
/// comma-separated integers → integers, other comma-separated numbers → floats, anything
/// else → string. [`conform`] then gives each the type its integrator declares. Located at
/// `<command line>`.
pub fn parse_param(arg: &str) -> Result<Param, Diagnostic> {
    let (k, v) = arg.split_once('=').ok_or_else(|| {
        Diagnostic::error(Some(FileLoc::command_line()), format!("--param expects key=value, got \"{arg}\""))
    })?;
    let k = k.trim();
    if k.is_empty() {
        return Err(Diagnostic::error(Some(FileLoc::command_line()), format!("--param has an empty key in \"{arg}\"")));
    }
    let v = v.trim();
    let loc = FileLoc::command_line();
    let value = if v == "true" || v == "false" {
        ParamValue::Bool(vec![v == "true"])
    } else if let Ok(i) = v.parse::<i32>() {
        ParamValue::Int(vec![i])
    } else if let Ok(f) = v.parse::<f32>() {
        ParamValue::Float(vec![f])
    } else if v.contains(',') && v.split(',').all(|s| s.trim().parse::<i32>().is_ok()) {
        ParamValue::Int(v.split(',').map(|s| s.trim().parse::<i32>().unwrap_or(0)).collect())
    } else if v.contains(',') && v.split(',').all(|s| s.trim().parse::<f32>().is_ok()) {
        ParamValue::Float(v.split(',').map(|s| s.trim().parse::<f32>().unwrap_or(0.0)).collect())
    } else {
        ParamValue::String(vec![v.to_string()])
    };
    let mut p = Param::new(k, value, loc);
    p.loose = true;
    Ok(p)
}

/// Every `--param` argument, parsed ([`parse_param`]).
pub fn parse_all(args: &[String]) -> Result<Vec<Param>, Diagnostic> {
    args.iter().map(|a| parse_param(a)).collect()
}

/// The command-line parameters given the types `integrator` declares for them
/// ([`penumbra_integrators::common::params::ParamSpec::conform`]): a name it does not declare, or
/// a value that is not of its type or out of its range, is an error that lists its parameters.
pub fn conform(integrator: &Entry, params: &[Param]) -> Result<Vec<Param>, Diagnostic> {
    params
        .iter()
        .map(|p| {
            let error =
                |msg: String| Diagnostic::error(Some(p.loc.clone()), format!("{msg}; {}", listing(integrator.params)));
            match integrator.params.iter().find(|s| s.name == p.name) {
                None => Err(error(format!("integrator \"{}\" has no parameter \"{}\"", integrator.name, p.name))),
                Some(spec) => spec.conform(integrator.name, p).map_err(error),
            }
        })
        .collect()
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
            return Err(unknown_integrator(n));
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

/// The message for an integrator name penumbra does not know: the valid names, and the
/// nearest one when the name looks like a misspelling of it (issue 41).
pub fn unknown_integrator(name: &str) -> String {
    let names = penumbra_integrators::names();
    let hint = nearest(name, &names).map(|n| format!(" (did you mean \"{n}\"?)")).unwrap_or_default();
    format!("unknown integrator \"{name}\"{hint}; valid names: {}", names.join(", "))
}

/// `-i NAME` as clap's value parser: a name the registry knows, else a usage error (exit 64)
/// with [`unknown_integrator`]'s message.
pub fn integrator_arg(name: &str) -> Result<String, String> {
    let name = name.trim();
    if name.is_empty() {
        // `-i a,,b` / `-i a,`: an empty item of a list, dropped by the list's reader.
        return Ok(String::new());
    }
    match penumbra_integrators::find(name) {
        Some(_) => Ok(name.to_string()),
        None => Err(unknown_integrator(name)),
    }
}

/// The candidate nearest to `name` by edit distance (case-insensitive), if it is within a
/// third of the name's length (at least 1), or one of them starts with the other.
pub fn nearest<'a>(name: &str, candidates: &[&'a str]) -> Option<&'a str> {
    let lower = name.to_ascii_lowercase();
    let budget = (lower.chars().count() / 3).max(1);
    candidates
        .iter()
        .map(|c| (edit_distance(&lower, &c.to_ascii_lowercase()), *c))
        .filter(|(d, c)| *d <= budget || (lower.len() >= 3 && c.starts_with(lower.as_str())))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// Levenshtein distance over chars.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let next = (diag + usize::from(ca != *cb)).min(row[j] + 1).min(row[j + 1] + 1);
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
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
        assert_eq!(parse_param("pixelbounds=0,4,2,8").unwrap().value, ParamValue::Int(vec![0, 4, 2, 8]));
        assert!(parse_param("novalue").is_err());
        assert!(parse_param("=3").is_err());
    }
}

#[cfg(test)]
mod conform_tests {
    use super::*;

    fn conformed(integrator: &str, args: &[&str]) -> Result<Vec<Param>, String> {
        let entry = penumbra_integrators::find(integrator).unwrap();
        let params: Vec<Param> = args.iter().map(|a| parse_param(a).unwrap()).collect();
        conform(entry, &params).map_err(|d| d.message)
    }

    #[test]
    fn types_come_from_the_integrator() {
        let p = conformed("ambientocclusion", &["maxdistance=1", "nsamples=8", "cossample=false"]).unwrap();
        assert_eq!(p[0].value, ParamValue::Float(vec![1.0]));
        assert_eq!(p[1].value, ParamValue::Int(vec![8]));
        assert_eq!(p[2].value, ParamValue::Bool(vec![false]));
        assert!(p.iter().all(|p| p.loc == FileLoc::command_line()));
        let p = conformed("directlighting", &["pixelbounds=0,4,2,8"]).unwrap();
        assert_eq!(p[0].value, ParamValue::Int(vec![0, 4, 2, 8]));
    }

    #[test]
    fn unknown_and_ill_typed_are_errors() {
        let e = conformed("ltc", &["shadow=false"]).unwrap_err();
        assert!(e.contains("no parameter \"shadow\"") && e.contains("shadows (bool)"), "{e}");
        let e = conformed("ltc", &["shadows=flase"]).unwrap_err();
        assert!(e.contains("expects a bool"), "{e}");
        let e = conformed("ambientocclusion", &["nsamples=2.5"]).unwrap_err();
        assert!(e.contains("expects an integer"), "{e}");
        let e = conformed("ltc", &["mode=fast"]).unwrap_err();
        assert!(e.contains("auto, silhouette"), "{e}");
        let e = conformed("ambientocclusion", &["nsamples=0"]).unwrap_err();
        assert!(e.contains("must be in 1..=1048576, got 0"), "{e}");
    }

    #[test]
    fn misspelt_integrators_get_the_nearest_name() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(nearest("directlightning", &penumbra_integrators::names()), Some("directlighting"));
        assert_eq!(nearest("LTC", &penumbra_integrators::names()), Some("ltc"));
        assert_eq!(nearest("ambient", &penumbra_integrators::names()), Some("ambientocclusion"));
        assert_eq!(nearest("nosuch", &penumbra_integrators::names()), None);
        let m = unknown_integrator("shexpp");
        assert!(m.contains("did you mean \"shexp\"") && m.contains("valid names: "), "{m}");
        assert!(integrator_arg("path").is_ok());
        assert!(integrator_arg("nosuch").unwrap_err().starts_with("unknown integrator \"nosuch\"; valid"));
    }
}
