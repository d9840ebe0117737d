//! The transformed scenes: each [`Variant`] edits the parsed description (transforms,
//! parameters, added shapes), never the text, so includes, PLY meshes and instances follow.

use penumbra_core::geometry::Bounds3;
use penumbra_core::scene::{BuildOptions, Requirements, Scene};
use penumbra_core::spectrum::spectrum_to_rgb;
use penumbra_parser::{
    DiagSink, FileLoc, Param, ParamSet, ParamValue, SceneDescription, ShapeDesc, SpectrumValue, Transform,
};

/// What a variant changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// The whole scene, camera included, scaled about the origin (point-like lights' intensity
    /// by s², so that their irradiance is unchanged).
    Scale(f64),
    /// The whole scene moved by this multiple of its extent (bounding-box diagonal), along a
    /// direction that is not a coordinate axis.
    Translate(f64),
    /// The whole scene turned about its centre by [`ROTATION_DEGREES`] about [`ROTATION_AXIS`].
    Rotate,
    /// Every light's `scale` multiplied (the image scales exactly).
    LightScale(f64),
    /// Every area light's shape shrunk about its centre by [`TINY_LIGHT_FACTOR`] at constant
    /// power (radiance × 1/factor²).
    TinyLight,
    /// Every area light's shape turned [`GRAZING_DEGREES`] about its centre and an axis in its
    /// plane: what it lit, it now lights at grazing angles.
    GrazingLight,
    /// One shape (the first that neither emits nor lacks a material) written twice.
    Duplicate,
    /// That shape and a copy of it moved by [`OFFSET_FRACTION`] of its size.
    OffsetCopy,
    /// Every microfacet roughness set to this value (pbrt-v3's clamps: 0 and 1).
    Roughness(f32),
}

/// How the variant's image must relate to the base image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Expect {
    /// The same image, up to noise (z-scores gate it).
    Same,
    /// The base image times this factor exactly (compared after dividing).
    Scaled(f64),
    /// Another image: only non-finite, negative and above-bound pixels count.
    Changed,
}

impl Expect {
    /// What the variant's image is divided by before it is compared with the base.
    pub fn factor(self) -> f64 {
        match self {
            Expect::Scaled(k) => k,
            _ => 1.0,
        }
    }
}

pub const ROTATION_DEGREES: f64 = 37.0;
pub const ROTATION_AXIS: [f64; 3] = [1.0, 2.0, 3.0];
pub const TINY_LIGHT_FACTOR: f64 = 1e-3;
pub const GRAZING_DEGREES: f64 = 89.0;
pub const OFFSET_FRACTION: f64 = 1e-6;
/// The translation direction (normalised when used).
const TRANSLATION_DIRECTION: [f64; 3] = [1.0, 1.0, 1.0];

#[derive(Clone, Debug, PartialEq)]
pub struct Variant {
    pub name: String,
    pub kind: Kind,
}

/// Formats a factor as the variant names write it: `1e-4`, `1e4`, `0.5`.
pub fn factor_name(v: f64) -> String {
    let e = v.abs().log10().round();
    if v > 0.0 && (v / 10f64.powf(e) - 1.0).abs() < 1e-9 && e != 0.0 {
        format!("1e{}", e as i32)
    } else {
        format!("{v}")
    }
}

impl Variant {
    pub fn new(kind: Kind) -> Variant {
        let name = match kind {
            Kind::Scale(s) => format!("scale-{}", factor_name(s)),
            Kind::Translate(k) => format!("translate-{}", factor_name(k)),
            Kind::Rotate => "rotate".into(),
            Kind::LightScale(k) => format!("light-{}", factor_name(k)),
            Kind::TinyLight => "tiny-light".into(),
            Kind::GrazingLight => "grazing-light".into(),
            Kind::Duplicate => "duplicate".into(),
            Kind::OffsetCopy => "offset-copy".into(),
            Kind::Roughness(r) => format!("roughness-{r}"),
        };
        Variant { name, kind }
    }

    /// What the image must do (a light scale: unless the image does not depend on the lights).
    pub fn expect(&self) -> Expect {
        match self.kind {
            Kind::Scale(_) | Kind::Translate(_) | Kind::Rotate | Kind::Duplicate | Kind::OffsetCopy => Expect::Same,
            Kind::LightScale(k) => Expect::Scaled(k),
            Kind::TinyLight | Kind::GrazingLight | Kind::Roughness(_) => Expect::Changed,
        }
    }

    /// The scene transformed, or why this variant does not apply to it.
    pub fn apply(&self, base: &SceneDescription, geo: &Geometry) -> Result<SceneDescription, String> {
        let mut d = base.clone();
        match self.kind {
            Kind::Scale(s) => {
                d.transform_world(&Transform::scale([s; 3]).ok_or("a scale must be finite and non-zero")?);
                let s2 = s * s;
                for l in &mut d.lights {
                    if matches!(l.entity.kind.as_str(), "point" | "spot" | "goniometric" | "projection") {
                        scale_spectrum_param(&mut l.entity.params, "scale", s2)?;
                    }
                }
            }
            Kind::Translate(k) => {
                let n = TRANSLATION_DIRECTION.iter().map(|v| v * v).sum::<f64>().sqrt();
                let dist = k * geo.extent;
                d.transform_world(&Transform::translate(TRANSLATION_DIRECTION.map(|v| v / n * dist)));
            }
            Kind::Rotate => {
                let c = geo.center;
                let r = Transform::rotate(ROTATION_DEGREES, ROTATION_AXIS).ok_or("bad rotation axis")?;
                let t = Transform::translate(c).compose(&r).compose(&Transform::translate(c.map(|v| -v)));
                d.transform_world(&t);
            }
            Kind::LightScale(k) => {
                for l in &mut d.lights {
                    scale_spectrum_param(&mut l.entity.params, "scale", k)?;
                }
                for a in &mut d.area_lights {
                    scale_spectrum_param(&mut a.params, "scale", k)?;
                }
            }
            Kind::TinyLight => {
                let f = TINY_LIGHT_FACTOR;
                let mut any = false;
                for s in d.shapes.iter_mut().filter(|s| s.area_light.is_some()) {
                    let c = object_centroid(s);
                    let shrink = Transform::translate(c)
                        .compose(&Transform::scale([f; 3]).ok_or("bad factor")?)
                        .compose(&Transform::translate(c.map(|v| -v)));
                    let t = &mut s.render_from_object;
                    t.start = t.start.compose(&shrink);
                    t.end = t.end.compose(&shrink);
                    any = true;
                }
                if !any {
                    return Err("the scene has no area light".into());
                }
                for a in &mut d.area_lights {
                    scale_spectrum_param(&mut a.params, "scale", 1.0 / (f * f))?;
                }
            }
            Kind::GrazingLight => {
                let mut any = false;
                for s in d.shapes.iter_mut().filter(|s| s.area_light.is_some()) {
                    let t = s.render_from_object.start;
                    let c = t.apply_point(object_centroid(s));
                    let n = world_normal(s);
                    // An axis in the light's plane: n × the coordinate axis least along n.
                    let e = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
                    let axis = match e {
                        0 => [0.0, n[2], -n[1]],
                        1 => [-n[2], 0.0, n[0]],
                        _ => [n[1], -n[0], 0.0],
                    };
                    let r = Transform::rotate(GRAZING_DEGREES, axis).ok_or("a light without a normal")?;
                    let turn = Transform::translate(c).compose(&r).compose(&Transform::translate(c.map(|v| -v)));
                    let x = &mut s.render_from_object;
                    x.start = turn.compose(&x.start);
                    x.end = turn.compose(&x.end);
                    any = true;
                }
                if !any {
                    return Err("the scene has no area light".into());
                }
            }
            Kind::Duplicate | Kind::OffsetCopy => {
                let (i, size) = geo.chosen_shape.ok_or("the scene has no shape that could be copied")?;
                let mut copy = d.shapes[i].clone();
                if self.kind == Kind::OffsetCopy {
                    let n = ROTATION_AXIS.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let by = Transform::translate(ROTATION_AXIS.map(|v| v / n * OFFSET_FRACTION * size));
                    copy.render_from_object.start = by.compose(&copy.render_from_object.start);
                    copy.render_from_object.end = by.compose(&copy.render_from_object.end);
                }
                d.shapes.push(copy);
            }
            Kind::Roughness(r) => {
                let mut any = false;
                for m in &mut d.materials {
                    let names: &[&str] = match m.entity.kind.as_str() {
                        "plastic" | "translucent" => &["roughness"],
                        "metal" | "uber" => &["roughness", "uroughness", "vroughness"],
                        "substrate" | "glass" => &["uroughness", "vroughness"],
                        _ => &[],
                    };
                    for &n in names {
                        // metal's and uber's uroughness/vroughness win over roughness where given.
                        if n == "roughness" || m.entity.params.find(n).is_some() || names.len() == 2 {
                            let loc = m.entity.params.loc_of(n).cloned().unwrap_or_else(FileLoc::builtin);
                            m.entity.params.add(Param::new(n, ParamValue::Float(vec![r]), loc));
                            any = true;
                        }
                    }
                }
                if !any {
                    return Err("the scene has no material with a microfacet roughness".into());
                }
            }
        }
        Ok(d)
    }
}

/// The default variants, in the order they are reported.
pub fn defaults(scales: &[f64], translations: &[f64]) -> Vec<Variant> {
    let mut v: Vec<Variant> = scales.iter().map(|&s| Variant::new(Kind::Scale(s))).collect();
    v.push(Variant::new(Kind::Rotate));
    v.extend(translations.iter().map(|&k| Variant::new(Kind::Translate(k))));
    v.extend([1e6, 1e-6].map(|k| Variant::new(Kind::LightScale(k))));
    v.push(Variant::new(Kind::TinyLight));
    v.push(Variant::new(Kind::GrazingLight));
    v.push(Variant::new(Kind::Duplicate));
    v.push(Variant::new(Kind::OffsetCopy));
    v.extend([0.0, 1.0].map(|r| Variant::new(Kind::Roughness(r))));
    v
}

/// `--variants`: names (`scale-1e-4`, `rotate`…) or groups (`scale`, `translate`, `light`,
/// `roughness`, `geometry`, `all`) from `all`.
pub fn select(all: &[Variant], list: &[String]) -> Result<Vec<Variant>, String> {
    let mut out: Vec<Variant> = Vec::new();
    for item in list.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        let group = |v: &Variant| match item {
            "all" => true,
            "scale" => matches!(v.kind, Kind::Scale(_)),
            "translate" => matches!(v.kind, Kind::Translate(_)),
            "light" => matches!(v.kind, Kind::LightScale(_) | Kind::TinyLight | Kind::GrazingLight),
            "roughness" => matches!(v.kind, Kind::Roughness(_)),
            "geometry" => matches!(v.kind, Kind::Duplicate | Kind::OffsetCopy),
            _ => v.name == item,
        };
        let found: Vec<&Variant> = all.iter().filter(|v| group(v)).collect();
        if found.is_empty() {
            let names: Vec<&str> = all.iter().map(|v| v.name.as_str()).collect();
            return Err(format!(
                "--variants: unknown variant \"{item}\"; valid: all, scale, translate, light, roughness, geometry, {}",
                names.join(", ")
            ));
        }
        for v in found {
            if !out.contains(v) {
                out.push(v.clone());
            }
        }
    }
    Ok(out)
}

/// What the variants need to know of the scene's geometry (from a build without a BVH).
pub struct Geometry {
    /// The bounding box's diagonal length.
    pub extent: f64,
    pub center: [f64; 3],
    /// The shape that `duplicate` and `offset-copy` copy, and its size (bounding-box diagonal).
    pub chosen_shape: Option<(usize, f64)>,
}

impl Geometry {
    pub fn of(desc: &SceneDescription, opts: &BuildOptions) -> Result<Geometry, String> {
        let scene = Scene::build(desc, Requirements::default(), opts, &DiagSink::new()).map_err(|d| d.to_string())?;
        let b = scene.bounds;
        if b.is_empty() {
            return Err("the scene has no geometry".into());
        }
        let diag = |b: &Bounds3| b.diagonal().as_dvec3().length();
        let c = b.center().as_dvec3();
        // The first shape with a material and no area light, found among the built objects by its location.
        let chosen_shape =
            desc.shapes.iter().position(|s| s.material.is_some() && s.area_light.is_none()).and_then(|i| {
                let loc = &desc.shapes[i].entity.loc;
                let k = scene.objects.iter().position(|o| o.instance.is_none() && &o.loc == loc)?;
                Some((i, diag(&scene.meshes.get(k)?.bounds())))
            });
        Ok(Geometry { extent: diag(&b), center: [c.x, c.y, c.z], chosen_shape })
    }
}

/// The mean of a shape's object-space `P` (its centre for a triangle mesh), else the object's
/// origin (the centre of pbrt's quadrics).
fn object_centroid(s: &ShapeDesc) -> [f64; 3] {
    match s.entity.params.find("P").map(|p| &p.value) {
        Some(ParamValue::Point3(p)) if p.len() >= 3 => {
            let n = (p.len() / 3) as f64;
            let mut c = [0.0; 3];
            for q in p.chunks_exact(3) {
                (0..3).for_each(|i| c[i] += q[i] as f64 / n);
            }
            c
        }
        _ => [0.0; 3],
    }
}

/// A shape's world-space normal: of its first triangle for a mesh written with `P` and
/// `indices`, else of its object-space z axis (pbrt's disk).
fn world_normal(s: &ShapeDesc) -> [f64; 3] {
    let t = &s.render_from_object.start;
    if let (Some(ParamValue::Point3(p)), Some(ParamValue::Int(i))) =
        (s.entity.params.find("P").map(|p| &p.value), s.entity.params.find("indices").map(|p| &p.value))
    {
        let v = |k: usize| -> Option<[f64; 3]> {
            let j = *i.get(k)? as usize;
            let q = p.get(3 * j..3 * j + 3)?;
            Some(t.apply_point([q[0] as f64, q[1] as f64, q[2] as f64]))
        };
        if let (Some(a), Some(b), Some(c)) = (v(0), v(1), v(2)) {
            let (u, w) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
            return [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
        }
    }
    t.apply_normal([0.0, 0.0, 1.0])
}

/// Multiplies a light's spectrum parameter `name` (absent: 1) by `k`, as RGB.
fn scale_spectrum_param(ps: &mut ParamSet, name: &str, k: f64) -> Result<(), String> {
    let (rgb, loc) = match ps.find(name) {
        Some(p) => match &p.value {
            ParamValue::Spectrum(v) => {
                let c = spectrum_to_rgb(v).map_err(|e| format!("{}: \"{name}\": {e}", p.loc))?;
                (c.to_array(), p.loc.clone())
            }
            ParamValue::Float(v) if !v.is_empty() => ([v[0]; 3], p.loc.clone()),
            _ => return Err(format!("{}: \"{name}\" is not a spectrum", p.loc)),
        },
        None => ([1.0; 3], FileLoc::builtin()),
    };
    let v = rgb.iter().map(|&c| (c as f64 * k) as f32).collect();
    ps.add(Param::new(name, ParamValue::Spectrum(SpectrumValue::Rgb(v)), loc));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_groups() {
        assert_eq!(factor_name(1e-4), "1e-4");
        assert_eq!(factor_name(1e4), "1e4");
        assert_eq!(factor_name(0.5), "0.5");
        let all = defaults(&[1e-4, 1e4], &[1e2, 1e4]);
        let names: Vec<String> = all.iter().map(|v| v.name.clone()).collect();
        assert_eq!(names[..4], ["scale-1e-4", "scale-1e4", "rotate", "translate-1e2"]);
        let s = select(&all, &["scale".into(), "rotate".into(), "scale-1e4".into()]).unwrap();
        assert_eq!(s.len(), 3);
        assert!(select(&all, &["nope".into()]).unwrap_err().contains("unknown variant \"nope\""));
    }

    const SCENE: &str = r#"LookAt 0 2 -5  0 0 0  0 1 0 Camera "perspective"
        Film "image" "integer xresolution" 8 "integer yresolution" 8
        WorldBegin
        LightSource "point" "rgb I" [1 1 1] "point from" [0 3 0]
        AttributeBegin AreaLightSource "diffuse" "rgb L" [2 2 2]
          Shape "trianglemesh" "integer indices" [0 1 2] "point P" [1 2 0  3 2 0  2 2 3] AttributeEnd
        Material "plastic" "float roughness" 0.3
        Shape "trianglemesh" "integer indices" [0 1 2 0 2 3] "point P" [-1 0 -1 1 0 -1 1 0 1 -1 0 1]
        Material "substrate"
        Shape "sphere" "float radius" 0.5
        WorldEnd"#;

    fn rgb(ps: &ParamSet, name: &str) -> Vec<f32> {
        match &ps.find(name).unwrap().value {
            ParamValue::Spectrum(SpectrumValue::Rgb(v)) => v.clone(),
            v => panic!("{v:?}"),
        }
    }

    #[test]
    fn variants_edit_the_description() {
        let base = penumbra_parser::parse_str(SCENE, "<test>", None).unwrap().scene;
        let geo = Geometry::of(&base, &BuildOptions::default()).unwrap();
        // The quad (first shape with a material and no area light), diagonal 2√2.
        assert_eq!(geo.chosen_shape.map(|(i, _)| i), Some(1));
        assert!((geo.chosen_shape.unwrap().1 - 8f64.sqrt()).abs() < 1e-6, "{:?}", geo.chosen_shape);
        let apply = |k: Kind| Variant::new(k).apply(&base, &geo).unwrap();

        // Scale: the point light's scale by s², so its irradiance at scaled distances is unchanged.
        let d = apply(Kind::Scale(1e-4));
        assert!((rgb(&d.lights[0].entity.params, "scale")[0] - 1e-8).abs() < 1e-14);
        let p = d.shapes[1].render_from_object.start.apply_point([1.0, 0.0, 1.0]);
        assert!((p[0] - 1e-4).abs() < 1e-12 && (p[2] - 1e-4).abs() < 1e-12, "{p:?}");

        // Translation by 1e2 extents along (1,1,1)/√3.
        let d = apply(Kind::Translate(1e2));
        let p = d.shapes[1].render_from_object.start.apply_point([0.0; 3]);
        assert!((p[0] - 1e2 * geo.extent / 3f64.sqrt()).abs() < 1e-9, "{p:?}");

        // Light scale: every light and area light.
        let d = apply(Kind::LightScale(1e6));
        assert_eq!(rgb(&d.lights[0].entity.params, "scale"), vec![1e6; 3]);
        assert_eq!(rgb(&d.area_lights[0].params, "scale"), vec![1e6; 3]);

        // Tiny light: the emitter shrunk 1000× about its centroid (2, 2, 1), radiance × 1e6.
        let d = apply(Kind::TinyLight);
        let t = &d.shapes[0].render_from_object.start;
        let (c, v) = (t.apply_point([2.0, 2.0, 1.0]), t.apply_point([1.0, 2.0, 0.0]));
        assert!(c.iter().zip([2.0, 2.0, 1.0]).all(|(a, b)| (a - b).abs() < 1e-12), "{c:?}");
        assert!((v[0] - (2.0 - 1e-3)).abs() < 1e-9, "{v:?}");
        assert!((rgb(&d.area_lights[0].params, "scale")[0] - 1e6).abs() < 1.0);

        // Grazing: the emitter's normal turned 89° about its centroid.
        let d = apply(Kind::GrazingLight);
        let t = &d.shapes[0].render_from_object.start;
        let c = t.apply_point([2.0, 2.0, 1.0]);
        assert!(c.iter().zip([2.0, 2.0, 1.0]).all(|(a, b)| (a - b).abs() < 1e-12), "{c:?}");
        let (n0, n1) = (world_normal(&base.shapes[0]), world_normal(&d.shapes[0]));
        let len = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let cos = (0..3).map(|i| n0[i] * n1[i]).sum::<f64>() / (len(n0) * len(n1));
        assert!((cos - GRAZING_DEGREES.to_radians().cos()).abs() < 1e-9, "{cos}");

        // Duplicate and offset copy: one more shape, the copy 1e-6 of the quad's size away.
        let d = apply(Kind::Duplicate);
        assert_eq!((d.shapes.len(), &d.shapes[3]), (4, &base.shapes[1]));
        let d = apply(Kind::OffsetCopy);
        let (a, b) = (
            base.shapes[1].render_from_object.start.apply_point([0.0; 3]),
            d.shapes[3].render_from_object.start.apply_point([0.0; 3]),
        );
        let moved = (0..3).map(|i| (a[i] - b[i]).powi(2)).sum::<f64>().sqrt();
        assert!((moved / (OFFSET_FRACTION * 8f64.sqrt()) - 1.0).abs() < 1e-6, "{moved}");

        // Roughness: plastic's roughness; substrate's u and v roughness, written where absent.
        let d = apply(Kind::Roughness(0.0));
        let rough = |m: usize, n: &str| d.materials[m].entity.params.find(n).map(|p| p.value.clone());
        let zero = Some(ParamValue::Float(vec![0.0]));
        let (plastic, substrate) = (
            d.materials.iter().position(|m| m.entity.kind == "plastic").unwrap(),
            d.materials.iter().position(|m| m.entity.kind == "substrate").unwrap(),
        );
        assert_eq!(rough(plastic, "roughness"), zero);
        assert_eq!((rough(substrate, "uroughness"), rough(substrate, "vroughness")), (zero.clone(), zero));
    }

    #[test]
    fn light_scale_multiplies_or_adds_the_scale_parameter() {
        let mut ps = ParamSet::new();
        scale_spectrum_param(&mut ps, "scale", 1e6).unwrap();
        scale_spectrum_param(&mut ps, "scale", 2.0).unwrap();
        assert_eq!(ps.find("scale").unwrap().value, ParamValue::Spectrum(SpectrumValue::Rgb(vec![2e6; 3])));
    }
}
