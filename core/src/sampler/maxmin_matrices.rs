//! Generator matrices for the maxmindist sampler.
//!
//! **Deviation from pbrt-v3.** pbrt-v3 uses Grünschloß et al.'s max-min-distance matrices
//! ("Enumerating quasi-Monte Carlo point sequences in elementary intervals", 2012). Those
//! tables were not available to this project from a source it could use, so the matrices
//! below come from our own search ([`search_maxmin_matrix`]), which keeps the defining
//! property — for 2^m samples, the points (i / 2^m, C·i) form a (0, m, 2)-net (one point in
//! every elementary interval of area 2^-m) — and, among random matrices with that property,
//! keeps the one with the largest minimum toroidal distance between points. Such a matrix
//! is a uniformly random C = L·U (unit lower/upper triangular over GF(2) on the top-left
//! m×m block, which is exactly the condition that every leading principal minor is
//! non-singular) plus random lower-order output bits. The search is a plain random search,
//! so the resulting minimum distances are good but generally below Grünschloß's optimised
//! ones. Entry `m` is for 2^m samples per pixel (m ≤ 16). Minimum distances reached, as a
//! fraction of the hexagonal-lattice ideal sqrt(2 / (sqrt(3) n)), for m = 1…16:
//! 0.93 0.94 0.92 0.87 0.82 0.79 0.64 0.67 0.59 0.52 0.59 0.45 0.35 0.39 0.46 0.31
//! (m = 0 is a single point). Regenerated (about 25 minutes on one core) with
//! `PENUMBRA_MAXMIN_EFFORT=10 cargo test -p penumbra-core --lib -- --ignored print_maxmin_matrices --nocapture`,
//! whose standard output (the `[…]` rows) is `maxmin_matrices.in`.

use crate::rng::Rng;

/// Minimum toroidal distance² of the points (i/n, C·i) with n = 2^m; exits early with a value
/// ≤ `give_up` as soon as the minimum is known to be at most `give_up`.
pub fn min_toroidal_distance2(c: &[u32; 32], m: u32, give_up: f64) -> f64 {
    let n = 1usize << m;
    let ys: Vec<f64> =
        (0..n as u32).map(|i| super::lowdiscrepancy::multiply_generator(c, i) as f64 / 4294967296.0).collect();
    let mut best = f64::INFINITY;
    for d in 1..n {
        let dx = d.min(n - d) as f64 / n as f64;
        if dx * dx >= best {
            break;
        }
        for i in 0..n {
            let mut dy = (ys[i] - ys[(i + d) % n]).abs();
            dy = dy.min(1.0 - dy);
            let d2 = dx * dx + dy * dy;
            if d2 < best {
                best = d2;
                if best <= give_up {
                    return best;
                }
            }
        }
    }
    if n == 1 {
        return 0.0;
    }
    best
}

fn lu_product(l: &[u32; 32], u: &[u32; 32], m: usize) -> [u32; 32] {
    // C = L·U: column j of C is L applied to column j of U.
    let mut c = [0u32; 32];
    for j in 0..m {
        let mut v = 0u32;
        for (r, lr) in l.iter().enumerate().take(j + 1) {
            if u[j] >> (31 - r) & 1 == 1 {
                v ^= lr;
            }
        }
        c[j] = v;
    }
    c
}

/// Search (from `seed`) for a (0,m,2)-net generator matrix with a large minimum toroidal
/// distance: `candidates` uniformly random matrices with the net property, then `refinements`
/// steps of hill climbing that flip one free bit of the best matrix's L or U factor and keep
/// the change when the minimum distance does not decrease. Returns the matrix and its minimum
/// distance in units of the hexagonal-lattice spacing sqrt(2 / (sqrt(3) n)) (1 is the ideal).
pub fn search_maxmin_matrix(m: u32, candidates: u32, refinements: u32, seed: u64) -> ([u32; 32], f64) {
    let m = m.min(32);
    let mu = m as usize;
    let mut rng = Rng::new(seed);
    // Rows are output bits (0 = most significant), columns index bits; column j is a u32 with row r at bit 31 - r.
    let mut identity = [0u32; 32];
    for (j, v) in identity.iter_mut().enumerate() {
        *v = 1 << (31 - j);
    }
    let mut best_lu = (identity, identity);
    let mut best = min_toroidal_distance2(&lu_product(&identity, &identity, mu), m, 0.0);
    for _ in 0..candidates {
        let (mut l, mut u) = (identity, identity);
        for j in 0..mu {
            // L: unit lower triangular, with random output bits below row m as well.
            if j + 1 < 32 {
                l[j] |= rng.uniform_u32() & (u32::MAX >> (j + 1));
            }
            // U: unit upper triangular on the m×m block.
            if j > 0 {
                u[j] |= rng.uniform_u32() & !(u32::MAX >> j);
            }
        }
        let d2 = min_toroidal_distance2(&lu_product(&l, &u, mu), m, best);
        if d2 > best {
            best = d2;
            best_lu = (l, u);
        }
    }
    for _ in 0..refinements {
        if mu == 0 {
            break;
        }
        let (mut l, mut u) = best_lu;
        let j = rng.uniform_u32_below(m) as usize;
        if rng.uniform_u32() & 1 == 0 && j + 1 < 32 {
            l[j] ^= 1 << (30 - j - rng.uniform_u32_below(31 - j as u32) as usize);
        } else if j > 0 {
            u[j] ^= 1 << (31 - rng.uniform_u32_below(j as u32) as usize);
        } else {
            continue;
        }
        let d2 = min_toroidal_distance2(&lu_product(&l, &u, mu), m, best);
        if d2 >= best {
            best = d2;
            best_lu = (l, u);
        }
    }
    let n = (1u64 << m) as f64;
    let ideal = (2.0 / (3f64.sqrt() * n)).sqrt();
    (lu_product(&best_lu.0, &best_lu.1, mu), best.sqrt() / ideal)
}

/// See the module documentation.
pub const C_MAX_MIN_DIST: [[u32; 32]; 17] = include!("maxmin_matrices.in");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[ignore]
    fn print_maxmin_matrices() {
        println!("[");
        for m in 0..=16u32 {
            // PENUMBRA_MAXMIN_EFFORT scales the hill-climbing budget (the committed table used 10).
            let effort: u32 = std::env::var("PENUMBRA_MAXMIN_EFFORT").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
            let (tries, climbs) = match m {
                0..=8 => (20_000, 20_000 * effort),
                9..=12 => (1_000, 6_000 * effort),
                _ => (100, 3_000 * effort),
            };
            let (c, q) = search_maxmin_matrix(m, tries, climbs, 0x6d61_786d_696e + m as u64);
            eprintln!("m={m}: min distance {q:.3} of hexagonal");
            let cols: Vec<String> = c.iter().map(|v| format!("{v:#010x}")).collect();
            println!("    [{}],", cols.join(", "));
        }
        println!("]");
    }
}
