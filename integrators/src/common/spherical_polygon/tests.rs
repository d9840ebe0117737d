use super::*;
use glam::Vec3;
use penumbra_core::rng::Rng;
use std::f64::consts::PI;

fn cos_sample(rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform_f64(), rng.uniform_f64());
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Monte Carlo form factor of `inside` (cosine-weighted sampling: the hit fraction)
/// and its standard error.
fn mc_form_factor(n: usize, seed: u64, inside: impl Fn(DVec3) -> bool) -> (f64, f64) {
    let mut rng = Rng::new(seed);
    let hits = (0..n).filter(|_| inside(cos_sample(&mut rng))).count() as f64;
    let p = hits / n as f64;
    (p, (p * (1.0 - p) / n as f64).sqrt().max(1.0 / n as f64))
}

/// Form factor from the origin to the rectangle [0,a]x[0,b] at height h (corner above the point).
fn corner_rect(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a / h, b / h);
    let sx = (1.0 + x * x).sqrt();
    let sy = (1.0 + y * y).sqrt();
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

fn rect(x0: f64, x1: f64, y0: f64, y1: f64, h: f64) -> Vec<DVec3> {
    vec![DVec3::new(x0, y0, h), DVec3::new(x1, y0, h), DVec3::new(x1, y1, h), DVec3::new(x0, y1, h)]
}

fn rand_dir(rng: &mut Rng) -> DVec3 {
    let z = 1.0 - 2.0 * rng.uniform_f64();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * rng.uniform_f64();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

fn rot_z(v: DVec3, a: f64) -> DVec3 {
    DVec3::new(v.x * a.cos() - v.y * a.sin(), v.x * a.sin() + v.y * a.cos(), v.z)
}

// --- edge integral, form factor, solid angle ---------------------------------------------------

#[test]
fn edge_integral_matches_naive_formula_and_is_stable() {
    let mut rng = Rng::new(1);
    for _ in 0..1000 {
        let a = rand_dir(&mut rng);
        let b = rand_dir(&mut rng);
        let naive = a.dot(b).clamp(-1.0, 1.0).acos() * a.cross(b).normalize().z;
        assert!((edge_integral(a, b) - naive).abs() < 1e-9, "{a} {b}");
        // non-unit input gives the same value
        assert!((edge_integral(a * 3.0, b * 0.25) - naive).abs() < 1e-9);
        assert!((edge_integral(b, a) + naive).abs() < 1e-9);
    }
    // nearly parallel: θ ~ 1e-12 -> contribution ~ θ·n_z, finite and tiny
    let a = DVec3::new(0.3, 0.4, 0.866).normalize();
    let b = (a + DVec3::new(1e-12, -2e-12, 0.0)).normalize();
    let e = edge_integral(a, b);
    assert!(e.is_finite() && e.abs() < 1e-11, "{e}");
    assert_eq!(edge_integral(a, a), 0.0);
    assert_eq!(edge_integral(a, DVec3::ZERO), 0.0);
    // nearly antipodal: θ -> π, |n_z| ≤ 1
    let b = -a + DVec3::new(0.0, 1e-9, 0.0);
    let e = edge_integral(a, b);
    assert!(e.is_finite() && e.abs() <= PI + 1e-9);
    // exactly antipodal: undefined arc -> 0
    assert_eq!(edge_integral(a, -a), 0.0);
    // small angles, unit or not: θ to full relative precision
    let c = DVec3::new(1.0, 0.0, 0.0);
    for t in [0.9e-4f64, 1.1e-4, 1e-6, 1e-9, 1e-12, 0.5, 1.5] {
        let d = DVec3::new(t.cos(), t.sin(), 0.0);
        assert!((edge_integral(c, d) - t).abs() < 1e-15 * t.max(1.0), "t={t}: {}", edge_integral(c, d));
        let e = edge_integral(c * 1e-6, d * 1e5);
        assert!((e - t).abs() < 1e-14 * t, "t={t}, scaled: {e}");
    }
}

#[test]
fn rectangle_parallel_to_receiver_matches_closed_form() {
    for (a, b, h) in [(1.0, 1.0, 1.0), (2.0, 0.5, 0.7), (10.0, 3.0, 0.1), (0.01, 0.02, 5.0)] {
        let p = rect(0.0, a, 0.0, b, h);
        let f = form_factor(&p);
        let want = corner_rect(a, b, h);
        assert!((f - want).abs() < 1e-12 * (1.0 + want), "{a} {b} {h}: {f} vs {want}");
        // reversed orientation: negative
        let mut r = p.clone();
        r.reverse();
        assert!((form_factor(&r) + want).abs() < 1e-12);
    }
    // unit square centred on the axis at height h: four corner rectangles
    for h in [0.25, 1.0, 4.0] {
        let f = form_factor(&rect(-0.5, 0.5, -0.5, 0.5, h));
        assert!((f - 4.0 * corner_rect(0.5, 0.5, h)).abs() < 1e-12);
    }
}

#[test]
fn disk_polygon_matches_disk_form_factor() {
    // inscribed regular N-gon of radius R at height h: area-equivalent radius
    let (rr, h, n) = (0.8f64, 0.6f64, 4000usize);
    let poly: Vec<DVec3> =
        (0..n).map(|i| 2.0 * PI * i as f64 / n as f64).map(|t| DVec3::new(rr * t.cos(), rr * t.sin(), h)).collect();
    let f = form_factor(&poly);
    let want = rr * rr / (h * h + rr * rr);
    assert!((f - want).abs() < 2e-6, "{f} vs {want}");
    // solid angle of the disk: 2π(1 − h/√(h²+R²))
    let sa = solid_angle(&poly);
    let want = 2.0 * PI * (1.0 - h / (h * h + rr * rr).sqrt());
    assert!((sa - want).abs() < 2e-5, "{sa} vs {want}");
}

#[test]
fn form_factor_is_invariant_under_rotation_about_z() {
    let mut rng = Rng::new(7);
    for _ in 0..50 {
        let m = rand_dir(&mut rng);
        let poly: Vec<DVec3> = (0..5).map(|_| (m + 0.5 * rand_dir(&mut rng)).normalize()).collect();
        let f = form_factor(&poly);
        for a in [0.3, 1.7, 4.0] {
            let r: Vec<DVec3> = poly.iter().map(|v| rot_z(*v, a)).collect();
            assert!((form_factor(&r) - f).abs() < 1e-12);
        }
    }
}

#[test]
fn solid_angle_closed_forms() {
    // octant
    let o = [DVec3::X, DVec3::Y, DVec3::Z];
    assert!((solid_angle(&o) - PI / 2.0).abs() < 1e-14);
    // a cube face from the cube's centre
    let face = rect(-1.0, 1.0, -1.0, 1.0, 1.0);
    assert!((solid_angle(&face) - 4.0 * PI / 6.0).abs() < 1e-13);
    // form factor of the cube's top face from its centre: 1/3 of... check vector form factor: along z
    let v = vector_form_factor(&face);
    assert!(v.x.abs() < 1e-14 && v.y.abs() < 1e-14);
    assert!((v.z - form_factor(&face)).abs() < 1e-14);
    // a hemisphere-sized loop: the whole upper hemisphere (4 horizon points plus ... ) via a big square
    let big = rect(-1e7, 1e7, -1e7, 1e7, 1.0);
    assert!((solid_angle(&big) - 2.0 * PI).abs() < 1e-6);
    assert!((form_factor(&big) - 1.0).abs() < 1e-6);
}

#[test]
fn winding_number_agrees_with_solid_angle_by_monte_carlo() {
    let mut rng = Rng::new(3);
    let poly: Vec<DVec3> = [(0.2, 0.1), (0.9, 0.3), (0.4, 0.5), (0.8, 0.9), (0.1, 0.7)]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 0.5))
        .collect();
    let n = 200_000;
    let hits = (0..n).filter(|_| contains(&poly, rand_dir(&mut rng))).count() as f64;
    let est = 4.0 * PI * hits / n as f64;
    let se = 4.0 * PI * ((hits / n as f64) * (1.0 - hits / n as f64) / n as f64).sqrt();
    let sa = solid_angle(&poly);
    assert!((est - sa).abs() < 4.0 * se, "{est} vs {sa} ± {se}");
}

// --- horizon clipping --------------------------------------------------------------------------

#[test]
fn horizon_clipping_of_a_crossing_polygon_matches_monte_carlo() {
    let mut rng = Rng::new(11);
    for case in 0..6 {
        // random quad around a direction near the horizon
        let m =
            DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, 0.2 * (rng.uniform_f64() - 0.5)).normalize();
        let poly: Vec<DVec3> = (0..4)
            .map(|k| {
                let (u, v) = orthonormal_basis(m);
                let t = PI / 2.0 * k as f64 + 0.3 * rng.uniform_f64();
                (m + 0.6 * (u * t.cos() + v * t.sin())).normalize()
            })
            .collect();
        let f = form_factor(&poly);
        let (est, se) = mc_form_factor(100_000, 100 + case, |d| contains(&poly, d));
        // orientation sign
        let s = solid_angle(&poly).signum();
        assert!((s * f - est).abs() < 4.0 * se + 1e-9, "case {case}: {f} vs {est} ± {se}");
    }
}

#[test]
fn horizon_clipping_of_a_non_convex_comb_crossing_many_times() {
    // a comb in the plane y = 1: teeth dip below z = 0 several times
    let mut pts = vec![DVec3::new(-2.0, 1.0, 1.0)];
    for k in 0..5 {
        let x = -2.0 + 0.8 * k as f64;
        pts.push(DVec3::new(x + 0.1, 1.0, -0.5));
        pts.push(DVec3::new(x + 0.3, 1.0, -0.5));
        pts.push(DVec3::new(x + 0.4, 1.0, 0.3));
        pts.push(DVec3::new(x + 0.8, 1.0, 0.3));
    }
    pts.push(DVec3::new(2.0, 1.0, 1.0));
    let poly = project(DVec3::ZERO, &pts);
    let c = clip_to_horizon(&poly);
    assert!(c.iter().all(|v| v.z >= 0.0));
    let f = form_factor(&poly).abs();
    let (est, se) = mc_form_factor(200_000, 5, |d| contains(&poly, d));
    assert!((f - est).abs() < 4.0 * se, "{f} vs {est} ± {se}");
}

#[test]
fn horizon_clipping_with_vertices_on_the_horizon() {
    // triangle with two vertices exactly on the horizon
    let t = vec![DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, 0.0, 1.0)];
    assert_eq!(clip_to_horizon(&t), t);
    assert!((form_factor(&t) - 0.25).abs() < 1e-14); // octant: 1/4 of the cosine
                                                     // the mirrored triangle below: touching, not crossing -> empty
    let b = vec![DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 0.0, -1.0), DVec3::new(0.0, 1.0, 0.0)];
    assert!(clip_to_horizon(&b).is_empty());
    assert_eq!(form_factor(&b), 0.0);
    // a quad with an edge lying on the horizon and a vertex below
    let q = project(
        DVec3::ZERO,
        &[(1.0, 0.0), (0.5, 1.0), (-1.0, 0.5), (-0.5, -1.0), (2.0, 0.0)].map(|(x, z)| DVec3::new(x, 1.0, z)),
    );
    let c = clip_to_horizon(&q);
    assert!(c.iter().all(|v| v.z >= 0.0));
    let (est, se) = mc_form_factor(100_000, 9, |d| contains(&q, d));
    assert!((form_factor(&q).abs() - est).abs() < 4.0 * se);
    // entirely below
    let below: Vec<DVec3> = t.iter().map(|v| DVec3::new(v.x, v.y, -v.z - 0.1)).collect();
    assert_eq!(form_factor(&below), 0.0);
}

// --- set difference ----------------------------------------------------------------------------

fn random_triangle(rng: &mut Rng, center: DVec3, size: f64) -> Vec<DVec3> {
    (0..3)
        .map(|_| center + size * DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5))
        .collect()
}

fn visible_mc(light: &[DVec3], occ: &[Vec<DVec3>], n: usize, seed: u64) -> (f64, f64) {
    mc_form_factor(n, seed, |d| contains(light, d) && !occ.iter().any(|o| contains(o, d)))
}

#[test]
fn difference_matches_monte_carlo_on_random_configurations() {
    let mut rng = Rng::new(21);
    for case in 0..8 {
        let lc = DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, 2.0 + rng.uniform_f64());
        let (lx, ly) = (0.5 + rng.uniform_f64(), 0.5 + rng.uniform_f64());
        let lw = rect(lc.x - lx, lc.x + lx, lc.y - ly, lc.y + ly, lc.z);
        let light = project(DVec3::ZERO, &lw);
        let occ: Vec<Vec<DVec3>> = (0..(1 + case))
            .map(|_| {
                let c = lc * (0.3 + 0.5 * rng.uniform_f64())
                    + DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, 0.0);
                project(DVec3::ZERO, &random_triangle(&mut rng, c, 1.2))
            })
            .collect();
        let vis = difference(std::slice::from_ref(&light), &occ);
        let f = form_factor_loops(&vis);
        let (est, se) = visible_mc(&light, &occ, 100_000, 1000 + case as u64);
        assert!((f - est).abs() < 4.0 * se, "case {case}: {f} vs {est} ± {se}");
    }
}

#[test]
fn difference_with_light_crossing_horizon_and_occluder_partly_behind() {
    // tilted light crossing the horizon, occluder triangle with a vertex behind the shading point
    let lw = vec![
        DVec3::new(-1.0, 2.0, -0.5),
        DVec3::new(1.0, 2.0, -0.5),
        DVec3::new(1.0, 1.0, 1.5),
        DVec3::new(-1.0, 1.0, 1.5),
    ];
    let light = project(DVec3::ZERO, &lw);
    let ow = vec![DVec3::new(-0.2, 1.0, 0.3), DVec3::new(0.5, 1.5, 0.3), DVec3::new(0.0, -3.0, 0.4)];
    let occ = vec![project(DVec3::ZERO, &ow)];
    let clipped = clip_to_horizon(&light);
    let vis = difference(&[clipped], &occ);
    let f = form_factor_loops(&vis);
    let (est, se) = visible_mc(&light, &occ, 200_000, 77);
    assert!((f - est).abs() < 4.0 * se, "{f} vs {est} ± {se}");
    // the same without clipping the light first (difference itself needs no horizon clip)
    let f2 = form_factor_loops(&difference(&[light], &occ));
    assert!((f - f2).abs() < 1e-7, "{f} vs {f2}");
}

#[test]
fn difference_with_light_spanning_almost_a_hemisphere_over_several_faces() {
    // huge light close to the point: spans five cube faces
    let lw = rect(-50.0, 50.0, -50.0, 50.0, 1.0);
    let light = project(DVec3::ZERO, &lw);
    let occ = vec![
        project(DVec3::ZERO, &rect(-0.3, 2.0, -0.2, 0.5, 0.5)),
        project(DVec3::ZERO, &rect(5.0, 40.0, -1.0, 1.0, 0.9)),
    ];
    let vis = difference(std::slice::from_ref(&light), &occ);
    let want = form_factor(&light) - form_factor(&occ[0]) - form_factor(&occ[1]);
    assert!((form_factor_loops(&vis) - want).abs() < 1e-7, "{} vs {want}", form_factor_loops(&vis));
    let sa: f64 = vis.iter().map(|l| solid_angle(l)).sum();
    let want_sa = solid_angle(&light) - solid_angle(&occ[0]) - solid_angle(&occ[1]);
    assert!((sa - want_sa).abs() < 1e-6);
}

#[test]
fn difference_with_no_occluders_returns_the_light() {
    let light = project(DVec3::ZERO, &rect(-0.5, 1.0, -0.2, 0.7, 1.0));
    let f = form_factor(&light);
    let vis = difference(std::slice::from_ref(&light), &[]);
    assert!((form_factor_loops(&vis) - f).abs() < 1e-8);
    // negative input orientation still gives positive output
    let mut rev = light.clone();
    rev.reverse();
    let vis = difference(&[rev], &[]);
    assert!((form_factor_loops(&vis) - f).abs() < 1e-8);
}

#[test]
fn difference_hole_gives_outer_positive_and_hole_negative() {
    let light = project(DVec3::ZERO, &rect(-1.0, 1.0, -1.0, 1.0, 1.0));
    let occ = vec![project(DVec3::ZERO, &rect(-0.3, -0.1, 0.1, 0.2, 0.5))];
    let vis = difference(std::slice::from_ref(&light), &occ);
    assert_eq!(vis.len(), 2, "{vis:?}");
    let mut s: Vec<f64> = vis.iter().map(|l| solid_angle(l)).collect();
    s.sort_by(|a, b| a.partial_cmp(b).unwrap());
    assert!(s[0] < 0.0 && s[1] > 0.0);
    let want = form_factor(&light) - form_factor(&occ[0]);
    assert!((form_factor_loops(&vis) - want).abs() < 1e-8);
    // feeding the result back in: subtract a second occluder
    let occ2 = vec![project(DVec3::ZERO, &rect(0.2, 0.4, -0.5, -0.3, 0.7))];
    let vis2 = difference(&vis, &occ2);
    let want2 = want - form_factor(&occ2[0]);
    assert!((form_factor_loops(&vis2) - want2).abs() < 1e-8);
}

#[test]
fn difference_occluder_covering_light_entirely_is_empty() {
    let light = project(DVec3::ZERO, &rect(-0.5, 0.5, -0.5, 0.5, 2.0));
    let occ = vec![project(DVec3::ZERO, &rect(-1.0, 1.0, -1.0, 1.0, 1.0))];
    let vis = difference(&[light], &occ);
    assert!(form_factor_loops(&vis).abs() < 1e-9, "{vis:?}");
}

#[test]
fn difference_coplanar_identical_occluder_removes_everything() {
    let lw = rect(-0.5, 0.5, -0.5, 0.5, 2.0);
    let light = project(DVec3::ZERO, &lw);
    // the same quad as two triangles (shared diagonal), one of them reversed
    let t1 = project(DVec3::ZERO, &[lw[0], lw[1], lw[2]]);
    let t2 = project(DVec3::ZERO, &[lw[0], lw[3], lw[2]]);
    let vis = difference(&[light], &[t1, t2]);
    assert!(form_factor_loops(&vis).abs() < 1e-9, "{vis:?}");
}

#[test]
fn difference_shared_vertices_and_edges_between_occluders() {
    // a fan of triangles sharing the centre vertex and their edges, covering half of the light
    let light = project(DVec3::ZERO, &rect(-1.0, 1.0, -1.0, 1.0, 1.0));
    let c = DVec3::new(0.0, 0.0, 0.5);
    let ring: Vec<DVec3> =
        (0..=8).map(|k| PI * k as f64 / 8.0).map(|t| DVec3::new(0.3 * t.cos(), 0.3 * t.sin(), 0.5)).collect();
    let occ: Vec<Vec<DVec3>> = ring.windows(2).map(|w| project(DVec3::ZERO, &[c, w[0], w[1]])).collect();
    let fan_ff: f64 = occ.iter().map(|o| form_factor(o).abs()).sum();
    let vis = difference(std::slice::from_ref(&light), &occ);
    let want = form_factor(&light) - fan_ff;
    assert!((form_factor_loops(&vis) - want).abs() < 1e-8);
    // occluder sharing a whole edge (collinear) with the light's boundary
    let half = project(DVec3::ZERO, &rect(0.0, 1.0, -1.0, 1.0, 1.0));
    let vis = difference(std::slice::from_ref(&light), std::slice::from_ref(&half));
    let want = form_factor(&light) - form_factor(&half);
    assert!((form_factor_loops(&vis) - want).abs() < 1e-8);
    assert!(vis.len() == 1, "{vis:?}");
}

#[test]
fn difference_zero_area_and_degenerate_occluders_are_ignored() {
    let light = project(DVec3::ZERO, &rect(-1.0, 1.0, -1.0, 1.0, 1.0));
    let f = form_factor(&light);
    let occ = vec![
        // collinear points
        project(DVec3::ZERO, &[DVec3::new(0.0, 0.0, 0.5), DVec3::new(0.1, 0.1, 0.5), DVec3::new(0.2, 0.2, 0.5)]),
        // repeated vertex
        project(DVec3::ZERO, &[DVec3::new(0.0, 0.0, 0.5), DVec3::new(0.0, 0.0, 0.5), DVec3::new(0.2, 0.0, 0.5)]),
        // a triangle whose plane contains the shading point (edge-on: zero solid angle)
        project(DVec3::ZERO, &[DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 0.0, 0.5), DVec3::new(0.0, 0.3, 0.7)]),
        // a triangle through the shading point itself (antipodal directions, zero vector)
        project(DVec3::ZERO, &[DVec3::new(-1.0, 0.0, -1.0), DVec3::new(1.0, 0.0, 1.0), DVec3::ZERO]),
        // too few vertices, non-finite
        vec![DVec3::X, DVec3::Y],
        vec![DVec3::X, DVec3::Y, DVec3::new(f64::NAN, 0.0, 1.0)],
    ];
    let vis = difference(&[light], &occ);
    assert!((form_factor_loops(&vis) - f).abs() < 1e-8, "{} vs {f}", form_factor_loops(&vis));
}

#[test]
fn difference_union_of_many_small_triangles() {
    // per-triangle mode: 1000 random small triangles in front of a light; checks against MC and
    // reports the time (no timed assertion).
    let mut rng = Rng::new(99);
    let light = project(DVec3::ZERO, &rect(-1.0, 1.0, -1.0, 1.0, 2.0));
    let occ: Vec<Vec<DVec3>> = (0..1000)
        .map(|_| {
            let c = DVec3::new(2.0 * rng.uniform_f64() - 1.0, 2.0 * rng.uniform_f64() - 1.0, 1.0 + rng.uniform_f64());
            project(DVec3::ZERO, &random_triangle(&mut rng, c, 0.15))
        })
        .collect();
    let t0 = std::time::Instant::now();
    let vis = difference(std::slice::from_ref(&light), &occ);
    let dt = t0.elapsed();
    eprintln!("difference: 1000 triangles -> {} loops in {:.2} ms", vis.len(), dt.as_secs_f64() * 1e3);
    let f = form_factor_loops(&vis);
    let (est, se) = visible_mc(&light, &occ, 100_000, 4242);
    assert!((f - est).abs() < 4.0 * se, "{f} vs {est} ± {se}");
}

// --- silhouettes -------------------------------------------------------------------------------

fn cube_mesh(c: Vec3, h: f32) -> TriangleMesh {
    let p: Vec<Vec3> = (0..8)
        .map(|i| {
            c + h * Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    // outward-wound quads
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut indices = Vec::new();
    for q in quads {
        indices.push([q[0], q[1], q[2]]);
        indices.push([q[0], q[2], q[3]]);
    }
    TriangleMesh { positions: p, indices, ..Default::default() }
}

fn icosphere(c: Vec3, r: f32) -> TriangleMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ];
    let f: [[u32; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let positions = v.iter().map(|&(x, y, z)| c + r * Vec3::new(x, y, z).normalize()).collect();
    TriangleMesh { positions, indices: f.to_vec(), ..Default::default() }
}

fn brute_silhouette_form_factor(mesh: &TriangleMesh, p: DVec3) -> f64 {
    // sum of the front faces' (projected, reversed = positive) signed form factors
    (0..mesh.triangle_count())
        .map(|t| {
            let w = mesh.vertices(t).map(|q| q.as_dvec3());
            let n = (w[1] - w[0]).cross(w[2] - w[0]);
            if n.dot(p - w[0]) > 0.0 {
                let mut l = project(p, &w);
                l.reverse();
                form_factor(&l)
            } else {
                0.0
            }
        })
        .sum()
}

#[test]
fn silhouette_of_cube_and_icosphere_matches_brute_force() {
    let mut rng = Rng::new(5);
    for mesh in [cube_mesh(Vec3::new(0.2, -0.1, 3.0), 1.0), icosphere(Vec3::new(0.0, 0.5, 2.5), 1.2)] {
        assert!(mesh.is_closed_convex(1e-5));
        let adj = mesh.build_adjacency();
        for _ in 0..30 {
            let p =
                DVec3::new(4.0 * rng.uniform_f64() - 2.0, 4.0 * rng.uniform_f64() - 2.0, 1.5 * rng.uniform_f64() - 1.0);
            let loops = silhouette_loops(&mesh, &adj, p, 1e-9);
            assert_eq!(loops.len(), 1, "p = {p}");
            let l = &loops[0];
            // brute-force: every silhouette edge (front/back pair) appears exactly once in the loop
            let front = |t: u32| {
                let w = mesh.vertices(t as usize).map(|q| q.as_dvec3());
                (w[1] - w[0]).cross(w[2] - w[0]).normalize().dot(p - w[0]) > 1e-9
            };
            let sil = adj.edges.iter().filter(|e| front(e.tris[0]) != front(e.tris[1])).count();
            assert_eq!(l.len(), sil);
            let proj = project(p, l);
            assert!(solid_angle(&proj) > 0.0, "loop must be positive as seen from p");
            let want = brute_silhouette_form_factor(&mesh, p);
            assert!((form_factor(&proj) - want).abs() < 1e-9, "{} vs {want}", form_factor(&proj));
        }
    }
}

/// An open cylinder (no caps) of `n` sides along z, radius `r`, from `z0` to `z1`, wound outwards,
/// its seam welded.
fn open_cylinder(c: Vec3, r: f32, z0: f32, z1: f32, n: u32) -> TriangleMesh {
    let mut p = Vec::new();
    for k in 0..n {
        let phi = std::f32::consts::TAU * k as f32 / n as f32;
        let (s, co) = phi.sin_cos();
        p.push(c + Vec3::new(r * co, r * s, z0));
        p.push(c + Vec3::new(r * co, r * s, z1));
    }
    let mut indices = Vec::new();
    for k in 0..n {
        let (a, b) = (2 * k, 2 * k + 1);
        let (c2, d) = (2 * ((k + 1) % n), 2 * ((k + 1) % n) + 1);
        indices.push([a, c2, d]);
        indices.push([a, d, b]);
    }
    TriangleMesh { positions: p, indices, ..Default::default() }
}

/// An open convex mesh (a cylinder without caps): what a point outside sees of it is bounded by
/// its silhouette edges and the boundary edges of its faces turned towards the point, one loop
/// whose form factor is the front faces' (none hides another).
#[test]
fn outline_of_open_cylinder_matches_front_faces() {
    let mut rng = Rng::new(9);
    let mesh = open_cylinder(Vec3::new(0.1, -0.2, 3.0), 0.6, -1.0, 1.0, 24);
    let adj = mesh.build_adjacency();
    assert!(adj.boundary_edges() == 48 && !adj.is_closed_manifold());
    let mut checked = 0;
    for _ in 0..60 {
        let p = DVec3::new(6.0 * rng.uniform_f64() - 3.0, 6.0 * rng.uniform_f64() - 3.0, 6.0 * rng.uniform_f64());
        let want = brute_silhouette_form_factor(&mesh, p);
        let loops = silhouette_loops(&mesh, &adj, p, 1e-9);
        if want == 0.0 {
            continue; // inside the cylinder's hull, or no face turned towards p
        }
        assert_eq!(loops.len(), 1, "p = {p}");
        let proj = project(p, &loops[0]);
        assert!(solid_angle(&proj) > 0.0, "loop must be positive as seen from p");
        assert!((form_factor(&proj) - want).abs() < 1e-9, "p = {p}: {} vs {want}", form_factor(&proj));
        checked += 1;
    }
    assert!(checked > 20, "{checked}");
}

#[test]
fn silhouette_with_exactly_edge_on_faces() {
    // a point in the plane of the cube's top face (z = 4) and of its side x = 1.2: those faces are edge-on
    let mesh = cube_mesh(Vec3::new(0.2, 0.0, 3.0), 1.0);
    let adj = mesh.build_adjacency();
    for p in [DVec3::new(0.0, -3.0, 4.0), DVec3::new(1.2, -3.0, 4.0), DVec3::new(1.2, -3.0, 1.0)] {
        let loops = silhouette_loops(&mesh, &adj, p, 1e-7);
        assert_eq!(loops.len(), 1, "p = {p}");
        let proj = project(p, &loops[0]);
        let sa = solid_angle(&proj);
        // brute force solid angle of the cube: sum over strictly front faces
        let want: f64 = (0..mesh.triangle_count())
            .map(|t| {
                let w = mesh.vertices(t).map(|q| q.as_dvec3());
                let n = (w[1] - w[0]).cross(w[2] - w[0]).normalize();
                if n.dot(p - w[0]) > 1e-7 {
                    -solid_angle(&project(p, &w))
                } else {
                    0.0
                }
            })
            .sum();
        assert!((sa - want).abs() < 1e-9, "{sa} vs {want}");
    }
    // inside the cube: nothing faces p
    assert!(silhouette_loops(&mesh, &adj, DVec3::new(0.2, 0.0, 3.0), 1e-7).is_empty());
}

// --- property tests: Boolean operations, clipping, invariances ----------------------------------

mod props {
    use super::*;
    use glam::DQuat;
    use proptest::collection::vec;
    use proptest::prelude::*;
    use std::f64::consts::TAU;

    /// A simple planar polygon in a gnomonic chart (coordinates of order 1).
    #[derive(Clone, Debug)]
    struct Shape {
        pts: Vec<(f64, f64)>,
        /// Per-vertex length of the direction vectors (loops need not be unit).
        lengths: Vec<f64>,
        reversed: bool,
    }

    /// Convex triangles and quads (points on a circle at increasing angles), regular-ish stars
    /// and random star-shaped polygons (both simple, generally non-convex).
    fn shape() -> impl Strategy<Value = Shape> {
        (
            0..4usize,
            3..10usize,
            vec(0.0..1.0f64, 20),
            vec(0.15..1.0f64, 20),
            vec(0.3..3.0f64, 20),
            0.0..TAU,
            any::<bool>(),
        )
            .prop_map(|(kind, n, jitter, radii, lengths, phase, reversed)| {
                let (n, radius): (usize, Box<dyn Fn(usize) -> f64>) = match kind {
                    0 => (3, Box::new(|_| 1.0)),
                    1 => (4, Box::new(|_| 1.0)),
                    2 => (2 * n, Box::new(move |i| if i % 2 == 0 { 1.0 } else { 0.2 + 0.6 * radii[i] })),
                    _ => (n + 2, Box::new(move |i| radii[i])),
                };
                let pts = (0..n)
                    .map(|i| {
                        let a = phase + TAU * (i as f64 + 0.8 * jitter[i]) / n as f64;
                        let r = radius(i);
                        (r * a.cos(), r * a.sin())
                    })
                    .collect();
                Shape { pts, lengths: lengths[..n].to_vec(), reversed }
            })
    }

    fn unit_dir() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, 0.0..TAU).prop_map(|(z, phi)| {
            let r = (1.0 - z * z).max(0.0).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
    }

    /// The loop of `s` scaled by `size` in the chart of the tangent plane at `center`.
    fn place(s: &Shape, center: DVec3, size: f64) -> Vec<DVec3> {
        let (u, v) = orthonormal_basis(center);
        let mut l: Vec<DVec3> =
            s.pts.iter().zip(&s.lengths).map(|(&(x, y), &len)| (center + size * (x * u + y * v)) * len).collect();
        if s.reversed {
            l.reverse();
        }
        l
    }

    /// A light-like loop `a` and one to three loops `b` near it (overlapping it most of the time).
    #[derive(Clone, Debug)]
    struct Config {
        a: Vec<DVec3>,
        b: Vec<Vec<DVec3>>,
    }

    fn config() -> impl Strategy<Value = Config> {
        (unit_dir(), 0.05..2.0f64, shape(), vec((shape(), -1.5..1.5f64, -1.5..1.5f64, 0.1..1.5f64), 1..4)).prop_map(
            |(center, size, sa, bs)| {
                let (u, v) = orthonormal_basis(center);
                let b = bs
                    .iter()
                    .map(|(s, dx, dy, k)| {
                        let c = (center + size * (dx * u + dy * v)).normalize();
                        place(s, c, size * k)
                    })
                    .collect();
                Config { a: place(&sa, center, size), b }
            },
        )
    }

    fn sa(loops: &[Vec<DVec3>]) -> f64 {
        loops.iter().map(|l| solid_angle(l)).sum()
    }

    fn vff(loops: &[Vec<DVec3>]) -> DVec3 {
        loops.iter().map(|l| vector_form_factor(l)).sum()
    }

    fn close(x: f64, y: f64, scale: f64) -> bool {
        (x - y).abs() <= 1e-7 * scale.abs() + 1e-9
    }

    fn close_v(x: DVec3, y: DVec3, scale: f64) -> bool {
        (x - y).abs().max_element() <= 1e-7 * scale.abs() + 1e-9
    }

    /// Solid angle, form factor and vector form factor of a set of loops: additive
    /// fingerprints of its region (the last one encodes its boundary's shape).
    fn fingerprint(loops: &[Vec<DVec3>]) -> (f64, f64, DVec3) {
        (sa(loops), form_factor_loops(loops), vff(loops))
    }

    fn same(x: (f64, f64, DVec3), y: (f64, f64, DVec3), scale: f64) -> bool {
        close(x.0, y.0, scale) && close(x.1, y.1, scale) && close_v(x.2, y.2, scale)
    }

    fn shifted(l: &[DVec3], k: usize) -> Vec<DVec3> {
        let mut s = l.to_vec();
        s.rotate_left(k % l.len());
        s
    }

    fn reversed(l: &[DVec3]) -> Vec<DVec3> {
        l.iter().rev().copied().collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]

        #[test]
        fn difference_and_intersection_partition_the_subject(c in config()) {
            let a = std::slice::from_ref(&c.a);
            let sign = solid_angle(&c.a).signum();
            let (sa_a, ff_a) = (sign * solid_angle(&c.a), sign * form_factor(&c.a));
            let d = difference(a, &c.b);
            let i = intersection(a, &c.b);
            let (sd, si) = (sa(&d), sa(&i));
            prop_assert!(sd >= -1e-9 && si >= -1e-9, "{sd} {si}");
            prop_assert!(close(sd + si, sa_a, sa_a), "solid angle: {sd} + {si} vs {sa_a}");
            let (fd, fi) = (form_factor_loops(&d), form_factor_loops(&i));
            prop_assert!(close(fd + fi, ff_a, sa_a), "form factor: {fd} + {fi} vs {ff_a}");
            prop_assert!(close_v(vff(&d) + vff(&i), sign * vector_form_factor(&c.a), sa_a));
            // intersection ≤ each b; union by inclusion–exclusion.
            let ub = union(&[], &c.b);
            prop_assert!(si <= sa(&ub) + 1e-9);
            let u = union(a, &c.b);
            prop_assert!(close(sa(&u) + si, sa_a + sa(&ub), sa_a + sa(&ub)), "{} + {si} vs {sa_a} + {}", sa(&u), sa(&ub));
            prop_assert!(close(form_factor_loops(&u) + fi, ff_a + form_factor_loops(&ub), sa_a + sa(&ub)));
            // and A ∖ B = (A ∪ B) ∖ B
            prop_assert!(close(sa(&difference(&u, &c.b)), sd, sa_a + sa(&ub)));
        }

        #[test]
        fn boolean_results_have_the_expected_winding_numbers(c in config(), samples in vec((-1.3..1.3f64, -1.3..1.3f64), 24)) {
            let a = std::slice::from_ref(&c.a);
            let (d, i, u) = (difference(a, &c.b), intersection(a, &c.b), union(a, &c.b));
            let m = hemisphere_center(&c.a).unwrap();
            let (e1, e2) = orthonormal_basis(m);
            let size = c.a.iter().map(|p| (p.normalize() - m).length()).fold(0.0, f64::max);
            for (x, y) in samples {
                let q = (m + size * (x * e1 + y * e2)).normalize();
                let in_a = contains(&c.a, q);
                let in_b = c.b.iter().any(|l| contains(l, q));
                let (wd, wi, wu) = (winding_number_loops(&d, q), winding_number_loops(&i, q), winding_number_loops(&u, q));
                prop_assert_eq!(wd, i32::from(in_a && !in_b), "difference at {}", q);
                prop_assert_eq!(wi, i32::from(in_a && in_b), "intersection at {}", q);
                prop_assert_eq!(wu, i32::from(in_a || in_b), "union at {}", q);
            }
        }

        #[test]
        fn clipping_splits_the_solid_angle_and_never_increases_it(c in config(), n in unit_dir(), offset in -0.5..0.5f64) {
            // A plane through the loop's hemisphere centre tilted by `offset`: both sides are hit.
            let m = hemisphere_center(&c.a).unwrap();
            let n = (n - m * n.dot(m)).normalize_or(DVec3::X) + m * offset;
            let s = solid_angle(&c.a);
            let (up, down) = (clip_to_halfspace(&c.a, n), clip_to_halfspace(&c.a, -n));
            let (su, sd) = (solid_angle(&up), solid_angle(&down));
            prop_assert!(su * s >= -1e-12 && sd * s >= -1e-12, "{su} {sd} vs {s}");
            prop_assert!(su.abs() <= s.abs() + 1e-12 && sd.abs() <= s.abs() + 1e-12);
            prop_assert!(close(su + sd, s, s), "{su} + {sd} vs {s}");
            let fu = form_factor(&up) + form_factor(&down);
            prop_assert!(close(fu, form_factor(&c.a), s));
            // Clipping again to the same half-space changes nothing.
            prop_assert!(close(solid_angle(&clip_to_halfspace(&up, n)), su, s));
            // Horizon clipping: never more solid angle; all of it when above, none when below.
            let h = solid_angle(&clip_to_horizon(&c.a));
            prop_assert!(h.abs() <= s.abs() + 1e-12 && h * s >= -1e-12);
            if c.a.iter().all(|v| v.z > 0.0) {
                prop_assert_eq!(h, s);
            }
            if c.a.iter().all(|v| v.z < 0.0) {
                prop_assert_eq!(h, 0.0);
                prop_assert_eq!(form_factor(&c.a), 0.0);
            }
        }

        #[test]
        fn results_do_not_depend_on_the_vertex_order(c in config(), k in 0..32usize, j in 0..32usize) {
            let a = std::slice::from_ref(&c.a);
            let scale = solid_angle(&c.a).abs();
            let (s, f) = (solid_angle(&c.a), form_factor(&c.a));
            let a_shift = shifted(&c.a, k);
            prop_assert!(close(solid_angle(&a_shift), s, scale) && close(form_factor(&a_shift), f, scale));
            prop_assert!(close(solid_angle(&reversed(&c.a)), -s, scale) && close(form_factor(&reversed(&c.a)), -f, scale));
            prop_assert!(close_v(vector_form_factor(&a_shift), vector_form_factor(&c.a), scale));
            let b_shift: Vec<Vec<DVec3>> = c.b.iter().enumerate().map(|(t, l)| shifted(l, j + t)).collect();
            let b_rev: Vec<Vec<DVec3>> = c.b.iter().map(|l| reversed(l)).collect();
            let variants_a = [c.a.clone(), a_shift, reversed(&c.a)];
            for op in [difference, intersection, union] {
                let want = fingerprint(&op(a, &c.b));
                for va in &variants_a {
                    for vb in [&c.b, &b_shift, &b_rev] {
                        let got = fingerprint(&op(std::slice::from_ref(va), vb));
                        prop_assert!(same(got, want, scale), "{:?} vs {:?}", got, want);
                    }
                }
            }
        }

        #[test]
        fn results_are_invariant_under_global_rotation(c in config(), axis in unit_dir(), angle in 0.0..TAU) {
            let r = DQuat::from_axis_angle(axis, angle);
            let rot = |l: &Vec<DVec3>| l.iter().map(|v| r * *v).collect::<Vec<_>>();
            let back = |ls: Vec<Vec<DVec3>>| ls.iter().map(|l| l.iter().map(|v| r.inverse() * *v).collect()).collect::<Vec<Vec<DVec3>>>();
            let a = std::slice::from_ref(&c.a);
            let ra = vec![rot(&c.a)];
            let rb: Vec<Vec<DVec3>> = c.b.iter().map(rot).collect();
            let scale = solid_angle(&c.a).abs();
            prop_assert!(close(solid_angle(&ra[0]), solid_angle(&c.a), scale));
            for op in [difference, intersection, union] {
                let want = op(a, &c.b);
                let got = op(&ra, &rb);
                prop_assert!(close(sa(&got), sa(&want), scale + sa(&want)), "{} vs {}", sa(&got), sa(&want));
                prop_assert!(close_v(vff(&got), r * vff(&want), scale + sa(&want)));
                // Rotating the result back gives the same form factor (which depends on the frame).
                let ff_back = form_factor_loops(&back(got));
                prop_assert!(close(ff_back, form_factor_loops(&want), scale + sa(&want)), "{ff_back} vs {}", form_factor_loops(&want));
            }
        }
    }
}
#[test]
fn intersection_and_union_of_coplanar_rectangles_are_rectangles() {
    // Two overlapping rectangles in the plane z = 1.5: their intersection is the overlap
    // rectangle and their union's integrals follow by inclusion–exclusion.
    let a = project(DVec3::ZERO, &rect(-1.0, 0.5, -0.4, 0.8, 1.5));
    let b = project(DVec3::ZERO, &rect(-0.2, 2.0, 0.1, 1.9, 1.5));
    let overlap = project(DVec3::ZERO, &rect(-0.2, 0.5, 0.1, 0.8, 1.5));
    let mut b_rev = b.clone();
    b_rev.reverse();
    let i = intersection(std::slice::from_ref(&a), &[b_rev]);
    assert!((form_factor_loops(&i) - form_factor(&overlap)).abs() < 1e-8, "{}", form_factor_loops(&i));
    let u = union(std::slice::from_ref(&a), std::slice::from_ref(&b));
    let want = form_factor(&a) + form_factor(&b) - form_factor(&overlap);
    assert!((form_factor_loops(&u) - want).abs() < 1e-8, "{} vs {want}", form_factor_loops(&u));
    // Disjoint: empty intersection; no second operand: empty intersection, union = a.
    let far = project(DVec3::ZERO, &rect(3.0, 4.0, 3.0, 4.0, 1.5));
    assert!(intersection(std::slice::from_ref(&a), &[far]).is_empty());
    assert!(intersection(std::slice::from_ref(&a), &[]).is_empty());
    let ua = union(std::slice::from_ref(&a), &[]);
    assert!((form_factor_loops(&ua) - form_factor(&a)).abs() < 1e-8);
    assert!(union(&[], &[]).is_empty());
}

#[test]
fn hemisphere_center_of_a_wide_triangle_and_of_thin_margins() {
    // Found by the property tests: a wide triangle (solid angle 1.67) on which the former
    // normalised half-step perceptron bounced between vertices and gave up.
    let b = vec![
        DVec3::new(0.5545513464047539, -0.3491041284540045, 0.44045782427605645),
        DVec3::new(-0.7233387805723386, -0.2385331861679667, 0.2080550669549607),
        DVec3::new(0.6496324904128435, -0.3573311359757532, -0.27147020081629136),
    ];
    let m = hemisphere_center(&b).expect("the triangle lies in the hemisphere y < 0");
    assert!(b.iter().all(|v| v.normalize().dot(m) > 0.0));
    assert!(contains(&b, DVec3::new(-0.08620407937334723, -0.9962774998459984, 0.0)));
    // A rectangle seen from ever closer to its plane: margins down to ~1e-6.
    for h in [1.0, 1e-2, 1e-4] {
        let l = project(DVec3::ZERO, &rect(-10.0, 10.0, -3.0, 10.0, h));
        let m = hemisphere_center(&l).unwrap_or_else(|| panic!("h = {h}"));
        assert!(l.iter().all(|v| v.dot(m) > 0.0), "h = {h}");
    }
    // No open hemisphere: a loop through three directions whose hull holds the origin.
    let bad = vec![DVec3::X, DVec3::new(-1.0, 1.0, 0.0), DVec3::new(-1.0, -1.0, 0.0)];
    assert_eq!(hemisphere_center(&bad), None);
    assert_eq!(hemisphere_center(&[DVec3::X, -DVec3::X, DVec3::Y]), None);
}

// --- triangle chains ---------------------------------------------------------------------------

/// A closed torus (major radius `big`, minor `small`) about the z axis at `c`; vertices shared.
fn torus_mesh(c: Vec3, big: f32, small: f32, nu: usize, nv: usize) -> TriangleMesh {
    let mut positions = Vec::new();
    for i in 0..nu {
        let u = i as f32 / nu as f32 * std::f32::consts::TAU;
        for j in 0..nv {
            let v = j as f32 / nv as f32 * std::f32::consts::TAU;
            let r = big + small * v.cos();
            positions.push(c + Vec3::new(r * u.cos(), r * u.sin(), small * v.sin()));
        }
    }
    let id = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
    let mut indices = Vec::new();
    for i in 0..nu {
        for j in 0..nv {
            indices.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            indices.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriangleMesh { positions, indices, ..Default::default() }
}

/// Whether direction `d` from `p` passes through triangle `t` (its projection covers `d`).
fn covers(mesh: &TriangleMesh, t: usize, p: DVec3, d: DVec3) -> bool {
    let pv = project(p, &mesh.vertices(t).map(|q| q.as_dvec3()));
    let s = [pv[0].cross(pv[1]).dot(d), pv[1].cross(pv[2]).dot(d), pv[2].cross(pv[0]).dot(d)];
    let det = pv[0].dot(pv[1].cross(pv[2]));
    det != 0.0 && s.iter().all(|x| x * det.signum() > 0.0)
}

#[test]
fn triangle_chains_wind_once_per_covering_triangle() {
    // A non-convex closed mesh seen from outside, whole and in random subsets (open patches,
    // holes, folds in the projection): the chains' winding number in any direction is the
    // number of chosen triangles covering it, with far fewer edges than the triangles have.
    let mesh = torus_mesh(Vec3::ZERO, 1.0, 0.35, 24, 12);
    let weld: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let mut rng = Rng::new(7);
    for case in 0..12 {
        let p = rand_dir(&mut rng) * (1.6 + 2.0 * rng.uniform_f64()) + DVec3::new(0.0, 0.0, 0.2);
        let tris: Vec<usize> = (0..mesh.triangle_count()).filter(|_| case < 4 || rng.uniform_f64() < 0.7).collect();
        let chains = triangle_chains(&mesh, &tris, &weld, p);
        let loops: Vec<Vec<DVec3>> = chains.iter().map(|l| project(p, l)).collect();
        let edges: usize = loops.iter().map(|l| l.len()).sum();
        assert!(edges < tris.len() * 3, "case {case}: {edges} edges for {} triangles", tris.len());
        let centre = (DVec3::ZERO - p).normalize();
        for _ in 0..400 {
            // Directions around the torus (within ~35° of its centre).
            let d = (centre + rand_dir(&mut rng) * 0.7 * rng.uniform_f64()).normalize();
            let n = tris.iter().filter(|&&t| covers(&mesh, t, p, d)).count() as i32;
            assert_eq!(winding_number_loops(&loops, d), n, "case {case}: direction {d}");
        }
    }
}

#[test]
fn difference_chains_equals_difference_of_the_triangles() {
    // Subtracting the chains of a torus patch and subtracting its triangles one by one give the
    // same visible region (solid angle and form factor), with and without extra loops.
    let mesh = torus_mesh(Vec3::new(0.0, 0.0, 1.5), 0.6, 0.2, 20, 10);
    let weld: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let mut rng = Rng::new(11);
    for case in 0..6 {
        let p = DVec3::new(0.3 * rng.uniform_f64(), 0.3 * rng.uniform_f64(), 0.0);
        let tris: Vec<usize> = (0..mesh.triangle_count()).filter(|_| case == 0 || rng.uniform_f64() < 0.6).collect();
        let each: Vec<Vec<DVec3>> = tris.iter().map(|&t| project(p, &mesh.vertices(t).map(|q| q.as_dvec3()))).collect();
        let chains: Vec<Vec<DVec3>> = triangle_chains(&mesh, &tris, &weld, p).iter().map(|l| project(p, l)).collect();
        let extra = vec![project(p, &rect(-0.2, 0.4, 0.1, 0.5, 2.0))];
        let light = vec![project(p, &rect(-1.2, 1.2, -1.0, 1.0, 3.0))];
        let mut all = each.clone();
        all.extend(extra.iter().cloned());
        let a = difference(&light, &all);
        let b = difference_chains(&light, &extra, &chains);
        let solid_angle_loops = |l: &[Vec<DVec3>]| l.iter().map(|x| solid_angle(x)).sum::<f64>();
        let (sa, sb) = (solid_angle_loops(&a), solid_angle_loops(&b));
        assert!((sa - sb).abs() < 1e-7, "case {case}: solid angle {sa} (triangles) vs {sb} (chains)");
        assert!((form_factor_loops(&a) - form_factor_loops(&b)).abs() < 1e-7, "case {case}: form factor");
        assert!(sb < solid_angle(&light[0]) - 1e-3, "case {case}: the torus must hide part of the light");
    }
}

// --- difference with one convex occluder -------------------------------------------------------

/// Solid angle and form factor of a set of loops.
fn measures(loops: &[Vec<DVec3>]) -> (f64, f64) {
    (loops.iter().map(|l| solid_angle(l)).sum(), form_factor_loops(loops))
}

fn assert_same_region(got: &[Vec<DVec3>], want: &[Vec<DVec3>], what: &str) {
    let (g, w) = (measures(got), measures(want));
    // `difference` snaps to a ~1e-9 rad grid; the clip is exact to rounding.
    assert!((g.0 - w.0).abs() < 1e-7 && (g.1 - w.1).abs() < 1e-7, "{what}: {g:?} vs {w:?}");
}

#[test]
fn difference_convex_matches_difference_for_triangles_and_silhouettes() {
    let mut rng = Rng::new(77);
    let cube = cube_mesh(Vec3::new(0.1, 0.2, 1.4), 0.35);
    let ico = icosphere(Vec3::new(-0.2, 0.1, 1.3), 0.4);
    let (cube_adj, ico_adj) = (cube.build_adjacency(), ico.build_adjacency());
    let mut partial = 0;
    for case in 0..300 {
        let lc = DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, 2.0 + rng.uniform_f64());
        let (lx, ly) = (0.3 + rng.uniform_f64(), 0.3 + rng.uniform_f64());
        let lw = rect(lc.x - lx, lc.x + lx, lc.y - ly, lc.y + ly, lc.z);
        let mut light = project(DVec3::ZERO, &lw);
        let occ = match case % 3 {
            0 => {
                let c = lc * (0.3 + 0.5 * rng.uniform_f64())
                    + DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, 0.0);
                project(DVec3::ZERO, &random_triangle(&mut rng, c, 1.2))
            }
            k => {
                // A convex mesh's silhouette and the light, both seen from a point below.
                let p = DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, 0.5 * rng.uniform_f64() - 0.25);
                let (mesh, adj) = if k == 1 { (&cube, &cube_adj) } else { (&ico, &ico_adj) };
                let loops = silhouette_loops(mesh, adj, p, 1e-9);
                light = project(p, &lw);
                let mut l: Vec<DVec3> = project(p, &loops[0]);
                if case % 4 == 0 {
                    l.reverse();
                }
                l
            }
        };
        if case % 2 == 1 {
            light.reverse();
        }
        let want = difference(std::slice::from_ref(&light), std::slice::from_ref(&occ));
        let got = difference_convex(&light, &occ).expect("convex occluder");
        partial += usize::from(got.len() == 2);
        assert_same_region(&got, &want, &format!("case {case}"));
        // Rotating the loops' vertex order changes nothing.
        let mut lr = light.clone();
        lr.rotate_left(1);
        let mut or = occ.clone();
        or.rotate_left(2);
        assert_same_region(&difference_convex(&lr, &or).unwrap(), &want, &format!("case {case} rotated"));
    }
    // Most cases cut the light (neither miss nor cover it).
    assert!(partial > 200, "{partial} of 300 partly occluded");
}

#[test]
fn difference_convex_edge_cases() {
    let light = project(DVec3::ZERO, &rect(-1.0, 1.0, -1.0, 1.0, 2.0));
    let full = measures(std::slice::from_ref(&light));
    // Covering the light (larger, and identical: shared edges and vertices): nothing left.
    let big = project(DVec3::ZERO, &rect(-2.0, 2.0, -2.0, 2.0, 1.5));
    assert!(difference_convex(&light, &big).unwrap().is_empty());
    assert!(difference_convex(&light, &light).unwrap().is_empty());
    let mut rev = light.clone();
    rev.reverse();
    assert!(difference_convex(&rev, &light).unwrap().is_empty());
    // Missing it: the light, positive.
    let away = project(DVec3::ZERO, &rect(3.0, 4.0, -1.0, 1.0, 2.0));
    let r = difference_convex(&rev, &away).unwrap();
    assert_eq!(r.len(), 1);
    assert!((measures(&r).0 - full.0).abs() < 1e-12 && solid_angle(&r[0]) > 0.0);
    // Half covered along a shared, collinear edge: half the light (by symmetry of the rect).
    let half = project(DVec3::ZERO, &rect(0.0, 1.0, -1.0, 1.0, 2.0));
    let r = difference_convex(&light, &half).unwrap();
    let want = measures(&project_rect_half());
    assert!((measures(&r).0 - want.0).abs() < 1e-12, "{:?} vs {want:?}", measures(&r));
    // A hole: outer positive, hole negative.
    let small = project(DVec3::ZERO, &rect(-0.2, 0.2, -0.2, 0.2, 1.0));
    let r = difference_convex(&light, &small).unwrap();
    let want = difference(std::slice::from_ref(&light), std::slice::from_ref(&small));
    assert_same_region(&r, &want, "hole");
    // Zero-area occluder: the light. A non-convex occluder (an L): not applicable.
    let flat = vec![DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.1, 0.0, 1.0), DVec3::new(0.2, 0.0, 1.0)];
    assert!((measures(&difference_convex(&light, &flat).unwrap()).0 - full.0).abs() < 1e-12);
    let ell: Vec<DVec3> = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.5), (0.5, 0.5), (0.5, 1.0), (0.0, 1.0)]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 1.0).normalize())
        .collect();
    assert!(difference_convex(&light, &ell).is_none());
    // Unusable loops: not applicable (difference ignores them).
    assert!(difference_convex(&light, &[DVec3::ZERO, DVec3::X, DVec3::Y]).is_none());
    // Wider than a hemisphere about its mean: not applicable.
    let wide = vec![DVec3::X, DVec3::Y, -DVec3::X, DVec3::new(0.0, -1.0, 1e-3)];
    assert!(difference_convex(&light, &wide).is_none());
}

/// The left half of the light of `difference_convex_edge_cases`.
fn project_rect_half() -> Vec<Vec<DVec3>> {
    vec![project(DVec3::ZERO, &rect(-1.0, 0.0, -1.0, 1.0, 2.0))]
}
