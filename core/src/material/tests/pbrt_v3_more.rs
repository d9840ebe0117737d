//! `disney`, `fourier`, `hair`, `subsurface` and `kdsubsurface`: the lobes each builds from its
//! parameters (pbrt-v3's `ComputeScatteringFunctions`), defaults, warnings and errors, and
//! what `Material` reports about them (type names, BSSRDFs, specular lobes, LTC form).

use super::*;
use crate::bxdf::hair::sigma_a_from_concentration;
use crate::bxdf::{DisneyLobe, HairBxdf};

fn f(v: f32) -> ParamValue {
    ParamValue::Float(vec![v])
}

fn one(desc_params: Vec<(&str, ParamValue)>, kind: &str) -> Built {
    build(&scene(vec![], vec![mat(kind, params(desc_params), None)], PathBuf::new()), &[true])
}

#[test]
fn disney_defaults_are_pbrt_v3s_lobes() {
    let b = one(vec![], "disney");
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let bsdf = bsdf_of(&b, 0, &flat_si());
    let c = Vec3::splat(0.5);
    // roughness 0.5: α = 0.25 both ways; R0 = ((1.5 − 1)/(1.5 + 1))² = 0.04, untinted.
    let r0 = ((1.5f32 - 1.0) / (1.5 + 1.0)).powi(2);
    let fresnel = Fresnel::Disney { r0: Vec3::splat(r0), metallic: 0.0, eta: 1.5 };
    assert_eq!(
        bsdf.bxdfs(),
        &[
            Bxdf::Disney(DisneyLobe::Diffuse { r: c }),
            Bxdf::Disney(DisneyLobe::Retro { r: c, roughness: 0.5 }),
            Bxdf::microfacet_reflection(Vec3::ONE, MicrofacetDistribution::disney(0.25, 0.25), fresnel),
        ]
    );
    assert_eq!(bsdf.eta, 1.0);
    let m = b.materials.get(0).unwrap();
    assert_eq!(m.type_name(), "disney");
    assert!(!m.may_have_bssrdf());
    assert!(m.ltc_lobes(&flat_si(), &b.materials, &b.textures).is_none(), "Disney has no Lambertian-plus-GGX form");
}

#[test]
fn disney_every_lobe_and_the_thin_variant() {
    let p = vec![
        ("color", rgb(0.6, 0.3, 0.1)),
        ("metallic", f(0.25)),
        ("roughness", f(0.4)),
        ("speculartint", f(0.5)),
        ("anisotropic", f(0.5)),
        ("sheen", f(0.8)),
        ("sheentint", f(0.2)),
        ("clearcoat", f(0.7)),
        ("clearcoatgloss", f(0.5)),
        ("spectrans", f(0.4)),
        ("flatness", f(0.3)),
        ("difftrans", f(0.6)),
        ("eta", f(1.4)),
        ("thin", ParamValue::Bool(vec![true])),
    ];
    let b = one(p, "disney");
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let bsdf = bsdf_of(&b, 0, &flat_si());
    let c = Vec3::new(0.6, 0.3, 0.1);
    let dw = 0.75 * 0.6; // (1 − metallic)(1 − spectrans)
    let dt = 0.3; // difftrans / 2
    let lum = c.dot(crate::spectrum::LUMINANCE_WEIGHTS);
    let tint = c / lum;
    let sheen = Vec3::ONE * 0.8 + tint * 0.2;
    let aspect = (1.0f32 - 0.5 * 0.9).sqrt();
    let (ax, ay) = (0.16 / aspect, 0.16 * aspect);
    let r0 = 0.25 * c + 0.75 * (((1.4f32 - 1.0) / 2.4).powi(2) * (0.5 * Vec3::ONE + 0.5 * tint));
    let rs = (0.65 * 1.4 - 0.35) * 0.4;
    let l = bsdf.bxdfs();
    assert_eq!(l.len(), 8, "{l:?}");
    let near = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 1e-6;
    match (l[0], l[1], l[2], l[3]) {
        (
            Bxdf::Disney(DisneyLobe::Diffuse { r: d }),
            Bxdf::Disney(DisneyLobe::FakeSubsurface { r: ss, roughness }),
            Bxdf::Disney(DisneyLobe::Retro { r: rr, .. }),
            Bxdf::Disney(DisneyLobe::Sheen { r: sh }),
        ) => {
            assert!(near(d, dw * 0.7 * (1.0 - dt) * c) && near(ss, dw * 0.3 * (1.0 - dt) * c) && roughness == 0.4);
            assert!(near(rr, dw * c) && near(sh, dw * 0.8 * sheen), "{rr} {sh}");
        }
        other => panic!("{other:?}"),
    }
    match l[4] {
        Bxdf::MicrofacetReflection { r, distribution, fresnel: Fresnel::Disney { r0: got, metallic, eta } } => {
            assert_eq!((r, metallic, eta), (Vec3::ONE, 0.25, 1.4));
            assert!(near(got, r0), "{got} vs {r0}");
            let (gx, gy) = distribution.alphas();
            assert!(matches!(distribution, MicrofacetDistribution::DisneyTrowbridgeReitz { .. }));
            assert!((gx - ax).abs() < 1e-6 && (gy - ay).abs() < 1e-6);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(l[5], Bxdf::Disney(DisneyLobe::Clearcoat { weight: Vec3::splat(0.7), gloss: 0.5 * 0.1 + 0.5 * 0.001 }));
    match l[6] {
        Bxdf::MicrofacetTransmission { t, distribution, eta_a, eta_b, .. } => {
            assert!(near(t, 0.4 * Vec3::new(0.6f32.sqrt(), 0.3f32.sqrt(), 0.1f32.sqrt())));
            assert_eq!((eta_a, eta_b), (1.0, 1.4));
            // The thin variant's transmission roughness is scaled by the index (plain Trowbridge–Reitz).
            assert!(matches!(distribution, MicrofacetDistribution::TrowbridgeReitz { .. }));
            let (gx, gy) = distribution.alphas();
            assert!(
                (gx - (rs * rs / aspect).max(0.001)).abs() < 1e-6 && (gy - (rs * rs * aspect).max(0.001)).abs() < 1e-6
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(l[7], Bxdf::LambertianTransmission { t } if near(t, dt * c)));
}

#[test]
fn disney_scatter_distance_makes_a_bssrdf_unless_thin() {
    let p = |thin: bool| {
        vec![
            ("scatterdistance", rgb(0.1, 0.2, 0.3)),
            ("color", rgb(0.5, 0.5, 0.5)),
            ("thin", ParamValue::Bool(vec![thin])),
        ]
    };
    let b = one(p(false), "disney");
    let m = b.materials.get(0).unwrap();
    assert!(m.may_have_bssrdf() && m.may_be_specular());
    let si = flat_si();
    let bsdf = bsdf_of(&b, 0, &si);
    assert_eq!(bsdf.bxdfs()[0], Bxdf::specular_transmission(Vec3::ONE, 1.0, 1.5, TransportMode::Radiance));
    let ss = m.bssrdf(&si, &TextureEvalContext::from_si(&si), &bsdf, BsdfOptions::default(), &b.textures, 0).unwrap();
    assert_eq!(ss.eta, 1.5);
    match ss.profile {
        crate::bssrdf::Profile::Disney { r, d } => {
            assert_eq!(r, Vec3::splat(0.5));
            assert!((d - 0.2 * Vec3::new(0.1, 0.2, 0.3)).abs().max_element() < 1e-7);
        }
        other => panic!("{other:?}"),
    }
    let b = one(p(true), "disney");
    let m = b.materials.get(0).unwrap();
    assert!(!m.may_have_bssrdf());
    let bsdf = bsdf_of(&b, 0, &si);
    assert!(m.bssrdf(&si, &TextureEvalContext::from_si(&si), &bsdf, BsdfOptions::default(), &b.textures, 0).is_none());
}

#[test]
fn hair_absorption_sources_defaults_and_warnings() {
    let si = si_at(Vec2::new(0.3, 0.8), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
    let hair_of = |b: &Built| -> (Bsdf, HairBxdf) {
        let bsdf = bsdf_of(b, 0, &si);
        match bsdf.bxdfs() {
            [Bxdf::Hair(h)] => (bsdf.clone(), *h),
            other => panic!("{other:?}"),
        }
    };
    // Default: eumelanin 1.3; h = −1 + 2v; the frame's x axis is ∂p/∂u.
    let b = one(vec![], "hair");
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let (bsdf, h) = hair_of(&b);
    assert_eq!(h, HairBxdf::new(-1.0 + 2.0 * 0.8, 1.55, sigma_a_from_concentration(1.3, 0.0), 0.3, 0.3, 2.0));
    assert!((bsdf.local_to_world(Vec3::X) - Vec3::Y).length() < 1e-6);
    assert_eq!(bsdf.eta, 1.55);
    // sigma_a wins over color and the melanins, with pbrt-v3's warnings.
    let b = one(vec![("sigma_a", rgb(0.1, 0.2, 0.3)), ("color", rgb(0.5, 0.5, 0.5)), ("pheomelanin", f(1.0))], "hair");
    let ws = b.warnings.snapshot();
    assert_eq!(ws.len(), 2, "{ws:?}");
    assert!(ws.iter().any(|w| w.message.contains("ignoring \"color\" since \"sigma_a\"")), "{ws:?}");
    assert!(ws.iter().any(|w| w.message.contains("ignoring \"pheomelanin\" since \"sigma_a\"")), "{ws:?}");
    assert_eq!(hair_of(&b).1, HairBxdf::new(0.6, 1.55, Vec3::new(0.1, 0.2, 0.3), 0.3, 0.3, 2.0));
    // color over the melanins; melanins alone.
    let b = one(vec![("color", rgb(0.5, 0.4, 0.3)), ("eumelanin", f(2.0)), ("beta_n", f(0.5))], "hair");
    assert_eq!(b.warnings.snapshot().len(), 1);
    let sa = crate::bxdf::hair::sigma_a_from_reflectance(Vec3::new(0.5, 0.4, 0.3), 0.5);
    assert_eq!(hair_of(&b).1, HairBxdf::new(0.6, 1.55, sa, 0.3, 0.5, 2.0));
    let b = one(vec![("eumelanin", f(0.5)), ("pheomelanin", f(-3.0)), ("eta", f(1.4)), ("alpha", f(0.0))], "hair");
    assert!(b.warnings.is_empty());
    assert_eq!(hair_of(&b).1, HairBxdf::new(0.6, 1.4, sigma_a_from_concentration(0.5, 0.0), 0.3, 0.3, 0.0));
}

#[test]
fn fourier_reads_relative_to_the_scene_and_locates_errors() {
    let dir = std::env::temp_dir().join(format!("penumbra-fourier-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = include_bytes!("../../../../scenes/materials/mono.bsdf");
    std::fs::write(dir.join("good.bsdf"), good).unwrap();
    let mut bad = good.to_vec();
    bad[24] = 2; // nChannels
    std::fs::write(dir.join("bad.bsdf"), &bad).unwrap();
    let named = |file: &str| params(vec![("bsdffile", ParamValue::String(vec![file.into()]))]);
    let desc = scene(vec![], vec![mat("fourier", named("good.bsdf"), None)], dir.clone());
    let b = build(&desc, &[true]);
    let bsdf = bsdf_of(&b, 0, &flat_si());
    assert!(matches!(bsdf.bxdfs(), [Bxdf::Fourier(_)]));
    assert_eq!((bsdf.eta, b.materials.get(0).unwrap().type_name()), (1.0, "fourier"));
    for (file, want) in [("bad.bsdf", "byte 24: expected nChannels 1 or 3"), ("missing.bsdf", "cannot read")] {
        let desc = scene(vec![], vec![mat("fourier", named(file), None)], dir.clone());
        let warnings = DiagSink::new();
        let mut textures = Textures::new(&desc);
        let e = Materials::build(&desc, &[true], &mut textures, &warnings).unwrap_err();
        assert!(e.message.contains(want) && e.message.contains(file), "{e:?}");
        assert_eq!(e.loc, Some(loc(100)), "located at the parameter");
    }
    let desc = scene(vec![], vec![mat("fourier", ParamSet::new(), None)], dir.clone());
    let mut textures = Textures::new(&desc);
    let e = Materials::build(&desc, &[true], &mut textures, &DiagSink::new()).unwrap_err();
    assert!(e.message.contains("needs a \"string bsdffile\""), "{e:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn subsurface_interface_media_and_bssrdf() {
    let si = flat_si();
    // The interface is glass's: smooth by default (specular reflection and transmission, η 1.33).
    let b = one(vec![("name", ParamValue::String(vec!["Skin1".into()])), ("g", f(0.5))], "subsurface");
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let bsdf = bsdf_of(&b, 0, &si);
    let fr = Fresnel::Dielectric { eta_i: 1.0, eta_t: 1.33 };
    assert_eq!(
        bsdf.bxdfs(),
        &[
            Bxdf::specular_reflection(Vec3::ONE, fr),
            Bxdf::specular_transmission(Vec3::ONE, 1.0, 1.33, TransportMode::Radiance)
        ]
    );
    assert_eq!(bsdf.eta, 1.33);
    let m = b.materials.get(0).unwrap();
    assert!(m.may_have_bssrdf() && m.may_be_specular() && m.ltc_lobes(&si, &b.materials, &b.textures).is_none());
    let Material::Subsurface(s) = m else { panic!() };
    // A measured medium sets g to 0 (its σ'_s are reduced coefficients).
    assert_eq!(s.g, 0.0);
    let ss = m.bssrdf(&si, &TextureEvalContext::from_si(&si), &bsdf, BsdfOptions::default(), &b.textures, 0).unwrap();
    match ss.profile {
        crate::bssrdf::Profile::Tabulated { sigma_t, rho, .. } => {
            let (a, s) = (Vec3::new(0.032, 0.17, 0.48), Vec3::new(0.74, 0.88, 1.01));
            assert!((sigma_t - (a + s)).abs().max_element() < 1e-6 && (rho - s / (a + s)).abs().max_element() < 1e-6);
        }
        other => panic!("{other:?}"),
    }
    // An unknown medium warns and keeps the defaults (whole milk).
    let b = one(vec![("name", ParamValue::String(vec!["Marmite".into()]))], "subsurface");
    assert!(b.warnings.snapshot().iter().any(|w| w.message.contains("\"Marmite\" not found")));
    // kdsubsurface: rough interface, coefficients from the albedo and mean free path.
    let b = one(
        vec![("Kd", rgb(0.2, 0.5, 0.8)), ("mfp", rgb(0.5, 0.5, 0.5)), ("uroughness", f(0.1)), ("vroughness", f(0.1))],
        "kdsubsurface",
    );
    assert!(b.warnings.is_empty(), "{:?}", b.warnings.snapshot());
    let bsdf = bsdf_of(&b, 0, &si);
    assert!(matches!(bsdf.bxdfs(), [Bxdf::MicrofacetReflection { .. }, Bxdf::MicrofacetTransmission { .. }]));
    let m = b.materials.get(0).unwrap();
    assert_eq!(m.type_name(), "kdsubsurface");
    let ss = m.bssrdf(&si, &TextureEvalContext::from_si(&si), &bsdf, BsdfOptions::default(), &b.textures, 3).unwrap();
    assert_eq!(ss.material, 3);
    match ss.profile {
        crate::bssrdf::Profile::Tabulated { sigma_t, .. } => {
            assert!((sigma_t - Vec3::splat(2.0)).abs().max_element() < 1e-5)
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn mix_scales_the_new_lobes_exactly() {
    let desc = scene(
        vec![],
        vec![
            mat("disney", params(vec![("clearcoat", f(1.0)), ("sheen", f(1.0))]), Some("d")),
            mat("hair", ParamSet::new(), Some("h")),
            mat(
                "mix",
                params(vec![
                    ("namedmaterial1", ParamValue::String(vec!["d".into()])),
                    ("namedmaterial2", ParamValue::String(vec!["h".into()])),
                    ("amount", rgb(0.25, 0.5, 0.75)),
                ]),
                None,
            ),
        ],
        PathBuf::new(),
    );
    let b = build(&desc, &[true, true, true]);
    let si = flat_si();
    let (d, h, m) = (bsdf_of(&b, 0, &si), bsdf_of(&b, 1, &si), bsdf_of(&b, 2, &si));
    let amount = Vec3::new(0.25, 0.5, 0.75);
    for (wo, wi) in [(dir(0.3, 0.2), dir(0.8, 2.0)), (dir(1.1, 0.0), dir(0.2, 4.0)), (dir(0.5, 1.0), -dir(0.6, 1.5))] {
        let want = d.f(wo, wi, BxdfFlags::ALL) * amount + h.f(wo, wi, BxdfFlags::ALL) * (Vec3::ONE - amount);
        let got = m.f(wo, wi, BxdfFlags::ALL);
        assert!((got - want).abs().max_element() <= 1e-5 * want.max_element().max(1e-3), "{got} vs {want}");
    }
}
