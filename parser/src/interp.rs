//! The pbrt-v3 graphics state: directives in, a flat [`SceneDescription`] out.
//!
//! The interpreter pulls tokens from a stack of [`Lexer`]s (one per open
//! `Include`), keeps pbrt-v3's state (CTM pair and active-transform bits,
//! attribute and transform stacks, named coordinate systems, scoped texture
//! and named-material namespaces, current material / area light / media /
//! reverse orientation, the open object definition) and emits every entity
//! with the state already applied: transforms composed, textures and
//! materials resolved to indices.

use crate::diag::{Diagnostic, FileLoc, Severity};
use crate::lexer::{Kind, Lexer, CHUNK};
use crate::number::{looks_numeric, parse_f32, parse_f64, parse_i32, show};
use crate::params::{Param, ParamSet, ParamValue, SpectrumValue, TextureRef};
use crate::scene::*;
use crate::transform::{AnimatedTransform, Matrix4, Transform};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Deepest `Include` nesting accepted.
pub(crate) const MAX_INCLUDE_DEPTH: usize = 64;
/// Deepest `AttributeBegin`/`TransformBegin`/`ObjectBegin` nesting accepted.
pub(crate) const MAX_NESTING: usize = 10_000;

type R<T> = Result<T, Diagnostic>;

/// A namespace whose definitions are undone at `AttributeEnd`: each name maps
/// to a stack of definitions, and a log of names defined lets a scope be popped
/// without copying the maps at every `AttributeBegin`.
struct Scoped<T: Copy> {
    map: HashMap<String, Vec<T>>,
    log: Vec<String>,
}

impl<T: Copy> Scoped<T> {
    fn new() -> Self {
        Scoped { map: HashMap::new(), log: Vec::new() }
    }
    fn define(&mut self, name: &str, v: T) {
        self.map.entry(name.to_string()).or_default().push(v);
        self.log.push(name.to_string());
    }
    fn get(&self, name: &str) -> Option<T> {
        self.map.get(name).and_then(|v| v.last().copied())
    }
    fn mark(&self) -> usize {
        self.log.len()
    }
    fn restore(&mut self, mark: usize) {
        while self.log.len() > mark {
            if let Some(n) = self.log.pop() {
                if let Some(v) = self.map.get_mut(&n) {
                    v.pop();
                    if v.is_empty() {
                        self.map.remove(&n);
                    }
                }
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum CurMat {
    /// pbrt-v3's initial `matte` with no parameters.
    Default,
    /// `Material "none"`/`""`.
    Interface,
    Index(usize),
}

#[derive(Clone, Debug)]
struct Gs {
    mat: CurMat,
    reverse: bool,
    area_light: Option<usize>,
    inside: Option<String>,
    outside: Option<String>,
}

struct Frame {
    gs: Gs,
    marks: [usize; 3],
    loc: FileLoc,
}

struct Source {
    lex: Lexer,
    /// Canonical path, for include-cycle detection (`None` for in-memory text).
    canon: Option<PathBuf>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Ty {
    Int,
    Float,
    Point2,
    Vector2,
    Point3,
    Vector3,
    Normal,
    Rgb,
    Xyz,
    Blackbody,
    Spectrum,
    Bool,
    Str,
    Texture,
}

const TYPE_NAMES: &str =
    "integer, float, point2, vector2, point3/point, vector3/vector, normal, rgb/color, xyz, blackbody, spectrum, bool, string, texture";

fn lookup_type(t: &str) -> Option<Ty> {
    Some(match t {
        "integer" => Ty::Int,
        "float" => Ty::Float,
        "point2" => Ty::Point2,
        "vector2" => Ty::Vector2,
        "point3" | "point" => Ty::Point3,
        "vector3" | "vector" => Ty::Vector3,
        "normal" => Ty::Normal,
        "rgb" | "color" => Ty::Rgb,
        "xyz" => Ty::Xyz,
        "blackbody" => Ty::Blackbody,
        "spectrum" => Ty::Spectrum,
        "bool" => Ty::Bool,
        "string" => Ty::Str,
        "texture" => Ty::Texture,
        _ => return None,
    })
}

pub(crate) struct Interp {
    files: Vec<Source>,
    base_dir: PathBuf,
    main_file: Option<PathBuf>,
    warnings: Vec<Diagnostic>,

    camera: Option<CameraDesc>,
    film: Option<Entity>,
    sampler: Option<Entity>,
    filter: Option<Entity>,
    integrator: Option<Entity>,
    accelerator: Option<Entity>,
    transform_times: (f32, f32),
    shapes: Vec<ShapeDesc>,
    lights: Vec<LightDesc>,
    area_lights: Vec<Entity>,
    materials: Vec<MaterialDesc>,
    textures: Vec<TextureDesc>,
    media: Vec<MediumDesc>,
    instance_definitions: Vec<InstanceDefinition>,
    instances: Vec<InstanceUse>,
    files_read: Vec<PathBuf>,

    ctm: [Transform; 2],
    active: u8,
    named_cs: HashMap<String, [Transform; 2]>,
    gs: Gs,
    float_tex: Scoped<usize>,
    spec_tex: Scoped<usize>,
    named_mat: Scoped<Option<usize>>,
    attr_stack: Vec<Frame>,
    tf_stack: Vec<([Transform; 2], u8)>,
    in_world: bool,
    /// An options-block directive has been seen (so the file is not a world fragment).
    saw_options: bool,
    /// A `WorldBegin` was read (a world-block fragment parsed standalone has none).
    saw_world_begin: bool,
    world_ended: bool,
    current_instance: Option<usize>,
    instance_names: HashMap<String, usize>,
    default_material: Option<usize>,
}

impl Interp {
    pub(crate) fn new(lex: Lexer, canon: Option<PathBuf>, base_dir: PathBuf, main_file: Option<PathBuf>) -> Interp {
        Interp {
            files: vec![Source { lex, canon }],
            base_dir,
            files_read: main_file.iter().cloned().collect(),
            main_file,
            warnings: vec![],
            camera: None,
            film: None,
            sampler: None,
            filter: None,
            integrator: None,
            accelerator: None,
            transform_times: (0.0, 1.0),
            shapes: vec![],
            lights: vec![],
            area_lights: vec![],
            materials: vec![],
            textures: vec![],
            media: vec![],
            instance_definitions: vec![],
            instances: vec![],
            ctm: [Transform::IDENTITY; 2],
            active: 3,
            named_cs: HashMap::new(),
            gs: Gs { mat: CurMat::Default, reverse: false, area_light: None, inside: None, outside: None },
            float_tex: Scoped::new(),
            spec_tex: Scoped::new(),
            named_mat: Scoped::new(),
            attr_stack: vec![],
            tf_stack: vec![],
            in_world: false,
            saw_options: false,
            saw_world_begin: false,
            world_ended: false,
            current_instance: None,
            instance_names: HashMap::new(),
            default_material: None,
        }
    }

    // ---- diagnostics -------------------------------------------------------

    fn diag(&self, severity: Severity, loc: FileLoc, msg: impl Into<String>) -> Diagnostic {
        let mut d = Diagnostic::error(None, msg);
        d.severity = severity;
        let mut line = None;
        if let Some(top) = self.files.last() {
            if top.lex.file == loc.file && top.lex.line() == loc.line {
                line = top.lex.current_line_text();
            }
        }
        d.source_line = line.or_else(|| crate::source_line(&loc));
        d.loc = Some(loc);
        d
    }
    fn err(&self, loc: FileLoc, msg: impl Into<String>) -> Diagnostic {
        self.diag(Severity::Error, loc, msg)
    }
    fn warn(&mut self, loc: FileLoc, msg: impl Into<String>) {
        let d = self.diag(Severity::Warning, loc, msg);
        self.warnings.push(d);
    }

    // ---- tokens --------------------------------------------------------------

    fn lex(&mut self) -> &mut Lexer {
        // The stack is never empty: the top-level file is only dropped by `finish`.
        let n = self.files.len() - 1;
        &mut self.files[n].lex
    }

    fn lex_err(&self, e: (String, FileLoc)) -> Diagnostic {
        self.err(e.1, e.0)
    }

    /// The next token's kind; at the end of an included file, continues in the includer.
    fn peek(&mut self) -> R<Kind> {
        loop {
            match self.lex().peek() {
                Ok(Kind::Eof) if self.files.len() > 1 => {
                    self.files.pop();
                }
                Ok(k) => return Ok(k),
                Err(e) => return Err(self.lex_err(e)),
            }
        }
    }

    fn here(&mut self) -> FileLoc {
        self.lex().here()
    }

    fn describe(&mut self, k: Kind) -> String {
        match k {
            Kind::Eof => "end of file".into(),
            Kind::LBracket => "'['".into(),
            Kind::RBracket => "']'".into(),
            Kind::Str => format!("string \"{}\"", show(self.lex().text())),
            Kind::Bare => format!("\"{}\"", show(self.lex().text())),
        }
    }

    fn expect_string(&mut self, what: &str) -> R<(String, FileLoc)> {
        let k = self.peek()?;
        let loc = self.here();
        if k != Kind::Str {
            let found = self.describe(k);
            return Err(self.err(loc, format!("{what}: expected a quoted string, found {found}")));
        }
        let s = self.lex().string().map_err(|m| self.err(loc.clone(), m))?;
        self.lex().consume();
        Ok((s, loc))
    }

    fn expect_f64(&mut self, what: &str) -> R<f64> {
        let k = self.peek()?;
        let loc = self.here();
        if k != Kind::Bare {
            let found = self.describe(k);
            return Err(self.err(loc, format!("{what}: expected a number, found {found}")));
        }
        let v = parse_f64(self.lex().text()).map_err(|m| self.err(loc, format!("{what}: {m}")))?;
        self.lex().consume();
        Ok(v)
    }

    fn expect_f64s<const N: usize>(&mut self, what: &str) -> R<[f64; N]> {
        let mut v = [0.0; N];
        for x in v.iter_mut() {
            *x = self.expect_f64(what)?;
        }
        Ok(v)
    }

    fn expect_kind(&mut self, want: Kind, what: &str) -> R<()> {
        let k = self.peek()?;
        if k != want {
            let loc = self.here();
            let found = self.describe(k);
            let w = if want == Kind::LBracket { "'['" } else { "']'" };
            return Err(self.err(loc, format!("{what}: expected {w}, found {found}")));
        }
        self.lex().consume();
        Ok(())
    }

    // ---- parameter lists -----------------------------------------------------

    fn parse_params(&mut self) -> R<ParamSet> {
        let mut ps = ParamSet::new();
        while self.peek()? == Kind::Str {
            let (decl, loc) = self.expect_string("parameter")?;
            let mut words = decl.split([' ', '\t']).filter(|w| !w.is_empty());
            let (Some(tname), Some(name)) = (words.next(), words.next()) else {
                return Err(self.err(
                    loc,
                    format!("parameter declaration \"{decl}\" must be \"type name\" (e.g. \"float radius\")"),
                ));
            };
            let Some(ty) = lookup_type(tname) else {
                return Err(self.err(
                    loc,
                    format!("unknown parameter type \"{tname}\" in \"{decl}\"; expected one of {TYPE_NAMES}"),
                ));
            };
            if words.next().is_some() {
                // `"float radius 2 Shape "sphere"`: a closing quote is missing and the string ran on
                // to the next one.
                return Err(self.err(
                    loc,
                    format!(
                        "parameter declaration \"{decl}\" is more than \"type name\": a closing quote is probably missing (the string runs on to the next '\"')"
                    ),
                ));
            }
            let name = name.to_string();
            let value = self.parse_value(ty, &decl, &name, &loc)?;
            ps.add(Param::new(name, value, loc));
        }
        Ok(ps)
    }

    /// Reads a parameter's value(s): a single token or a bracketed list.
    fn parse_value(&mut self, ty: Ty, decl: &str, name: &str, loc: &FileLoc) -> R<ParamValue> {
        let k = self.peek()?;
        let open = self.here();
        let bracket = match k {
            Kind::LBracket => {
                self.lex().consume();
                true
            }
            Kind::Bare | Kind::Str => false,
            _ => {
                let found = self.describe(k);
                return Err(self.err(open, format!("parameter \"{decl}\" has no value (found {found})")));
            }
        };
        let numeric_ty = !matches!(ty, Ty::Bool | Ty::Str | Ty::Texture);
        // Decide numbers vs strings on the first value (spectrum accepts both).
        let first = self.peek_in_list(bracket, &open, decl)?;
        let strings = match first {
            Some(Kind::Str) => true,
            Some(_) => false,
            None => !numeric_ty,
        };
        if strings && numeric_ty && ty != Ty::Spectrum {
            let l = self.here();
            return Err(self.err(
                l,
                format!(
                    "parameter \"{decl}\": expected numeric values for type \"{}\", found a string",
                    type_label(ty)
                ),
            ));
        }
        if !strings && !numeric_ty {
            let l = self.here();
            let extra =
                if ty == Ty::Bool { " (bool values are the quoted strings \"true\" and \"false\")" } else { "" };
            return Err(self.err(
                l,
                format!(
                    "parameter \"{decl}\": expected quoted string values for type \"{}\", found a number{extra}",
                    type_label(ty)
                ),
            ));
        }
        if strings {
            let vals = self.read_strings(bracket, &open, decl)?;
            return self.string_value(ty, decl, name, loc, vals);
        }
        if ty == Ty::Int {
            let mut v = Vec::new();
            self.read_numbers(bracket, &open, decl, &mut v, parse_i32)?;
            return Ok(ParamValue::Int(v));
        }
        let mut v: Vec<f32> = Vec::new();
        self.read_numbers(bracket, &open, decl, &mut v, parse_f32)?;
        let arity = match ty {
            Ty::Point2 | Ty::Vector2 | Ty::Spectrum | Ty::Blackbody => 2,
            Ty::Point3 | Ty::Vector3 | Ty::Normal | Ty::Rgb | Ty::Xyz => 3,
            _ => 1,
        };
        if ty == Ty::Blackbody && v.len() == 1 {
            self.warn(
                loc.clone(),
                format!(
                    "parameter \"{decl}\": pbrt-v3 blackbody values are (temperature, scale) pairs; \
                     only a temperature was given, using scale 1"
                ),
            );
            v.push(1.0);
        }
        if v.len() / arity * arity != v.len() {
            let what = if matches!(ty, Ty::Spectrum | Ty::Blackbody) { "pairs of" } else { "a multiple of" };
            let n = if matches!(ty, Ty::Spectrum | Ty::Blackbody) { String::new() } else { format!("{arity} ") };
            return Err(self.err(
                loc.clone(),
                format!(
                    "parameter \"{decl}\": type \"{}\" expects {what} {n}values, found {} value{}",
                    type_label(ty),
                    v.len(),
                    if v.len() == 1 { "" } else { "s" }
                ),
            ));
        }
        Ok(match ty {
            Ty::Float => ParamValue::Float(v),
            Ty::Point2 => ParamValue::Point2(v),
            Ty::Vector2 => ParamValue::Vector2(v),
            Ty::Point3 => ParamValue::Point3(v),
            Ty::Vector3 => ParamValue::Vector3(v),
            Ty::Normal => ParamValue::Normal(v),
            Ty::Rgb => ParamValue::Spectrum(SpectrumValue::Rgb(v)),
            Ty::Xyz => ParamValue::Spectrum(SpectrumValue::Xyz(v)),
            Ty::Blackbody => ParamValue::Spectrum(SpectrumValue::Blackbody(v)),
            _ => ParamValue::Spectrum(SpectrumValue::Sampled(v)),
        })
    }

    /// Kind of the next value in a list, or `None` at its end (consuming nothing).
    fn peek_in_list(&mut self, bracket: bool, open: &FileLoc, decl: &str) -> R<Option<Kind>> {
        let k = self.lex().peek().map_err(|e| self.lex_err(e))?;
        match k {
            Kind::RBracket if bracket => Ok(None),
            Kind::Bare | Kind::Str => Ok(Some(k)),
            Kind::Eof if bracket => {
                Err(self.err(open.clone(), format!("unclosed '[' in the value of parameter \"{decl}\"")))
            }
            _ => {
                let l = self.here();
                let found = self.describe(k);
                Err(self.err(l, format!("parameter \"{decl}\": unexpected {found} in its value list")))
            }
        }
    }

    /// The hot loop: numbers straight into `out`.
    fn read_numbers<T>(
        &mut self,
        bracket: bool,
        open: &FileLoc,
        decl: &str,
        out: &mut Vec<T>,
        parse: fn(&[u8]) -> Result<T, String>,
    ) -> R<()> {
        loop {
            let n = self.files.len() - 1;
            let lex = &mut self.files[n].lex;
            match lex.peek() {
                Ok(Kind::Bare) => match parse(lex.text()) {
                    Ok(x) => {
                        out.push(x);
                        lex.consume();
                        if !bracket {
                            return Ok(());
                        }
                    }
                    Err(m) => {
                        let l = lex.here();
                        let t = lex.text();
                        if bracket
                            && t.first().is_some_and(u8::is_ascii_uppercase)
                            && t.iter().all(u8::is_ascii_alphanumeric)
                        {
                            // A directive-like word (`Shape`) where a number should be, inside
                            // brackets: most likely the next directive, after a list whose ']' is
                            // missing.
                            let word = crate::number::show(lex.text());
                            return Err(self.err(
                                open.clone(),
                                format!("unclosed '[' in the value of parameter \"{decl}\": the list runs into \"{word}\" at {l}"),
                            ));
                        }
                        return Err(self.err(l, format!("parameter \"{decl}\": {m}")));
                    }
                },
                Ok(Kind::RBracket) if bracket => {
                    lex.consume();
                    return Ok(());
                }
                Ok(Kind::Str) => {
                    let l = lex.here();
                    return Err(
                        self.err(l, format!("parameter \"{decl}\": mixed strings and numbers in one value list"))
                    );
                }
                Ok(Kind::Eof) if bracket => {
                    return Err(self.err(open.clone(), format!("unclosed '[' in the value of parameter \"{decl}\"")));
                }
                Ok(k) => {
                    let l = lex.here();
                    let found = self.describe(k);
                    return Err(self.err(l, format!("parameter \"{decl}\": unexpected {found} in its value list")));
                }
                Err(e) => return Err(self.lex_err(e)),
            }
        }
    }

    fn read_strings(&mut self, bracket: bool, open: &FileLoc, decl: &str) -> R<Vec<(String, FileLoc)>> {
        let mut out = vec![];
        loop {
            match self.peek_in_list(bracket, open, decl)? {
                None => {
                    self.lex().consume();
                    return Ok(out);
                }
                Some(Kind::Str) => {
                    let l = self.here();
                    let s = self.lex().string().map_err(|m| self.err(l.clone(), m))?;
                    self.lex().consume();
                    out.push((s, l));
                    if !bracket {
                        return Ok(out);
                    }
                }
                Some(_) => {
                    let l = self.here();
                    return Err(
                        self.err(l, format!("parameter \"{decl}\": mixed strings and numbers in one value list"))
                    );
                }
            }
        }
    }

    fn string_value(
        &mut self,
        ty: Ty,
        decl: &str,
        name: &str,
        loc: &FileLoc,
        vals: Vec<(String, FileLoc)>,
    ) -> R<ParamValue> {
        match ty {
            Ty::Str => Ok(ParamValue::String(vals.into_iter().map(|v| v.0).collect())),
            Ty::Bool => {
                let mut out = Vec::with_capacity(vals.len());
                for (s, l) in vals {
                    match s.as_str() {
                        "true" => out.push(true),
                        "false" => out.push(false),
                        _ => {
                            return Err(self.err(
                                l,
                                format!(
                                    "parameter \"{decl}\": bool value must be \"true\" or \"false\", found \"{s}\""
                                ),
                            ))
                        }
                    }
                }
                Ok(ParamValue::Bool(out))
            }
            Ty::Texture => {
                if vals.len() != 1 {
                    return Err(self.err(
                        loc.clone(),
                        format!(
                            "parameter \"{decl}\": a texture parameter takes exactly one name, found {}",
                            vals.len()
                        ),
                    ));
                }
                let tex = vals.into_iter().next().map(|v| v.0).unwrap_or_default();
                let r = TextureRef { float: self.float_tex.get(&tex), spectrum: self.spec_tex.get(&tex), name: tex };
                if r.float.is_none() && r.spectrum.is_none() {
                    self.warn(
                        loc.clone(),
                        format!("parameter \"{decl}\": no texture named \"{}\" is defined in this scope", r.name),
                    );
                }
                Ok(ParamValue::Texture(r))
            }
            Ty::Spectrum => {
                if vals.len() != 1 {
                    return Err(self.err(
                        loc.clone(),
                        format!("parameter \"{decl}\": expected one .spd file name, found {}", vals.len()),
                    ));
                }
                let Some((file, l)) = vals.into_iter().next() else {
                    return Err(self.err(loc.clone(), format!("parameter \"{decl}\": no value")));
                };
                let path = self.resolve(&file);
                let v = read_spd(&path).map_err(|m| {
                    self.err(l, format!("parameter \"{decl}\": cannot read spectrum file \"{}\": {m}", path.display()))
                })?;
                let _ = name;
                self.files_read.push(path);
                Ok(ParamValue::Spectrum(SpectrumValue::Sampled(v)))
            }
            _ => Err(self.err(loc.clone(), format!("parameter \"{decl}\": unexpected string value"))),
        }
    }

    fn resolve(&self, name: &str) -> PathBuf {
        let p = Path::new(name);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }

    // ---- graphics state ----------------------------------------------------

    fn animated(&self) -> AnimatedTransform {
        AnimatedTransform {
            start: self.ctm[0],
            end: self.ctm[1],
            start_time: self.transform_times.0,
            end_time: self.transform_times.1,
        }
    }

    fn for_active(&mut self, f: impl Fn(&Transform) -> Transform) {
        for i in 0..2 {
            if self.active & (1 << i) != 0 {
                self.ctm[i] = f(&self.ctm[i]);
            }
        }
    }

    fn concat(&mut self, t: Transform) {
        self.for_active(|c| c.compose(&t));
    }

    fn warn_if_animated(&mut self, loc: &FileLoc, what: &str) {
        if self.ctm[0] != self.ctm[1] {
            self.warn(
                loc.clone(),
                format!("animated transformations set; ignoring for \"{what}\" and using the start transform only"),
            );
        }
    }

    fn kind_and_params(&mut self, what: &str) -> R<(String, ParamSet)> {
        let (kind, _) = self.expect_string(what)?;
        let params = self.parse_params()?;
        Ok((kind, params))
    }

    fn need_world(&mut self, loc: &FileLoc, what: &str) -> R<()> {
        if !self.in_world && !self.saw_options && !self.world_ended {
            // A file of world-block directives only (an `Include` fragment) parses standalone.
            self.warn(
                loc.clone(),
                format!(
                    "\"{what}\" before any WorldBegin: reading this file as a world-block fragment (as if Included)"
                ),
            );
            self.in_world = true;
            return Ok(());
        }
        if !self.in_world {
            return Err(
                self.err(loc.clone(), format!("\"{what}\" is only allowed inside the world block (after WorldBegin)"))
            );
        }
        Ok(())
    }

    fn need_options(&mut self, loc: &FileLoc, what: &str) -> R<()> {
        self.saw_options = true;
        if self.in_world {
            return Err(self.err(
                loc.clone(),
                format!("options cannot be set inside the world block: \"{what}\" must come before WorldBegin"),
            ));
        }
        Ok(())
    }

    fn push_check(&self, loc: &FileLoc) -> R<()> {
        if self.tf_stack.len() >= MAX_NESTING {
            return Err(self.err(
                loc.clone(),
                format!("AttributeBegin/TransformBegin/ObjectBegin nested more than {MAX_NESTING} deep"),
            ));
        }
        Ok(())
    }

    fn attribute_begin(&mut self, loc: &FileLoc) -> R<()> {
        self.push_check(loc)?;
        self.attr_stack.push(Frame {
            gs: self.gs.clone(),
            marks: [self.float_tex.mark(), self.spec_tex.mark(), self.named_mat.mark()],
            loc: loc.clone(),
        });
        self.tf_stack.push((self.ctm, self.active));
        Ok(())
    }

    fn attribute_end(&mut self, loc: &FileLoc) {
        let Some(f) = self.attr_stack.pop() else {
            self.warn(loc.clone(), "unmatched AttributeEnd; ignoring it");
            return;
        };
        self.gs = f.gs;
        self.float_tex.restore(f.marks[0]);
        self.spec_tex.restore(f.marks[1]);
        self.named_mat.restore(f.marks[2]);
        if let Some((t, a)) = self.tf_stack.pop() {
            self.ctm = t;
            self.active = a;
        }
    }

    fn current_material(&mut self) -> Option<usize> {
        match self.gs.mat {
            CurMat::Interface => None,
            CurMat::Index(i) => Some(i),
            CurMat::Default => Some(*self.default_material.get_or_insert_with(|| {
                self.materials.push(MaterialDesc { entity: Entity::default_of("matte"), name: None });
                self.materials.len() - 1
            })),
        }
    }

    // ---- the directive loop ----------------------------------------------------

    pub(crate) fn run(mut self) -> R<(SceneDescription, Vec<Diagnostic>)> {
        loop {
            let k = self.peek()?;
            let loc = self.here();
            match k {
                Kind::Eof => {
                    if self.saw_world_begin && !self.world_ended {
                        // pbrt-v3 reports an error and renders nothing (issue 41).
                        self.warn(
                            loc,
                            "missing WorldEnd: the scene ends inside the world block; rendering what was read (pbrt-v3 renders nothing without it)",
                        );
                    }
                    break;
                }
                Kind::Bare => {
                    let word = crate::diag::escape_lossy(self.lex().text());
                    self.lex().consume();
                    self.directive(&word, loc)?;
                }
                _ => {
                    let found = self.describe(k);
                    return Err(self.err(loc, format!("expected a directive, found {found}")));
                }
            }
        }
        Ok(self.finish())
    }

    fn directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        if self.world_ended && !matches!(word, "ColorSpace" | "Option" | "Attribute" | "Import") {
            return Err(self
                .err(loc, format!("\"{word}\" after WorldEnd: penumbra renders a single WorldBegin/WorldEnd block")));
        }
        match word {
            "Identity" | "Translate" | "Scale" | "Rotate" | "LookAt" | "Transform" | "ConcatTransform"
            | "CoordinateSystem" | "CoordSysTransform" | "ActiveTransform" | "TransformTimes" => {
                self.transform_directive(word, loc)
            }
            "Camera" | "Film" | "Sampler" | "PixelFilter" | "Integrator" | "Accelerator" | "WorldBegin" => {
                self.options_directive(word, loc)
            }
            "MakeNamedMedium" | "MediumInterface" => self.medium_directive(word, loc),
            "AttributeBegin" | "AttributeEnd" | "TransformBegin" | "TransformEnd" | "ReverseOrientation" => {
                self.block_directive(word, loc)
            }
            "Material" | "MakeNamedMaterial" | "NamedMaterial" | "Texture" => self.material_directive(word, loc),
            "LightSource" | "AreaLightSource" | "Shape" | "ObjectBegin" | "ObjectEnd" | "ObjectInstance" => {
                self.entity_directive(word, loc)
            }
            "WorldEnd" => self.world_end(loc),
            "Include" => {
                let (name, nloc) = self.expect_string(word)?;
                self.include(&name, nloc)
            }
            "ColorSpace" | "Option" | "Attribute" | "Import" => self.skip_pbrt_v4(word, loc),
            _ => Err(self.err(loc, format!("unknown directive \"{}\"", show(word.as_bytes())))),
        }
    }

    /// `Identity` … `TransformTimes` (allowed anywhere): the CTM, the active transform and named coordinate systems.
    fn transform_directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        match word {
            "Identity" => self.for_active(|_| Transform::IDENTITY),
            "Translate" => {
                let v = self.expect_f64s::<3>("Translate")?;
                self.concat(Transform::translate(v));
            }
            "Scale" => {
                let v = self.expect_f64s::<3>("Scale")?;
                let t = Transform::scale(v)
                    .ok_or_else(|| self.err(loc, "Scale: a zero or non-finite factor makes the transform singular"))?;
                self.concat(t);
            }
            "Rotate" => {
                let v = self.expect_f64s::<4>("Rotate")?;
                let t = Transform::rotate(v[0], [v[1], v[2], v[3]])
                    .ok_or_else(|| self.err(loc, "Rotate: the rotation axis has zero length"))?;
                self.concat(t);
            }
            "LookAt" => {
                let v = self.expect_f64s::<9>("LookAt")?;
                let t = Transform::look_at([v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]).ok_or_else(
                    || {
                        self.err(
                            loc,
                            "LookAt: the eye equals the look-at point, or \"up\" is parallel to the viewing direction",
                        )
                    },
                )?;
                self.concat(t);
            }
            "Transform" | "ConcatTransform" => {
                let m = self.read_matrix(word)?;
                let t = Transform::from_matrix(m)
                    .ok_or_else(|| self.err(loc, format!("{word}: the matrix is singular or not finite")))?;
                if word == "Transform" {
                    self.for_active(|_| t);
                } else {
                    self.concat(t);
                }
            }
            "CoordinateSystem" => {
                let (n, _) = self.expect_string(word)?;
                self.named_cs.insert(n, self.ctm);
            }
            "CoordSysTransform" => {
                let (n, nloc) = self.expect_string(word)?;
                match self.named_cs.get(&n) {
                    Some(t) => self.ctm = *t,
                    None => self.warn(nloc, format!("couldn't find named coordinate system \"{n}\"")),
                }
            }
            "ActiveTransform" => {
                let k = self.peek()?;
                let aloc = self.here();
                let arg = if k == Kind::Bare {
                    String::from_utf8_lossy(self.lex().text()).into_owned()
                } else {
                    String::new()
                };
                self.active = match arg.as_str() {
                    "StartTime" => 1,
                    "EndTime" => 2,
                    "All" => 3,
                    _ => {
                        let found = self.describe(k);
                        return Err(
                            self.err(aloc, format!("ActiveTransform expects StartTime, EndTime or All, found {found}"))
                        );
                    }
                };
                self.lex().consume();
            }
            "TransformTimes" => {
                let v = self.expect_f64s::<2>(word)?;
                self.need_options(&loc, word)?;
                self.transform_times = (v[0] as f32, v[1] as f32);
            }
            _ => unreachable!("\"{word}\" is dispatched by `directive` to another group"),
        }
        Ok(())
    }

    /// The options block: camera, film, sampler, filter, integrator, accelerator, and `WorldBegin`.
    fn options_directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        match word {
            "Camera" => {
                let (kind, params) = self.kind_and_params(word)?;
                self.need_options(&loc, word)?;
                let cfw = self.animated();
                let wfc = AnimatedTransform { start: cfw.start.inverse(), end: cfw.end.inverse(), ..cfw };
                self.named_cs.insert("camera".to_string(), [wfc.start, wfc.end]);
                self.camera = Some(CameraDesc {
                    entity: Entity::new(kind, params, loc),
                    camera_from_world: cfw,
                    world_from_camera: wfc,
                    medium: self.gs.outside.clone(),
                });
            }
            "Film" | "Sampler" | "PixelFilter" | "Integrator" | "Accelerator" => {
                let (kind, params) = self.kind_and_params(word)?;
                self.need_options(&loc, word)?;
                let e = Some(Entity::new(kind, params, loc));
                match word {
                    "Film" => self.film = e,
                    "Sampler" => self.sampler = e,
                    "PixelFilter" => self.filter = e,
                    "Integrator" => self.integrator = e,
                    _ => self.accelerator = e,
                }
            }
            "WorldBegin" => {
                self.need_options(&loc, word)?;
                self.in_world = true;
                self.saw_world_begin = true;
                self.ctm = [Transform::IDENTITY; 2];
                self.active = 3;
                self.named_cs.insert("world".to_string(), self.ctm);
            }
            _ => unreachable!("\"{word}\" is dispatched by `directive` to another group"),
        }
        Ok(())
    }

    /// `MakeNamedMedium` and `MediumInterface` (allowed anywhere).
    fn medium_directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        match word {
            "MakeNamedMedium" => {
                let (name, _) = self.expect_string(word)?;
                let params = self.parse_params()?;
                let kind = params.get_one_string("type", "");
                if kind.is_empty() {
                    return Err(self.err(loc, format!("MakeNamedMedium \"{name}\": no \"string type\" parameter")));
                }
                self.warn_if_animated(&loc, word);
                self.media.push(MediumDesc {
                    name,
                    entity: Entity::new(kind, params, loc),
                    render_from_medium: self.animated(),
                });
            }
            "MediumInterface" => {
                let (inside, _) = self.expect_string(word)?;
                let outside = if self.peek()? == Kind::Str { self.expect_string(word)?.0 } else { inside.clone() };
                let nz = |s: String| if s.is_empty() { None } else { Some(s) };
                self.gs.inside = nz(inside);
                self.gs.outside = nz(outside);
            }
            _ => unreachable!("\"{word}\" is dispatched by `directive` to another group"),
        }
        Ok(())
    }

    /// Attribute and transform blocks, and `ReverseOrientation` (world block).
    fn block_directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        match word {
            "AttributeBegin" => {
                self.need_world(&loc, word)?;
                self.attribute_begin(&loc)?;
            }
            "AttributeEnd" => {
                self.need_world(&loc, word)?;
                self.attribute_end(&loc);
            }
            "TransformBegin" => {
                self.need_world(&loc, word)?;
                self.push_check(&loc)?;
                self.tf_stack.push((self.ctm, self.active));
            }
            "TransformEnd" => {
                self.need_world(&loc, word)?;
                match self.tf_stack.pop() {
                    Some((t, a)) => {
                        self.ctm = t;
                        self.active = a;
                    }
                    None => self.warn(loc, "unmatched TransformEnd; ignoring it"),
                }
            }
            "ReverseOrientation" => {
                self.need_world(&loc, word)?;
                self.gs.reverse = !self.gs.reverse;
            }
            _ => unreachable!("\"{word}\" is dispatched by `directive` to another group"),
        }
        Ok(())
    }

    /// Materials, named materials and textures (world block).
    fn material_directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        match word {
            "Material" => {
                let (kind, params) = self.kind_and_params(word)?;
                self.need_world(&loc, word)?;
                if kind.is_empty() || kind == "none" {
                    self.gs.mat = CurMat::Interface;
                } else {
                    self.materials.push(MaterialDesc { entity: Entity::new(kind, params, loc), name: None });
                    self.gs.mat = CurMat::Index(self.materials.len() - 1);
                }
            }
            "MakeNamedMaterial" => {
                let (name, _) = self.expect_string(word)?;
                let params = self.parse_params()?;
                self.need_world(&loc, word)?;
                let kind = params.get_one_string("type", "");
                if kind.is_empty() {
                    return Err(self.err(loc, format!("MakeNamedMaterial \"{name}\": no \"string type\" parameter")));
                }
                self.warn_if_animated(&loc, word);
                if kind == "none" {
                    self.named_mat.define(&name, None);
                } else {
                    self.materials
                        .push(MaterialDesc { entity: Entity::new(kind, params, loc), name: Some(name.clone()) });
                    self.named_mat.define(&name, Some(self.materials.len() - 1));
                }
            }
            "NamedMaterial" => {
                let (name, nloc) = self.expect_string(word)?;
                self.need_world(&loc, word)?;
                match self.named_mat.get(&name) {
                    Some(Some(i)) => self.gs.mat = CurMat::Index(i),
                    Some(None) => self.gs.mat = CurMat::Interface,
                    None => {
                        return Err(self.err(
                            nloc,
                            format!("NamedMaterial: no material named \"{name}\" is defined in this scope"),
                        ))
                    }
                }
            }
            "Texture" => {
                let (name, _) = self.expect_string(word)?;
                let (ty, tloc) = self.expect_string(word)?;
                let (class, _) = self.expect_string(word)?;
                let params = self.parse_params()?;
                self.need_world(&loc, word)?;
                let kind = match ty.as_str() {
                "float" => TextureKind::Float,
                "spectrum" | "color" => TextureKind::Spectrum,
                _ => {
                    return Err(self.err(
                        tloc,
                        format!("Texture \"{name}\": unknown texture type \"{ty}\" (expected \"float\", \"spectrum\" or \"color\")"),
                    ))
                }
            };
                self.warn_if_animated(&loc, word);
                self.textures.push(TextureDesc {
                    name: name.clone(),
                    kind,
                    entity: Entity::new(class, params, loc),
                    render_from_texture: self.animated(),
                });
                let idx = self.textures.len() - 1;
                match kind {
                    TextureKind::Float => self.float_tex.define(&name, idx),
                    TextureKind::Spectrum => self.spec_tex.define(&name, idx),
                }
            }
            _ => unreachable!("\"{word}\" is dispatched by `directive` to another group"),
        }
        Ok(())
    }

    /// Lights, area lights, shapes and object instancing (world block).
    fn entity_directive(&mut self, word: &str, loc: FileLoc) -> R<()> {
        match word {
            "LightSource" => {
                let (kind, params) = self.kind_and_params(word)?;
                self.need_world(&loc, word)?;
                self.warn_if_animated(&loc, word);
                self.lights.push(LightDesc {
                    entity: Entity::new(kind, params, loc),
                    render_from_light: self.animated(),
                    medium: self.gs.outside.clone(),
                });
            }
            "AreaLightSource" => {
                let (kind, params) = self.kind_and_params(word)?;
                self.need_world(&loc, word)?;
                self.area_lights.push(Entity::new(kind, params, loc));
                self.gs.area_light = Some(self.area_lights.len() - 1);
            }
            "Shape" => {
                let (kind, params) = self.kind_and_params(word)?;
                self.need_world(&loc, word)?;
                self.shape(Entity::new(kind, params, loc));
            }
            "ObjectBegin" => {
                let (name, _) = self.expect_string(word)?;
                self.need_world(&loc, word)?;
                if self.current_instance.is_some() {
                    return Err(self.err(loc, format!("ObjectBegin \"{name}\" inside another object definition")));
                }
                self.attribute_begin(&loc)?;
                self.instance_definitions.push(InstanceDefinition { name: name.clone(), shapes: vec![], loc });
                let idx = self.instance_definitions.len() - 1;
                self.instance_names.insert(name, idx);
                self.current_instance = Some(idx);
            }
            "ObjectEnd" => {
                self.need_world(&loc, word)?;
                if self.current_instance.take().is_none() {
                    self.warn(loc.clone(), "ObjectEnd outside of an object definition");
                }
                self.attribute_end(&loc);
            }
            "ObjectInstance" => {
                let (name, nloc) = self.expect_string(word)?;
                self.need_world(&loc, word)?;
                if self.current_instance.is_some() {
                    return Err(self.err(loc, "ObjectInstance can't be used inside an object definition"));
                }
                let Some(&definition) = self.instance_names.get(&name) else {
                    return Err(self.err(nloc, format!("ObjectInstance: no object named \"{name}\" has been defined")));
                };
                self.instances.push(InstanceUse { definition, render_from_instance: self.animated(), loc });
            }
            _ => unreachable!("\"{word}\" is dispatched by `directive` to another group"),
        }
        Ok(())
    }

    /// `WorldEnd`: warns about blocks left open, closes them, and ends the world block.
    fn world_end(&mut self, loc: FileLoc) -> R<()> {
        self.need_world(&loc, "WorldEnd")?;
        if self.current_instance.is_some() {
            self.warn(loc.clone(), "WorldEnd inside an object definition (missing ObjectEnd)");
            self.current_instance = None;
        }
        if let Some(f) = self.attr_stack.last() {
            let n = self.attr_stack.len();
            let first = f.loc.clone();
            self.warn(
                loc.clone(),
                format!(
                    "missing AttributeEnd: {n} AttributeBegin block(s) still open at WorldEnd (innermost at {first})"
                ),
            );
        }
        let open_tf = self.tf_stack.len().saturating_sub(self.attr_stack.len());
        if open_tf > 0 {
            self.warn(
                loc.clone(),
                format!("missing TransformEnd: {open_tf} TransformBegin block(s) still open at WorldEnd"),
            );
        }
        self.attr_stack.clear();
        self.tf_stack.clear();
        self.world_ended = true;
        Ok(())
    }

    /// pbrt-v4's `ColorSpace`, `Option`, `Attribute` and `Import`: a warning, then the
    /// directive's arguments (strings, brackets, numbers, booleans) are skipped.
    fn skip_pbrt_v4(&mut self, word: &str, loc: FileLoc) -> R<()> {
        self.warn(
            loc,
            format!("\"{word}\" is a pbrt-v4 directive: this file looks like pbrt-v4 syntax; skipping \"{word}\" and its arguments"),
        );
        loop {
            match self.peek()? {
                Kind::Str | Kind::LBracket | Kind::RBracket => self.lex().consume(),
                Kind::Bare => {
                    let t = self.lex().text();
                    if looks_numeric(t) || t == b"true" || t == b"false" {
                        self.lex().consume();
                    } else {
                        break;
                    }
                }
                Kind::Eof => break,
            }
        }
        Ok(())
    }
    fn read_matrix(&mut self, what: &str) -> R<Matrix4> {
        self.expect_kind(Kind::LBracket, what)?;
        let v = self.expect_f64s::<16>(what)?;
        self.expect_kind(Kind::RBracket, what)?;
        // The scene gives the matrix column by column (pbrt-v3 transposes on reading).
        let mut m = [[0.0; 4]; 4];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = v[j * 4 + i];
            }
        }
        Ok(m)
    }

    fn shape(&mut self, entity: Entity) {
        let loc = entity.loc.clone();
        let mut area = self.gs.area_light;
        if area.is_some() && self.ctm[0] != self.ctm[1] {
            self.warn(loc.clone(), "ignoring the current area light for an animated shape (as pbrt-v3)");
            area = None;
        }
        if area.is_some() && self.current_instance.is_some() {
            self.warn(loc, "area lights not supported with object instancing; this shape emits no light");
            area = None;
        }
        let material = self.current_material();
        let sd = ShapeDesc {
            entity,
            render_from_object: self.animated(),
            reverse_orientation: self.gs.reverse,
            material,
            area_light: area,
            inside_medium: self.gs.inside.clone(),
            outside_medium: self.gs.outside.clone(),
        };
        match self.current_instance {
            Some(i) => self.instance_definitions[i].shapes.push(sd),
            None => self.shapes.push(sd),
        }
    }

    fn include(&mut self, name: &str, loc: FileLoc) -> R<()> {
        let path = self.resolve(name);
        if self.files.len() >= MAX_INCLUDE_DEPTH {
            return Err(self.err(loc, format!("Include nested more than {MAX_INCLUDE_DEPTH} deep")));
        }
        let canon = std::fs::canonicalize(&path)
            .map_err(|e| self.err(loc.clone(), format!("cannot open included file \"{}\": {e}", path.display())))?;
        if let Some(i) = self.files.iter().position(|f| f.canon.as_ref() == Some(&canon)) {
            let mut chain: Vec<String> = self.files[i..].iter().map(|f| f.lex.file.to_string()).collect();
            chain.push(path.display().to_string());
            return Err(self.err(loc, format!("Include cycle: {}", chain.join(" -> "))));
        }
        let file = std::fs::File::open(&path)
            .map_err(|e| self.err(loc.clone(), format!("cannot open included file \"{}\": {e}", path.display())))?;
        if file.metadata().map(|m| m.is_dir()).unwrap_or(false) {
            return Err(self.err(loc, format!("cannot include \"{}\": it is a directory", path.display())));
        }
        let lex = Lexer::from_reader(Box::new(file), Arc::from(path.display().to_string()), CHUNK);
        self.files_read.push(path);
        self.files.push(Source { lex, canon: Some(canon) });
        Ok(())
    }

    fn finish(mut self) -> (SceneDescription, Vec<Diagnostic>) {
        let times = self.transform_times;
        let mut camera = self.camera.take().unwrap_or_else(|| CameraDesc {
            entity: Entity::default_of("perspective"),
            camera_from_world: AnimatedTransform::default(),
            world_from_camera: AnimatedTransform::default(),
            medium: None,
        });
        // pbrt-v3 builds the camera at the end, with the final TransformTimes.
        for t in [&mut camera.camera_from_world, &mut camera.world_from_camera] {
            t.start_time = times.0;
            t.end_time = times.1;
        }
        let scene = SceneDescription {
            camera,
            film: self.film.unwrap_or_else(|| Entity::default_of("image")),
            sampler: self.sampler.unwrap_or_else(|| Entity::default_of("halton")),
            filter: self.filter.unwrap_or_else(|| Entity::default_of("box")),
            integrator: self.integrator.unwrap_or_else(|| Entity::default_of("path")),
            accelerator: self.accelerator.unwrap_or_else(|| Entity::default_of("bvh")),
            transform_times: times,
            shapes: self.shapes,
            lights: self.lights,
            area_lights: self.area_lights,
            materials: self.materials,
            textures: self.textures,
            media: self.media,
            instance_definitions: self.instance_definitions,
            instances: self.instances,
            main_file: self.main_file,
            base_dir: self.base_dir,
            files_read: self.files_read,
        };
        (scene, self.warnings)
    }
}

fn type_label(ty: Ty) -> &'static str {
    match ty {
        Ty::Int => "integer",
        Ty::Float => "float",
        Ty::Point2 => "point2",
        Ty::Vector2 => "vector2",
        Ty::Point3 => "point3",
        Ty::Vector3 => "vector3",
        Ty::Normal => "normal",
        Ty::Rgb => "rgb",
        Ty::Xyz => "xyz",
        Ty::Blackbody => "blackbody",
        Ty::Spectrum => "spectrum",
        Ty::Bool => "bool",
        Ty::Str => "string",
        Ty::Texture => "texture",
    }
}

/// Reads an `.spd` file: whitespace-separated numbers, `#` comments to end of line,
/// taken as (wavelength, value) pairs.
fn read_spd(path: &Path) -> Result<Vec<f32>, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    let mut v = Vec::new();
    for (ln, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = match memchr::memchr(b'#', line) {
            Some(k) => &line[..k],
            None => line,
        };
        for tok in line.split(|b| b.is_ascii_whitespace() || *b == b',').filter(|t| !t.is_empty()) {
            v.push(parse_f32(tok).map_err(|m| format!("line {}: {m}", ln + 1))?);
        }
    }
    if v.len() / 2 * 2 != v.len() {
        return Err(format!("expected (wavelength, value) pairs, found {} numbers", v.len()));
    }
    Ok(v)
}
