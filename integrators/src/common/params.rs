//! Typed, documented integrator parameters.
//!
//! Each integrator declares `pub const PARAMS: &[ParamSpec]` beside its constructor (name,
//! type, default, range, one-line doc) and reads its values through [`Params`], which checks
//! ranges and parses enumerations with located errors and warnings. The same list checks
//! `--param` on the command line ([`ParamSpec::conform`]), and writes the parameter lists of
//! `render --help` and the integrators' pages in docs/integrators/ ([`help_text`], [`markdown`]).
//!
//! Scene-file parameters keep pbrt-v3's semantics: one of another type is not seen (and is
//! reported unused), an unknown enumeration word warns and uses the default unless the
//! parameter is [`ParamSpec::strict`].

use penumbra_parser::{DiagSink, Diagnostic, Param, ParamSet, ParamValue};
use std::fmt::Write as _;

/// A parameter's type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    Int,
    Float,
    Bool,
    String,
    /// One of these words (a `"string"` in the scene file).
    Enum(&'static [&'static str]),
    /// Exactly this many integers (pbrt-v3's `pixelbounds`).
    Ints(usize),
}

impl Kind {
    /// The pbrt-v3 type a scene file writes it as.
    pub fn pbrt_type(&self) -> &'static str {
        match self {
            Kind::Int | Kind::Ints(_) => "integer",
            Kind::Float => "float",
            Kind::Bool => "bool",
            Kind::String | Kind::Enum(_) => "string",
        }
    }

    /// How `render --help` and error messages name it.
    pub fn describe(&self) -> String {
        match self {
            Kind::Int => "integer".into(),
            Kind::Float => "float".into(),
            Kind::Bool => "bool".into(),
            Kind::String => "string".into(),
            Kind::Enum(v) => v.join("|"),
            Kind::Ints(n) => format!("{n} integers"),
        }
    }
}

/// A parameter's value when the scene and the command line do not give it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DefaultValue {
    Int(i32),
    Float(f32),
    Bool(bool),
    Str(&'static str),
    /// No value: the integrator decides as this says.
    Unset(&'static str),
}

impl std::fmt::Display for DefaultValue {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            DefaultValue::Int(v) => write!(f, "{v}"),
            DefaultValue::Float(v) if v.is_infinite() => {
                write!(f, "{}", if *v > 0.0 { "infinity" } else { "-infinity" })
            }
            DefaultValue::Float(v) => write!(f, "{v}"),
            DefaultValue::Bool(v) => write!(f, "{v}"),
            DefaultValue::Str(v) => write!(f, "{v}"),
            DefaultValue::Unset(why) => write!(f, "({why})"),
        }
    }
}

/// The values a parameter accepts (NaN is never accepted by a float range).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    Any,
    /// `lo ..= hi`.
    Int(i32, i32),
    /// `> 0`, infinity included.
    Positive,
    /// `> 0` and finite.
    PositiveFinite,
    /// `>= 0` and finite.
    NonNegativeFinite,
    /// Finite.
    Finite,
    /// `lo < v <= hi`.
    LeftOpen(f32, f32),
}

impl Range {
    fn contains_int(&self, v: i32) -> bool {
        match *self {
            Range::Int(lo, hi) => (lo..=hi).contains(&v),
            _ => true,
        }
    }

    fn contains_float(&self, v: f32) -> bool {
        match *self {
            Range::Any | Range::Int(..) => true,
            Range::Positive => v > 0.0,
            Range::PositiveFinite => v > 0.0 && v.is_finite(),
            Range::NonNegativeFinite => v >= 0.0 && v.is_finite(),
            Range::Finite => v.is_finite(),
            Range::LeftOpen(lo, hi) => v > lo && v <= hi,
        }
    }

    /// "in 1..=1024", "positive", …; empty for `Any`.
    pub fn describe(&self) -> String {
        match *self {
            Range::Any => String::new(),
            Range::Int(lo, hi) => format!("in {lo}..={hi}"),
            Range::Positive => "positive".into(),
            Range::PositiveFinite => "positive and finite".into(),
            Range::NonNegativeFinite => "non-negative and finite".into(),
            Range::Finite => "finite".into(),
            Range::LeftOpen(lo, hi) => format!("in ({lo}, {hi}]"),
        }
    }
}

/// One integrator parameter: what it is called, its type, default, accepted values and a
/// one-line doc.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: Kind,
    pub default: DefaultValue,
    pub range: Range,
    /// An unknown enumeration word in the scene file is an error (otherwise a warning and the
    /// default, as pbrt-v3 treats its `strategy` and `lightsamplestrategy`).
    pub strict: bool,
    pub doc: &'static str,
}

impl ParamSpec {
    const fn new(name: &'static str, kind: Kind, default: DefaultValue, doc: &'static str) -> ParamSpec {
        ParamSpec { name, kind, default, range: Range::Any, strict: false, doc }
    }
    pub const fn int(name: &'static str, default: i32, doc: &'static str) -> ParamSpec {
        ParamSpec::new(name, Kind::Int, DefaultValue::Int(default), doc)
    }
    pub const fn float(name: &'static str, default: f32, doc: &'static str) -> ParamSpec {
        ParamSpec::new(name, Kind::Float, DefaultValue::Float(default), doc)
    }
    pub const fn bool(name: &'static str, default: bool, doc: &'static str) -> ParamSpec {
        ParamSpec::new(name, Kind::Bool, DefaultValue::Bool(default), doc)
    }
    /// One of `values`; the first is the default.
    pub const fn choice(name: &'static str, values: &'static [&'static str], doc: &'static str) -> ParamSpec {
        ParamSpec::new(name, Kind::Enum(values), DefaultValue::Str(values[0]), doc)
    }
    /// `n` integers, absent by default (`what` says what happens then).
    pub const fn ints(name: &'static str, n: usize, what: &'static str, doc: &'static str) -> ParamSpec {
        ParamSpec::new(name, Kind::Ints(n), DefaultValue::Unset(what), doc)
    }
    /// Accepts `lo ..= hi` only.
    pub const fn range(self, lo: i32, hi: i32) -> ParamSpec {
        ParamSpec { range: Range::Int(lo, hi), ..self }
    }
    pub const fn within(self, range: Range) -> ParamSpec {
        ParamSpec { range, ..self }
    }
    /// Absent by default (`what` says what happens then).
    pub const fn unset(self, what: &'static str) -> ParamSpec {
        ParamSpec { default: DefaultValue::Unset(what), ..self }
    }
    /// An unknown enumeration word is an error, in the scene file too.
    pub const fn strict(self) -> ParamSpec {
        ParamSpec { strict: true, ..self }
    }

    /// `"<type> <name>"` as a scene file writes it.
    pub fn declaration(&self) -> String {
        format!("{} {}", self.kind.pbrt_type(), self.name)
    }

    /// The range error for `got`, or `None` when it is accepted.
    fn range_error(&self, owner: &str, got: &dyn std::fmt::Display, ok: bool) -> Option<String> {
        (!ok).then(|| format!("{owner}: \"{}\" must be {}, got {got}", self.name, self.range.describe()))
    }

    /// A command-line parameter (its type inferred from its text) as this parameter's type,
    /// checked against its range and values: an integer is accepted for a float, a number or
    /// a word for a string. `Err` says what was expected.
    pub fn conform(&self, owner: &str, p: &Param) -> Result<Param, String> {
        let expected = |what: &str| format!("{owner}: \"{}\" expects {what}, got \"{}\"", self.name, text_of(&p.value));
        let value = match (self.kind, &p.value) {
            (Kind::Int, ParamValue::Int(v)) if v.len() == 1 => {
                if let Some(e) = self.range_error(owner, &v[0], self.range.contains_int(v[0])) {
                    return Err(e);
                }
                ParamValue::Int(v.clone())
            }
            (Kind::Int, _) => return Err(expected("an integer")),
            (Kind::Float, ParamValue::Int(v)) if v.len() == 1 => ParamValue::Float(vec![v[0] as f32]),
            (Kind::Float, ParamValue::Float(v)) if v.len() == 1 => ParamValue::Float(v.clone()),
            (Kind::Float, _) => return Err(expected("a number")),
            (Kind::Bool, ParamValue::Bool(v)) => ParamValue::Bool(v.clone()),
            (Kind::Bool, _) => return Err(expected("a bool (true or false)")),
            (Kind::String, v) => ParamValue::String(vec![text_of(v)]),
            (Kind::Enum(values), v) => {
                let word = text_of(v);
                if !values.contains(&word.as_str()) {
                    return Err(expected(&format!("one of {}", values.join(", "))));
                }
                ParamValue::String(vec![word])
            }
            (Kind::Ints(n), ParamValue::Int(v)) if v.len() == n => ParamValue::Int(v.clone()),
            (Kind::Ints(n), _) => return Err(expected(&format!("{n} comma-separated integers"))),
        };
        if let ParamValue::Float(v) = &value {
            if let Some(e) = self.range_error(owner, &v[0], self.range.contains_float(v[0])) {
                return Err(e);
            }
        }
        Ok(Param::new(p.name.clone(), value, p.loc.clone()))
    }
}

/// A command-line value as the user typed it (near enough: numbers re-printed).
fn text_of(v: &ParamValue) -> String {
    fn join<T: ToString>(v: &[T]) -> String {
        v.iter().map(T::to_string).collect::<Vec<_>>().join(",")
    }
    match v {
        ParamValue::Int(x) => join(x),
        ParamValue::Float(x) => join(x),
        ParamValue::Bool(x) => join(x),
        ParamValue::String(x) => x.join(","),
        other => other.type_name().to_string(),
    }
}

/// An integrator's parameter values, read through its [`ParamSpec`]s.
pub struct Params<'a> {
    owner: &'static str,
    specs: &'static [ParamSpec],
    set: &'a ParamSet,
    warnings: &'a DiagSink,
}

impl<'a> Params<'a> {
    /// `owner` is the integrator's registered name (messages start with it).
    pub fn new(owner: &'static str, specs: &'static [ParamSpec], set: &'a ParamSet, warnings: &'a DiagSink) -> Self {
        Params { owner, specs, set, warnings }
    }

    pub fn set(&self) -> &'a ParamSet {
        self.set
    }

    pub fn warnings(&self) -> &'a DiagSink {
        self.warnings
    }

    /// The declared parameter `name` of type `kind` (a mismatch is the integrator's bug,
    /// reported as an error rather than a panic).
    fn spec(&self, name: &str, kind: fn(&Kind) -> bool) -> Result<&'static ParamSpec, Diagnostic> {
        self.specs.iter().find(|s| s.name == name && kind(&s.kind)).ok_or_else(|| {
            Diagnostic::error(None, format!("{}: internal error: parameter \"{name}\" is not declared", self.owner))
        })
    }

    fn out_of_range(&self, spec: &ParamSpec, got: &dyn std::fmt::Display, ok: bool) -> Result<(), Diagnostic> {
        match spec.range_error(self.owner, got, ok) {
            Some(msg) => Err(Diagnostic::error(self.set.loc_of(spec.name).cloned(), msg)),
            None => Ok(()),
        }
    }

    pub fn int(&self, name: &str) -> Result<i32, Diagnostic> {
        let spec = self.spec(name, |k| *k == Kind::Int)?;
        let default = match spec.default {
            DefaultValue::Int(d) => d,
            _ => 0,
        };
        let v = self.set.get_one_int(name, default);
        self.out_of_range(spec, &v, spec.range.contains_int(v))?;
        Ok(v)
    }

    /// An integer whose range excludes negative values.
    pub fn count(&self, name: &str) -> Result<u32, Diagnostic> {
        let v = self.int(name)?;
        u32::try_from(v).map_err(|_| {
            Diagnostic::error(
                self.set.loc_of(name).cloned(),
                format!("{}: \"{name}\" must not be negative, got {v}", self.owner),
            )
        })
    }

    pub fn float(&self, name: &str) -> Result<f32, Diagnostic> {
        let spec = self.spec(name, |k| *k == Kind::Float)?;
        let default = match spec.default {
            DefaultValue::Float(d) => d,
            _ => 0.0,
        };
        let v = self.set.get_one_float(name, default);
        self.out_of_range(spec, &v, spec.range.contains_float(v))?;
        Ok(v)
    }

    pub fn bool(&self, name: &str) -> Result<bool, Diagnostic> {
        let spec = self.spec(name, |k| *k == Kind::Bool)?;
        Ok(self.set.get_one_bool(name, spec.default == DefaultValue::Bool(true)))
    }

    /// The integers of `name`, if given (of any count: the caller says what a wrong one means).
    pub fn ints(&self, name: &str) -> Result<Option<&'a [i32]>, Diagnostic> {
        self.spec(name, |k| matches!(k, Kind::Ints(_)))?;
        Ok(self.set.get_ints(name))
    }

    /// The enumeration `name` as `values[i]` for its `i`-th word. An unknown word warns and
    /// gives the default, or is an error for a strict parameter.
    pub fn choice<T: Copy, const N: usize>(&self, name: &str, values: [T; N]) -> Result<T, Diagnostic> {
        self.choice_or_unset(name, values)?.ok_or_else(|| {
            Diagnostic::error(None, format!("{}: internal error: \"{name}\" has no default", self.owner))
        })
    }

    /// [`Params::choice`] for a parameter without a default: `None` when it is not given.
    pub fn choice_or_unset<T: Copy, const N: usize>(
        &self,
        name: &str,
        values: [T; N],
    ) -> Result<Option<T>, Diagnostic> {
        let spec = self.spec(name, |k| matches!(k, Kind::Enum(_)))?;
        let Kind::Enum(words) = spec.kind else { unreachable!("spec() checked the kind") };
        if words.len() != N {
            return Err(Diagnostic::error(
                None,
                format!("{}: internal error: \"{name}\" has {} words and {N} values", self.owner, words.len()),
            ));
        }
        let Some(word) = self.set.get_strings(name).and_then(|v| v.first()) else {
            return Ok(match spec.default {
                DefaultValue::Str(d) => words.iter().position(|w| *w == d).map(|i| values[i]),
                _ => None,
            });
        };
        if let Some(i) = words.iter().position(|w| w == word) {
            return Ok(Some(values[i]));
        }
        let loc = self.set.loc_of(name).cloned();
        let expected = format!("expected {}", or_list(words));
        match spec.default {
            DefaultValue::Str(d) if !spec.strict => {
                self.warnings
                    .warn(loc, format!("{}: unknown {name} \"{word}\" ({expected}): using \"{d}\"", self.owner));
                Ok(words.iter().position(|w| *w == d).map(|i| values[i]))
            }
            _ => Err(Diagnostic::error(loc, format!("{}: unknown \"{name}\" \"{word}\" ({expected})", self.owner))),
        }
    }
}

/// `a, b or c`.
fn or_list(words: &[&str]) -> String {
    match words {
        [] => String::new(),
        [one] => (*one).to_string(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
    }
}

/// One integrator's parameters as `render --help` lists them: one line each.
pub fn help_text(specs: &[ParamSpec]) -> String {
    let mut o = String::new();
    if specs.is_empty() {
        let _ = writeln!(o, "      (no parameters)");
    }
    for s in specs {
        let range = s.range.describe();
        let range = if range.is_empty() { String::new() } else { format!(", {range}") };
        let _ = writeln!(o, "      {}: {} = {}{range}. {}", s.name, s.kind.describe(), s.default, s.doc);
    }
    o
}

/// One integrator's parameters as its page (docs/integrators/NAME.md) lists them: a table.
pub fn markdown(specs: &[ParamSpec]) -> String {
    let mut o = String::new();
    if specs.is_empty() {
        let _ = writeln!(o, "No parameters.");
        return o;
    }
    let _ = writeln!(o, "| parameter | default | accepts | |");
    let _ = writeln!(o, "|---|---|---|---|");
    for s in specs {
        let accepts = match s.kind {
            Kind::Enum(words) => words.iter().map(|w| format!("`{w}`")).collect::<Vec<_>>().join(", "),
            Kind::Ints(n) => format!("{n} values"),
            _ => s.range.describe(),
        };
        let _ =
            writeln!(o, "| `\"{}\"` | {} | {accepts} | {} |", s.declaration(), s.default, s.doc.replace('|', "\\|"));
    }
    o
}

/// `its parameters: name (type), …`, for command-line errors.
pub fn listing(specs: &[ParamSpec]) -> String {
    if specs.is_empty() {
        return "it has no parameters".to_string();
    }
    let each: Vec<String> = specs.iter().map(|s| format!("{} ({})", s.name, s.kind.describe())).collect();
    format!("its parameters: {}", each.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_parser::FileLoc;
    use std::sync::Arc;

    const SPECS: &[ParamSpec] = &[
        ParamSpec::int("n", 4, "a count").range(1, 8),
        ParamSpec::float("d", f32::INFINITY, "a distance").within(Range::Positive),
        ParamSpec::bool("on", true, "a switch"),
        ParamSpec::choice("mode", &["a", "b"], "a mode"),
        ParamSpec::choice("kind", &["x", "y"], "a strict mode").strict(),
    ];

    fn set(params: &[(&str, ParamValue)]) -> ParamSet {
        let mut ps = ParamSet::new();
        for (i, (n, v)) in params.iter().enumerate() {
            ps.add(Param::new(*n, v.clone(), FileLoc::new(Arc::from("s.pbrt"), i as u32 + 3, 5)));
        }
        ps
    }

    #[test]
    fn reads_defaults_and_values() {
        let w = DiagSink::new();
        let empty = set(&[]);
        let p = Params::new("t", SPECS, &empty, &w);
        assert_eq!(p.int("n").unwrap(), 4);
        assert_eq!(p.float("d").unwrap(), f32::INFINITY);
        assert!(p.bool("on").unwrap());
        assert_eq!(p.choice("mode", [1, 2]).unwrap(), 1);
        let given = set(&[("n", ParamValue::Int(vec![8])), ("mode", ParamValue::String(vec!["b".into()]))]);
        let p = Params::new("t", SPECS, &given, &w);
        assert_eq!(p.int("n").unwrap(), 8);
        assert_eq!(p.choice("mode", [1, 2]).unwrap(), 2);
        assert!(given.report_unused("t").is_empty());
        assert!(w.take().is_empty());
    }

    #[test]
    fn range_and_enum_errors_are_located() {
        let w = DiagSink::new();
        let bad = set(&[
            ("n", ParamValue::Int(vec![9])),
            ("d", ParamValue::Float(vec![0.0])),
            ("mode", ParamValue::String(vec!["c".into()])),
            ("kind", ParamValue::String(vec!["z".into()])),
        ]);
        let p = Params::new("t", SPECS, &bad, &w);
        let e = p.int("n").unwrap_err();
        assert_eq!(e.message, "t: \"n\" must be in 1..=8, got 9");
        assert_eq!(e.loc.as_ref().map(|l| l.line), Some(3));
        assert!(p.float("d").unwrap_err().message.contains("must be positive"));
        assert_eq!(p.choice("mode", [1, 2]).unwrap(), 1);
        let warned = w.take();
        assert_eq!(warned.len(), 1);
        assert!(
            warned[0].message.contains("unknown mode \"c\" (expected a or b): using \"a\""),
            "{}",
            warned[0].message
        );
        let e = p.choice("kind", [1, 2]).unwrap_err();
        assert_eq!(e.loc.as_ref().map(|l| l.line), Some(6));
        // A value list of the wrong length and an undeclared name are errors, not panics.
        assert!(p.choice("mode", [1, 2, 3]).is_err());
        assert!(p.int("missing").is_err());
    }

    #[test]
    fn conform_converts_and_rejects() {
        let loc = FileLoc::new(Arc::from("<command line>"), 1, 1);
        let p = |n: &str, v: ParamValue| Param::new(n, v, loc.clone());
        let f = SPECS[1].conform("t", &p("d", ParamValue::Int(vec![1]))).unwrap();
        assert_eq!(f.value, ParamValue::Float(vec![1.0]));
        let e = SPECS[0].conform("t", &p("n", ParamValue::Float(vec![2.5]))).unwrap_err();
        assert_eq!(e, "t: \"n\" expects an integer, got \"2.5\"");
        let e = SPECS[2].conform("t", &p("on", ParamValue::String(vec!["flase".into()]))).unwrap_err();
        assert!(e.contains("expects a bool"), "{e}");
        assert!(SPECS[0].conform("t", &p("n", ParamValue::Int(vec![0]))).unwrap_err().contains("1..=8"));
        assert!(SPECS[3]
            .conform("t", &p("mode", ParamValue::String(vec!["c".into()])))
            .unwrap_err()
            .contains("one of a, b"));
    }
}
