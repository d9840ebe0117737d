use super::*;
use penumbra_core::rng::Rng;
use penumbra_core::sampling::cosine_sample_hemisphere;
use penumbra_core::sh::{basis, ShOrder};

fn plane_frame() -> Frame<DVec3> {
    Frame { x: DVec3::X, y: DVec3::Y, z: DVec3::Z }
}

/// A plane z = 0 of cache points on a `k × k` grid of spacing `h` around the origin, each with
/// `rays` cosine-distributed directions; `hit(o, d)` gives the hit distance (∞: a miss).
fn plane_cache(k: i32, h: f64, rays: usize, hit: impl Fn(DVec3, DVec3) -> f64) -> Vec<CachePoint> {
    plane_rays(k, h, rays, hit).into_iter().map(|(p, rays)| CachePoint::new(p, DVec3::Z, h, &rays)).collect()
}

/// [`plane_cache`]'s points and rays.
fn plane_rays(k: i32, h: f64, rays: usize, hit: impl Fn(DVec3, DVec3) -> f64) -> Vec<(DVec3, Vec<CachedRay>)> {
    let mut rng = Rng::new(7);
    let mut out = Vec::new();
    for j in -k..=k {
        for i in -k..=k {
            let p = DVec3::new(i as f64 * h, j as f64 * h, 0.0);
            let rays = (0..rays)
                .map(|_| {
                    let u = glam::Vec2::new(rng.uniform_f32(), rng.uniform_f32());
                    let d = cosine_sample_hemisphere(u).as_dvec3().normalize();
                    CachedRay { d, t: hit(p, d), n_hit: DVec3::Z }
                })
                .collect();
            out.push((p, rays));
        }
    }
    out
}

fn ao(cells: &[CellValue]) -> Option<f64> {
    let mut s = 0.0;
    for c in cells {
        match c {
            CellValue::Filtered(v) => s += v,
            CellValue::Brute => return None,
        }
    }
    Some(std::f64::consts::PI * s / cells.len() as f64)
}

#[test]
fn cells_invert_the_concentric_map_and_have_equal_projected_area() {
    let n = 8;
    let mut counts = vec![0usize; n * n];
    for j in 0..64 {
        for i in 0..64 {
            let u = glam::Vec2::new((i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 64.0);
            let w = cosine_sample_hemisphere(u).as_dvec3();
            let c = cell_of(w, n);
            assert_eq!(c, (j / 8) * n + i / 8, "u {u:?}");
            counts[c] += 1;
        }
    }
    assert!(counts.iter().all(|&c| c == 64));
    for c in 0..n * n {
        assert_eq!(cell_of(cell_center(c, n), n), c);
    }
}

/// The filter's f32 branch-free lookup ([`Grid32`]) chooses [`cell_of`]'s cell but within f32
/// rounding of a cell boundary: on the cell centres, on the unnormalised vectors the filter
/// passes (any length, with its reciprocal), and on 100 000 random directions, where a
/// direction within ~1e-6 of one of the 16 boundaries (about 2 expected) may differ.
#[test]
fn f32_cell_lookup_matches_the_f64_one() {
    for n in [1, 5, 8, 13] {
        let g = Grid32::new(n);
        for c in 0..n * n {
            let w = cell_center(c, n) * 3.7;
            assert_eq!(g.cell(w.x as f32, w.y as f32, 1.0 / w.length() as f32) as usize, c, "n {n}");
        }
    }
    let (n, g) = (8, Grid32::new(8));
    let mut rng = Rng::new(3);
    let mut differ = 0;
    for _ in 0..100_000 {
        let u = glam::Vec2::new(rng.uniform_f32(), rng.uniform_f32());
        let w = cosine_sample_hemisphere(u).as_dvec3().normalize();
        differ += (g.cell(w.x as f32, w.y as f32, 1.0) as usize != cell_of(w, n)) as usize;
    }
    assert!(differ <= 10, "{differ} of 100 000 directions in another cell");
    assert_eq!(g.cell(0.0, 0.0, 0.5), cell_of(DVec3::Z, n) as u32, "the pole");
}

#[test]
fn unoccluded_plane_is_pi_exactly() {
    let cache = plane_cache(8, 0.01, 12, |_, _| f64::INFINITY);
    let recv = Receiver { p: DVec3::ZERO, frame: plane_frame(), footprint: 0.01 };
    let (mut s, mut out) = (Scratch::default(), Vec::new());
    filter_receiver(&recv, cache.iter(), &FilterParams::default(), &mut s, &mut out);
    assert_eq!(ao(&out), Some(std::f64::consts::PI));
}

/// Occluded fraction (cosine-weighted) at the plane point under a parallel disk of radius ρ at
/// height h, offset a horizontally (the digest's closed form).
fn disk_fraction(rho: f64, h: f64, a: f64) -> f64 {
    let z = h * h + a * a + rho * rho;
    0.5 * (1.0 - (z - 2.0 * rho * rho) / (z * z - 4.0 * rho * rho * a * a).sqrt())
}

fn disk_hit(rho: f64, h: f64) -> impl Fn(DVec3, DVec3) -> f64 {
    move |o: DVec3, d: DVec3| {
        let t = (h - o.z) / d.z;
        let q = o + t * d;
        if t > 0.0 && q.x * q.x + q.y * q.y <= rho * rho {
            t
        } else {
            f64::INFINITY
        }
    }
}

#[test]
fn plane_under_a_disk_matches_the_closed_form() {
    let (rho, h) = (1.0, 1.0);
    // A 33×33 window of spacing 0.02 (±0.16): the disk is at one depth per direction cone.
    let cache = plane_rays(8, 0.02, 64, disk_hit(rho, h));
    let (mut s, mut out) = (Scratch::default(), Vec::new());
    // Measured (64 rays per point): 1.5720 / 1.7777 / 2.2832 against 1.5708 / 1.7656 / 2.2733.
    for a in [0.0, 0.5, 1.0] {
        let p = DVec3::new(a, 0.0, 0.0);
        let shifted: Vec<CachePoint> = cache
            .iter()
            .map(|(q, rays)| {
                let rays: Vec<CachedRay> =
                    rays.iter().map(|r| CachedRay { t: disk_hit(rho, h)(*q + p, r.d), ..*r }).collect();
                CachePoint::new(*q + p, DVec3::Z, 0.02, &rays)
            })
            .collect();
        let recv = Receiver { p, frame: plane_frame(), footprint: 0.02 };
        filter_receiver(&recv, shifted.iter(), &FilterParams::default(), &mut s, &mut out);
        let brute = out.iter().filter(|c| **c == CellValue::Brute).count();
        let got: f64 = std::f64::consts::PI
            * out.iter().map(|c| if let CellValue::Filtered(v) = c { *v } else { 0.5 }).sum::<f64>()
            / out.len() as f64;
        let exact = std::f64::consts::PI * (1.0 - disk_fraction(rho, h, a));
        eprintln!("a {a}: filtered AO {got:.4} vs exact {exact:.4}, {brute} brute cells");
        assert!(brute <= 4, "a {a}: {brute} brute-forced cells");
        assert!((got - exact).abs() < 0.01 * exact, "a {a}: {got} vs {exact}");
    }
}

/// Over all cells the full-visibility transfer is the clamped cosine's projection, `Â_l Y_lm(z)`
/// with `Â_0 = π`, `Â_1 = 2π/3`, `Â_2 = π/4`, `Â_3 = 0`; band 0 of every cell is `Y_0 · π / cells²`.
#[test]
fn cell_transfer_sums_to_the_clamped_cosine() {
    let order = ShOrder::new(4).unwrap();
    let pi = std::f64::consts::PI;
    let (cells, k) = (8, order.coeffs());
    let table = cell_transfer(cells, order);
    let y = basis::eval_vec(order, DVec3::Z);
    let a_hat = [pi, 2.0 * pi / 3.0, pi / 4.0, 0.0];
    for i in 0..k {
        let l = (i as f64).sqrt() as usize;
        let sum: f64 = table.chunks_exact(k).map(|row| row[i]).sum();
        let want = a_hat[l] * y[i];
        assert!((sum - want).abs() < 1e-12, "coefficient {i}: {sum} vs {want}");
    }
    for row in table.chunks_exact(k) {
        assert!((row[0] - y[0] * pi / (cells * cells) as f64).abs() < 1e-14);
    }
}

/// Through a plane parallel to the receiver the warp's Jacobian is `cos³θ_p / cos³θ_q`, so the
/// weight is `cos⁴θ_p / cos⁴θ_q`; a receiver's own ray weighs 1.
#[test]
fn occluded_jacobian_through_a_parallel_plane() {
    let h = 0.7;
    let q = DVec3::new(0.3, -0.2, 0.0);
    for d in [DVec3::new(0.2, 0.1, 1.0), DVec3::new(-0.6, 0.4, 0.5), DVec3::new(0.9, -0.3, 0.2)] {
        let d = d.normalize();
        let t = h / d.z;
        let r = CachedRay { d, t, n_hit: -DVec3::Z };
        let hit = q + t * d;
        let v = hit.normalize();
        let want = (v.z / d.z).powi(4).min(JACOBIAN_CAP);
        let got = occluded_jacobian(&r, DVec3::Z, DVec3::Z, v, hit.length());
        assert!((got - want).abs() < 1e-12 * want, "{got} vs {want}");
        let own = occluded_jacobian(&r, DVec3::Z, DVec3::Z, d, t);
        assert!((own - 1.0).abs() < 1e-12);
    }
}

/// The filter's Jacobian from the per-ray factor precomputed in [`CachePoint::new`]
/// ([`hit_jacobian`]) is [`occluded_jacobian`] (to rounding), for neighbours and hits in
/// general position, a ray leaving below the neighbour's horizon (weight 0) and a hit seen
/// edge-on from the neighbour (capped).
#[test]
fn precomputed_jacobian_matches_occluded_jacobian() {
    let mut rng = Rng::new(11);
    let mut unit = || DVec3::new(rng.uniform_f32() as f64, rng.uniform_f32() as f64, rng.uniform_f32() as f64);
    let (n_p, recv) = (DVec3::new(0.1, -0.05, 1.0).normalize(), DVec3::new(0.2, 0.1, -0.3));
    let mut checked = 0;
    for i in 0..200 {
        let n_q = (DVec3::Z + 0.2 * (unit() - 0.5)).normalize();
        let q = recv + 0.1 * (unit() - 0.5);
        let mut d = (unit() - DVec3::new(0.5, 0.5, 0.0) + DVec3::new(0.0, 0.0, 0.05)).normalize();
        let mut m = (unit() - 0.5).normalize();
        if i == 0 {
            d = (d - n_q * (d.dot(n_q) + 0.1)).normalize(); // below the neighbour's horizon
        }
        if i == 1 {
            m = (m - d * m.dot(d)).normalize(); // m ⟂ d
        }
        let t = 0.05 + unit().x;
        let r = CachedRay { d, t, n_hit: m };
        let cp = CachePoint::new(q, n_q, 0.01, &[r]);
        // As `gather` forms the terms: the point's offset in f64, the ray's terms in f32.
        let (ht, o) = (cp.hits[0], q - recv);
        let u = o + ht.r.as_dvec3();
        let z2 = u.length_squared();
        let m_u = ht.m.dot(o.as_vec3()) + ht.mr;
        let got = hit_jacobian(u.dot(n_p) as f32, m_u, ht.k, z2 as f32) as f64;
        let want = occluded_jacobian(&r, n_q, n_p, u / z2.sqrt(), z2.sqrt());
        if i == 0 {
            assert_eq!(want, 0.0, "below the horizon");
        }
        if i == 1 {
            assert_eq!(want, JACOBIAN_CAP, "edge-on hit (|m·d| ≈ 1e-17)");
        }
        // f32: a dozen roundings of 6e-8 each.
        assert!((got - want).abs() <= 2e-6 * want.max(1.0), "case {i}: {got} vs {want}");
        checked += (want > 0.0 && want < JACOBIAN_CAP) as usize;
    }
    assert!(checked > 50, "only {checked} uncapped non-zero weights");
}

/// The kernel as it was written before the weight loops lost their branches, `(1 − t²/T²)⁴`
/// below `T² = 2.25` and 0 from there: the specification [`kernel`]'s select must equal.
fn kernel_branch(t2: f64) -> f64 {
    const T2: f64 = 1.5 * 1.5;
    if t2 < T2 {
        let a = 1.0 - t2 * (1.0 / T2);
        let a2 = a * a;
        a2 * a2
    } else {
        0.0
    }
}

/// The weight loops' branch-free kernel is the branch form bit for bit: below, at and beyond the
/// support's end `t² = 2.25` (the images must not change), and for the infinite radius's `0`.
#[test]
fn select_kernel_is_the_kernel_bit_for_bit() {
    let mut t2s: Vec<f64> = (0..=4000).map(|i| i as f64 * 1e-3).collect();
    t2s.extend([
        2.25,
        f64::from_bits(2.25f64.to_bits() - 1),
        f64::from_bits(2.25f64.to_bits() + 1),
        1e30,
        f64::INFINITY,
    ]);
    for t2 in t2s {
        assert_eq!(kernel(t2).to_bits(), kernel_branch(t2).to_bits(), "t2 = {t2}");
    }
}
