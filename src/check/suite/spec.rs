//! The suite file: TOML, a `[defaults]` table and one `[[case]]` table per image, both with
//! the keys of [`KEYS`]. Paths are relative to the suite file. Every error names
//! `file:line:column`.

use std::path::{Path, PathBuf};
use toml_edit::{Item, Table, Value};

/// How a case's reference is weighed (the gate's modes, and the noise-free tolerance test).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Both noisy, both with variance channels: Welch's t per value (the A/B test).
    Welch,
    /// The reference is converged: a z-test on the test's variance alone.
    Converged,
    /// The same estimator made both (a pbrt-v3 reference has no variance channels).
    SameEstimator,
    /// Noise-free integrators: `|d| <= abs + rel*|ref|` alone.
    Tolerance,
}

/// Who renders a missing reference under `--make-references`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Renderer {
    Penumbra,
    /// pbrt-v3's binary (`--pbrt PATH` or the case's `pbrt = "PATH"`), on the scene file as is.
    Pbrt,
}

/// One render-and-check.
#[derive(Clone, Debug)]
pub struct Case {
    pub name: String,
    /// `file:line:column` of the case's table, for messages.
    pub at: String,
    /// `None`: the embedded default scene.
    pub scene: Option<PathBuf>,
    pub integrator: Option<String>,
    pub params: Vec<String>,
    pub spp: Option<u32>,
    pub seed: u64,
    pub resolution: Option<(u32, u32)>,
    pub sampler: Option<String>,
    /// `None`: the reference is rendered afresh every run (A/B of two penumbra renders).
    pub reference: Option<PathBuf>,
    pub reference_spp: Option<u32>,
    pub reference_seed: u64,
    pub reference_integrator: Option<String>,
    pub reference_params: Vec<String>,
    pub reference_renderer: Renderer,
    pub pbrt: Option<PathBuf>,
    pub kind: Kind,
    pub abs: Option<f64>,
    pub rel: Option<f64>,
    pub alpha: Option<f64>,
    pub fail_percent: Option<f64>,
    pub block: Option<usize>,
}

/// The keys a case (or `[defaults]`) may set.
pub const KEYS: &[&str] = &[
    "name",
    "scene",
    "integrator",
    "params",
    "spp",
    "seed",
    "resolution",
    "sampler",
    "reference",
    "reference_spp",
    "reference_seed",
    "reference_integrator",
    "reference_params",
    "reference_renderer",
    "pbrt",
    "kind",
    "abs",
    "rel",
    "alpha",
    "fail_percent",
    "block",
];

/// The default seed offset of a reference rendered by penumbra: independent of the test's.
pub const REFERENCE_SEED_OFFSET: u64 = 1_000_003;

struct Src<'a> {
    file: &'a Path,
    text: &'a str,
}

impl Src<'_> {
    fn at(&self, span: Option<std::ops::Range<usize>>) -> String {
        let start = span.map(|s| s.start).unwrap_or(0).min(self.text.len());
        let before = &self.text[..start];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map(|l| l.chars().count()).unwrap_or(0) + 1;
        format!("{}:{line}:{col}", self.file.display())
    }

    fn err(&self, item: &Item, msg: impl std::fmt::Display) -> String {
        format!("{}: {msg}", self.at(item.span()))
    }
}

/// A case's keys: its own table over `[defaults]`.
struct Fields<'a> {
    src: &'a Src<'a>,
    own: &'a Table,
    defaults: Option<&'a Table>,
}

impl<'a> Fields<'a> {
    fn get(&self, key: &str) -> Option<&'a Item> {
        self.own.get(key).or_else(|| self.defaults.and_then(|d| d.get(key)))
    }

    fn value(&self, key: &str) -> Result<Option<(&'a Item, &'a Value)>, String> {
        match self.get(key) {
            None => Ok(None),
            Some(i) => match i.as_value() {
                Some(v) => Ok(Some((i, v))),
                None => Err(self.src.err(i, format!("`{key}` must be a value, not a table"))),
            },
        }
    }

    fn string(&self, key: &str) -> Result<Option<String>, String> {
        match self.value(key)? {
            None => Ok(None),
            Some((i, v)) => v
                .as_str()
                .map(|s| Some(s.to_string()))
                .ok_or_else(|| self.src.err(i, format!("`{key}` must be a string"))),
        }
    }

    fn path(&self, key: &str, dir: &Path) -> Result<Option<PathBuf>, String> {
        Ok(self.string(key)?.map(|s| dir.join(s)))
    }

    fn uint(&self, key: &str) -> Result<Option<u64>, String> {
        match self.value(key)? {
            None => Ok(None),
            Some((i, v)) => match v.as_integer() {
                Some(n) if n >= 0 => Ok(Some(n as u64)),
                _ => Err(self.src.err(i, format!("`{key}` must be a non-negative integer"))),
            },
        }
    }

    fn number(&self, key: &str) -> Result<Option<f64>, String> {
        match self.value(key)? {
            None => Ok(None),
            Some((i, v)) => match v.as_float().or_else(|| v.as_integer().map(|n| n as f64)) {
                Some(x) if x.is_finite() && x >= 0.0 => Ok(Some(x)),
                _ => Err(self.src.err(i, format!("`{key}` must be a non-negative number"))),
            },
        }
    }

    fn strings(&self, key: &str) -> Result<Vec<String>, String> {
        match self.value(key)? {
            None => Ok(Vec::new()),
            Some((i, v)) => {
                let bad = || self.src.err(i, format!("`{key}` must be an array of strings like [\"maxdepth=5\"]"));
                let a = v.as_array().ok_or_else(bad)?;
                a.iter().map(|s| s.as_str().map(str::to_string).ok_or_else(bad)).collect()
            }
        }
    }

    fn u32_of(&self, key: &str) -> Result<Option<u32>, String> {
        match self.uint(key)? {
            Some(n) if n == 0 || n > u32::MAX as u64 => {
                Err(self.src.err(self.get(key).unwrap_or(&Item::None), format!("`{key}` must lie in 1..=2^32-1")))
            }
            n => Ok(n.map(|n| n as u32)),
        }
    }
}

fn check_keys(src: &Src, t: &Table, what: &str) -> Result<(), String> {
    for (k, item) in t.iter() {
        if !KEYS.contains(&k) {
            let at = t.key(k).and_then(|key| key.span()).or_else(|| item.span());
            return Err(format!("{}: unknown key `{k}` in {what} (known: {})", src.at(at), KEYS.join(", ")));
        }
    }
    Ok(())
}

/// Reads a suite file.
pub fn read(path: &Path) -> Result<Vec<Case>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse(&text, path)
}

/// Parses a suite's text (`file` names it in messages and anchors its relative paths).
pub fn parse(text: &str, file: &Path) -> Result<Vec<Case>, String> {
    let src = Src { file, text };
    let doc = toml_edit::Document::parse(text).map_err(|e| {
        let at = src.at(e.span());
        format!("{at}: {}", e.message())
    })?;
    let root = doc.as_table();
    for (k, item) in root.iter() {
        if !matches!(k, "defaults" | "case") {
            return Err(src.err(item, format!("unknown top-level key `{k}` (a suite has [defaults] and [[case]])")));
        }
    }
    let defaults = match root.get("defaults") {
        None => None,
        Some(i) => Some(i.as_table().ok_or_else(|| src.err(i, "`defaults` must be a table: [defaults]"))?),
    };
    if let Some(d) = defaults {
        check_keys(&src, d, "[defaults]")?;
    }
    let Some(cases) = root.get("case") else {
        return Err(format!("{}: no [[case]] tables", file.display()));
    };
    let cases =
        cases.as_array_of_tables().ok_or_else(|| src.err(cases, "`case` must be an array of tables: [[case]]"))?;
    let dir = file.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut out: Vec<Case> = Vec::new();
    for t in cases.iter() {
        check_keys(&src, t, "[[case]]")?;
        let c = case(&Fields { src: &src, own: t, defaults }, &dir, src.at(t.span()))?;
        if let Some(prev) = out.iter().find(|p| p.name == c.name) {
            return Err(format!("{}: a second case named {:?} (first at {})", c.at, c.name, prev.at));
        }
        out.push(c);
    }
    Ok(out)
}

fn kind(f: &Fields) -> Result<Kind, String> {
    let k = f.string("kind")?.unwrap_or_else(|| "welch".into());
    Ok(match k.as_str() {
        "welch" => Kind::Welch,
        "converged" => Kind::Converged,
        "same-estimator" => Kind::SameEstimator,
        "tolerance" => Kind::Tolerance,
        other => {
            let item = f.get("kind").unwrap_or(&Item::None);
            return Err(f
                .src
                .err(item, format!("`kind` must be welch, converged, same-estimator or tolerance, got {other:?}")));
        }
    })
}

fn resolution(f: &Fields) -> Result<Option<(u32, u32)>, String> {
    let Some((i, v)) = f.value("resolution")? else { return Ok(None) };
    let bad = || f.src.err(i, "`resolution` must be [width, height] with positive integers");
    let a = v.as_array().ok_or_else(bad)?;
    let n: Vec<i64> = a.iter().map(|x| x.as_integer().ok_or_else(bad)).collect::<Result<_, _>>()?;
    match n[..] {
        [w, h] if w > 0 && h > 0 && w <= u32::MAX as i64 && h <= u32::MAX as i64 => Ok(Some((w as u32, h as u32))),
        _ => Err(bad()),
    }
}

fn case(f: &Fields, dir: &Path, at: String) -> Result<Case, String> {
    let name = f
        .own
        .get("name")
        .and_then(|i| i.as_str())
        .map(str::to_string)
        .ok_or_else(|| format!("{at}: every [[case]] needs a `name` (a string)"))?;
    if name.is_empty() || name.chars().any(|c| !(c.is_ascii_alphanumeric() || "-_.".contains(c))) {
        return Err(format!("{at}: case name {name:?} must be non-empty ASCII letters, digits, '-', '_' or '.'"));
    }
    let seed = f.uint("seed")?.unwrap_or(0);
    let renderer = match f.string("reference_renderer")?.as_deref() {
        None | Some("penumbra") => Renderer::Penumbra,
        Some("pbrt") | Some("pbrt-v3") => Renderer::Pbrt,
        Some(o) => {
            let item = f.get("reference_renderer").unwrap_or(&Item::None);
            return Err(f.src.err(item, format!("`reference_renderer` must be penumbra or pbrt, got {o:?}")));
        }
    };
    let c = Case {
        name,
        scene: f.path("scene", dir)?,
        integrator: f.string("integrator")?,
        params: f.strings("params")?,
        spp: f.u32_of("spp")?,
        seed,
        resolution: resolution(f)?,
        sampler: f.string("sampler")?,
        reference: f.path("reference", dir)?,
        reference_spp: f.u32_of("reference_spp")?,
        reference_seed: f.uint("reference_seed")?.unwrap_or(seed.wrapping_add(REFERENCE_SEED_OFFSET)),
        reference_integrator: f.string("reference_integrator")?,
        reference_params: f.strings("reference_params")?,
        reference_renderer: renderer,
        pbrt: f.path("pbrt", dir)?,
        kind: kind(f)?,
        abs: f.number("abs")?,
        rel: f.number("rel")?,
        alpha: f.number("alpha")?,
        fail_percent: f.number("fail_percent")?,
        block: f.uint("block")?.map(|b| b as usize),
        at,
    };
    validate(&c)?;
    Ok(c)
}

fn validate(c: &Case) -> Result<(), String> {
    if c.kind == Kind::Tolerance && c.abs.is_none() && c.rel.is_none() {
        return Err(format!("{}: case {:?}: kind = \"tolerance\" needs `abs` and/or `rel`", c.at, c.name));
    }
    if c.reference.is_none() && c.reference_renderer == Renderer::Pbrt {
        return Err(format!(
            "{}: case {:?}: a pbrt-v3 reference needs a `reference` path (it is rendered once, by --make-references)",
            c.at, c.name
        ));
    }
    if c.reference_renderer == Renderer::Pbrt && c.scene.is_none() {
        return Err(format!("{}: case {:?}: a pbrt-v3 reference needs a `scene` file", c.at, c.name));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_example_suite_parses() {
        let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/check/example.toml");
        let cases = read(&file).expect("example suite");
        assert_eq!(cases.len(), 3);
        assert_eq!(cases[0].kind, Kind::Welch);
        assert!(cases[0].reference.is_none() && cases[0].reference_integrator.as_deref() == Some("directlighting"));
        assert_eq!(cases[0].resolution, Some((32, 32)), "from [defaults]");
        assert_eq!(cases[0].reference_seed, 1 + REFERENCE_SEED_OFFSET);
        assert_eq!(cases[1].kind, Kind::Converged);
        assert_eq!(cases[1].reference_spp, Some(1024));
        assert_eq!(cases[2].kind, Kind::Tolerance);
        assert_eq!((cases[2].abs, cases[2].rel, cases[2].reference_seed), (Some(1e-6), Some(0.001), 0));
    }

    #[test]
    fn errors_name_file_line_column() {
        let f = Path::new("s.toml");
        let e = |t: &str| parse(t, f).expect_err(t);
        assert!(e("[[case]]\nname = \"a\"\nspp = -3\n").starts_with("s.toml:3:7: `spp`"));
        assert!(e("[[case]]\nname = \"a\"\nkind = \"fuzzy\"\n").starts_with("s.toml:3:8: `kind` must be"));
        assert!(e("[[case]]\nname = \"a\"\n[[case]]\nname = \"a\"\n").contains("a second case named \"a\""));
        assert!(e("[[case]]\nspp = 4\n").contains("needs a `name`"));
        assert!(e("[[case]\n").starts_with("s.toml:1:"), "{}", e("[[case]\n"));
        assert!(e("[defaults]\nspp = 4\n").contains("no [[case]] tables"));
        assert!(e("[[case]]\nname = \"a\"\nresolution = [32]\n").starts_with("s.toml:3:14: `resolution`"));
        assert!(e("[[case]]\nname = \"a\"\nreference_renderer = \"pbrt\"\n").contains("needs a `reference` path"));
    }
}
