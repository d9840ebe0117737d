use super::*;
use crate::rng::Rng;
use penumbra_parser::{
    AnimatedTransform, CameraDesc, Entity, MaterialDesc, Param, ParamValue, SceneDescription, TextureDesc, TextureKind,
    TextureRef,
};
use std::sync::Arc as StdArc;

pub(crate) fn loc(line: u32) -> FileLoc {
    FileLoc::new(StdArc::from("test.pbrt"), line, 1)
}

pub(crate) fn scene(textures: Vec<TextureDesc>, materials: Vec<MaterialDesc>, base_dir: PathBuf) -> SceneDescription {
    SceneDescription {
        camera: CameraDesc {
            entity: Entity::default_of("perspective"),
            camera_from_world: AnimatedTransform::default(),
            world_from_camera: AnimatedTransform::default(),
            medium: None,
        },
        film: Entity::default_of("image"),
        sampler: Entity::default_of("halton"),
        filter: Entity::default_of("box"),
        integrator: Entity::default_of("directlighting"),
        accelerator: Entity::default_of("bvh"),
        transform_times: (0.0, 1.0),
        shapes: vec![],
        lights: vec![],
        area_lights: vec![],
        materials,
        textures,
        media: vec![],
        instance_definitions: vec![],
        instances: vec![],
        main_file: None,
        base_dir,
        files_read: vec![],
    }
}

pub(crate) fn params(list: Vec<(&str, ParamValue)>) -> ParamSet {
    let mut ps = ParamSet::new();
    for (i, (n, v)) in list.into_iter().enumerate() {
        ps.add(Param::new(n, v, loc(100 + i as u32)));
    }
    ps
}

pub(crate) fn tex(name: &str, kind: TextureKind, class: &str, p: ParamSet) -> TextureDesc {
    TextureDesc {
        name: name.into(),
        kind,
        entity: Entity::new(class, p, loc(10)),
        render_from_texture: AnimatedTransform::default(),
    }
}

pub(crate) fn fref(name: &str, i: usize) -> ParamValue {
    ParamValue::Texture(TextureRef { name: name.into(), float: Some(i), spectrum: None })
}

pub(crate) fn sref(name: &str, i: usize) -> ParamValue {
    ParamValue::Texture(TextureRef { name: name.into(), float: None, spectrum: Some(i) })
}

fn ctx_uv(u: f32, v: f32) -> TextureEvalContext {
    TextureEvalContext { uv: Vec2::new(u, v), ..Default::default() }
}

/// Fraction of the box `[s-ds, s+ds]×[t-dt, t+dt]` in odd checks, by a midpoint grid.
fn brute_force_checker(st: Vec2, ds: f32, dt: f32) -> f32 {
    let n = 600;
    let mut odd = 0usize;
    for i in 0..n {
        for j in 0..n {
            let s = st.x - ds + 2.0 * ds * (i as f32 + 0.5) / n as f32;
            let t = st.y - dt + 2.0 * dt * (j as f32 + 0.5) / n as f32;
            if (s.floor() as i64 + t.floor() as i64).rem_euclid(2) == 1 {
                odd += 1;
            }
        }
    }
    odd as f32 / (n * n) as f32
}

#[test]
fn checkerboard_closed_form_matches_supersampled_box_average() {
    let mut rng = Rng::new(7);
    let mut checked = 0;
    for _ in 0..40 {
        let st = Vec2::new(rng.uniform_f32() * 8.0 - 4.0, rng.uniform_f32() * 8.0 - 4.0);
        let ds = 0.05 + 0.9 * rng.uniform_f32();
        let dt = 0.05 + 0.9 * rng.uniform_f32();
        // Differentials whose per-axis max is (ds, dt).
        let (dx, dy) = (Vec2::new(ds, -0.3 * dt), Vec2::new(0.5 * ds, dt));
        let Some(a) = checkerboard_closed_form(st, dx, dy) else { continue };
        let b = brute_force_checker(st, ds, dt);
        assert!((a - b).abs() < 5e-3, "st {st} ds {ds} dt {dt}: closed form {a} vs brute force {b}");
        checked += 1;
    }
    assert!(checked > 20);
    // A footprint inside one check point-samples; a huge one averages to 1/2.
    assert_eq!(checkerboard_closed_form(Vec2::new(0.5, 0.5), Vec2::new(0.1, 0.0), Vec2::new(0.0, 0.1)), None);
    assert_eq!(checkerboard_closed_form(Vec2::new(0.5, 0.5), Vec2::new(3.0, 0.0), Vec2::new(0.0, 0.1)), Some(0.5));
}

#[test]
fn checkerboard_texture_point_and_filtered() {
    let p = params(vec![
        ("tex1", ParamValue::Float(vec![2.0])),
        ("tex2", ParamValue::Float(vec![5.0])),
        ("uscale", ParamValue::Float(vec![4.0])),
        ("vscale", ParamValue::Float(vec![4.0])),
    ]);
    let desc = scene(vec![tex("c", TextureKind::Float, "checkerboard", p)], vec![], PathBuf::new());
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    t.ensure(0, &w).unwrap();
    assert!(w.is_empty(), "{:?}", w.snapshot());
    // (u, v) = (0.1, 0.1) → st (0.4, 0.4): even check → tex1. (0.3, 0.1) → (1.2, 0.4): odd → tex2.
    assert_eq!(t.eval_float(FloatParam::Tex(0), &ctx_uv(0.1, 0.1)), 2.0);
    assert_eq!(t.eval_float(FloatParam::Tex(0), &ctx_uv(0.3, 0.1)), 5.0);
    // Negative cells: (-0.1, 0.1) → (-0.4, 0.4): floor sum -1 → odd → tex2.
    assert_eq!(t.eval_float(FloatParam::Tex(0), &ctx_uv(-0.1, 0.1)), 5.0);
    // A footprint straddling s = 1 evenly: half in each → 3.5.
    let mut c = ctx_uv(0.25, 0.1);
    c.dudx = 0.05;
    let v = t.eval_float(FloatParam::Tex(0), &c);
    assert!((v - 3.5).abs() < 1e-5, "{v}");
}

/// pbrt-v3's `dots` shows its `"outside"` texture in the dots and `"inside"` between them
/// (its constructor's parameters are swapped), as the real pbrt-v3 renders
/// `textures/dots.pbrt` of the pbrt-v3 scene collection.
#[test]
fn dots_show_outside_in_the_dots_as_pbrt_v3() {
    let p = params(vec![("inside", ParamValue::Float(vec![2.0])), ("outside", ParamValue::Float(vec![7.0]))]);
    let desc = scene(vec![tex("d", TextureKind::Float, "dots", p)], vec![], PathBuf::new());
    let mut t = Textures::new(&desc);
    t.ensure(0, &DiagSink::new()).unwrap();
    let n2 = |x: f32, y: f32| noise(Vec3::new(x, y, 0.5));
    let (mut dots, mut between) = (0, 0);
    for cell in 0..64 {
        let (sc, tc) = ((cell % 8) as f32, (cell / 8) as f32);
        // A dot's centre (its cell's noise decides whether it has one) and a cell corner.
        let centre = Vec2::new(sc + 0.15 * n2(sc + 1.5, tc + 2.8), tc + 0.15 * n2(sc + 4.5, tc + 9.8));
        if n2(sc + 0.5, tc + 0.5) > 0.0 {
            assert_eq!(t.eval_float(FloatParam::Tex(0), &ctx_uv(centre.x, centre.y)), 7.0);
            dots += 1;
        }
        assert_eq!(t.eval_float(FloatParam::Tex(0), &ctx_uv(sc + 0.5, tc + 0.5)), 2.0);
        between += 1;
    }
    assert!(dots > 10 && between == 64);
}

#[test]
fn checkerboard_3d_uses_point_parity() {
    let p = params(vec![("dimension", ParamValue::Int(vec![3]))]);
    let desc = scene(vec![tex("c", TextureKind::Spectrum, "checkerboard", p)], vec![], PathBuf::new());
    let mut t = Textures::new(&desc);
    t.ensure(0, &DiagSink::new()).unwrap();
    let at = |p: Vec3| t.eval_spectrum(SpectrumParam::Tex(0), &TextureEvalContext { p, ..Default::default() });
    assert_eq!(at(Vec3::new(0.5, 0.5, 0.5)), Vec3::ONE);
    assert_eq!(at(Vec3::new(1.5, 0.5, 0.5)), Vec3::ZERO);
    assert_eq!(at(Vec3::new(1.5, 1.5, 0.5)), Vec3::ONE);
    assert_eq!(at(Vec3::new(-0.5, 0.5, 0.5)), Vec3::ZERO);
}

#[test]
fn mappings_at_known_points() {
    let uv = Mapping2D::Uv { su: 2.0, sv: 3.0, du: 0.5, dv: -1.0 };
    let mut c = ctx_uv(0.25, 0.5);
    c.dudx = 0.1;
    c.dvdy = 0.2;
    let (st, dx, dy) = uv.map(&c);
    assert_eq!(st, Vec2::new(1.0, 0.5));
    assert_eq!(dx, Vec2::new(0.2, 0.0));
    assert_eq!(dy, Vec2::new(0.0, 0.6));

    let planar = Mapping2D::Planar { vs: Vec3::new(1.0, 0.0, 0.0), vt: Vec3::new(0.0, 0.0, 2.0), ds: 0.25, dt: 0.0 };
    let c = TextureEvalContext { p: Vec3::new(3.0, 7.0, -1.0), dpdx: Vec3::new(0.0, 0.0, 1.0), ..Default::default() };
    let (st, dx, _) = planar.map(&c);
    assert_eq!(st, Vec2::new(3.25, -2.0));
    assert_eq!(dx, Vec2::new(0.0, 2.0));

    // Spherical about a texture space translated to (1, 0, 0).
    let xf = Transform::translate([1.0, 0.0, 0.0]);
    let w = DiagSink::new();
    let sph = Mapping2D::from_params(
        &params(vec![("mapping", ParamValue::String(vec!["spherical".into()]))]),
        &xf,
        &loc(1),
        &w,
    );
    let at = |p: Vec3| sph.map(&TextureEvalContext { p, ..Default::default() }).0;
    let near = |a: Vec2, b: Vec2| (a - b).length() < 1e-5;
    assert!(near(at(Vec3::new(1.0, 0.0, 5.0)), Vec2::new(0.0, 0.0)));
    assert!(near(at(Vec3::new(3.0, 0.0, 0.0)), Vec2::new(0.5, 0.0)));
    assert!(near(at(Vec3::new(1.0, 2.0, 0.0)), Vec2::new(0.5, 0.25)));
    assert!(near(at(Vec3::new(1.0, -2.0, 0.0)), Vec2::new(0.5, 0.75)));
    assert!(near(at(Vec3::new(1.0, 0.0, -1.0)), Vec2::new(1.0, 0.0)));

    let cyl = Mapping2D::Cylindrical { texture_from_render: Mat4::IDENTITY };
    let (st, _, _) = cyl.map(&TextureEvalContext { p: Vec3::new(0.0, 1.0, 0.0), ..Default::default() });
    assert!(near(st, Vec2::new(0.75, 0.0)), "{st}");
    assert!(w.is_empty());
}

/// 4×4 image, top row first: R = x + 4·y_top, G = 2R, B = 0.25, written as PFM (bottom row first).
fn write_test_pfm(dir: &Path, name: &str, scale: f32) -> PathBuf {
    let mut bytes = b"PF\n4 4\n-1.0\n".to_vec();
    for yb in 0..4 {
        let y_top = 3 - yb;
        for x in 0..4 {
            let r = (x + 4 * y_top) as f32 * scale;
            for v in [r, 2.0 * r, 0.25] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("penumbra-texture-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Texel (x, y_top) red value of the test image.
fn red(x: i32, y_top: i32) -> f32 {
    (x + 4 * y_top) as f32
}

#[test]
fn imagemap_bilinear_lookup_and_wrap_modes() {
    let dir = temp_dir("wrap");
    write_test_pfm(&dir, "img.pfm", 1.0);
    let mk = |wrap: &str| {
        tex(
            "img",
            TextureKind::Spectrum,
            "imagemap",
            params(vec![
                ("filename", ParamValue::String(vec!["img.pfm".into()])),
                ("wrap", ParamValue::String(vec![wrap.into()])),
            ]),
        )
    };
    let desc = scene(vec![mk("repeat"), mk("clamp"), mk("black"), mk("repeat")], vec![], dir.clone());
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    for i in 0..4 {
        t.ensure(i, &w).unwrap();
    }
    assert!(w.is_empty(), "{:?}", w.snapshot());
    // Two textures on the same (file, gamma, wrap) share one pyramid.
    assert_eq!(t.image_count(), 3);
    let ev = |i: usize, u: f32, v: f32| t.eval_spectrum(SpectrumParam::Tex(i), &ctx_uv(u, v));
    // Texel centres: (s, t) = ((x+.5)/4, (j+.5)/4) with j counted from the bottom.
    for x in 0..4 {
        for j in 0..4 {
            let c = ev(0, (x as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 4.0);
            let r = red(x, 3 - j);
            assert!((c - Vec3::new(r, 2.0 * r, 0.25)).length() < 1e-5, "texel ({x},{j}): {c}");
        }
    }
    // Halfway between texels (1, j=2) and (2, j=2), and a 4-texel bilinear mix.
    let r = ev(0, 0.5, 2.5 / 4.0).x;
    assert!((r - 0.5 * (red(1, 1) + red(2, 1))).abs() < 1e-5);
    let r = ev(0, 0.5, 0.5).x;
    let expect = 0.25 * (red(1, 1) + red(2, 1) + red(1, 2) + red(2, 2));
    assert!((r - expect).abs() < 1e-5, "{r} vs {expect}");
    // s = 0 lies halfway between texel -1 and texel 0.
    let v = 0.5 / 4.0; // bottom row centre (y_top = 3)
    let rep = ev(0, 0.0, v).x;
    assert!((rep - 0.5 * (red(3, 3) + red(0, 3))).abs() < 1e-5, "repeat {rep}");
    let cl = ev(1, 0.0, v).x;
    assert!((cl - red(0, 3)).abs() < 1e-5, "clamp {cl}");
    let bl = ev(2, 0.0, v).x;
    assert!((bl - 0.5 * red(0, 3)).abs() < 1e-5, "black {bl}");
    // Repeat is periodic.
    assert!((ev(0, 0.3 + 2.0, 0.7 - 1.0) - ev(0, 0.3, 0.7)).length() < 1e-4);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn imagemap_gamma_scale_invert_and_float_luminance() {
    let dir = temp_dir("gamma");
    write_test_pfm(&dir, "g.pfm", 1.0 / 16.0);
    let fname = ParamValue::String(vec!["g.pfm".into()]);
    let desc = scene(
        vec![
            tex(
                "a",
                TextureKind::Spectrum,
                "imagemap",
                params(vec![("filename", fname.clone()), ("gamma", ParamValue::Bool(vec![true]))]),
            ),
            tex(
                "b",
                TextureKind::Float,
                "imagemap",
                params(vec![("filename", fname.clone()), ("scale", ParamValue::Float(vec![2.0]))]),
            ),
            tex(
                "c",
                TextureKind::Float,
                "imagemap",
                params(vec![
                    ("filename", fname.clone()),
                    ("gamma", ParamValue::Bool(vec![true])),
                    ("invert", ParamValue::Bool(vec![true])),
                ]),
            ),
        ],
        vec![],
        dir.clone(),
    );
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    for i in 0..3 {
        t.ensure(i, &w).unwrap();
    }
    let (x, j) = (1, 3);
    let c = ctx_uv((x as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 4.0);
    let r = red(x, 3 - j) / 16.0;
    let raw = Vec3::new(r, 2.0 * r, 0.25);
    let a = t.eval_spectrum(SpectrumParam::Tex(0), &c);
    let expect = Vec3::new(
        crate::spectrum::srgb_decode(raw.x),
        crate::spectrum::srgb_decode(raw.y),
        crate::spectrum::srgb_decode(raw.z),
    );
    assert!((a - expect).length() < 1e-5, "{a} vs {expect}");
    assert!((crate::spectrum::srgb_decode(0.5) - 0.214_041_14).abs() < 1e-6);
    let b = t.eval_float(FloatParam::Tex(1), &c);
    assert!((b - 2.0 * luminance(raw)).abs() < 1e-5);
    // pbrt-v3 decodes the luminance of the raw values for float image textures.
    let cc = t.eval_float(FloatParam::Tex(2), &c);
    assert!((cc - (1.0 - crate::spectrum::srgb_decode(luminance(raw)))).abs() < 1e-5);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn mipmap_filters_average_large_footprints_and_resample_keeps_constants() {
    let data: Vec<f32> = (0..16).map(|i| i as f32).collect();
    let mean = 7.5;
    for wrap in [WrapMode::Repeat, WrapMode::Clamp] {
        let m = MipMap::new(4, 4, data.clone(), wrap).unwrap();
        assert_eq!(m.levels(), 3);
        let st = Vec2::new(0.3, 0.6);
        let big = (Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0));
        assert!((m.lookup(st, big.0, big.1, true, 8.0) - mean).abs() < 1e-5);
        assert!((m.lookup(st, big.0, big.1, false, 8.0) - mean).abs() < 1e-5);
        // Zero differentials: both filters reduce to bilinear on level 0.
        let z = Vec2::ZERO;
        assert_eq!(m.lookup(st, z, z, true, 8.0), m.bilerp(0, st));
        assert_eq!(m.lookup(st, z, z, false, 8.0), m.bilerp(0, st));
        // Trilinear: the level is log2 of the largest footprint component (pbrt-v3 after its
        // aaa552a), here a half of the texture: level 1 of 3 exactly, bilinear there.
        let half = (Vec2::new(0.5, 0.1), Vec2::new(-0.2, 0.3));
        assert_eq!(m.lookup(st, half.0, half.1, true, 8.0), m.bilerp(1, st));
        // EWA with a small footprint stays close to the bilinear value.
        let e = m.lookup(Vec2::new(0.5, 0.5), Vec2::new(0.01, 0.0), Vec2::new(0.0, 0.01), false, 8.0);
        assert!((e - m.bilerp(0, Vec2::new(0.5, 0.5))).abs() < 0.6, "{e}");
    }
    // Non-power-of-two images are Lanczos-resampled up; constants survive exactly.
    let m = MipMap::new(3, 5, vec![Vec3::splat(0.7); 15], WrapMode::Repeat).unwrap();
    assert_eq!(m.resolution(), (4, 8));
    for t in 0..8 {
        for s in 0..4 {
            assert!((m.texel(0, s, t) - Vec3::splat(0.7)).abs().max_element() < 1e-5);
        }
    }
}

#[test]
fn scale_and_mix_compose_textures() {
    let desc = scene(
        vec![
            tex("two", TextureKind::Float, "constant", params(vec![("value", ParamValue::Float(vec![2.0]))])),
            tex("three", TextureKind::Float, "constant", params(vec![("value", ParamValue::Float(vec![3.0]))])),
            tex(
                "prod",
                TextureKind::Float,
                "scale",
                params(vec![("tex1", fref("two", 0)), ("tex2", fref("three", 1))]),
            ),
            tex("amt", TextureKind::Float, "constant", params(vec![("value", ParamValue::Float(vec![0.25]))])),
            tex(
                "mixed",
                TextureKind::Float,
                "mix",
                params(vec![
                    ("tex1", fref("prod", 2)),
                    ("tex2", ParamValue::Float(vec![10.0])),
                    ("amount", fref("amt", 3)),
                ]),
            ),
            tex(
                "red",
                TextureKind::Spectrum,
                "constant",
                params(vec![("value", ParamValue::Spectrum(SpectrumValue::Rgb(vec![1.0, 0.5, 0.25])))]),
            ),
            tex("smix", TextureKind::Spectrum, "mix", params(vec![("tex2", sref("red", 5))])),
            tex(
                "sscale",
                TextureKind::Spectrum,
                "scale",
                params(vec![("tex1", sref("red", 5)), ("tex2", sref("red", 5))]),
            ),
        ],
        vec![],
        PathBuf::new(),
    );
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    t.ensure(4, &w).unwrap();
    // Building "mixed" built exactly what it references.
    assert_eq!(t.built_count(), 5);
    let c = TextureEvalContext::default();
    assert_eq!(t.eval_float(FloatParam::Tex(2), &c), 6.0);
    assert!((t.eval_float(FloatParam::Tex(4), &c) - (0.75 * 6.0 + 0.25 * 10.0)).abs() < 1e-6);
    t.ensure(6, &w).unwrap();
    t.ensure(7, &w).unwrap();
    // Spectrum mix defaults: tex1 = 0, amount = 0.5.
    assert!((t.eval_spectrum(SpectrumParam::Tex(6), &c) - Vec3::new(0.5, 0.25, 0.125)).length() < 1e-6);
    assert!((t.eval_spectrum(SpectrumParam::Tex(7), &c) - Vec3::new(1.0, 0.25, 0.0625)).length() < 1e-6);
    assert!(w.is_empty(), "{:?}", w.snapshot());
}

#[test]
fn textures_are_built_lazily_and_unused_broken_ones_are_harmless() {
    let dir = temp_dir("lazy");
    let desc = scene(
        vec![
            tex(
                "broken",
                TextureKind::Spectrum,
                "imagemap",
                params(vec![("filename", ParamValue::String(vec!["does-not-exist.pfm".into()]))]),
            ),
            tex("ok", TextureKind::Spectrum, "constant", params(vec![])),
        ],
        vec![],
        dir.clone(),
    );
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    let mat = params(vec![("Kd", sref("ok", 1))]);
    let p = t.get_spectrum_param(&mat, "Kd", Vec3::splat(0.5), &w).unwrap();
    assert_eq!(p, SpectrumParam::Tex(1));
    assert!(t.is_built(1) && !t.is_built(0));
    assert_eq!(t.built_count(), 1);
    // Referencing the broken one is a located error at its filename parameter.
    let mat = params(vec![("Kd", sref("broken", 0))]);
    let e = t.get_spectrum_param(&mat, "Kd", Vec3::splat(0.5), &w).unwrap_err();
    assert!(e.is_error());
    assert!(e.message.contains("does-not-exist.pfm"), "{}", e.message);
    assert_eq!(e.loc, Some(loc(100)));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn texture_param_lookup_rules() {
    let desc = scene(
        vec![tex("f", TextureKind::Float, "constant", params(vec![("value", ParamValue::Float(vec![0.3]))]))],
        vec![],
        PathBuf::new(),
    );
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    let p = params(vec![
        ("roughness", fref("f", 0)),
        ("sigma", ParamValue::Float(vec![20.0])),
        ("Kd", ParamValue::Spectrum(SpectrumValue::Rgb(vec![0.1, 0.2, 0.3]))),
        ("Ks", ParamValue::Texture(TextureRef { name: "nope".into(), float: None, spectrum: None })),
        ("Kr", fref("f", 0)),
    ]);
    assert_eq!(t.get_float_param(&p, "roughness", 0.1, &w).unwrap(), FloatParam::Tex(0));
    assert_eq!(t.get_float_param(&p, "sigma", 0.0, &w).unwrap(), FloatParam::Const(20.0));
    assert_eq!(t.get_float_param(&p, "bumpmap", 7.0, &w).unwrap(), FloatParam::Const(7.0));
    assert_eq!(t.get_float_param_opt(&p, "uroughness", &w).unwrap(), None);
    assert_eq!(t.get_spectrum_param(&p, "Kd", Vec3::ONE, &w).unwrap(), SpectrumParam::Const(Vec3::new(0.1, 0.2, 0.3)));
    assert_eq!(t.get_spectrum_param(&p, "Kt", Vec3::ONE, &w).unwrap(), SpectrumParam::Const(Vec3::ONE));
    let e = t.get_spectrum_param(&p, "Ks", Vec3::ONE, &w).unwrap_err();
    assert!(e.message.contains("nope") && e.loc == Some(loc(103)), "{e:?}");
    // A float texture where a spectrum one is needed is an error too.
    let e = t.get_spectrum_param(&p, "Kr", Vec3::ONE, &w).unwrap_err();
    assert!(e.message.contains("spectrum texture named \"f\""), "{}", e.message);
    assert!(t.eval_float(FloatParam::Tex(0), &TextureEvalContext::default()) == 0.3);
}

#[test]
fn bad_texture_definitions_are_located_errors() {
    let desc = scene(
        vec![
            tex("a", TextureKind::Float, "checkerboard", params(vec![("dimension", ParamValue::Int(vec![4]))])),
            tex("b", TextureKind::Float, "sparkles", params(vec![])),
            tex("c", TextureKind::Float, "uv", params(vec![])),
            tex("d", TextureKind::Spectrum, "imagemap", params(vec![])),
        ],
        vec![],
        PathBuf::new(),
    );
    let mut t = Textures::new(&desc);
    let w = DiagSink::new();
    for i in 0..4 {
        let e = t.ensure(i, &w).unwrap_err();
        assert!(e.is_error() && e.loc.is_some(), "{e:?}");
    }
    assert_eq!(t.built_count(), 0);
}

#[test]
fn perlin_noise_properties() {
    let perm = noise_perm();
    let mut seen = [false; 256];
    for &v in &perm[..256] {
        seen[v as usize] = true;
    }
    assert!(seen.iter().all(|&s| s));
    assert_eq!(perm[..256], perm[256..]);
    // Zero at lattice points, bounded, continuous, not identically zero.
    let mut rng = Rng::new(3);
    let mut max_abs = 0.0f32;
    for _ in 0..2000 {
        let p = Vec3::new(rng.uniform_f32(), rng.uniform_f32(), rng.uniform_f32()) * 20.0 - Vec3::splat(10.0);
        assert_eq!(noise(p.floor()), 0.0);
        let n = noise(p);
        assert!(n.abs() <= 1.0 + 1e-5);
        assert!((noise(p + Vec3::splat(1e-4)) - n).abs() < 1e-2);
        max_abs = max_abs.max(n.abs());
    }
    assert!(max_abs > 0.3);
    // Zero differentials: all octaves.
    let p = Vec3::new(0.3, 0.7, 0.1);
    let f: f32 = (0..8).map(|i| 0.5f32.powi(i) * noise(1.99f32.powi(i) * p)).sum();
    assert!((fbm(p, Vec3::ZERO, Vec3::ZERO, 0.5, 8) - f).abs() < 1e-5);
}

#[test]
fn ray_differentials_give_uv_derivatives() {
    use crate::geometry::{Ray, RayDifferential, RayOffsets};
    // Plane z = 0 with u = x/2, v = y/4: ∂p/∂u = (2,0,0), ∂p/∂v = (0,4,0).
    let mut si = SurfaceInteraction {
        p: Vec3::new(1.0, 1.0, 0.0),
        uv: Vec2::new(0.5, 0.25),
        dpdu: Vec3::new(2.0, 0.0, 0.0),
        dpdv: Vec3::new(0.0, 4.0, 0.0),
        ..Default::default()
    };
    let down = Vec3::new(0.0, 0.0, -1.0);
    let ray = |rx: (Vec3, Vec3), ry: (Vec3, Vec3)| RayDifferential {
        ray: Ray::new(Vec3::new(1.0, 1.0, 3.0), down, f32::INFINITY),
        offsets: Some(RayOffsets { rx_o: rx.0, rx_d: rx.1, ry_o: ry.0, ry_d: ry.1 }),
    };
    si.compute_differentials(&ray((Vec3::new(1.1, 1.0, 3.0), down), (Vec3::new(1.0, 1.2, 3.0), down)));
    let c = TextureEvalContext::from_si(&si);
    assert!((c.dpdx - Vec3::new(0.1, 0.0, 0.0)).length() < 1e-5);
    assert!((c.dudx - 0.05).abs() < 1e-5 && c.dvdx.abs() < 1e-6);
    assert!((c.dvdy - 0.05).abs() < 1e-5 && c.dudy.abs() < 1e-6);
    // Parallel offset rays: no differentials.
    let side = Vec3::X;
    si.compute_differentials(&ray((Vec3::ONE, side), (Vec3::ONE, side)));
    let c = TextureEvalContext::from_si(&si);
    assert_eq!((c.dudx, c.dvdy, c.dpdx), (0.0, 0.0, Vec3::ZERO));
    // No offset rays: no differentials.
    si.compute_differentials(&RayDifferential::plain(Ray::new(Vec3::ZERO, down, 1.0)));
    assert_eq!(si.diff, Default::default());
}

/// pbrt-v3's `MarbleTexture::Evaluate` spline, written as its Bernstein polynomial in f64 (not
/// de Casteljau, as penumbra and pbrt-v3 do): `first = min(1, ⌊6t⌋)` and parameter `6t − first`,
/// which runs to 5 at t = 1, so the cubic is extrapolated far past its control points.
fn pbrt_v3_marble_spline(t: f64) -> [f64; 3] {
    const C: [[f64; 3]; 9] = [
        [0.58, 0.58, 0.6],
        [0.58, 0.58, 0.6],
        [0.58, 0.58, 0.6],
        [0.5, 0.5, 0.5],
        [0.6, 0.59, 0.58],
        [0.58, 0.58, 0.6],
        [0.58, 0.58, 0.6],
        [0.2, 0.2, 0.33],
        [0.58, 0.58, 0.6],
    ];
    let first = ((6.0 * t).floor() as usize).min(1);
    let u = 6.0 * t - first as f64;
    let b = [(1.0 - u).powi(3), 3.0 * u * (1.0 - u).powi(2), 3.0 * u * u * (1.0 - u), u.powi(3)];
    std::array::from_fn(|c| 1.5 * (0..4).map(|i| b[i] * C[first + i][c]).sum::<f64>())
}

#[test]
fn marble_follows_pbrt_v3_including_its_extrapolated_spline() {
    // The closed form's own figures: t = 1 evaluates the cubic at 5 (1.5 × 27.08 = 40.62 in R,
    // 42.15 in B), and the spline jumps at t = 1/6 where `first` turns from 0 to 1.
    let at1 = pbrt_v3_marble_spline(1.0);
    assert!((at1[0] - 40.62).abs() < 1e-9 && (at1[2] - 42.15).abs() < 1e-9, "{at1:?}");
    assert!((pbrt_v3_marble_spline(0.0)[0] - 0.87).abs() < 1e-12);
    // With variation 0 the marble is sin(scale · y) of the texture-space point, and pbrt-v3's
    // 3D mapping applies the texture's CTM itself (not its inverse): a Translate 0 T 0 moves
    // the lookup to y + T.
    let (scale, shift) = (0.7f32, -0.4f32);
    let p = params(vec![("scale", ParamValue::Float(vec![scale])), ("variation", ParamValue::Float(vec![0.0]))]);
    let mut d = tex("m", TextureKind::Spectrum, "marble", p);
    d.render_from_texture = AnimatedTransform::fixed(penumbra_parser::Transform::translate([0.0, shift as f64, 0.0]));
    let desc = scene(vec![d], vec![], PathBuf::new());
    let mut t = Textures::new(&desc);
    t.ensure(0, &DiagSink::new()).unwrap();
    let mut worst = 0.0f64;
    let mut seen_extrapolated = false;
    for i in 0..=400 {
        // y over more than a period of sin(scale·y): every t in [0, 1].
        let y = -6.0 + i as f32 * 0.03;
        let ctx = TextureEvalContext { p: Vec3::new(0.3, y, -1.2), ..Default::default() };
        let got = t.eval_spectrum(SpectrumParam::Tex(0), &ctx);
        let tt = 0.5 + 0.5 * ((scale * (y + shift)) as f64).sin();
        if (6.0 * tt - (6.0 * tt).round()).abs() < 1e-3 {
            continue; // at a segment boundary f32 and f64 may pick different `first`
        }
        let want = pbrt_v3_marble_spline(tt);
        for c in 0..3 {
            // f32 evaluation of a cubic at up to 5: relative 1e-5 of its magnitude.
            let err = (got[c] as f64 - want[c]).abs() / want[c].abs().max(1.0);
            worst = worst.max(err);
        }
        seen_extrapolated |= want[2] > 10.0;
    }
    assert!(seen_extrapolated);
    assert!(worst < 2e-4, "marble differs from pbrt-v3's spline by {worst:e} (relative)");
    // With variation, the fbm term (scaled point and differentials) is added before the sine.
    let p = params(vec![("scale", ParamValue::Float(vec![2.0])), ("octaves", ParamValue::Int(vec![4]))]);
    let desc = scene(vec![tex("m", TextureKind::Spectrum, "marble", p)], vec![], PathBuf::new());
    let mut t = Textures::new(&desc);
    t.ensure(0, &DiagSink::new()).unwrap();
    for q in [Vec3::new(0.3, 0.2, 1.7), Vec3::new(-2.1, 0.05, 4.4), Vec3::new(1.0, 1.1, 3.0)] {
        let (dx, dy) = (Vec3::new(0.01, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.02));
        let ctx = TextureEvalContext { p: q, dpdx: dx, dpdy: dy, ..Default::default() };
        let m = 2.0 * q.y + 0.2 * fbm(2.0 * q, 2.0 * dx, 2.0 * dy, 0.5, 4);
        let want = pbrt_v3_marble_spline(0.5 + 0.5 * (m as f64).sin());
        let got = t.eval_spectrum(SpectrumParam::Tex(0), &ctx);
        for c in 0..3 {
            assert!((got[c] as f64 - want[c]).abs() <= 2e-4 * want[c].abs().max(1.0), "{q}: {got} vs {want:?}");
        }
    }
}
