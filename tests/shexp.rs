//! `shexp` (seed 003): closed forms and invariants of its pieces, and renders against the
//! pbrt-v3 references.

mod common;

use glam::DVec3;
use penumbra_core::geometry::Ray;
use penumbra_core::scene::{BuildOptions, Requirements, Scene};
use penumbra_core::sh::ShOrder;
use penumbra_core::sh::{self, ShRotation};
use penumbra_core::Vec3;
use penumbra_integrators::shexp::lighting::EnvLighting;
use penumbra_integrators::shexp::sphereset::{self, Sphere, SphereSets};
use penumbra_integrators::shexp::visibility::{ExpChoice, Visibility};
use penumbra_parser::DiagSink;
use std::f64::consts::PI;

fn scene(rel: &str) -> Scene {
    let parsed = penumbra_parser::parse_file(&common::scene(rel)).unwrap();
    let req = Requirements { lights: true, ..Default::default() };
    Scene::build(&parsed.scene, req, &BuildOptions::default(), &DiagSink::new()).unwrap()
}

/// `∫ L(ω) max(0, n·ω) y(ω) dω` per channel by brute force over a fine (θ, φ) grid of world
/// directions (order 4).
fn lh_brute(scene: &Scene, n: DVec3, ground: Option<DVec3>) -> Vec<[f64; 3]> {
    let (nt, np) = (800, 1600);
    let mut out = vec![[0.0; 3]; 16];
    let order = ShOrder::new(4).unwrap();
    for i in 0..nt {
        let t = PI * (i as f64 + 0.5) / nt as f64;
        for j in 0..np {
            let p = 2.0 * PI * (j as f64 + 0.5) / np as f64;
            let d = DVec3::new(t.sin() * p.cos(), t.cos(), t.sin() * p.sin());
            let c = n.dot(d);
            if c <= 0.0 || ground.is_some_and(|g| g.dot(d) <= 0.0) {
                continue;
            }
            let dw = t.sin() * (PI / nt as f64) * (2.0 * PI / np as f64);
            let ray = Ray::new(Vec3::ZERO, d.as_vec3(), f32::INFINITY);
            let l: Vec3 = scene.light_list().iter().map(|l| l.le(&ray)).sum();
            let y = penumbra_core::sh::eval_vec(order, d);
            for (o, yi) in out.iter_mut().zip(&y) {
                for c2 in 0..3 {
                    o[c2] += l[c2] as f64 * c * dw * yi;
                }
            }
        }
    }
    out
}

#[test]
fn lh_matches_brute_force_irradiance() {
    let s = scene("suite/env/objects-studio.pbrt");
    let lights: Vec<_> = s.light_list().iter().collect();
    let order = ShOrder::new(4).unwrap();
    for ground in [None, Some(DVec3::Y)] {
        let env = EnvLighting::from_lights(&lights, ground, order, 32);
        let mut lh = vec![[0.0; 3]; 16];
        let mut tmp = vec![0.0; 16];
        for n in [DVec3::Y, DVec3::X, -DVec3::X, DVec3::Z, -DVec3::Z, DVec3::new(0.3, 0.5, -0.8).normalize()] {
            env.lh(n, &mut lh, &mut tmp);
            let brute = lh_brute(&s, n, ground);
            let scale = brute[0].iter().fold(0.0f64, |a, b| a.max(b.abs()));
            for (i, (a, b)) in lh.iter().zip(&brute).enumerate() {
                eprintln!("ground {ground:?} n {n:.2} coeff {i}: ours {:.5} brute {:.5}", a[1], b[1]);
                for c in 0..3 {
                    assert!((a[c] - b[c]).abs() <= 0.004 * scale, "coeff {i} ch {c}: {} vs {}", a[c], b[c]);
                }
            }
        }
    }
}

/// `LH(n)` of a uniform sky of radiance 1 (closed form: the clamped cosine turned to n).
fn uniform_lh(n: DVec3, order: ShOrder) -> Vec<f64> {
    let mut lh = vec![0.0; order.coeffs()];
    sh::zonal::rotate_zh(&sh::zonal::clamped_cosine(order), n, &mut lh).unwrap();
    lh
}

/// shexp's `∫ V max(0, n·ω) dω / π` for `spheres` at receiver `p` under the uniform sky.
fn shaded(vis: &Visibility, p: DVec3, n: DVec3, spheres: &[Sphere]) -> f64 {
    let order = vis.order();
    let mut v = vec![0.0; order.coeffs()];
    let mut s = vis.scratch();
    vis.vector(p, n, &mut |f: &mut dyn FnMut(&Sphere)| spheres.iter().for_each(&mut *f), &mut s, &mut v);
    let lh = uniform_lh(n, order);
    lh.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() / PI
}

fn sphere_at(theta_deg: f64, beta_deg: f64, dist: f64) -> Sphere {
    let (t, b) = (theta_deg.to_radians(), beta_deg.to_radians());
    Sphere { center: DVec3::new(b.sin(), 0.0, b.cos()) * dist, radius: dist * t.sin() }
}

#[test]
fn one_sphere_over_a_plane_under_a_uniform_sky() {
    // The digest's table (seed 003 notes §9): exact cos-weighted visible fraction
    // 1 − sin²θ cos β, order-4 values within 0.012 of it up to θ = 45°.
    let order = ShOrder::new(4).unwrap();
    // Columns: θ, β, the digest's exact-exp∘log and OL values (its log table is not Newton-refined
    // as core's is, which moves exp∘log at 45° from 0.4924 to the projection's 0.4931).
    let table = [
        (10.0, 0.0, 0.9680, 0.9679),
        (30.0, 0.0, 0.7404, 0.7369),
        (30.0, 45.0, 0.8277, 0.8254),
        (45.0, 0.0, 0.4924, 0.5088),
    ];
    for exp in [ExpChoice::ScalingSquaring, ExpChoice::Hybrid, ExpChoice::OptimalLinear] {
        let vis = Visibility::new(order, exp, 45f64.to_radians()).unwrap();
        for (theta, beta, exp_log, ol) in table {
            let got = shaded(&vis, DVec3::ZERO, DVec3::Z, &[sphere_at(theta, beta, 1.0)]);
            let exact = 1.0 - theta.to_radians().sin().powi(2) * beta.to_radians().cos();
            eprintln!("{exp:?} θ {theta} β {beta}: shexp {got:.4}, exact {exact:.4}, digest exp∘log {exp_log} OL {ol}");
            match exp {
                // The exponential is exact to 1e-9 here: the digest's exact-exp∘log column.
                ExpChoice::ScalingSquaring => assert!((got - exp_log).abs() <= 8e-4, "θ {theta}: {got} vs {exp_log}"),
                ExpChoice::OptimalLinear => assert!((got - ol).abs() <= 8e-4, "θ {theta}: {got} vs {ol}"),
                ExpChoice::Hybrid => {}
            }
            // OL misses by 0.0131 at 30° (the digest's figure too): its table is fitted on
            // single spheres, but it is not the default.
            let tol = if exp == ExpChoice::OptimalLinear { 0.014 } else { 0.012 };
            assert!((got - exact).abs() <= tol, "{exp:?} θ {theta} β {beta}: {got} vs exact {exact}");
        }
    }
}

/// A small deterministic generator for configurations.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn random_spheres(rng: &mut Lcg, count: usize) -> Vec<Sphere> {
    (0..count)
        .map(|_| {
            let (u, v) = (rng.next(), rng.next());
            let z = 0.15 + 0.85 * u;
            let phi = 2.0 * PI * v;
            let dir = DVec3::new((1.0 - z * z).sqrt() * phi.cos(), (1.0 - z * z).sqrt() * phi.sin(), z);
            let dist = 1.0 + 2.0 * rng.next();
            Sphere { center: dir * dist, radius: dist * (5.0 + 25.0 * rng.next()).to_radians().sin() }
        })
        .collect()
}

#[test]
fn adding_a_sphere_never_brightens() {
    let order = ShOrder::new(4).unwrap();
    let vis = Visibility::new(order, ExpChoice::ScalingSquaring, 45f64.to_radians()).unwrap();
    let mut rng = Lcg(7);
    let mut worst: f64 = 0.0;
    for _ in 0..300 {
        let count = 1 + (rng.next() * 8.0) as usize;
        let mut spheres = random_spheres(&mut rng, count);
        let before = shaded(&vis, DVec3::ZERO, DVec3::Z, &spheres[..count - 1]);
        let after = shaded(&vis, DVec3::ZERO, DVec3::Z, &spheres);
        worst = worst.max(after - before);
        spheres.clear();
    }
    eprintln!("largest brightening from adding a sphere: {worst:.2e}");
    // SH ringing lets a far-off cap add a little light; the clamp keeps the total in [0, 1].
    assert!(worst <= 2e-3, "{worst}");
}

/// A rotation matrix about `axis` by `angle`.
fn rotation(axis: DVec3, angle: f64) -> glam::DMat3 {
    glam::DMat3::from_axis_angle(axis.normalize(), angle)
}

#[test]
fn rotating_spheres_normal_and_environment_together_changes_nothing() {
    let order = ShOrder::new(4).unwrap();
    let vis = Visibility::new(order, ExpChoice::ScalingSquaring, 45f64.to_radians()).unwrap();
    let mut rng = Lcg(11);
    // A non-uniform environment: random SH coefficients (positive DC).
    let env: Vec<f64> = (0..16).map(|i| if i == 0 { 3.0 } else { rng.next() - 0.5 }).collect();
    for trial in 0..20 {
        let spheres = random_spheres(&mut rng, 6);
        let r = rotation(DVec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5), 6.0 * rng.next());
        let p = DVec3::new(0.1, -0.2, 0.05);
        let mut s = vis.scratch();
        let mut v = vec![0.0; 16];
        let mut vr = vec![0.0; 16];
        vis.vector(p, DVec3::Z, &mut |f: &mut dyn FnMut(&Sphere)| spheres.iter().for_each(&mut *f), &mut s, &mut v);
        let turned: Vec<Sphere> = spheres.iter().map(|x| Sphere { center: r * x.center, radius: x.radius }).collect();
        vis.vector(
            r * p,
            r * DVec3::Z,
            &mut |f: &mut dyn FnMut(&Sphere)| turned.iter().for_each(&mut *f),
            &mut s,
            &mut vr,
        );
        let rot = ShRotation::new(order, r).unwrap();
        let mut env_r = vec![0.0; 16];
        rot.apply(&env, &mut env_r).unwrap();
        let a: f64 = v.iter().zip(&env).map(|(x, y)| x * y).sum();
        let b: f64 = vr.iter().zip(&env_r).map(|(x, y)| x * y).sum();
        assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "trial {trial}: {a} vs {b}");
    }
}

#[test]
fn receiver_inside_rules_are_scale_relative_and_continuous() {
    use penumbra_integrators::shexp::visibility::adjust;
    for scale in [1e-4, 1.0, 1e4] {
        let s = Sphere { center: DVec3::new(0.0, 0.0, -0.2) * scale, radius: 0.5 * scale };
        // Receiver inside: dropped; wholly behind: dropped; in front: kept.
        assert!(adjust(&s, DVec3::ZERO, DVec3::Z).is_none());
        assert!(adjust(&s, DVec3::new(0.0, 0.0, 0.8) * scale, DVec3::Z).is_none());
        assert_eq!(adjust(&s, DVec3::new(0.0, 0.0, -0.8) * scale, DVec3::Z), Some(s));
        // Centre in front, crossing: tangent to the plane at the centre's foot, through the top.
        let t = adjust(&s, DVec3::new(0.0, 0.0, -0.4) * scale, DVec3::Z).unwrap();
        assert!((t.center.z - t.radius - (-0.4 * scale)).abs() < 1e-12 * scale);
        assert!((t.center.z + t.radius - 0.3 * scale).abs() < 1e-12 * scale);
        // Centre behind, receiver outside: shrinks to nothing as the receiver nears the cut disc.
        let n = DVec3::Z;
        let mut last = f64::INFINITY;
        for i in 0..50 {
            let x = (1.2 - 0.01 * i as f64) * scale; // the disc has radius √(0.25 − 0.04) ≈ 0.458
            let r = adjust(&s, DVec3::new(x, 0.0, -0.1 * scale), n).map(|a| a.radius).unwrap_or(0.0);
            assert!(r <= last * (1.0 + 1e-12));
            last = r;
        }
        assert!(last < 1e-9 * scale || adjust(&s, DVec3::new(0.72 * scale, 0.0, -0.1 * scale), n).is_some());
        // A centre in the receiver's tangent plane up to rounding (a planar shell's): the same
        // sphere whichever side rounding put it on (receiver inside it, then outside it).
        let flat = |dz: f64| Sphere { center: DVec3::new(0.3, 0.0, dz) * scale, radius: 0.5 * scale };
        for p in [DVec3::ZERO, DVec3::X * scale] {
            match (adjust(&flat(1e-9), p, n), adjust(&flat(-1e-9), p, n)) {
                (None, None) => {}
                (Some(a), Some(b)) => assert!(
                    a.center.distance(b.center) + (a.radius - b.radius).abs() < 1e-8 * scale,
                    "scale {scale}, receiver {p}: {a:?} vs {b:?}"
                ),
                (a, b) => panic!("scale {scale}, receiver {p}: {a:?} vs {b:?}"),
            }
        }
    }
}

/// A matte floor of `tiles` coplanar quads (at z = −0.37, which no scale represents exactly)
/// pierced by a sphere under a white sky: the floor is
/// not a ground plane (the sphere reaches below it), so every tile casts shadows through
/// conservative shells whose centres lie in the floor's plane.
fn pierced_floor(tiles: usize, pre_camera: &str, world: &str) -> String {
    let quads: String = (0..tiles)
        .map(|i| {
            let (x0, x1) = (-6.0 + 12.0 * i as f64 / tiles as f64, -6.0 + 12.0 * (i + 1) as f64 / tiles as f64);
            format!(
                "Shape \"trianglemesh\" \"point P\" [ {x0} -6 -0.37  {x1} -6 -0.37  {x1} 6 -0.37  {x0} 6 -0.37 ] \"integer indices\" [ 0 1 2 2 3 0 ]\n"
            )
        })
        .collect();
    format!(
        r#"LookAt 3 -6 4  0 0 0.3  0 0 1
{pre_camera}
Camera "perspective" "float fov" [ 45 ]
Sampler "halton" "integer pixelsamples" [ 4 ]
PixelFilter "box"
WorldBegin
{world}
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "matte" "rgb Kd" [ 0.5 0.5 0.5 ]
{quads}Translate 0 0 0.3
Shape "sphere" "float radius" [ 1 ]
WorldEnd
"#
    )
}

/// The floor's own shells and a coplanar tile's shells have their centres in the receiver's
/// tangent plane, where rounding decided the side: a floor point found a hair below its plane
/// was shadowed by a tangent sphere of half the shell's radius, one a hair above was not, so
/// the floor was speckled and changed when the scene was scaled or turned (hackmad's
/// `materials/plastic`, a dragon through a floor: rel. RMSE 6.5–10 % scaled, 19 % turned). A
/// plane never shadows itself, and a centre within the rules' tolerance of the plane is in it.
#[test]
fn a_pierced_floor_renders_the_same_scaled_and_turned() {
    let o = common::Opts { integrator: Some("shexp"), spp: Some(4), resolution: Some((32, 32)), ..Default::default() };
    let mut failed = Vec::new();
    for tiles in [1, 2] {
        let base = common::render_text(&pierced_floor(tiles, "", ""), &o);
        let mean = common::mean(&base.image);
        for (name, pre, world) in [
            ("scale-1e-4", "Scale 1e4 1e4 1e4", "Scale 1e-4 1e-4 1e-4"),
            ("scale-1e4", "Scale 1e-4 1e-4 1e-4", "Scale 1e4 1e4 1e4"),
            ("rotate", "Rotate -37 1 2 3", "Rotate 37 1 2 3"),
        ] {
            let r = common::render_text(&pierced_floor(tiles, pre, world), &o);
            let rel = common::rmse(&base.image, &r.image) / mean;
            eprintln!("{tiles} tile(s), {name}: rel. RMSE {rel:.2e}");
            if !(rel < 1e-3) {
                failed.push(format!("{tiles} tile(s), {name}: rel. RMSE {rel:.2e}"));
            }
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}

fn render_scene(rel: &str, params: &[&str], res: u32, spp: u32) -> common::Render {
    common::render_path(
        &common::scene(rel),
        &common::Opts {
            integrator: Some("shexp"),
            params,
            spp: Some(spp),
            resolution: Some((res, res)),
            ..Default::default()
        },
    )
}

#[test]
fn white_furnace_without_blockers_is_the_albedo() {
    // A lone exact sphere under a constant sky of radiance 1: V = 1 everywhere on it, so each
    // pixel is Kd (0.5) on the sphere, 1 on the sky, and a blend of the two at the silhouette.
    let text = r#"
LookAt 0 0 -4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
Film "image" "integer xresolution" [ 16 ] "integer yresolution" [ 16 ]
Sampler "halton" "integer pixelsamples" [ 4 ]
PixelFilter "box"
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "matte" "rgb Kd" [ 0.5 0.5 0.5 ]
Shape "sphere" "float radius" [ 1 ]
WorldEnd
"#;
    let r =
        common::render_text(text, &common::Opts { integrator: Some("shexp"), resolution: None, ..Default::default() });
    let px = |x: usize, y: usize| r.image.data[(y * 16 + x) * 3];
    for (x, y) in [(8, 8), (7, 7), (6, 9), (9, 6)] {
        assert!((px(x, y) - 0.5).abs() <= 1e-6, "pixel ({x},{y}) = {}", px(x, y));
    }
    assert!(r.image.data.iter().all(|v| *v >= 0.5 - 1e-6 && *v <= 1.0 + 1e-6));
}

const SPHERES_ON_PLANE: &str = include_str!("../scenes/suite/ao/spheres-on-plane.pbrt");

/// The spheres-on-plane scene with camera and world scaled by `s`.
fn scaled_spheres_on_plane(s: f64) -> String {
    let t = SPHERES_ON_PLANE.replace("../textures/", &format!("{}/scenes/suite/textures/", common::root().display()));
    let t = t.replace(
        "LookAt 0 3.5 -6  0 0.3 0  0 1 0",
        &format!("LookAt 0 {} {}  0 {} 0  0 1 0", 3.5 * s, -6.0 * s, 0.3 * s),
    );
    t.replace("WorldBegin", &format!("WorldBegin\nScale {s} {s} {s}"))
}

#[test]
fn scenes_scaled_by_1e4_either_way_render_the_same_image() {
    let o = common::Opts { integrator: Some("shexp"), spp: Some(1), resolution: Some((32, 32)), ..Default::default() };
    let base = common::render_text(&scaled_spheres_on_plane(1.0), &o);
    for s in [1e-4, 1e4] {
        let r = common::render_text(&scaled_spheres_on_plane(s), &o);
        let d = common::rmse(&base.image, &r.image);
        let max = base.image.data.iter().zip(&r.image.data).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        eprintln!("scale {s}: rmse {d:.2e}, max {max:.2e}");
        assert!(d < 2e-3 && common::mean(&r.image) > 0.0, "scale {s}: rmse {d}");
    }
}

#[test]
fn spheres_on_plane_matches_pbrt_within_two_percent() {
    let r = render_scene("suite/ao/spheres-on-plane.pbrt", &[], 64, 4);
    let reference = common::reference("ao/spheres-on-plane.exr");
    let (a, b) = (common::mean(&r.image), common::mean(&reference));
    let rmse = common::rmse(&r.image, &reference);
    eprintln!("spheres-on-plane 64²: mean {a:.5} vs pbrt-v3 {b:.5} ({:+.2} %), rmse {rmse:.5}", 100.0 * (a / b - 1.0));
    assert!((a / b - 1.0).abs() <= 0.02);
    // Measured 0.012 (2.1 % of the mean; pbrt-v3's own noise at 64² is part of it).
    assert!(rmse <= 0.03 * b, "rmse {rmse}");
    assert!(r.image.data.iter().all(|v| v.is_finite()));
}

#[test]
fn objects_sky_sun_matches_pbrt_within_two_percent() {
    // The sun is split off as a directional light with shadow rays (brightlights 4; with 0 the
    // image mean is −8.0 %, RMSE 23 % of the mean; measured at 256², 4 spp).
    let r = render_scene("suite/env/objects-sky-sun.pbrt", &[], 64, 4);
    let reference = common::reference("env/objects-sky-sun.exr");
    let (a, b) = (common::mean(&r.image), common::mean(&reference));
    eprintln!("objects-sky-sun 64²: mean {a:.5} vs pbrt-v3 {b:.5} ({:+.2} %)", 100.0 * (a / b - 1.0));
    assert!((a / b - 1.0).abs() <= 0.02);
    assert!(r.image.data.iter().all(|v| v.is_finite()));
}

#[test]
fn objects_studio_within_two_percent() {
    // Order 4 with the bright-region split at its defaults (peak ≥ 4× the map's mean, radius ≤
    // 45°): −1.5 % at 64² 4 spp, −1.65 % at 256² (measured). The split at 8× and 15° left the
    // soft boxes in the SH projection: −4.4 % (256²), the order-4 truncation of L·max(0, n·ω)
    // ringing near the horizon, where the far ground sees the objects (without any split:
    // −8.5 %; order 6 −2.6 %, order 8 −0.3 %).
    let r = render_scene("suite/env/objects-studio.pbrt", &[], 64, 4);
    let reference = common::reference("env/objects-studio.exr");
    let (a, b) = (common::mean(&r.image), common::mean(&reference));
    eprintln!("objects-studio 64² order 4: mean {a:.5} vs pbrt-v3 {b:.5} ({:+.2} %)", 100.0 * (a / b - 1.0));
    assert!((a / b - 1.0).abs() <= 0.02, "{a} vs {b}");
    assert!(r.warnings.iter().any(|w| w.contains("non-Lambertian")), "{:?}", r.warnings);
    // The old split misses the goal (so this test tells the two apart).
    let old = render_scene("suite/env/objects-studio.pbrt", &["brightratio=8", "brightradius=15"], 64, 4);
    let a_old = common::mean(&old.image);
    eprintln!("  with the 8x / 15° split: {:+.2} %", 100.0 * (a_old / b - 1.0));
    assert!((a_old / b - 1.0).abs() > 0.03);
}

#[test]
fn environment_path_is_bit_identical_across_threads_and_crops() {
    // The conformance test's scene has no environment; this one has fitted spheres, a ground
    // cut, split bright lights and a glossy lobe.
    let path = common::scene("suite/env/objects-studio.pbrt");
    common::assert_deterministic(40, 36, |threads, crop| {
        common::render_path(
            &path,
            &common::Opts {
                integrator: Some("shexp"),
                params: &["lhresolution=8"],
                spp: Some(2),
                resolution: Some((40, 36)),
                threads,
                crop,
                ..Default::default()
            },
        )
    });
}

/// A lone exact sphere (centre (0, 1, 0), radius 1, albedo KD) over a ground plane y = 0 of
/// albedo 0.8 under a sky of radiance 1. The plane reaches ±1000: at ±20 the sky below its edge
/// brightens the sphere's sides in `path` by about 6 %, where `shexp` cuts at an infinite plane.
const BALL_ON_GROUND: &str = r#"
LookAt 0 4 -6  0 0.5 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Film "image" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
Sampler "halton" "integer pixelsamples" [ 2 ]
PixelFilter "box"
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
AttributeBegin
  Material "matte" "rgb Kd" [ KD KD KD ]
  Translate 0 1 0
  Shape "sphere" "float radius" [ 1 ]
AttributeEnd
AttributeBegin
  Material "matte" "rgb Kd" [ 0.8 0.8 0.8 ]
  Shape "trianglemesh" "integer indices" [ 0 1 2 0 2 3 ] "point P" [ -1000 0 -1000 -1000 0 1000 1000 0 1000 1000 0 -1000 ]
AttributeEnd
WorldEnd
"#;

fn ball_scene(kd: f32) -> Scene {
    let text = BALL_ON_GROUND.replace("KD", &kd.to_string());
    let parsed = penumbra_parser::parse_str(&text, "ball.pbrt", None).unwrap();
    with_sphere_sets(&parsed.scene, 32)
}

/// The scene as `shexp` builds it, with `spheres` leaves per fitted object.
fn with_sphere_sets(desc: &penumbra_parser::SceneDescription, spheres: u32) -> Scene {
    let req = Requirements { accel: true, lights: true, materials: true, ..Default::default() };
    let mut scene = Scene::build(desc, req, &BuildOptions::default(), &DiagSink::new()).unwrap();
    let params = sphereset::fit::FitParams { spheres, ..Default::default() };
    let dir = sphereset::cache::default_dir();
    let sets = sphereset::build_for_scene(&scene.meshes, &scene.objects, &params, Default::default(), dir.as_deref());
    scene.prepared = Some(std::sync::Arc::new(sets));
    scene
}

/// `∫ L(ω) max(0, n·ω) dω` at ground point `q` (n = +y) from the unit sphere at (0, 1, 0) whose
/// surface with normal `m` has radiance `radiance(m)`: a fine quadrature over the hemisphere.
fn sphere_irradiance(q: DVec3, radiance: impl Fn(DVec3) -> f64) -> f64 {
    let c = DVec3::new(0.0, 1.0, 0.0);
    let n = 600;
    let mut e = 0.0;
    for i in 0..n {
        let t = (i as f64 + 0.5) / n as f64 * PI / 2.0;
        for j in 0..2 * n {
            let p = (j as f64 + 0.5) / (2 * n) as f64 * 2.0 * PI;
            let d = DVec3::new(t.sin() * p.cos(), t.cos(), t.sin() * p.sin());
            let oc = q - c;
            let b = d.dot(oc);
            let disc = b * b - (oc.length_squared() - 1.0);
            if disc <= 0.0 {
                continue;
            }
            let tt = -b - disc.sqrt();
            if tt <= 0.0 {
                continue;
            }
            let m = (q + d * tt - c).normalize();
            e += radiance(m) * t.cos() * t.sin() * (PI / 2.0 / n as f64) * (PI / n as f64);
        }
    }
    e
}

#[test]
fn a_lone_sphere_reflects_its_radiance_onto_the_ground() {
    // Pass 2 alone on ground points at x from the contact point, with the sphere's white
    // radiance given in closed form, (1 + m_y)/2 under the sky cut by the ground (so only
    // Voronoi sampling, the SH truncation of r_S and the form factor are measured).
    // Measured: "exact" +1.0 % (x = 1.02) … −0.1 % (x = 8); "thesis" −11.7 … −20.2 %, and
    // +6.5 % at x = 8 (its mean ignores the receiver's cosine across the sphere, and order-4
    // ringing brightens small caps near the horizon).
    use penumbra_integrators::shexp::reflect::{surface::SurfaceSample, tables::FormFactor, Reflectors, Surfaces};
    let scene = ball_scene(0.9);
    let sets = scene.prepared::<SphereSets>().unwrap();
    let order = ShOrder::new(4).unwrap();
    let vis = Visibility::new(order, ExpChoice::ScalingSquaring, 45f64.to_radians()).unwrap();
    let surfaces = Surfaces::build(&scene, sets, order, &std::sync::atomic::AtomicBool::new(false));
    let only = surfaces.surfaces[0].as_ref().unwrap();
    assert!(only.samples.iter().all(Option::is_some), "every geodesic direction finds the sphere");
    // c_S of a uniform albedo is that constant (0.9 in f32).
    assert!(
        (only.colour[0][0] - 0.9 * sh::SQRT_4PI).abs() < 1e-6 && only.colour[0][1..].iter().all(|c| c.abs() < 1e-9)
    );
    let white = |m: DVec3| (1.0 + m.y) / 2.0;
    let shade = |s: &SurfaceSample| [white(s.n); 3];
    for model in [FormFactor::Thesis, FormFactor::Exact] {
        let r = Reflectors::build(sets, &surfaces, model, &shade).unwrap();
        let mut scratch = r.scratch(&vis);
        for x in [1.02, 1.1, 1.2, 1.5, 2.0, 3.0, 4.0, 8.0] {
            let q = DVec3::new(x, 0.0, 0.0);
            let got = r.irradiance(&vis, sets, q, DVec3::Y, 1, &mut scratch);
            let want = 0.9 * sphere_irradiance(q, white);
            let err = got[0] / want - 1.0;
            eprintln!("{model:?} ground x {x}: shexp {:.5} exact {want:.5} ({:+.1} %)", got[0], 100.0 * err);
            assert!(got[0] == got[1] && got[1] == got[2]);
            match model {
                FormFactor::Exact => assert!(err.abs() <= 0.02, "x {x}: {err}"),
                FormFactor::Thesis => assert!((-0.22..=0.08).contains(&err), "x {x}: {err}"),
            }
        }
    }
}

fn shexp_opts<'a>(params: &'a [&'a str], res: (u32, u32), spp: u32) -> common::Opts<'a> {
    common::Opts { integrator: Some("shexp"), params, spp: Some(spp), resolution: Some(res), ..Default::default() }
}

#[test]
fn interreflection_brightens_the_ground_near_a_bright_sphere_and_falls_with_distance() {
    // A row of 16 pixels looking straight down at the ground from x = 1.05 to 5.05 (pixel
    // centres, no jitter): the added light is the sphere's reflection alone (the ground plane
    // does not reflect onto itself), kd_g/π · E^R with E^R from pass 1's white radiance, which
    // for an exact sphere under the cut sky is (1 + m_y)/2: within 2 % of the quadrature.
    let text = BALL_ON_GROUND
        .replace("KD", "0.9")
        .replace("LookAt 0 4 -6  0 0.5 0  0 1 0", "LookAt 3.05 5 0  3.05 0 0  0 0 1")
        .replace(
            r#"Camera "perspective" "float fov" [ 40 ]"#,
            r#"Camera "orthographic" "float screenwindow" [ -2 2 -0.01 0.01 ]"#,
        )
        .replace(
            r#""integer xresolution" [ 48 ] "integer yresolution" [ 48 ]"#,
            r#""integer xresolution" [ 16 ] "integer yresolution" [ 1 ]"#,
        )
        .replace(
            r#"Sampler "halton" "integer pixelsamples" [ 2 ]"#,
            r#"Sampler "stratified" "integer xsamples" [ 1 ] "integer ysamples" [ 1 ] "bool jitter" "false""#,
        );
    let row = |params: &[&str]| common::render_text(&text, &shexp_opts(params, (16, 1), 1)).image;
    let (off, on) = (row(&[]), row(&["interreflect=true"]));
    let white = |m: DVec3| (1.0 + m.y) / 2.0;
    let mut last = f64::INFINITY;
    for i in 0..16 {
        // The camera's x axis is world +x (pbrt's LookAt: up +z, looking down −y).
        let x = 3.05 - 2.0 + 4.0 * (i as f64 + 0.5) / 16.0;
        let added = (on.data[i * 3] - off.data[i * 3]) as f64;
        let want = 0.8 / PI * 0.9 * sphere_irradiance(DVec3::new(x, 0.0, 0.0), white);
        eprintln!("x {x:.2}: added {added:.5}, quadrature {want:.5} ({:+.2} %)", 100.0 * (added / want - 1.0));
        assert!(added > 0.0 && added < last, "x {x}: {added} after {last}");
        assert!((added / want - 1.0).abs() <= 0.02, "x {x}: {added} vs {want}");
        last = added;
    }
    // Never darker anywhere in a perspective view (sphere and ground).
    let img =
        |params: &[&str]| common::render_text(&BALL_ON_GROUND.replace("KD", "0.9"), &shexp_opts(params, (32, 32), 1));
    let (off, on) = (img(&[]), img(&["interreflect=true"]));
    let brighter = on.image.data.iter().zip(&off.image.data).filter(|(a, b)| a > b).count();
    assert!(on.image.data.iter().zip(&off.image.data).all(|(a, b)| a >= b));
    assert!(brighter > on.image.data.len() / 2, "{brighter}");
}

/// Pixel sums of `a − b` over the pixels where `mask` is (or is not) zero.
fn masked_sums(
    a: &penumbra_core::image::Image,
    b: &penumbra_core::image::Image,
    mask: &penumbra_core::image::Image,
) -> [(f64, usize); 2] {
    let mut out = [(0.0, 0), (0.0, 0)];
    for ((pa, pb), m) in a.data.chunks(3).zip(b.data.chunks(3)).zip(mask.data.chunks(3)) {
        let k = usize::from(m.iter().any(|v| *v != 0.0));
        out[k].0 += pa.iter().zip(pb).map(|(x, y)| (x - y) as f64).sum::<f64>();
        out[k].1 += 1;
    }
    out
}

/// shexp's one-bounce light (interreflect on − off) against `path`'s (maxdepth 2 − 1, the same
/// samples) on the pixels where `mask` is black ([0]) and the others ([1]): the share
/// recovered, and the RMS difference of the two bounce images over the RMS of path's.
fn bounce_against_path(text: &str, mask: &str, res: u32, path_spp: u32) -> ([f64; 2], f64) {
    // A coarse LH(N) cubemap: its build is most of a small render's cost, and it moves on and
    // off alike.
    let shexp = |params: &[&str]| {
        let params: Vec<&str> = params.iter().copied().chain(["lhresolution=8"]).collect();
        common::render_text(text, &shexp_opts(&params, (res, res), 2)).image
    };
    let path = |depth: &str| {
        let o = common::Opts {
            integrator: Some("path"),
            params: &[depth],
            spp: Some(path_spp),
            resolution: Some((res, res)),
            ..Default::default()
        };
        common::render_text(text, &o).image
    };
    let (off, on) = (shexp(&[]), shexp(&["interreflect=true"]));
    let (p1, p2) = (path("maxdepth=1"), path("maxdepth=2"));
    let mask = common::render_text(mask, &shexp_opts(&["lhresolution=8"], (res, res), 2)).image;
    let (ours, theirs) = (masked_sums(&on, &off, &mask), masked_sums(&p2, &p1, &mask));
    let recovered = [ours[0].0 / theirs[0].0, ours[1].0 / theirs[1].0];
    let (mut d2, mut p2sum) = (0.0, 0.0);
    for i in 0..on.data.len() {
        let (a, b) = ((on.data[i] - off.data[i]) as f64, (p2.data[i] - p1.data[i]) as f64);
        d2 += (a - b) * (a - b);
        p2sum += b * b;
    }
    (recovered, (d2 / p2sum).sqrt())
}

#[test]
fn interreflection_recovers_most_of_paths_one_bounce_light() {
    // `path` maxdepth 2 minus maxdepth 1 (same samples, 128 spp) is the one-bounce light;
    // shexp's interreflect on minus off is its estimate (32², 2 spp). The shares below were
    // measured; on env/objects-studio they moved by at most 1.3 points over path seeds 0–2 at
    // 128 and 256 spp, so ±5 points is about four of those deviations. The RMS of the
    // difference of the two bounce images is over the RMS of path's (without interreflect it
    // is 100 % by definition); path's own noise is part of it.
    let ball = BALL_ON_GROUND.replace("KD", "0.9");
    let ball_mask = ball.replace("[ 0.8 0.8 0.8 ]", "[ 0 0 0 ]");
    let (rec, rms) = bounce_against_path(&ball, &ball_mask, 32, 128);
    eprintln!(
        "ball: recovered ground {:.1} %, sphere {:.1} %, RMS {:.1} %",
        100.0 * rec[0],
        100.0 * rec[1],
        100.0 * rms
    );
    // The ground sees the sphere's reflection (pass 1 + 2: exact to ~1 %, see the test above),
    // the sphere the ground plane's (its shadowed light at five seen points).
    assert!((rec[0] - GROUND_BALL).abs() <= 0.05, "{rec:?}");
    assert!((rec[1] - SPHERE_BALL).abs() <= 0.05, "{rec:?}");
    assert!(rms <= 0.2, "{rms}");
    let studio = std::fs::read_to_string(common::scene("suite/env/objects-studio.pbrt"))
        .unwrap()
        .replace("../textures/", &format!("{}/scenes/suite/textures/", common::root().display()));
    let ground = studio.rfind("[ 0.5 0.5 0.5 ]").unwrap();
    let studio_mask = format!("{}[ 0 0 0 ]{}", &studio[..ground], &studio[ground + "[ 0.5 0.5 0.5 ]".len()..]);
    let (srec, srms) = bounce_against_path(&studio, &studio_mask, 32, 128);
    eprintln!(
        "studio: recovered ground {:.1} %, objects {:.1} %, RMS {:.1} %",
        100.0 * srec[0],
        100.0 * srec[1],
        100.0 * srms
    );
    // The shortfall: the fitted spheres' overlapping baked occlusion and SH products (ground;
    // 86 % with the icosphere made matte), the icosphere's glossy bounce, which only the
    // Lambertian lobe's reflection is modelled for, and the ground's direct light near the
    // objects, 5–20 % darker than path's there (the bounding spheres overshadow), which the
    // objects see bounced.
    assert!((srec[0] - GROUND_STUDIO).abs() <= 0.05, "{srec:?}");
    assert!((srec[1] - OBJECTS_STUDIO).abs() <= 0.05, "{srec:?}");
    assert!(srms <= 0.55, "{srms}");
}

/// The shares of path's one-bounce light measured by the test above (RMS of the difference:
/// ball 16 %, studio 44 % of path's). The studio's were 0.763 and 0.704 before issue 39's
/// sphere-set changes (fit in snapped canonical coordinates, `sphereset::Canonical`, fit
/// version 4; the ground plane's choice); measured since: 0.815 and 0.733, nearer path's (the
/// same with pixel shading's hard switch in place of the blend; which change moved them was
/// not separated).
const GROUND_BALL: f64 = 0.978;
const SPHERE_BALL: f64 = 0.963;
const GROUND_STUDIO: f64 = 0.815;
const OBJECTS_STUDIO: f64 = 0.733;

#[test]
fn objects_of_albedo_zero_reflect_nothing() {
    // A black sphere on the ground: its spheres block but reflect nothing, and the ground's
    // bounce lands on a black surface: the image is the one without interreflect, bit for bit.
    let text = BALL_ON_GROUND.replace("KD", "0");
    let (off, on) = (
        common::render_text(&text, &shexp_opts(&[], (32, 32), 2)),
        common::render_text(&text, &shexp_opts(&["interreflect=true"], (32, 32), 2)),
    );
    common::assert_same(&on.image.data, &off.image.data, "albedo 0, interreflect on vs off");
    assert_eq!(on.stats.counters.get("reflecting spheres"), None);
}

#[test]
fn interreflection_is_bit_identical_across_threads_and_crops() {
    let path = common::scene("suite/env/objects-studio.pbrt");
    common::assert_deterministic(24, 20, |threads, crop| {
        common::render_path(
            &path,
            &common::Opts {
                integrator: Some("shexp"),
                params: &["interreflect=true", "lhresolution=8"],
                spp: Some(1),
                resolution: Some((24, 20)),
                threads,
                crop,
                ..Default::default()
            },
        )
    });
}

#[test]
fn interreflection_stays_finite_on_the_stiff_scenes() {
    // The stiff scenes have area lights only: a sky is added so that the bounce runs.
    let dir = common::root().join("scenes/suite/stiff");
    let mut names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    names.sort();
    let mut scaled = Vec::new();
    for path in names.iter().filter(|p| p.extension().is_some_and(|e| e == "pbrt")) {
        let text = std::fs::read_to_string(path).unwrap();
        let text = text.replacen("WorldBegin", "WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 0.5 0.5 0.5 ]", 1);
        let r = common::render_text(&text, &shexp_opts(&["interreflect=true", "lhresolution=8"], (24, 24), 1));
        let bad = r.image.data.iter().filter(|v| !v.is_finite() || **v < 0.0).count();
        eprintln!(
            "{}: mean {:.4}, reflecting spheres {:?}, bad samples {}",
            path.display(),
            common::mean(&r.image),
            r.stats.counters.get("reflecting spheres"),
            r.stats.bad_samples
        );
        assert_eq!(bad, 0, "{}", path.display());
        assert_eq!(r.stats.bad_samples, 0, "{}", path.display());
        assert!(r.warnings.iter().any(|w| w.contains("bounces the \"infinite\" lights only")), "{:?}", r.warnings);
        if path.to_string_lossy().contains("scaled-") {
            scaled.push(r.image);
        }
    }
    // The same scene at 1e-4 and 1e4: the bounce's tolerances are relative.
    assert_eq!(scaled.len(), 2);
    let (a, b) = (common::mean(&scaled[0]), common::mean(&scaled[1]));
    eprintln!("scaled 1e-4 vs 1e4: mean {a:.6} vs {b:.6}, rmse {:.2e}", common::rmse(&scaled[0], &scaled[1]));
    assert!((a / b - 1.0).abs() <= 1e-3 && common::rmse(&scaled[0], &scaled[1]) <= 2e-3 * a);
}

#[test]
fn surface_rules_do_not_depend_on_winding() {
    // A closed cube wound outwards, with one face flipped (the parity rule decides the sides),
    // wound inwards, and wound outwards under ReverseOrientation: the same sphere set (the
    // first's) gives the same colour environments and sample points.
    use penumbra_integrators::shexp::reflect::Surfaces;
    let cube = |indices: &str, reverse: bool| {
        let text = format!(
            r#"LookAt 0 4 -6  0 0.5 0  0 1 0
Camera "perspective"
Film "image" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
AttributeBegin
  Material "matte" "rgb Kd" [ 0.9 0.5 0.2 ]
  {}
  Shape "trianglemesh" "integer indices" [ {indices} ]
      "point P" [ -1 0 -1  1 0 -1  -1 2 -1  1 2 -1  -1 0 1  1 0 1  -1 2 1  1 2 1 ]
AttributeEnd
WorldEnd
"#,
            if reverse { "ReverseOrientation" } else { "" }
        );
        let parsed = penumbra_parser::parse_str(&text, "cube.pbrt", None).unwrap();
        with_sphere_sets(&parsed.scene, 6)
    };
    let outward = "0 2 3 0 3 1 4 5 7 4 7 6 0 1 5 0 5 4 2 6 7 2 7 3 0 4 6 0 6 2 1 3 7 1 7 5";
    let one_flipped = "0 3 2 0 1 3 4 5 7 4 7 6 0 1 5 0 5 4 2 6 7 2 7 3 0 4 6 0 6 2 1 3 7 1 7 5";
    let inward = "2 0 3 3 0 1 5 4 7 7 4 6 1 0 5 5 0 4 6 2 7 7 2 3 4 0 6 6 0 2 3 1 7 7 1 5";
    let order = ShOrder::new(4).unwrap();
    let no = std::sync::atomic::AtomicBool::new(false);
    let base = cube(outward, false);
    let sets = base.prepared::<SphereSets>().unwrap().clone();
    assert_eq!(sets.sets.len(), 1);
    let reference = Surfaces::build(&base, &sets, order, &no);
    for (name, indices, reverse) in
        [("one face flipped", one_flipped, false), ("inward", inward, false), ("reversed", outward, true)]
    {
        let mut scene = cube(indices, reverse);
        scene.prepared = Some(std::sync::Arc::new(sets.clone()));
        let other = Surfaces::build(&scene, &sets, order, &no);
        for (a, b) in reference.surfaces.iter().zip(&other.surfaces) {
            let (a, b) = (a.as_ref().unwrap(), b.as_ref().unwrap());
            for (ca, cb) in a.colour.iter().zip(&b.colour) {
                for (x, y) in ca.iter().zip(cb) {
                    assert!((x - y).abs() <= 1e-6, "{name}: c_S {x} vs {y}");
                }
            }
            for (sa, sb) in a.samples.iter().zip(&b.samples) {
                match (sa, sb) {
                    (Some(sa), Some(sb)) => {
                        assert!(sa.si.p.distance(sb.si.p) <= 1e-5, "{name}: {:?} vs {:?}", sa.si.p, sb.si.p);
                        assert!(sa.n.distance(sb.n) <= 1e-6, "{name}: normal {:?} vs {:?}", sa.n, sb.n);
                    }
                    (None, None) => {}
                    _ => panic!("{name}: a sample point differs in validity"),
                }
            }
        }
        eprintln!("{name}: same c_S and samples over {} leaves", sets.sets[0].leaves.len());
    }
}

/// `"shading" "pixel"` (the default with an environment) against `"sample"`: identical at 1 spp;
/// at more samples the same image up to the variation of the Lambertian environment term inside
/// a pixel, from fewer evaluations of it (at ⌈√m⌉ of each surface's m samples, at every sample
/// where those differ by over 5–10 %; the split bright regions' shadow rays stay per sample),
/// and converging to it. Measured (48², relative RMSE at 16 → 64 spp; evaluations): studio
/// 0.048 → 0.014 % (0.42, 0.32), sky-sun 0.080 → 0.025 % (0.42, 0.33); bounds 0.12 % and
/// 0.05 %, 64's at most half of 16's, evaluations under half. Shading each surface at its
/// central and farthest sample alone kept a floor (studio 0.083 → 0.066 %, sky-sun 0.150 →
/// 0.119 %) and fails the 64-spp bound and the convergence (issue 37).
#[test]
fn pixel_shading_matches_sample_shading() {
    const P: [[&str; 1]; 2] = [["shading=pixel"], ["shading=sample"]];
    for name in ["env/objects-studio", "env/objects-sky-sun"] {
        let path = common::scene(&format!("suite/{name}.pbrt"));
        let o = |spp, k: usize| common::Opts {
            integrator: Some("shexp"),
            params: &P[k],
            spp: Some(spp),
            resolution: Some((48, 48)),
            ..Default::default()
        };
        let (p1, s1) = (common::render_path(&path, &o(1, 0)), common::render_path(&path, &o(1, 1)));
        assert_eq!(p1.image.data, s1.image.data, "{name}: 1 spp must be identical");
        let mut errors = Vec::new();
        for (spp, bound) in [(16, 0.0012), (64, 0.0005)] {
            let (p, s) = (common::render_path(&path, &o(spp, 0)), common::render_path(&path, &o(spp, 1)));
            let e = common::rmse(&p.image, &s.image) / common::mean(&s.image);
            let receivers = |r: &common::Render| r.stats.counters["shexp.receivers"];
            let ratio = receivers(&p) / receivers(&s);
            eprintln!("{name}: pixel vs sample shading, {spp} spp, relative RMSE {e:.5}, evaluations {ratio:.3}");
            assert!(e < bound, "{name}, {spp} spp: relative RMSE {e} (bound {bound})");
            assert!(ratio < 0.5, "{name}, {spp} spp: {ratio} of sample shading's evaluations");
            errors.push(e);
        }
        assert!(errors[1] <= 0.5 * errors[0], "{name}: pixel shading does not converge: {errors:?}");
    }
}

/// Issue 39's own scene: the open quadrics of hackmad's `shapes/all-shapes` (270° cylinder, cone
/// and paraboloid, two hyperboloids pbrt-v3 fits with its implicit surface, an annulus) as they
/// stand there, over its floor under its constant sky and sun (`scenes/open-shapes/all-shapes-open`;
/// the closed tetrahedron and Loop surface and the curves left out). Against `directlighting`
/// rendered here (256 spp; the issue's goal is stated against it): the image mean within 2 % and no
/// 8×8 block beyond 5 %. Measured 64², 16 spp: mean −0.02 %, worst block 2.93 %; the conservative
/// shells (`"shells"`, the method before) −3.53 % and a block −46.1 %, so the test fails on them.
/// The mean is also held to pbrt-v3's (1024 spp): −0.01 %. (Before rays leaving pbrt-v3's
/// hyperboloid were blocked where they pass through it — `real_scenes`'
/// `hyperboloid_rays_through_the_surface_are_blocked_as_in_pbrt_v3` — penumbra's own
/// `directlighting` was 19.4 % brighter than pbrt-v3 in a block of the first hyperboloid; now
/// 3.0 %, both at 256 spp.)
#[test]
fn all_shapes_open_quadrics_match_directlighting() {
    let scene = "open-shapes/all-shapes-open.pbrt";
    let r = render_scene(scene, &[], 64, 16);
    let dl = common::render_path(
        &common::scene(scene),
        &common::Opts {
            integrator: Some("directlighting"),
            spp: Some(256),
            resolution: Some((64, 64)),
            ..Default::default()
        },
    );
    assert!(r.image.data.iter().all(|v| v.is_finite()));
    let (a, b) = (common::mean(&r.image), common::mean(&dl.image));
    let (ours, theirs) = (common::block_means(&r.image), common::block_means(&dl.image));
    let worst = ours.iter().zip(&theirs).map(|(o, t)| (o / t - 1.0).abs()).fold(0.0, f64::max);
    let pbrt = common::mean(&common::reference("open-shapes/all-shapes-open.exr"));
    eprintln!(
        "open-shapes/all-shapes-open 64², 16 spp: mean {a:.5} vs directlighting {b:.5} ({:+.2} %, pbrt-v3 {:+.2} %), worst 8×8 block {:.2} %",
        100.0 * (a / b - 1.0),
        100.0 * (a / pbrt - 1.0),
        100.0 * worst
    );
    assert!((a / b - 1.0).abs() <= 0.02, "image mean {a} vs directlighting's {b}");
    assert!((a / pbrt - 1.0).abs() <= 0.02, "image mean {a} vs pbrt-v3's {pbrt}");
    assert!(worst <= 0.05, "an 8×8 block {:.2} % off", 100.0 * worst);
    assert_open_quadrics_traced(&r.warnings);
}

/// Issue 39: open quadrics and meshes (an open cylinder and cone, a paraboloid, a hyperboloid,
/// partial spheres, an annulus, an open triangle sheet) shadow and receive as in pbrt-v3: their
/// shadows are traced (`"openmeshes" "trace"`, one warning per object). The issue's goal: the
/// image mean within 2 % and no 8×8 block beyond 5 % of pbrt-v3's (1024 spp, whose block noise
/// is far below that). Measured 64², 16 spp: mean +0.01 %, worst block −3.65 % against
/// directlighting at 256 spp; the conservative shells (`"shells"`, the method before) −6.96 %
/// and a block −57 % (the open cylinder's inside black), so the test fails on them.
#[test]
fn open_shapes_match_pbrt_v3() {
    let r = render_scene("open-shapes/combined.pbrt", &[], 64, 16);
    let reference = common::reference("open-shapes/combined.exr");
    assert!(r.image.data.iter().all(|v| v.is_finite()));
    let (a, b) = (common::mean(&r.image), common::mean(&reference));
    let (ours, theirs) = (common::block_means(&r.image), common::block_means(&reference));
    let worst = ours.iter().zip(&theirs).map(|(o, t)| (o / t - 1.0).abs()).fold(0.0, f64::max);
    eprintln!(
        "open-shapes/combined 64², 16 spp: mean {a:.5} vs pbrt-v3 {b:.5} ({:+.2} %), worst 8×8 block {:.2} %",
        100.0 * (a / b - 1.0),
        100.0 * worst
    );
    assert!((a / b - 1.0).abs() <= 0.02, "image mean {a} vs {b}");
    assert!(worst <= 0.05, "an 8×8 block {:.2} % off", 100.0 * worst);
    assert_open_quadrics_traced(&r.warnings);
}

/// One warning names each open quadric kind (cylinder, cone, paraboloid, hyperboloid, disk)
/// whose shadows `shexp` traces.
fn assert_open_quadrics_traced(warnings: &[String]) {
    for kind in ["cylinder", "cone", "paraboloid", "hyperboloid", "disk"] {
        assert!(
            warnings.iter().any(|w| w.contains(&format!("open mesh \"{kind}\"")) && w.contains("traced")),
            "no warning names the traced {kind}: {warnings:?}"
        );
    }
}
