//! The SH visibility vector at a receiver (seed 003 §4.2): every sphere adjusted by the
//! receiver-inside rules, its log-blocker `G_θ` looked up by angular radius, turned to the
//! sphere's direction and summed; `V = exp*(Σ G)`. Spheres whose cap exceeds `big_theta`
//! (near contact, where the clipped log round-trips badly: digest §8.2) are multiplied in as
//! explicit SH products of their blocker `B_θ = 1 − cap_θ` instead.

use crate::shexp::sphereset::{Sphere, SphereSets};
use glam::DVec3;
use penumbra_core::sh::{self, ExpScratch, LogBlockerTable, ShExp, ShOrder, TripleProduct, SQRT_4PI};
use std::sync::{Arc, Mutex, OnceLock};

/// Relative tolerance of the inside/behind tests (of the sphere's radius).
const REL_TOL: f64 = 1e-6;

/// The sphere to use at receiver `p` with unit normal `n` (seed 003 §4.2, Fig. 4.7), or
/// `None` when it cannot block: wholly behind the tangent plane, or containing `p`.
/// - wholly in front (`d ≥ r`, `d = (c − p)·n`): unchanged;
/// - crossing the plane with its centre in front (`d` above the tolerance: a centre in the
///   plane up to rounding, as a planar shell's, counts as behind, so rounding cannot pick the
///   rule): replaced by the sphere tangent to the plane at the centre's foot `q1 = c − d n`
///   and through the top point `q0 = c + r n`;
/// - crossing with the centre behind, `p` outside: that tangent sphere scaled about `q1` by
///   `α = min(1, (|p − q1| − ρ)/ρ)` (`ρ = √(r² − d²)`, the radius of the disc the sphere cuts
///   from the plane), dropped when `α ≤ 0`, so it shrinks to nothing as `p` nears the disc.
///   The thesis says "scaled"; scaling about `q1` keeps it tangent (the reading the digest
///   §2.1 names as the alternative to shexp-demo's radius-only scaling).
pub fn adjust(s: &Sphere, p: DVec3, n: DVec3) -> Option<Sphere> {
    let (c, r) = (s.center, s.radius);
    let d = (c - p).dot(n);
    let tol = REL_TOL * r;
    if d >= r - tol {
        return Some(*s);
    }
    if d <= -r + tol {
        return None;
    }
    let q1 = c - n * d;
    let tangent = Sphere { center: c + n * ((r - d) * 0.5), radius: (r + d) * 0.5 };
    if d > tol {
        return Some(tangent);
    }
    if p.distance_squared(c) <= (r + tol) * (r + tol) {
        return None;
    }
    let rho = (r * r - d * d).max(0.0).sqrt();
    let alpha = if rho > 0.0 { ((p.distance(q1) - rho) / rho).min(1.0) } else { 1.0 };
    if !(alpha > 0.0) {
        return None;
    }
    Some(Sphere { center: q1 + (tangent.center - q1) * alpha, radius: tangent.radius * alpha })
}

/// Cap half-angle and unit axis of a sphere seen from `p` (`θ = asin(min(1, r/|c − p|))`).
pub fn cap_of(s: &Sphere, p: DVec3) -> Option<(f64, DVec3)> {
    let v = s.center - p;
    let dist = v.length();
    if !(dist > 0.0) || !(s.radius > 0.0) {
        return None;
    }
    Some(((s.radius / dist).min(1.0).asin(), v / dist))
}

/// The log-blocker table of each order, built once per process.
fn log_table(order: ShOrder) -> Result<Arc<LogBlockerTable>, sh::ShError> {
    static TABLES: OnceLock<Mutex<Vec<Arc<LogBlockerTable>>>> = OnceLock::new();
    let m = TABLES.get_or_init(|| Mutex::new(Vec::new()));
    let mut v = m.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = v.iter().find(|t| t.order() == order) {
        return Ok(t.clone());
    }
    let t = Arc::new(LogBlockerTable::default_for(order)?);
    v.push(t.clone());
    Ok(t)
}

/// The scaling and squaring of the reflections' per-sphere visibilities (seed 003 §4.3.3, one
/// or two `exp*` per reflecting sphere and receiver): squarings past `‖f̂‖ = 1` and a Taylor
/// base to `1e-6` (at most degree 8), where the shadows square only past 4 and run the base
/// to `1e-10`. Measured on `env/objects-studio` (32², 2 spp): the reflected light changes by
/// 0.09 % RMS of its mean, for 39 % fewer instructions in the reflections.
pub const COARSE_EXP: sh::ExpMethod = sh::ExpMethod::ScalingSquaring { threshold: 1.0, max_degree: 8, tolerance: 1e-6 };

/// How `exp*` is evaluated (`"string exp"`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExpChoice {
    /// Scaling and squaring with a Taylor base (the default).
    ScalingSquaring,
    /// Ren et al.'s optimal linear `a 1 + b f̂`.
    OptimalLinear,
    /// Optimal linear at `f̂/2^p`, then `p` squarings (threshold 0.25, as shexp-demo).
    Hybrid,
}

impl ExpChoice {
    pub fn parse(s: &str) -> Option<ExpChoice> {
        match s {
            "ss" => Some(ExpChoice::ScalingSquaring),
            "ol" => Some(ExpChoice::OptimalLinear),
            "hyb" => Some(ExpChoice::Hybrid),
            _ => None,
        }
    }
}

/// Buffers for one receiver.
pub struct Scratch {
    g: Vec<f64>,
    y: Vec<f64>,
    f: Vec<f64>,
    cap: Vec<f64>,
    big: Vec<f64>,
    prod: Vec<f64>,
    tmp: Vec<f64>,
    exp: ExpScratch,
}

pub struct Visibility {
    order: ShOrder,
    logs: Arc<LogBlockerTable>,
    exp: ShExp,
    /// The exponential of the reflections' per-sphere visibilities ([`Self::exp_times`]).
    coarse: ShExp,
    products: &'static TripleProduct,
    big_theta: f64,
}

/// Calls its argument with every sphere to consider at a receiver.
pub type SphereSource<'a> = dyn FnMut(&mut dyn FnMut(&Sphere)) + 'a;

/// What one receiver's visibility used.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    pub logged: u32,
    pub multiplied: u32,
}

impl Visibility {
    pub fn new(order: ShOrder, exp: ExpChoice, big_theta: f64) -> Result<Visibility, sh::ShError> {
        let logs = log_table(order)?;
        let method = match exp {
            ExpChoice::ScalingSquaring => sh::ExpMethod::default(),
            ExpChoice::OptimalLinear => sh::ExpMethod::OptimalLinear(sh::OptimalLinearTable::from_log_table(&logs)?),
            ExpChoice::Hybrid => {
                sh::ExpMethod::Hybrid { table: sh::OptimalLinearTable::from_log_table(&logs)?, threshold: 0.25 }
            }
        };
        let coarse = match &method {
            sh::ExpMethod::ScalingSquaring { .. } => COARSE_EXP,
            m => m.clone(),
        };
        Ok(Visibility {
            order,
            exp: ShExp::new(order, method)?,
            coarse: ShExp::new(order, coarse)?,
            logs,
            products: TripleProduct::shared(order)?,
            big_theta,
        })
    }

    pub fn order(&self) -> ShOrder {
        self.order
    }

    pub fn scratch(&self) -> Scratch {
        let (n, k) = (self.order.n(), self.order.coeffs());
        Scratch {
            g: vec![0.0; n],
            y: vec![0.0; k],
            f: vec![0.0; k],
            cap: vec![0.0; n],
            big: vec![0.0; k],
            prod: vec![0.0; k],
            tmp: vec![0.0; k],
            exp: ExpScratch::new(self.order),
        }
    }

    /// `V` at receiver `p` (unit normal `n`) for `spheres` (already adjusted or not: they are
    /// adjusted here), into `out[..n²]`.
    pub fn vector(&self, p: DVec3, n: DVec3, spheres: &mut SphereSource, s: &mut Scratch, out: &mut [f64]) -> Counts {
        let k = self.order.coeffs();
        s.f.iter_mut().for_each(|v| *v = 0.0);
        let mut counts = Counts::default();
        let mut have_product = false;
        spheres(&mut |sphere: &Sphere| {
            let Some(adj) = adjust(sphere, p, n) else { return };
            let Some((theta, axis)) = cap_of(&adj, p) else { return };
            if theta <= self.big_theta {
                self.logs.lookup(theta, &mut s.g);
                let _ = sh::zonal::add_rotated_zh(&s.g, axis, 1.0, &mut s.y, &mut s.f);
                counts.logged += 1;
            } else {
                // B_θ = 1 − cap_θ, turned to the axis.
                sh::zonal::cap_into(theta, &mut s.cap);
                s.cap.iter_mut().for_each(|v| *v = -*v);
                s.cap[0] += SQRT_4PI;
                let _ = sh::zonal::rotate_zh(&s.cap, axis, &mut s.big);
                if have_product {
                    s.tmp.copy_from_slice(&s.prod);
                    let _ = self.products.product(&s.tmp, &s.big, &mut s.prod);
                } else {
                    s.prod.copy_from_slice(&s.big);
                    have_product = true;
                }
                counts.multiplied += 1;
            }
        });
        if counts.logged == 0 {
            out[..k].iter_mut().for_each(|v| *v = 0.0);
            out[0] = SQRT_4PI;
        } else if self.exp.exp(&s.f, out, &mut s.exp).is_err() {
            // Non-finite input (degenerate geometry): unshadowed rather than NaN.
            out[..k].iter_mut().for_each(|v| *v = 0.0);
            out[0] = SQRT_4PI;
        }
        if have_product {
            s.tmp.copy_from_slice(&out[..k]);
            let _ = self.products.product(&s.tmp, &s.prod, &mut out[..k]);
        }
        counts
    }

    /// The blocker of a cap of half-angle `theta` about unit `axis`, turned to the axis, into
    /// `out[..n²]`: its log `G_θ` when `theta ≤ big_theta` (returns `false`), else the blocker
    /// `B_θ = 1 − cap_θ` itself, to be multiplied in explicitly (returns `true`) — the split
    /// [`vector`](Self::vector) makes.
    pub fn blocker_into(&self, theta: f64, axis: DVec3, s: &mut Scratch, out: &mut [f64]) -> bool {
        let k = self.order.coeffs();
        if theta <= self.big_theta {
            self.logs.lookup(theta, &mut s.g);
            out[..k].iter_mut().for_each(|v| *v = 0.0);
            let _ = sh::zonal::add_rotated_zh(&s.g, axis, 1.0, &mut s.y, &mut out[..k]);
            false
        } else {
            sh::zonal::cap_into(theta, &mut s.cap);
            s.cap.iter_mut().for_each(|v| *v = -*v);
            s.cap[0] += SQRT_4PI;
            let _ = sh::zonal::rotate_zh(&s.cap, axis, &mut out[..k]);
            true
        }
    }

    /// `out = exp*(f) ∗ Π bigs` (the explicit blockers in the order given), as
    /// [`vector`](Self::vector) combines them; non-finite `f` gives the product alone. With
    /// `coarse`, scaling and squaring (the default `"exp"`) uses [`COARSE_EXP`].
    pub fn exp_times<'b>(
        &self,
        f: &[f64],
        bigs: impl Iterator<Item = &'b [f64]>,
        coarse: bool,
        s: &mut Scratch,
        out: &mut [f64],
    ) {
        let k = self.order.coeffs();
        let exp = if coarse { &self.coarse } else { &self.exp };
        if f[..k].iter().all(|v| *v == 0.0) || exp.exp(&f[..k], &mut out[..k], &mut s.exp).is_err() {
            out[..k].iter_mut().for_each(|v| *v = 0.0);
            out[0] = SQRT_4PI;
        }
        for b in bigs {
            s.tmp.copy_from_slice(&out[..k]);
            let _ = self.products.product(&s.tmp, b, &mut out[..k]);
        }
    }

    /// `out = f ∗ g` (the SH product at this order; `out` must not alias the inputs).
    pub fn product(&self, f: &[f64], g: &[f64], out: &mut [f64]) {
        let _ = self.products.product(f, g, out);
    }

    /// `V` at `p` on object `object` from every leaf of `sets` the hierarchy does not cull (a
    /// node wholly behind the tangent plane culls its subtree); the receiver's own set is
    /// skipped when it is convex or planar (it cannot shadow its own surface).
    pub fn vector_for_scene(
        &self,
        p: DVec3,
        n: DVec3,
        object: usize,
        sets: &SphereSets,
        s: &mut Scratch,
        out: &mut [f64],
    ) -> Counts {
        let mut all = |visit: &mut dyn FnMut(&Sphere)| {
            for_each_leaf_seen(sets, p, n, object, &mut |set, leaf| visit(&sets.sets[set].leaves[leaf]));
        };
        self.vector(p, n, &mut all, s, out)
    }
}

/// Calls `visit(set, leaf)` with every leaf of `sets` that may block at `p` (unit normal `n`)
/// on object `object`: the hierarchy culls nodes wholly behind the tangent plane, and the
/// receiver's own set is skipped when it is convex or planar (it cannot shadow its own surface).
pub fn for_each_leaf_seen(sets: &SphereSets, p: DVec3, n: DVec3, object: usize, visit: &mut dyn FnMut(usize, usize)) {
    for (i, set) in sets.sets.iter().enumerate() {
        if set.convex && set.object == object {
            continue;
        }
        set.hierarchy.for_each_leaf(
            &mut |node: &Sphere| (node.center - p).dot(n) > -node.radius * (1.0 - REL_TOL),
            &mut |leaf| visit(i, leaf),
        );
    }
}
