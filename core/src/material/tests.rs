use super::*;
use crate::bxdf::{fr_conductor, BxdfFlags};
use crate::geometry::Frame;
use crate::texture::tests::{fref, loc, params, scene, sref, tex};
use penumbra_parser::{Entity, MaterialDesc, ParamSet, ParamValue, SpectrumValue, TextureKind};
use std::f32::consts::PI;
use std::path::PathBuf;

fn si_at(uv: Vec2, dpdu: Vec3, dpdv: Vec3) -> SurfaceInteraction {
    let n = dpdu.cross(dpdv).normalize();
    SurfaceInteraction {
        p: Vec3::new(uv.x, uv.y, 0.0),
        p_error: Vec3::ZERO,
        n,
        uv,
        dpdu,
        dpdv,
        shading: Frame::from_zx(n, dpdu),
        shading_dpdu: dpdu,
        shading_dpdv: dpdv,
        ..Default::default()
    }
}

fn flat_si() -> SurfaceInteraction {
    si_at(Vec2::new(0.3, 0.6), Vec3::X, Vec3::Y)
}

fn mat(kind: &str, p: ParamSet, name: Option<&str>) -> MaterialDesc {
    MaterialDesc { entity: Entity::new(kind, p, loc(50)), name: name.map(String::from) }
}

fn rgb(r: f32, g: f32, b: f32) -> ParamValue {
    ParamValue::Spectrum(SpectrumValue::Rgb(vec![r, g, b]))
}

struct Built {
    materials: Materials,
    textures: Textures,
    warnings: DiagSink,
}

fn build(desc: &SceneDescription, used: &[bool]) -> Built {
    let warnings = DiagSink::new();
    let mut textures = Textures::new(desc);
    let materials = Materials::build(desc, used, &mut textures, &warnings).unwrap();
    Built { materials, textures, warnings }
}

fn bsdf_of(b: &Built, i: usize, si: &SurfaceInteraction) -> Bsdf {
    b.materials.get(i).unwrap().compute_bsdf(si, &b.materials, &b.textures)
}

fn dir(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// Textbook dielectric Fresnel reflectance (f64), light arriving from the `eta_i` side.
fn fresnel_dielectric(cos_i: f64, eta_i: f64, eta_t: f64) -> f64 {
    let sin_t = eta_i / eta_t * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rpar = (eta_t * cos_i - eta_i * cos_t) / (eta_t * cos_i + eta_i * cos_t);
    let rperp = (eta_i * cos_i - eta_t * cos_t) / (eta_i * cos_i + eta_t * cos_t);
    0.5 * (rpar * rpar + rperp * rperp)
}

/// Isotropic GGX D and Smith G, from their definitions (f64).
fn ggx_d_g(alpha: f64, wo: Vec3, wi: Vec3) -> (f64, f64) {
    let wh = (wo + wi).normalize();
    let cos2 = (wh.z as f64).powi(2);
    let tan2 = (1.0 - cos2) / cos2;
    let d = 1.0 / (std::f64::consts::PI * alpha * alpha * cos2 * cos2 * (1.0 + tan2 / (alpha * alpha)).powi(2));
    let lambda = |w: Vec3| {
        let c2 = (w.z as f64).powi(2);
        let t2 = (1.0 - c2) / c2;
        (-1.0 + (1.0 + alpha * alpha * t2).sqrt()) / 2.0
    };
    (d, 1.0 / (1.0 + lambda(wo) + lambda(wi)))
}

fn close(a: Vec3, b: Vec3, rel: f32) -> bool {
    (a - b).abs().max_element() <= rel * b.abs().max_element().max(1e-6)
}

#[test]
fn matte_with_kd_texture_is_lambertian() {
    let desc = scene(
        vec![tex("kd", TextureKind::Spectrum, "constant", params(vec![("value", rgb(0.2, 0.4, 0.6))]))],
        vec![
            mat("matte", params(vec![("Kd", sref("kd", 0))]), None),
            mat("matte", params(vec![("sigma", ParamValue::Float(vec![20.0]))]), None),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true, true]);
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let si = flat_si();
    let bsdf = bsdf_of(&b, 0, &si);
    assert_eq!(bsdf.bxdfs(), &[Bxdf::lambertian_reflection(Vec3::new(0.2, 0.4, 0.6))]);
    for (wo, wi) in [(dir(0.3, 0.1), dir(1.0, 2.0)), (dir(1.2, 4.0), dir(0.1, 0.5))] {
        let f = bsdf.f(wo, wi, BxdfFlags::ALL);
        assert!(close(f, Vec3::new(0.2, 0.4, 0.6) / PI, 1e-6), "{f}");
        // No transmission through an opaque matte.
        assert_eq!(bsdf.f(wo, -wi, BxdfFlags::ALL), Vec3::ZERO);
    }
    // Default Kd 0.5 and sigma → Oren–Nayar.
    assert_eq!(bsdf_of(&b, 1, &si).bxdfs(), &[Bxdf::oren_nayar(Vec3::splat(0.5), 20.0)]);
}

#[test]
fn plastic_is_lambertian_plus_ggx_with_pbrt_v3_fresnel() {
    let desc = scene(vec![], vec![mat("plastic", ParamSet::new(), None)], PathBuf::new());
    let b = build(&desc, &[true]);
    let si = flat_si();
    let bsdf = bsdf_of(&b, 0, &si);
    let alpha = roughness_to_alpha(0.1);
    let distrib = MicrofacetDistribution::trowbridge_reitz(alpha, alpha);
    assert_eq!(
        bsdf.bxdfs(),
        &[
            Bxdf::lambertian_reflection(Vec3::splat(0.25)),
            Bxdf::microfacet_reflection(Vec3::splat(0.25), distrib, Fresnel::Dielectric { eta_i: 1.5, eta_t: 1.0 }),
        ]
    );
    assert_eq!(bsdf.eta, 1.0);
    let (wo, wi) = (dir(0.4, 0.3), dir(0.5, 3.0));
    let (d, g) = ggx_d_g(alpha as f64, wo, wi);
    let wh = (wo + wi).normalize();
    let fr = fresnel_dielectric(wi.dot(wh) as f64, 1.5, 1.0);
    let spec = 0.25 * d * g * fr / (4.0 * wo.z as f64 * wi.z as f64);
    let expect = 0.25 / std::f64::consts::PI + spec;
    let f = bsdf.f(wo, wi, BxdfFlags::ALL);
    assert!(spec > 1e-3, "configuration should have a visible glossy part: {spec}");
    assert!(close(f, Vec3::splat(expect as f32), 1e-4), "{f} vs {expect}");
}

#[test]
fn metal_defaults_to_rough_copper_and_anisotropic_roughness() {
    let desc = scene(
        vec![],
        vec![
            mat("metal", ParamSet::new(), None),
            mat(
                "metal",
                params(vec![
                    ("uroughness", ParamValue::Float(vec![0.3])),
                    ("vroughness", ParamValue::Float(vec![0.05])),
                    ("remaproughness", ParamValue::Bool(vec![false])),
                ]),
                None,
            ),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true, true]);
    let si = flat_si();
    let bsdf = bsdf_of(&b, 0, &si);
    let a = roughness_to_alpha(0.01);
    let fresnel = Fresnel::Conductor { eta_i: Vec3::ONE, eta_t: copper_eta(), k: copper_k() };
    assert_eq!(
        bsdf.bxdfs(),
        &[Bxdf::microfacet_reflection(Vec3::ONE, MicrofacetDistribution::trowbridge_reitz(a, a), fresnel)]
    );
    // Evaluate the rougher anisotropic one against the formula along the (isotropic-free) half vector z.
    let bsdf = bsdf_of(&b, 1, &si);
    assert_eq!(
        bsdf.bxdfs(),
        &[Bxdf::microfacet_reflection(Vec3::ONE, MicrofacetDistribution::trowbridge_reitz(0.3, 0.05), fresnel)]
    );
    let (wo, wi) = (dir(0.3, 0.0), dir(0.3, PI));
    // wh = z: D = 1/(π αx αy); G from Λ along φ = 0 (alpha_x).
    let lambda = |t: f32| (-1.0 + (1.0 + 0.09 * t.tan().powi(2)).sqrt()) / 2.0;
    let g = 1.0 / (1.0 + 2.0 * lambda(0.3));
    let d = 1.0 / (PI * 0.3 * 0.05);
    let expect = fr_conductor(1.0, Vec3::ONE, copper_eta(), copper_k()) * d * g / (4.0 * 0.3f32.cos().powi(2));
    let f = bsdf.f(wo, wi, BxdfFlags::ALL);
    assert!(close(f, expect, 1e-3), "{f} vs {expect}");
}

#[test]
fn substrate_mirror_glass_uber_translucent_lobes() {
    let desc = scene(
        vec![],
        vec![
            mat("substrate", ParamSet::new(), None),
            mat("mirror", ParamSet::new(), None),
            mat("glass", params(vec![("index", ParamValue::Float(vec![1.33]))]), None),
            mat("uber", params(vec![("opacity", rgb(0.5, 0.5, 0.5))]), None),
            mat("translucent", ParamSet::new(), None),
            mat(
                "glass",
                params(vec![
                    ("uroughness", ParamValue::Float(vec![0.2])),
                    ("vroughness", ParamValue::Float(vec![0.2])),
                ]),
                None,
            ),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true; 6]);
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let si = flat_si();
    let a1 = roughness_to_alpha(0.1);
    let tr1 = MicrofacetDistribution::trowbridge_reitz(a1, a1);
    assert_eq!(bsdf_of(&b, 0, &si).bxdfs(), &[Bxdf::fresnel_blend(Vec3::splat(0.5), Vec3::splat(0.5), tr1)]);
    assert_eq!(bsdf_of(&b, 1, &si).bxdfs(), &[Bxdf::specular_reflection(Vec3::splat(0.9), Fresnel::NoOp)]);
    let glass = bsdf_of(&b, 2, &si);
    assert_eq!(glass.eta, 1.33);
    assert_eq!(
        glass.bxdfs(),
        &[
            Bxdf::specular_reflection(Vec3::ONE, Fresnel::Dielectric { eta_i: 1.0, eta_t: 1.33 }),
            Bxdf::specular_transmission(Vec3::ONE, 1.0, 1.33, TransportMode::Radiance),
        ]
    );
    let opts = BsdfOptions { mode: TransportMode::Radiance, allow_multiple_lobes: true };
    let m = b.materials.get(2).unwrap();
    let g2 = m.compute_bsdf_ext(
        &si,
        &TextureEvalContext::from_si(&si),
        &ShadingGeometry::of(&si),
        opts,
        &b.materials,
        &b.textures,
    );
    assert_eq!(g2.bxdfs(), &[Bxdf::fresnel_specular(Vec3::ONE, Vec3::ONE, 1.0, 1.33, TransportMode::Radiance)]);
    // Uber with opacity 0.5: pass-through transmission first, BSDF eta 1, lobes weighted by opacity.
    let uber = bsdf_of(&b, 3, &si);
    assert_eq!(uber.eta, 1.0);
    assert_eq!(
        uber.bxdfs(),
        &[
            Bxdf::specular_transmission(Vec3::splat(0.5), 1.0, 1.0, TransportMode::Radiance),
            Bxdf::lambertian_reflection(Vec3::splat(0.125)),
            Bxdf::microfacet_reflection(Vec3::splat(0.125), tr1, Fresnel::Dielectric { eta_i: 1.0, eta_t: 1.5 }),
        ]
    );
    let tl = bsdf_of(&b, 4, &si);
    assert_eq!(tl.eta, 1.5);
    assert_eq!(
        tl.bxdfs(),
        &[
            Bxdf::lambertian_reflection(Vec3::splat(0.125)),
            Bxdf::lambertian_transmission(Vec3::splat(0.125)),
            Bxdf::microfacet_reflection(Vec3::splat(0.125), tr1, Fresnel::Dielectric { eta_i: 1.0, eta_t: 1.5 }),
            Bxdf::microfacet_transmission(Vec3::splat(0.125), tr1, 1.0, 1.5, TransportMode::Radiance),
        ]
    );
    let a2 = roughness_to_alpha(0.2);
    let tr2 = MicrofacetDistribution::trowbridge_reitz(a2, a2);
    assert_eq!(
        bsdf_of(&b, 5, &si).bxdfs(),
        &[
            Bxdf::microfacet_reflection(Vec3::ONE, tr2, Fresnel::Dielectric { eta_i: 1.0, eta_t: 1.5 }),
            Bxdf::microfacet_transmission(Vec3::ONE, tr2, 1.0, 1.5, TransportMode::Radiance),
        ]
    );
}

#[test]
fn mix_weights_first_material_by_amount_and_builds_only_what_is_used() {
    let desc = scene(
        vec![tex(
            "broken",
            TextureKind::Spectrum,
            "imagemap",
            params(vec![("filename", ParamValue::String(vec!["missing.png".into()]))]),
        )],
        vec![
            mat("matte", params(vec![("Kd", rgb(0.8, 0.8, 0.8))]), Some("a")),
            mat("matte", params(vec![("Kd", rgb(0.2, 0.4, 0.0))]), Some("b")),
            mat(
                "mix",
                params(vec![
                    ("amount", rgb(0.25, 0.25, 0.25)),
                    ("namedmaterial1", ParamValue::String(vec!["a".into()])),
                    ("namedmaterial2", ParamValue::String(vec!["b".into()])),
                ]),
                None,
            ),
            mat("matte", params(vec![("Kd", sref("broken", 0))]), None),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[false, false, true, false]);
    assert_eq!(b.materials.built_count(), 3);
    assert!(b.materials.get(3).is_none());
    assert_eq!(b.textures.built_count(), 0);
    let bsdf = bsdf_of(&b, 2, &flat_si());
    let expect = 0.25 * Vec3::splat(0.8) + 0.75 * Vec3::new(0.2, 0.4, 0.0);
    let f = bsdf.f(dir(0.2, 0.0), dir(0.7, 1.0), BxdfFlags::ALL);
    assert!(close(f, expect / PI, 1e-6), "{f}");
    assert_eq!(bsdf.bxdfs().len(), 2);
    // The broken material, once used, is a located error.
    let w = DiagSink::new();
    let mut t = Textures::new(&desc);
    let e = Materials::build(&desc, &[false, false, false, true], &mut t, &w).unwrap_err();
    assert!(e.loc.is_some() && e.message.contains("missing.png"), "{e:?}");
    // An undefined named material is a located error.
    let desc2 = scene(
        vec![],
        vec![mat("mix", params(vec![("namedmaterial1", ParamValue::String(vec!["zz".into()]))]), None)],
        PathBuf::new(),
    );
    let e = Materials::build(&desc2, &[true], &mut Textures::new(&desc2), &w).unwrap_err();
    assert!(e.message.contains("zz") && e.loc == Some(loc(100)), "{e:?}");
}

#[test]
fn unknown_materials_become_matte_with_one_warning_per_type() {
    // pbrt-v4's names, unknown to pbrt-v3.
    let desc = scene(
        vec![],
        vec![
            mat(
                "coateddiffuse",
                params(vec![("Kd", rgb(0.3, 0.3, 0.3)), ("thickness", ParamValue::Float(vec![1.0]))]),
                None,
            ),
            mat("coateddiffuse", ParamSet::new(), None),
            mat("diffusetransmission", ParamSet::new(), None),
            mat("matte", params(vec![("Kdd", rgb(0.3, 0.3, 0.3))]), None),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true; 4]);
    let ws = b.warnings.snapshot();
    let coated: Vec<_> = ws.iter().filter(|w| w.message.contains("\"coateddiffuse\" unknown")).collect();
    let transmission: Vec<_> = ws.iter().filter(|w| w.message.contains("\"diffusetransmission\" unknown")).collect();
    assert_eq!(coated.len(), 1, "{ws:?}");
    assert_eq!(transmission.len(), 1, "{ws:?}");
    // The misspelled parameter of the real matte is reported; the unknown ones' parameters are not.
    assert!(ws.iter().any(|w| w.message.contains("Kdd")));
    assert_eq!(ws.len(), 3, "{ws:?}");
    let one = |c: f32| Material::Matte {
        kd: SpectrumParam::Const(Vec3::splat(c)),
        sigma: FloatParam::Const(0.0),
        bump: None,
    };
    assert_eq!(b.materials.get(0), Some(&one(0.3)));
    assert_eq!(b.materials.get(1), Some(&one(0.5)));
    assert_eq!(b.materials.get(2), Some(&one(0.5)));
}

#[test]
fn bump_mapping_constant_keeps_normal_and_ramp_tilts_it() {
    // d(u, v) = k·u via a float bilerp (v10 = v11 = k).
    let k = 0.6f32;
    let desc = scene(
        vec![
            tex("flat", TextureKind::Float, "constant", params(vec![("value", ParamValue::Float(vec![0.7]))])),
            tex(
                "ramp",
                TextureKind::Float,
                "bilerp",
                params(vec![
                    ("v00", ParamValue::Float(vec![0.0])),
                    ("v01", ParamValue::Float(vec![0.0])),
                    ("v10", ParamValue::Float(vec![k])),
                    ("v11", ParamValue::Float(vec![k])),
                ]),
            ),
        ],
        vec![
            mat("matte", params(vec![("bumpmap", fref("flat", 0))]), None),
            mat("matte", params(vec![("bumpmap", fref("ramp", 1))]), None),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true, true]);
    // Non-unit ∂p/∂u = 2x: the tilt is atan(k / |∂p/∂u|).
    let si = si_at(Vec2::new(0.3, 0.6), 2.0 * Vec3::X, Vec3::Y);
    let flat = bsdf_of(&b, 0, &si);
    assert!((flat.shading_normal() - Vec3::Z).length() < 1e-6);
    let ramp = bsdf_of(&b, 1, &si);
    let n = ramp.shading_normal();
    let expect = Vec3::new(-k, 0.0, 2.0).normalize();
    assert!((n - expect).length() < 1e-5, "{n} vs {expect}");
    let tilt = n.z.acos();
    assert!((tilt - (k / 2.0).atan()).abs() < 1e-5);
    // The geometric normal is untouched and the frame stays orthonormal.
    assert_eq!(ramp.geometric_normal(), Vec3::Z);
    let x = ramp.local_to_world(Vec3::X);
    assert!(x.dot(n).abs() < 1e-6 && (x.length() - 1.0).abs() < 1e-6);
    // With interpolated normals pbrt-v3's shading tangents are the negated frame axes,
    // so the same ramp tilts the other way (unit tangents: atan(k)).
    let m = b.materials.get(1).unwrap();
    let ctx = TextureEvalContext::from_si(&si);
    let unit = SurfaceInteraction { shading_dpdu: -si.shading.x, shading_dpdv: -si.shading.y, ..si };
    let (n2, _) = bump(FloatParam::Tex(1), &unit, &ShadingGeometry::of(&unit), &ctx, &b.textures);
    let _ = m;
    // Without differentials the displacement is differenced over pbrt-v3's 0.0005 in u: f32
    // rounding of d(u + du) − d(u) leaves ~1e-4 in the slope.
    assert!((n2 - Vec3::new(k, 0.0, 1.0).normalize()).length() < 1e-3, "{n2}");
}

#[test]
fn ltc_descriptions() {
    let desc = scene(
        vec![],
        vec![
            mat("plastic", params(vec![("Kd", rgb(0.1, 0.2, 0.3))]), None),
            mat("matte", params(vec![("sigma", ParamValue::Float(vec![10.0]))]), None),
            mat("metal", params(vec![("uroughness", ParamValue::Float(vec![0.3]))]), None),
            mat("metal", ParamSet::new(), None),
            mat("substrate", ParamSet::new(), None),
            mat("glass", ParamSet::new(), None),
            mat("matte", ParamSet::new(), None),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true; 7]);
    let si = flat_si();
    let l = |i: usize| b.materials.get(i).unwrap().ltc_lobes(&si, &b.materials, &b.textures);
    let a = roughness_to_alpha(0.1);
    let plastic = LtcLobe {
        alpha: a,
        kind: LtcLobeKind::Microfacet(LtcFresnel::Dielectric { eta_i: 1.5, eta_t: 1.0 }),
        scale: Vec3::splat(0.25),
    };
    assert_eq!(
        l(0),
        Some(LtcDescription {
            n: Vec3::Z,
            diffuse: Vec3::new(0.1, 0.2, 0.3),
            lobes: LtcLobes::from_slice(&[plastic]).unwrap(),
            transmits: false,
        })
    );
    assert_eq!(l(1), None);
    assert_eq!(l(2), None);
    let m = l(3).unwrap();
    assert_eq!(m.diffuse, Vec3::ZERO);
    let metal = m.lobes.as_slice()[0];
    assert_eq!(metal.kind, LtcLobeKind::Microfacet(LtcFresnel::Conductor { eta: copper_eta(), k: copper_k() }));
    assert_eq!(metal.alpha, roughness_to_alpha(0.01));
    assert_eq!(l(4).unwrap().lobes.as_slice()[0].kind, LtcLobeKind::BlendSpecular { rs: Vec3::splat(0.5) });
    assert_eq!(l(5), None);
    assert_eq!(
        l(6),
        Some(LtcDescription { n: Vec3::Z, diffuse: Vec3::splat(0.5), lobes: LtcLobes::default(), transmits: false })
    );
}

#[test]
fn scene_builds_only_used_materials_and_gives_bsdfs() {
    use crate::geometry::Ray;
    use crate::scene::{BuildOptions, Requirements, Scene};
    use penumbra_parser::{AnimatedTransform, ShapeDesc};
    let quad = |z: f32, material: Option<usize>| ShapeDesc {
        entity: Entity::new(
            "trianglemesh",
            params(vec![
                ("P", ParamValue::Point3(vec![0.0, 0.0, z, 1.0, 0.0, z, 1.0, 1.0, z, 0.0, 1.0, z])),
                ("indices", ParamValue::Int(vec![0, 1, 2, 0, 2, 3])),
                ("uv", ParamValue::Point2(vec![0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0])),
            ]),
            loc(60),
        ),
        render_from_object: AnimatedTransform::default(),
        reverse_orientation: false,
        material,
        area_light: None,
        inside_medium: None,
        outside_medium: None,
    };
    let checker = params(vec![
        ("tex1", rgb(0.1, 0.2, 0.3)),
        ("tex2", rgb(0.9, 0.8, 0.7)),
        ("uscale", ParamValue::Float(vec![2.0])),
        ("vscale", ParamValue::Float(vec![2.0])),
    ]);
    let mut desc = scene(
        vec![
            tex("checks", TextureKind::Spectrum, "checkerboard", checker),
            tex(
                "broken",
                TextureKind::Spectrum,
                "imagemap",
                params(vec![("filename", ParamValue::String(vec!["nope.exr".into()]))]),
            ),
        ],
        vec![
            mat("matte", params(vec![("Kd", sref("checks", 0))]), None),
            mat("matte", params(vec![("Kd", sref("broken", 1))]), None),
        ],
        PathBuf::new(),
    );
    desc.shapes = vec![quad(0.0, Some(0)), quad(-1.0, None)];
    let w = DiagSink::new();
    let req = Requirements { accel: true, materials: true, ..Default::default() };
    let opts = BuildOptions { resolution: Some((8, 8)), ..Default::default() };
    let sc = Scene::build(&desc, req, &opts, &w).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sc.materials.as_ref().unwrap().built_count(), 1);
    assert_eq!(sc.textures.as_ref().unwrap().built_count(), 1);
    let shoot = |x: f32, y: f32, z: f32| {
        let ray = Ray::new(Vec3::new(x, y, z), Vec3::new(0.0, 0.0, -1.0), f32::INFINITY);
        let hit = sc.intersect(&ray).expect("hit");
        sc.interaction(&ray, &hit)
    };
    // uv (0.25, 0.25) → st (0.5, 0.5): even check → tex1; uv (0.75, 0.25) → odd → tex2.
    for (x, y, kd) in [(0.25, 0.25, Vec3::new(0.1, 0.2, 0.3)), (0.75, 0.25, Vec3::new(0.9, 0.8, 0.7))] {
        let si = shoot(x, y, 1.0);
        let bsdf = sc.bsdf(&si).expect("material");
        let f = bsdf.f(si.wo, dir(0.5, 1.0), BxdfFlags::ALL);
        assert!(close(f, kd / PI, 1e-5), "{f} vs {kd}");
    }
    // The lower quad has no material; hit it from below.
    let ray = Ray::new(Vec3::new(0.5, 0.5, -2.0), Vec3::Z, f32::INFINITY);
    let hit = sc.intersect(&ray).expect("hit");
    assert!(sc.bsdf(&sc.interaction(&ray, &hit)).is_none());
    assert!(sc.report.stages.iter().any(|s| s.0 == "materials"));
}

mod pbrt_v3_more;
