//! Glossy lobes in `silhouette`'s `shade` mode by SH projection (Nowrouzezahrai et al. 2014,
//! §5 "glossy"; the issue's "glossy lobes by projecting the visible environment onto SH to an
//! order chosen from the BRDF's roughness, shaded with the material's BRDF").
//!
//! With `L_k` the SH coefficients (world basis, order `N`) of the visibility-masked
//! environment `L·V·H` (from [`super::shtable::ShTable`] over the point's visible
//! intervals) and `g_k` those of the lobes' `f(ω_o, ω)·|n_s·ω|` over the same hemisphere `H`
//! (the face-forwarded geometric normal's, where pbrt-v3's `BSDF::f` counts reflection lobes),
//! the reflected radiance is `Σ_k L_k g_k = ∫ P_N[L·V·H] · g`: exact when either factor is
//! band-limited to `N`. `g_k` is integrated by Gauss–Legendre in `cos θ` about the normal
//! times the uniform rule in `φ`, so the horizon kink of `H` is a boundary of the rule, not
//! inside it. Lambertian lobes are not in `g`: the caller integrates them exactly through the
//! vector irradiance.
//!
//! The order grows with the lobe's sharpness: a GGX/Beckmann lobe of roughness `α` has an
//! angular width ∝ `α` and SH coefficients falling off as `exp(−l²α²/4)` (RH02's Phong
//! estimate with `s ≈ 2/α²`), so `N = ⌈C/α⌉ + 1` bands keep the same fraction of it for any
//! `α`, capped at `"integer glossyorder"`; Oren–Nayar is smooth (order 3).

use penumbra_core::bxdf::{Bsdf, Bxdf, DisneyLobe};
use penumbra_core::geometry::Frame;
use penumbra_core::sh::{basis, quadrature::gauss_legendre, ShOrder};
use penumbra_core::{Rgb, Vec3};
use std::sync::OnceLock;

/// The highest glossy order (`"integer glossyorder"` ≤ 16).
pub const MAX_ORDER: usize = 16;
pub const MAX_COEFFS: usize = MAX_ORDER * MAX_ORDER;
/// Cells in `v` per meridian of the SH table (its memory is `3 · meridians · cells · 3N²`
/// floats: 85 MB at 128 meridians and order 12).
pub const TABLE_CELLS: usize = 128;
/// `C` of `N = ⌈C/α⌉ + 1`: on `env/objects-studio` (plastic, α = 0.31) the RMSE against pbrt-v3
/// falls 0.0163, 0.0134, 0.0084, 0.0066, 0.0057, 0.0054, 0.0053 at orders 2, 4, 6, 8, 10, 12,
/// 16; C = 3 gives order 11 there.
pub const ORDER_PER_INVERSE_ALPHA: f32 = 3.0;

/// The SH order of `disney`'s diffuse, fake-subsurface, retro-reflection and sheen lobes.
pub const DISNEY_DIFFUSE_ORDER: usize = 8;

/// How one surface's non-specular reflection splits: its Lambertian albedo (integrated
/// exactly by the caller), the other lobes (by SH), and the order they need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Split {
    pub diffuse: Rgb,
    pub order: ShOrder,
    /// Bit `i`: lobe `i` of the BSDF is shaded by SH.
    lobes: u32,
}

/// The SH order for a microfacet lobe of roughness `alpha`, at most `max`.
pub fn order_for_alpha(alpha: f32, max: ShOrder) -> usize {
    let n = (ORDER_PER_INVERSE_ALPHA / alpha.max(1e-3)).ceil() + 1.0;
    (n.min(max.n() as f32) as usize).clamp(3.min(max.n()), max.n())
}

impl Split {
    /// `None` when the BSDF has a non-specular transmission lobe (the caller uses the
    /// estimator) or no non-specular reflection lobe at all.
    pub fn of(bsdf: &Bsdf, max: ShOrder) -> Option<Split> {
        let (mut diffuse, mut order, mut lobes, mut any) = (Rgb::ZERO, 1usize, 0u32, false);
        for (i, b) in bsdf.bxdfs().iter().enumerate() {
            let need = match b {
                Bxdf::LambertianReflection { r } => {
                    diffuse += *r;
                    any = true;
                    continue;
                }
                Bxdf::SpecularReflection { .. } | Bxdf::SpecularTransmission { .. } | Bxdf::FresnelSpecular { .. } => {
                    continue
                }
                Bxdf::LambertianTransmission { .. }
                | Bxdf::MicrofacetTransmission { .. }
                | Bxdf::Hair(_)
                | Bxdf::Fourier(_)
                | Bxdf::SubsurfaceExit { .. } => return None,
                Bxdf::OrenNayar { .. } => 3.min(max.n()),
                // Polynomials of degree ≤ 8 in the directions' components (Schlick's fifth
                // powers times cosines), but for the sheen's `(1 − cos θ_d)^5`.
                Bxdf::Disney(DisneyLobe::Clearcoat { gloss, .. }) => order_for_alpha(*gloss, max),
                Bxdf::Disney(_) => DISNEY_DIFFUSE_ORDER.min(max.n()),
                Bxdf::MicrofacetReflection { distribution, .. } | Bxdf::FresnelBlend { distribution, .. } => {
                    let (ax, ay) = distribution.alphas();
                    order_for_alpha(ax.min(ay), max)
                }
            };
            any = true;
            lobes |= 1 << i;
            order = order.max(need);
        }
        any.then(|| Split { diffuse, order: ShOrder::new(order).expect("order within 1..=16"), lobes })
    }

    pub fn has_lobes(&self) -> bool {
        self.lobes != 0
    }
}

/// Gauss–Legendre nodes and weights on `[0, 1]` for `2N + 2` nodes, per order `N`.
fn nodes(order: ShOrder) -> &'static (Vec<f64>, Vec<f64>) {
    static NODES: OnceLock<Vec<(Vec<f64>, Vec<f64>)>> = OnceLock::new();
    &NODES.get_or_init(|| {
        (0..=MAX_ORDER)
            .map(|n| {
                let (x, w) = gauss_legendre(2 * n + 2);
                (x.iter().map(|x| 0.5 * (x + 1.0)).collect(), w.iter().map(|w| 0.5 * w).collect())
            })
            .collect()
    })[order.n()]
}

/// The SH coefficients (`3 · N²`, colour-major) of `Σ_lobes f(ω_o, ω) |n_s·ω|` over the
/// hemisphere of `ng` (unit, on `wo`'s side).
pub fn project_lobes(split: &Split, bsdf: &Bsdf, wo: Vec3, ng: Vec3, out: &mut [f64]) {
    let order = split.order;
    let k = order.coeffs();
    out[..3 * k].iter_mut().for_each(|v| *v = 0.0);
    if !split.has_lobes() {
        return;
    }
    let frame = Frame::from_z(ng);
    let (mu, wmu) = nodes(order);
    let n_phi = 4 * order.n() + 4;
    let dphi = std::f64::consts::TAU / n_phi as f64;
    let (wo_l, ns) = (bsdf.world_to_local(wo), bsdf.shading_normal());
    let mut y = [0.0f64; MAX_COEFFS];
    for (m, wm) in mu.iter().zip(wmu) {
        let s = (1.0 - m * m).max(0.0).sqrt();
        for j in 0..n_phi {
            let phi = (j as f64 + 0.5) * dphi;
            let wi = frame.from_local(Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, *m as f32));
            let wi_l = bsdf.world_to_local(wi);
            let mut f = Rgb::ZERO;
            for (i, b) in bsdf.bxdfs().iter().enumerate() {
                if split.lobes & (1 << i) != 0 {
                    f += b.f(wo_l, wi_l);
                }
            }
            let w = wm * dphi * ns.dot(wi).abs() as f64;
            if f == Rgb::ZERO || w == 0.0 {
                continue;
            }
            basis::eval(order, wi.as_dvec3(), &mut y[..k]);
            for c in 0..3 {
                let fw = f[c] as f64 * w;
                for (o, yk) in out[c * k..(c + 1) * k].iter_mut().zip(&y[..k]) {
                    *o += fw * yk;
                }
            }
        }
    }
}

/// The SH-shaded radiance of the split's lobes, given the visible environment's coefficients
/// `lsh` (`3 · N²`, colour-major, at the split's order); clamped at 0 (truncation can ring
/// below it).
pub fn shade(split: &Split, bsdf: &Bsdf, wo: Vec3, ng: Vec3, lsh: &[f64]) -> Rgb {
    if !split.has_lobes() {
        return Rgb::ZERO;
    }
    let k = split.order.coeffs();
    let mut g = [0.0f64; 3 * MAX_COEFFS];
    project_lobes(split, bsdf, wo, ng, &mut g);
    let dot = |c: usize| lsh[c * k..(c + 1) * k].iter().zip(&g[c * k..(c + 1) * k]).map(|(a, b)| a * b).sum::<f64>();
    Rgb::new(dot(0) as f32, dot(1) as f32, dot(2) as f32).max(Rgb::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;
    use penumbra_core::bxdf::{Fresnel, HairBxdf};
    use penumbra_core::microfacet::MicrofacetDistribution;

    /// Disney's lobes are all reflection: the diffuse family at [`DISNEY_DIFFUSE_ORDER`], the
    /// clearcoat and specular by their roughness; a lobe that transmits (hair, and so fourier)
    /// leaves the whole BSDF to the estimator.
    #[test]
    fn disney_lobes_are_projected_and_hair_falls_back() {
        let max = ShOrder::new(12).unwrap();
        let mut b = Bsdf::new(Vec3::Z, Vec3::X, Vec3::Z, 1.0);
        b.add(Bxdf::Disney(DisneyLobe::Diffuse { r: Rgb::splat(0.5) })).unwrap();
        b.add(Bxdf::Disney(DisneyLobe::Sheen { r: Rgb::splat(0.5) })).unwrap();
        let split = Split::of(&b, max).unwrap();
        assert_eq!((split.order.n(), split.lobes, split.diffuse), (DISNEY_DIFFUSE_ORDER, 0b11, Rgb::ZERO));
        let fresnel = Fresnel::Disney { r0: Rgb::splat(0.04), metallic: 0.0, eta: 1.5 };
        b.add(Bxdf::microfacet_reflection(Rgb::ONE, MicrofacetDistribution::disney(0.5, 0.5), fresnel)).unwrap();
        b.add(Bxdf::Disney(DisneyLobe::Clearcoat { weight: Rgb::ONE, gloss: 0.1 })).unwrap();
        let split = Split::of(&b, max).unwrap();
        assert_eq!((split.order.n(), split.lobes), (order_for_alpha(0.1, max), 0b1111));
        let mut h = Bsdf::new(Vec3::Z, Vec3::X, Vec3::Z, 1.55);
        h.add(Bxdf::Hair(HairBxdf::new(0.0, 1.55, Rgb::splat(0.2), 0.3, 0.3, 2.0))).unwrap();
        assert!(Split::of(&h, max).is_none());
    }
}
