//! Typed parameter lists (`"float radius" [ 1 ]`) with pbrt-v3's lookup rules:
//! a getter finds a parameter by name *and* type, and every lookup is
//! remembered so that unused (e.g. misspelled) parameters can be reported.

use crate::diag::{Diagnostic, FileLoc};
use std::sync::atomic::{AtomicBool, Ordering};

/// A spectrum-typed value as written in the scene; `penumbra-core` converts it
/// to RGB exactly as pbrt-v3 does.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectrumValue {
    /// `rgb`/`color`: a multiple of 3 values.
    Rgb(Vec<f32>),
    /// `xyz`: a multiple of 3 values.
    Xyz(Vec<f32>),
    /// `blackbody`: (temperature in kelvin, scale) pairs, as pbrt-v3.
    Blackbody(Vec<f32>),
    /// `spectrum`: (wavelength in nm, value) pairs, written inline or read from an `.spd` file.
    Sampled(Vec<f32>),
}

/// A `texture` parameter, resolved against the texture names in scope where
/// the entity was declared (pbrt-v3 scopes textures by `AttributeBegin/End`).
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    pub name: String,
    /// Index into `SceneDescription::textures` of the float texture of that name, if any.
    pub float: Option<usize>,
    /// Index into `SceneDescription::textures` of the spectrum texture of that name, if any.
    pub spectrum: Option<usize>,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    Int(Vec<i32>),
    Float(Vec<f32>),
    /// Flat `[x y x y …]`.
    Point2(Vec<f32>),
    Vector2(Vec<f32>),
    /// Flat `[x y z x y z …]`.
    Point3(Vec<f32>),
    Vector3(Vec<f32>),
    Normal(Vec<f32>),
    Bool(Vec<bool>),
    String(Vec<String>),
    Texture(TextureRef),
    Spectrum(SpectrumValue),
}

impl ParamValue {
    /// The canonical pbrt-v3 type name.
    pub fn type_name(&self) -> &'static str {
        match self {
            ParamValue::Int(_) => "integer",
            ParamValue::Float(_) => "float",
            ParamValue::Point2(_) => "point2",
            ParamValue::Vector2(_) => "vector2",
            ParamValue::Point3(_) => "point3",
            ParamValue::Vector3(_) => "vector3",
            ParamValue::Normal(_) => "normal",
            ParamValue::Bool(_) => "bool",
            ParamValue::String(_) => "string",
            ParamValue::Texture(_) => "texture",
            ParamValue::Spectrum(SpectrumValue::Rgb(_)) => "rgb",
            ParamValue::Spectrum(SpectrumValue::Xyz(_)) => "xyz",
            ParamValue::Spectrum(SpectrumValue::Blackbody(_)) => "blackbody",
            ParamValue::Spectrum(SpectrumValue::Sampled(_)) => "spectrum",
        }
    }
}

#[derive(Debug)]
pub struct Param {
    pub name: String,
    pub value: ParamValue,
    pub loc: FileLoc,
    /// Set for parameters given on the command line (`--param k=v`), whose
    /// type was inferred: getters then accept an integer where a float is asked for.
    pub loose: bool,
    used: AtomicBool,
}

impl Clone for Param {
    fn clone(&self) -> Self {
        Param {
            name: self.name.clone(),
            value: self.value.clone(),
            loc: self.loc.clone(),
            loose: self.loose,
            used: AtomicBool::new(self.used.load(Ordering::Relaxed)),
        }
    }
}

impl PartialEq for Param {
    fn eq(&self, o: &Self) -> bool {
        self.name == o.name && self.value == o.value && self.loc == o.loc
    }
}

impl Param {
    pub fn new(name: impl Into<String>, value: ParamValue, loc: FileLoc) -> Self {
        Param { name: name.into(), value, loc, loose: false, used: AtomicBool::new(false) }
    }
    pub fn was_used(&self) -> bool {
        self.used.load(Ordering::Relaxed)
    }
    pub fn mark_used(&self) {
        self.used.store(true, Ordering::Relaxed);
    }
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamSet {
    pub params: Vec<Param>,
}

macro_rules! flat_getters {
    ($one:ident, $many:ident, $variant:ident, $n:literal) => {
        /// The first value of this name and type, or `default`.
        pub fn $one(&self, name: &str, default: [f32; $n]) -> [f32; $n] {
            match self.$many(name) {
                Some(v) if !v.is_empty() => v[0],
                _ => default,
            }
        }
        /// All values of this name and type (tuples of the type's arity).
        pub fn $many(&self, name: &str) -> Option<&[[f32; $n]]> {
            self.find_used(name, |v| match v {
                ParamValue::$variant(x) => Some(bytemuck::cast_slice::<f32, [f32; $n]>(&x[..x.len() / $n * $n])),
                _ => None,
            })
        }
    };
}

impl ParamSet {
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds a parameter; a later one of the same name replaces an earlier one (pbrt-v3 semantics).
    pub fn add(&mut self, p: Param) {
        self.params.retain(|q| q.name != p.name);
        self.params.push(p);
    }
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }
    /// The parameter of this name, whatever its type, without marking it used.
    pub fn find(&self, name: &str) -> Option<&Param> {
        self.params.iter().find(|p| p.name == name)
    }
    pub fn loc_of(&self, name: &str) -> Option<&FileLoc> {
        self.find(name).map(|p| &p.loc)
    }
    /// Finds the parameter `name` for which `get` returns `Some`, and marks it used.
    pub fn find_used<'a, T: ?Sized>(
        &'a self,
        name: &str,
        get: impl Fn(&'a ParamValue) -> Option<&'a T>,
    ) -> Option<&'a T> {
        for p in &self.params {
            if p.name == name {
                if let Some(v) = get(&p.value) {
                    p.mark_used();
                    return Some(v);
                }
            }
        }
        None
    }

    pub fn get_ints(&self, name: &str) -> Option<&[i32]> {
        self.find_used(name, |v| match v {
            ParamValue::Int(x) => Some(x.as_slice()),
            _ => None,
        })
    }
    pub fn get_floats(&self, name: &str) -> Option<&[f32]> {
        self.find_used(name, |v| match v {
            ParamValue::Float(x) => Some(x.as_slice()),
            _ => None,
        })
    }
    pub fn get_bools(&self, name: &str) -> Option<&[bool]> {
        self.find_used(name, |v| match v {
            ParamValue::Bool(x) => Some(x.as_slice()),
            _ => None,
        })
    }
    pub fn get_strings(&self, name: &str) -> Option<&[String]> {
        self.find_used(name, |v| match v {
            ParamValue::String(x) => Some(x.as_slice()),
            _ => None,
        })
    }
    pub fn get_spectrum(&self, name: &str) -> Option<&SpectrumValue> {
        self.find_used(name, |v| match v {
            ParamValue::Spectrum(s) => Some(s),
            _ => None,
        })
    }
    pub fn get_texture(&self, name: &str) -> Option<&TextureRef> {
        self.find_used(name, |v| match v {
            ParamValue::Texture(t) => Some(t),
            _ => None,
        })
    }

    pub fn get_one_int(&self, name: &str, default: i32) -> i32 {
        self.get_ints(name).and_then(|v| v.first().copied()).unwrap_or(default)
    }
    /// A float, or for command-line parameters also an integer.
    pub fn get_one_float(&self, name: &str, default: f32) -> f32 {
        if let Some(v) = self.get_floats(name).and_then(|v| v.first().copied()) {
            return v;
        }
        for p in &self.params {
            if p.name == name && p.loose {
                if let ParamValue::Int(x) = &p.value {
                    if let Some(v) = x.first() {
                        p.mark_used();
                        return *v as f32;
                    }
                }
            }
        }
        default
    }
    pub fn get_one_bool(&self, name: &str, default: bool) -> bool {
        self.get_bools(name).and_then(|v| v.first().copied()).unwrap_or(default)
    }
    pub fn get_one_string(&self, name: &str, default: &str) -> String {
        self.get_strings(name).and_then(|v| v.first().cloned()).unwrap_or_else(|| default.to_string())
    }

    flat_getters!(get_one_point2, get_point2s, Point2, 2);
    flat_getters!(get_one_vector2, get_vector2s, Vector2, 2);
    flat_getters!(get_one_point3, get_point3s, Point3, 3);
    flat_getters!(get_one_vector3, get_vector3s, Vector3, 3);
    flat_getters!(get_one_normal, get_normals, Normal, 3);

    /// Marks every parameter used (for entities that are deliberately ignored
    /// after a warning has already been given for the whole entity).
    pub fn mark_all_used(&self) {
        for p in &self.params {
            p.mark_used();
        }
    }

    /// One warning per parameter nobody asked for, located where it was written.
    pub fn report_unused(&self, owner: &str) -> Vec<Diagnostic> {
        self.params
            .iter()
            .filter(|p| !p.was_used())
            .map(|p| {
                Diagnostic::warning(
                    Some(p.loc.clone()),
                    format!("parameter \"{} {}\" unused by {owner}", p.value.type_name(), p.name),
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loc() -> FileLoc {
        FileLoc::builtin()
    }

    #[test]
    fn getters_match_name_and_type_and_track_use() {
        let mut ps = ParamSet::new();
        ps.add(Param::new("radius", ParamValue::Float(vec![2.0]), loc()));
        ps.add(Param::new("P", ParamValue::Point3(vec![0., 1., 2., 3., 4., 5.]), loc()));
        ps.add(Param::new("radus", ParamValue::Float(vec![3.0]), loc()));
        assert_eq!(ps.get_one_int("radius", 7), 7);
        assert_eq!(ps.get_one_float("radius", 1.0), 2.0);
        assert_eq!(ps.get_point3s("P").unwrap(), &[[0., 1., 2.], [3., 4., 5.]]);
        let unused = ps.report_unused("shape \"sphere\"");
        assert_eq!(unused.len(), 1);
        assert!(unused[0].message.contains("radus"));
    }

    #[test]
    fn loose_params_coerce_int_to_float() {
        let mut ps = ParamSet::new();
        let mut p = Param::new("maxdistance", ParamValue::Int(vec![3]), loc());
        p.loose = true;
        ps.add(p);
        assert_eq!(ps.get_one_float("maxdistance", 0.0), 3.0);
        assert!(ps.report_unused("x").is_empty());
    }
}
