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
//! ones. Entry `m` is for 2^m samples per pixel (m ≤ 16); regenerate with
//! `cargo test -p penumbra-core --release -- --ignored print_maxmin_matrices --nocapture`.

use crate::rng::Rng;

/// Minimum toroidal distance² of the points (i/n, C·i) with n = 2^m, or early exit once below `give_up`.
pub fn min_toroidal_distance2(c: &[u32; 32], m: u32, give_up: f64) -> f64 {
    let n = 1usize << m;
    let ys: Vec<f64> = (0..n as u32).map(|i| super::lowdiscrepancy::multiply_generator(c, i) as f64 / 4294967296.0).collect();
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
                if best < give_up {
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

/// Random search (`candidates` tries from `seed`) for a (0,m,2)-net generator matrix with a large
/// minimum toroidal distance. Returns the matrix and its minimum distance (in units of the ideal
/// hexagonal-lattice spacing sqrt(2 / (sqrt(3) n)), so values close to 1 are near-optimal).
pub fn search_maxmin_matrix(m: u32, candidates: u32, seed: u64) -> ([u32; 32], f64) {
    let mut rng = Rng::new(seed);
    let mut best = (super::lowdiscrepancy::C_VAN_DER_CORPUT, min_toroidal_distance2(&super::lowdiscrepancy::C_VAN_DER_CORPUT, m, 0.0));
    let m = m.min(32);
    for _ in 0..candidates {
        // Rows are output bits (0 = most significant), columns index bits; column j is a u32 with row r at bit 31 - r.
        let mut l = [0u32; 32];
        let mut u = [0u32; 32];
        for j in 0..m as usize {
            // L: unit lower triangular (rows r ≥ j); random rows below m as well.
            let below: u32 = if j + 1 < 32 { rng.uniform_u32() & (u32::MAX >> (j + 1)) } else { 0 };
            l[j] = (1u32 << (31 - j)) | below;
            // U: unit upper triangular on the m×m block (rows r ≤ j).
            let above: u32 = if j > 0 { rng.uniform_u32() & !(u32::MAX >> j) } else { 0 };
            u[j] = (1u32 << (31 - j)) | above;
        }
        // C = L·U: column j of C is L applied to column j of U.
        let mut c = [0u32; 32];
        for j in 0..m as usize {
            let mut v = 0u32;
            for r in 0..=j {
                if u[j] >> (31 - r) & 1 == 1 {
                    v ^= l[r];
                }
            }
            c[j] = v;
        }
        let d2 = min_toroidal_distance2(&c, m, best.1);
        if d2 > best.1 {
            best = (c, d2);
        }
    }
    let n = (1u64 << m) as f64;
    let ideal = (2.0 / (3f64.sqrt() * n)).sqrt();
    (best.0, best.1.sqrt() / ideal)
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
            let tries = match m {
                0..=8 => 20_000,
                9..=12 => 2_000,
                _ => 150,
            };
            let (c, q) = search_maxmin_matrix(m, tries, 0x6d61_786d_696e + m as u64);
            eprintln!("m={m}: min distance {q:.3} of hexagonal");
            let cols: Vec<String> = c.iter().map(|v| format!("{v:#010x}")).collect();
            println!("    [{}],", cols.join(", "));
        }
        println!("]");
    }
}
