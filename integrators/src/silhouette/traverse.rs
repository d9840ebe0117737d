//! Depth-complexity traversal along meridians (Nowrouzezahrai et al. 2014, §3.2).
//!
//! The contour edges of a shading point, clipped to its visible half-space, are projected to
//! arcs; each arc's crossings with the meridians of [`Meridians`] go into one bucket per
//! meridian as `(v, ΔW)`, `ΔW` the change of the depth complexity walking away from the
//! pole ([`Contour::delta_w`]: one sign per edge). Each bucket is sorted by decreasing `v`
//! and walked from the pole (relative depth complexity 0 there, for every meridian) down to
//! the horizon, giving the meridian's intervals of constant relative `W`. The absolute
//! depth complexity is the relative one plus an unknown offset, the same on every meridian:
//! the intervals of minimal relative `W` are visible if any direction is, and one shadow ray
//! through the middle of the longest of them decides ([`Visibility::probe`]; the paper's
//! "shift the minimum to 0" alone reports open sky inside a closed box).
//!
//! Crossings closer than [`MERGE`] in `v` are merged before `W` is tested (T-junctions,
//! duplicated edges), so no interval of zero length carries a spurious `W`.

use super::dual::Contour;
use super::param::{azimuth, azimuth_approx, dist_to_integer, Meridians, PoleFrame, AZIMUTH_ERR};
use glam::DVec3;
use std::f64::consts::{PI, TAU};

/// Crossings of one meridian closer than this in `v` are one event. `v = cos θ` is
/// dimensionless (a crossing's `v` depends on directions from the point only), so this is a
/// scale-free tolerance of ~10⁴ ulps of `v`: coincident crossings (T-junctions, duplicated
/// edges), computed in f64, land closer than this.
pub const MERGE: f64 = 1e-12;

/// An interval `[lo, hi]` of `v` on a meridian with relative depth complexity `w`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub meridian: u32,
    pub lo: f64,
    pub hi: f64,
    pub w: i32,
}

/// What a traversal found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Visibility {
    /// The minimal relative depth complexity over the visible half-space.
    pub min_w: i32,
    /// The middle of the longest interval of minimal `W`: one shadow ray there tells whether
    /// the minimal intervals are unoccluded (absolute `W` 0) or everything is occluded.
    pub probe: DVec3,
    /// Arc–meridian crossings recorded.
    pub crossings: usize,
    /// Arcs after clipping that took the general path (not those certain to lie in front
    /// between two meridians, which record nothing).
    pub arcs: usize,
    /// Meridian pairs whose depth complexities at the horizon disagree with the arcs that
    /// meet the horizon between them (a missed or spurious crossing); 0 when consistent.
    pub mismatches: usize,
}

/// Per-thread buffers of a traversal.
#[derive(Clone, Debug, Default)]
pub struct Traversal {
    buckets: Vec<Vec<(f64, i32)>>,
    /// Arcs ending on the horizon: (meridian key of the end's azimuth, ΔW walking the horizon
    /// towards increasing azimuth).
    horizon: Vec<(i64, i32)>,
    /// Relative W at each meridian's horizon end, and the expected steps between them.
    end_w: Vec<i32>,
    steps: Vec<i32>,
    pub intervals: Vec<Interval>,
    /// Per-vertex results of the current point ([`Ends`]).
    ends: Ends,
}

/// [`Ends::wedge`] of a vertex behind (or on) the tangent plane.
const BEHIND: u32 = u32::MAX - 1;
/// [`Ends::wedge`] of a vertex in front but not certainly inside one wedge.
const UNSURE: u32 = u32::MAX;

/// What the traversal needs of each contour vertex before an arc's general path: whether it
/// is behind the tangent plane, else the wedge between meridians it is certainly inside
/// ([`Classifier::classify`]). Contours are chains, so most vertices end two contour edges:
/// computed once per point and vertex, kept by vertex index under a generation stamp.
#[derive(Clone, Debug, Default)]
struct Ends {
    /// `(stamp, wedge)` by vertex index.
    slot: Vec<(u32, u32)>,
    stamp: u32,
    /// [`diamond`] angle bins, at most one meridian per bin, after a copy of the first and
    /// before a copy of the last (see [`Classifier::classify`]'s index).
    bins: Vec<Bin>,
    n: usize,
}

/// One [`diamond`] angle bin `[b, b + 1)`, in bins (the diamond angle times
/// [`Classifier::scale`]), and the wedges a direction whose diamond angle `f` (in bins) falls
/// in it can be certainly inside.
#[derive(Clone, Copy, Debug)]
struct Bin {
    /// `f` strictly inside this range is certainly inside wedge `below`: the range between
    /// the meridian before the bin and the bin's meridian (or, without one, the meridian
    /// after the bin), each moved in by [`bin_margin`].
    below_range: (f64, f64),
    /// Likewise for wedge `above`, from the bin's meridian to the next; empty without one.
    above_range: (f64, f64),
    below: u32,
    above: u32,
}

/// A monotonic stand-in for the azimuth of `(x, y)` in `[0, 4]` ("diamond angle": quadrant
/// plus `|y|/(|x|+|y|)` or its complement), one division instead of `atan2`'s polynomial.
fn diamond(x: f64, y: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let t = ay / (ax + ay);
    if y >= 0.0 {
        if x >= 0.0 {
            t
        } else {
            2.0 - t
        }
    } else if x < 0.0 {
        2.0 + t
    } else {
        4.0 - t
    }
}

impl Ends {
    /// Bins per meridian: the diamond angle's slope in the azimuth is at least 1/2, so with
    /// 4n bins over [0, 4] (width 1/n < π/n) no bin holds two meridians.
    const BINS: usize = 4;

    fn prepare(&mut self, m: &Meridians) {
        if self.n != m.n || self.bins.len() != Self::BINS * m.n + 2 {
            self.n = m.n;
            let bins = Self::BINS * m.n;
            let scale = bins as f64 / 4.0;
            let margin = bin_margin(bins);
            // The meridians' diamond angles in bins (increasing with the index), and the
            // ones before the first and after the last, one turn (4·scale) away.
            let pos: Vec<f64> = (0..m.n).map(|j| diamond(m.cos[j], m.sin[j]) * scale).collect();
            let nn = m.n as isize;
            let at = |j: isize| pos[j.rem_euclid(nn) as usize] + 4.0 * scale * j.div_euclid(nn) as f64;
            let empty = (f64::INFINITY, f64::NEG_INFINITY);
            self.bins.clear();
            // Wedge i lies between meridians i − 1 and i: c meridians below the bin.
            let mut c = 0;
            for b in 0..bins {
                while c < nn && at(c) < b as f64 {
                    c += 1;
                }
                let inside = c < nn && at(c) < (b + 1) as f64;
                let (below_range, above_range) = if m.n < 4 {
                    // Fewer than 4 meridians: no wedge is ever certain.
                    (empty, empty)
                } else if inside {
                    ((at(c - 1) + margin, at(c) - margin), (at(c) + margin, at(c + 1) - margin))
                } else {
                    ((at(c - 1) + margin, at(c) - margin), empty)
                };
                let wedge = |i: isize| i.rem_euclid(nn) as u32;
                self.bins.push(Bin { below_range, above_range, below: wedge(c), above: wedge(c + 1) });
            }
            let (first, last) = (self.bins[0], self.bins[bins - 1]);
            self.bins.insert(0, first);
            self.bins.push(last);
        }
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.slot.iter_mut().for_each(|s| s.0 = 0);
            self.stamp = 1;
        }
    }
}

/// The local `(x, y)` of a direction: its components along the pole frame's `e1`, `e2`.
trait Plane: Copy {
    fn xy(&self, d: DVec3) -> (f64, f64);
}

/// Any frame: two dot products.
#[derive(Clone, Copy)]
struct Dots {
    e1: DVec3,
    e2: DVec3,
}

impl Plane for Dots {
    #[inline(always)]
    fn xy(&self, d: DVec3) -> (f64, f64) {
        (d.dot(self.e1), d.dot(self.e2))
    }
}

/// A frame whose `e1`, `e2` are the world axes `(A + 1) % 3`, `(A + 2) % 3` (the pole on
/// axis `A`, as [`super::param::Axes::WORLD`]'s frames are): their components, which equal the
/// dot products up to the sign of a zero (a zero's sign changes the diamond angle only on
/// the axes, where no meridian lies and either wedge it gives is certain).
#[derive(Clone, Copy)]
struct WorldAxes<const A: usize>;

impl<const A: usize> Plane for WorldAxes<A> {
    #[inline(always)]
    fn xy(&self, d: DVec3) -> (f64, f64) {
        let d = d.to_array();
        (d[(A + 1) % 3], d[(A + 2) % 3])
    }
}

impl<P: Plane> Classifier<'_, P> {
    /// [`BEHIND`] when `n·d ≤ 0`; else the wedge `i` (between meridians `i − 1` and `i`) the
    /// local direction of `d` lies strictly inside, farther than [`WEDGE_MARGIN`] radians from
    /// both sides, or [`UNSURE`]. Two ends certainly inside one wedge bound an arc that crosses
    /// no meridian (their keys from `atan2` are equal, or `n` and 0 in the wedge through
    /// azimuth 0, an empty range either way). Decided by the [`diamond`] angle: its bin's
    /// ranges are the meridians' diamond angles moved in by the margin, and the diamond
    /// angle's slope in the azimuth is at most 1, so a direction inside one is farther than
    /// WEDGE_MARGIN radians from every meridian, between the two that bound the wedge.
    #[inline(always)]
    fn classify(&self, d: DVec3) -> u32 {
        let h = self.n.dot(d);
        if !(h > 0.0) {
            return if h <= 0.0 { BEHIND } else { UNSURE };
        }
        let (x, y) = self.plane.xy(d);
        let f = diamond(x, y) * self.scale;
        // The bin, without a saturating cast: 0 ≤ f ≤ 4·bins ≤ 2³¹, so f + (2⁵² − ½) (exact
        // constant) rounds to 2⁵² + round(f − ½) from f = ½ on (ulp 1), whose low 32 bits
        // are that integer, and to 2⁵² − ½ or 2⁵² below (low bits −1 or 0, both bin 0).
        // Shifted by one past the copy of bin 0. A tie (f an integer) may give the bin below
        // f's: the ranges certify `f` itself, whichever bin they come from.
        // NaN: bin 0's copy, and fails every comparison; 4·bins: the copy of the last bin.
        let b = (f + (4503599627370496.0 - 0.5)).to_bits() as u32;
        let Some(bin) = self.bins.get(b.wrapping_add(1) as usize) else { return UNSURE };
        if f > bin.below_range.0 && f < bin.below_range.1 {
            bin.below
        } else if f > bin.above_range.0 && f < bin.above_range.1 {
            bin.above
        } else {
            UNSURE
        }
    }
}

/// [`Classifier::classify`]'s constants for one point.
struct Classifier<'a, P> {
    p: DVec3,
    n: DVec3,
    plane: P,
    /// Bins per unit of the diamond angle.
    scale: f64,
    bins: &'a [Bin],
}

/// [`WEDGE_MARGIN`] in bins (of `bins` over the diamond angle's [0, 4]), plus 1e-12 for the
/// rounding of the diamond angles (~1e-15, the meridians' from their rounded cos and sin) and
/// of the ranges' ends `at ± margin` (< 1e-13 bins up to 2²⁰ bins): a wedge certain from the
/// ranges is farther than WEDGE_MARGIN radians from its sides.
fn bin_margin(bins: usize) -> f64 {
    (WEDGE_MARGIN + 1e-12) * (bins as f64 / 4.0)
}

impl<'a, P: Plane> Classifier<'a, P> {
    /// The constants for a point at `p` with normal `n`, its meridians about the frame of
    /// `plane`, from [`Ends`]' bins.
    fn new(bins: &'a [Bin], p: DVec3, n: DVec3, plane: P) -> Self {
        Classifier { p, n, plane, scale: (bins.len() - 2) as f64 / 4.0, bins }
    }

    /// The wedge of vertex `v` at `x` (normalised), [`BEHIND`] or [`UNSURE`], computed once
    /// per point (`slot`: the vertex's entry of [`Ends::slot`]).
    #[inline(always)]
    fn wedge(&self, slot: &mut Vec<(u32, u32)>, stamp: u32, v: u32, x: &DVec3) -> u32 {
        let Some(s) = slot.get_mut(v as usize) else { return self.wedge_grown(slot, stamp, v, x) };
        if s.0 == stamp {
            return s.1;
        }
        let w = self.classify(*x - self.p);
        *s = (stamp, w);
        w
    }

    /// [`Self::wedge`] of a vertex beyond the slots: grows them first. (`x` by reference
    /// here and in `wedge`: a `DVec3` by value to a function not inlined is a copy on the
    /// stack, which the compiler made before every lookup.)
    #[cold]
    #[inline(never)]
    fn wedge_grown(&self, slot: &mut Vec<(u32, u32)>, stamp: u32, v: u32, x: &DVec3) -> u32 {
        slot.resize(v as usize + 1, (0, 0));
        let w = self.classify(*x - self.p);
        slot[v as usize] = (stamp, w);
        w
    }
}

/// The azimuths of an arc's two ends (local directions), for the decisions the traversal
/// takes from them: their meridian keys, which way round is shorter, whether the range wraps
/// through 0. [`azimuth_approx`]'s when every one of those decisions is certain to be the one
/// `atan2`'s azimuths give (each compared quantity farther than twice [`AZIMUTH_ERR`] from
/// its threshold), else `atan2`'s: the traversal's result is the same, at a fraction of the
/// cost (the two `atan2` per contour were a tenth of a shading point's time). `None` when an
/// end is on the pole axis.
fn end_azimuths(la: DVec3, lb: DVec3, m: &Meridians) -> Option<(f64, f64)> {
    if (la.x == 0.0 && la.y == 0.0) || (lb.x == 0.0 && lb.y == 0.0) {
        return None;
    }
    let (pa, pb) = (azimuth_approx(la), azimuth_approx(lb));
    let e = 2.0 * AZIMUTH_ERR;
    let clear = |phi: f64| {
        let u = phi / m.dphi - 0.5;
        dist_to_integer(u) * m.dphi > e && phi > e && phi < TAU - e
    };
    let d = (pb - pa).abs();
    if clear(pa) && clear(pb) && d > 2.0 * e && (d - PI).abs() > 2.0 * e {
        Some((pa, pb))
    } else {
        Some((azimuth(la)?, azimuth(lb)?))
    }
}

/// [`Classifier::classify`]'s distance from the wedge's sides (radians): far above the
/// rounding of `atan2`, of the meridians' `cos`/`sin` and of the keys (~1e-15), so the keys of
/// both ends are certainly the wedge's.
const WEDGE_MARGIN: f64 = 1e-9;

/// Records the crossings of the arc from local direction `la` to `lb` with the meridians of
/// `keys` (mod `n`) as `(v, dw)` in their buckets; returns how many.
#[inline(always)]
fn record(
    buckets: &mut [Vec<(f64, i32)>],
    m: &Meridians,
    keys: std::ops::Range<i64>,
    la: DVec3,
    lb: DVec3,
    dw: i32,
) -> usize {
    let mut crossings = 0;
    // Meridian `k mod n`, stepped with a wrap rather than a division per key.
    let mut next = keys.start.rem_euclid(m.n as i64) as usize;
    for _ in keys {
        let i = next;
        next = if i + 1 == m.n { 0 } else { i + 1 };
        let (ci, si) = (m.cos[i], m.sin[i]);
        // Meridian plane normal (−sin φ, cos φ, 0).
        let (fa, fb) = (-si * la.x + ci * la.y, -si * lb.x + ci * lb.y);
        if fa == fb {
            continue;
        }
        let t = (fa / (fa - fb)).clamp(0.0, 1.0);
        let q = la + (lb - la) * t;
        let len = q.length();
        if !(len > 0.0) {
            continue;
        }
        buckets[i].push(((q.z / len).clamp(-1.0, 1.0), dw));
        crossings += 1;
    }
    crossings
}

/// Sorts a meridian's crossings by decreasing `v`, then increasing ΔW: a total order on the
/// elements (two that compare equal are identical), so every sort gives the same slice. By
/// insertion for the few crossings a meridian usually has (~6 at 128 meridians on the
/// killeroo), the library's sort beyond.
fn sort_bucket(b: &mut [(f64, i32)]) {
    let order = |x: &(f64, i32), y: &(f64, i32)| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1));
    if b.len() > 16 {
        b.sort_unstable_by(order);
        return;
    }
    for i in 1..b.len() {
        let x = b[i];
        let mut j = i;
        while j > 0 && order(&x, &b[j - 1]) == std::cmp::Ordering::Less {
            b[j] = b[j - 1];
            j -= 1;
        }
        b[j] = x;
    }
}

impl Traversal {
    /// Traverses the contours of `p` (normalised coordinates, as [`super::dual::DualEdges`] gives
    /// them) in the visible half-space of `n` (unit), about `frame`'s pole (`n·pole > 0`).
    pub fn run(&mut self, contours: &[Contour], p: DVec3, n: DVec3, frame: &PoleFrame, m: &Meridians) -> Visibility {
        // The vertices' local (x, y) without dot products where the frame is the world's.
        let world = |a: usize| frame.e1 == DVec3::AXES[(a + 1) % 3] && frame.e2 == DVec3::AXES[(a + 2) % 3];
        match frame.axis {
            0 if world(0) => self.run_in(contours, p, n, frame, m, WorldAxes::<0>),
            1 if world(1) => self.run_in(contours, p, n, frame, m, WorldAxes::<1>),
            2 if world(2) => self.run_in(contours, p, n, frame, m, WorldAxes::<2>),
            _ => self.run_in(contours, p, n, frame, m, Dots { e1: frame.e1, e2: frame.e2 }),
        }
    }

    /// [`Self::run`] with the vertices' local `(x, y)` from `plane`.
    fn run_in<P: Plane>(
        &mut self,
        contours: &[Contour],
        p: DVec3,
        n: DVec3,
        frame: &PoleFrame,
        m: &Meridians,
        plane: P,
    ) -> Visibility {
        if self.buckets.len() != m.n {
            self.buckets = vec![Vec::new(); m.n];
        }
        self.buckets.iter_mut().for_each(Vec::clear);
        self.intervals.clear();
        self.horizon.clear();
        self.end_w.clear();
        let (mut crossings, mut arcs) = (0, 0);
        self.ends.prepare(m);
        let cl = Classifier::new(&self.ends.bins, p, n, plane);
        let (slot, stamp) = (&mut self.ends.slot, self.ends.stamp);
        for c in contours {
            // Both ends behind, or (at 128 meridians, 7 in 8 of a fine mesh's arcs) short, in
            // front and between two meridians: nothing to record.
            let wa = cl.wedge(slot, stamp, c.va, &c.a);
            let wb = cl.wedge(slot, stamp, c.vb, &c.b);
            if wa == wb && wa != UNSURE {
                continue;
            }
            // Both ends in front and certainly inside two wedges: the meridians crossed are
            // those between the wedges, the shorter way round, which the sign of the ends'
            // azimuthal cross product tells wherever it is clear of 0 (the azimuths differ by
            // more than ~1e-9 rad from 0 and π: atan2's decisions, and the certified
            // polynomial's, are the same there).
            if wa < BEHIND && wb < BEHIND {
                let dw = c.delta_w(p, frame.pole);
                if dw == 0 {
                    continue;
                }
                let (la, lb) = (frame.local(c.a - p), frame.local(c.b - p));
                let s = la.x * lb.y - la.y * lb.x;
                if s.abs() > 1e-9 * (la.x.abs() + la.y.abs()) * (lb.x.abs() + lb.y.abs()) {
                    let (k0, k1) = if s > 0.0 { (wa, wb) } else { (wb, wa) };
                    let k1 = if k1 < k0 { k1 + m.n as u32 } else { k1 };
                    arcs += 1;
                    crossings += record(&mut self.buckets, m, k0 as i64..k1 as i64, la, lb, dw);
                    continue;
                }
            }
            let (mut da, mut db) = (c.a - p, c.b - p);
            let (ha, hb) = (n.dot(da), n.dot(db));
            if ha <= 0.0 && hb <= 0.0 {
                continue;
            }
            let dw = c.delta_w(p, frame.pole);
            // Clip to the visible half-space (the part behind is never walked).
            if ha < 0.0 {
                da += (db - da) * (ha / (ha - hb));
            } else if hb < 0.0 {
                db += (da - db) * (hb / (hb - ha));
            }
            let (la, lb) = (frame.local(da), frame.local(db));
            let Some((pa, pb)) = end_azimuths(la, lb, m) else { continue };
            // An end on the horizon: walking the horizon (just above it) past that end crosses
            // the arc; the tangent there towards increasing azimuth is n × q.
            for (h, q, phi) in [(ha, da, pa), (hb, db, pb)] {
                if h <= 0.0 {
                    let t = n.cross(q);
                    let t = if frame.local(t).cross(frame.local(q)).z > 0.0 { -t } else { t };
                    self.horizon.push((m.key(phi), c.delta_w(p, -t)));
                }
            }
            // An arc in a meridian plane (its great circle through the pole) crosses no meridian.
            if dw == 0 {
                continue;
            }
            // The arc spans the shorter azimuth range between its ends (it does not contain
            // the pole axis, or `delta_w` would be 0).
            let mut d = pb - pa;
            if d > std::f64::consts::PI {
                d -= std::f64::consts::TAU;
            } else if d < -std::f64::consts::PI {
                d += std::f64::consts::TAU;
            }
            let (from, to) = if d >= 0.0 { (pa, pb) } else { (pb, pa) };
            let (k0, mut k1) = (m.key(from), m.key(to));
            if to < from {
                k1 += m.n as i64;
            }
            arcs += 1;
            crossings += record(&mut self.buckets, m, k0..k1, la, lb, dw);
        }
        let n_local = frame.local(n);
        let mut best = (i32::MAX, -1.0f64, 0u32, 0.0f64);
        for (i, bucket) in self.buckets.iter_mut().enumerate() {
            sort_bucket(bucket);
            let vh = m.horizon(i, n_local);
            let (mut w, mut top) = (0i32, 1.0f64);
            let mut j = 0;
            let mut push = |lo: f64, hi: f64, w: i32, out: &mut Vec<Interval>| {
                if hi > lo {
                    out.push(Interval { meridian: i as u32, lo, hi, w });
                    let len = hi - lo;
                    if w < best.0 || (w == best.0 && len > best.1) {
                        best = (w, len, i as u32, 0.5 * (lo + hi));
                    }
                }
            };
            while j < bucket.len() && bucket[j].0 > vh {
                // Merge the events within MERGE of this one.
                let v = bucket[j].0;
                let mut dw = 0;
                while j < bucket.len() && bucket[j].0 > v - MERGE {
                    dw += bucket[j].1;
                    j += 1;
                }
                push(v, top, w, &mut self.intervals);
                w += dw;
                top = v;
            }
            push(vh, top, w, &mut self.intervals);
            self.end_w.push(w);
        }
        // Around the horizon: W at consecutive meridian ends differs by the ΔW of the arcs
        // ending between them (key k: between meridians k − 1 and k).
        self.steps.clear();
        self.steps.resize(m.n, 0);
        for &(key, dw) in &self.horizon {
            self.steps[key.rem_euclid(m.n as i64) as usize] += dw;
        }
        let mismatches = (0..m.n).filter(|&k| self.end_w[k] - self.end_w[(k + m.n - 1) % m.n] != self.steps[k]).count();
        let (min_w, _, mi, v) = best;
        let (ci, si) = (m.cos[mi as usize], m.sin[mi as usize]);
        Visibility {
            min_w: if min_w == i32::MAX { 0 } else { min_w },
            probe: frame.direction(ci, si, v),
            crossings,
            arcs,
            mismatches,
        }
    }

    /// The intervals of relative depth complexity `w`.
    pub fn with_w(&self, w: i32) -> impl Iterator<Item = &Interval> {
        self.intervals.iter().filter(move |iv| iv.w == w)
    }
}

#[cfg(test)]
mod tests {
    use super::super::dual::DualEdges;
    use super::super::param::{moment, Axes};
    use super::*;
    use glam::Vec3;
    use penumbra_core::mesh::TriangleMesh;
    use std::f64::consts::PI;

    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed.wrapping_mul(0x9e3779b97f4a7c15) | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A closed UV sphere (welded poles and seam).
    fn sphere(c: Vec3, r: f32, nu: usize, nv: usize) -> TriangleMesh {
        let mut positions = Vec::new();
        for j in 0..=nv {
            let th = std::f32::consts::PI * j as f32 / nv as f32;
            for i in 0..nu {
                let ph = std::f32::consts::TAU * i as f32 / nu as f32;
                let d = if j == 0 {
                    Vec3::Z
                } else if j == nv {
                    -Vec3::Z
                } else {
                    Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
                };
                positions.push(c + d * r);
            }
        }
        let mut indices = Vec::new();
        let id = |i: usize, j: usize| (j * nu + i % nu) as u32;
        for j in 0..nv {
            for i in 0..nu {
                if j > 0 {
                    indices.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
                }
                if j + 1 < nv {
                    indices.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
                }
            }
        }
        TriangleMesh { positions, indices, ..Default::default() }
    }

    fn quad(corners: [Vec3; 4]) -> TriangleMesh {
        TriangleMesh { positions: corners.to_vec(), indices: vec![[0, 1, 2], [0, 2, 3]], ..Default::default() }
    }

    /// All hits of the ray `p + t d`, `t > 0`, with the meshes' triangles (normalised coordinates).
    fn hit_count(meshes: &[TriangleMesh], dual: &DualEdges, p: DVec3, d: DVec3) -> i32 {
        let mut n = 0;
        for m in meshes {
            for t in 0..m.indices.len() {
                let [a, b, c] = m.vertices(t).map(|v| dual.normalise(v));
                let (e1, e2) = (b - a, c - a);
                let h = d.cross(e2);
                let det = e1.dot(h);
                if det.abs() < 1e-300 {
                    continue;
                }
                let s = p - a;
                let u = s.dot(h) / det;
                let q = s.cross(e1);
                let v = d.dot(q) / det;
                let tt = e2.dot(q) / det;
                if u > 0.0 && v > 0.0 && u + v < 1.0 && tt > 0.0 {
                    n += 1;
                }
            }
        }
        n
    }

    fn scene() -> Vec<TriangleMesh> {
        vec![
            sphere(Vec3::new(0.3, 0.2, 0.9), 0.35, 24, 12),
            sphere(Vec3::new(-0.6, -0.1, 0.5), 0.25, 16, 8),
            quad([
                Vec3::new(-0.4, 0.6, 0.3),
                Vec3::new(0.5, 0.7, 0.4),
                Vec3::new(0.4, 0.9, 1.2),
                Vec3::new(-0.5, 0.8, 1.1),
            ]),
            // An open box around part of the scene (five faces, one missing).
            TriangleMesh {
                positions: vec![
                    Vec3::new(-1.5, -1.5, -0.5),
                    Vec3::new(1.5, -1.5, -0.5),
                    Vec3::new(1.5, 1.5, -0.5),
                    Vec3::new(-1.5, 1.5, -0.5),
                    Vec3::new(-1.5, -1.5, 2.0),
                    Vec3::new(1.5, -1.5, 2.0),
                    Vec3::new(1.5, 1.5, 2.0),
                    Vec3::new(-1.5, 1.5, 2.0),
                ],
                indices: vec![
                    [0, 1, 5],
                    [0, 5, 4],
                    [1, 2, 6],
                    [1, 6, 5],
                    [2, 3, 7],
                    [2, 7, 6],
                    [4, 5, 6],
                    [4, 6, 7],
                    [3, 0, 4],
                    [3, 4, 7],
                ],
                ..Default::default()
            },
        ]
    }

    /// A vertex's wedge, where the classification is certain, is the one `atan2`'s azimuth
    /// keys give, also for directions within 1e-12 rad of a meridian (there it must say
    /// unsure); behind the tangent plane it is `BEHIND`; and the diamond-angle bins guess well
    /// enough that nearly every direction is classified. For world frames (their components)
    /// and any frame (dot products, also a rotated one).
    #[test]
    fn vertex_wedges_are_the_keys_of_atan2() {
        let mut r = rng(9);
        let rotated = Axes::of_map(DVec3::new(0.3, 0.9, -0.2), DVec3::new(0.5, -0.4, 0.77)).unwrap().frame(1, -1.0);
        for n in [4, 7, 48, 128, 1000] {
            let m = Meridians::new(n);
            let mut ends = Ends::default();
            ends.prepare(&m);
            let (f2, f0) = (PoleFrame::new(2, 1.0), PoleFrame::new(0, -1.0));
            let dots = |f: &PoleFrame| Dots { e1: f.e1, e2: f.e2 };
            wedges_match_atan2(&mut r, &m, &ends, &f2, WorldAxes::<2>);
            wedges_match_atan2(&mut r, &m, &ends, &f0, WorldAxes::<0>);
            for f in [f2, f0, rotated] {
                wedges_match_atan2(&mut r, &m, &ends, &f, dots(&f));
            }
        }
    }

    fn wedges_match_atan2<P: Plane>(
        r: &mut impl FnMut() -> f64,
        m: &Meridians,
        ends: &Ends,
        axis: &PoleFrame,
        plane: P,
    ) {
        let n = m.n;
        let cl = Classifier::new(&ends.bins, DVec3::ZERO, axis.pole, plane);
        let (mut tried, mut unsure) = (0, 0);
        let mut check = |phi: f64, z: f64, near_side: bool| {
            let d = axis.e1 * phi.cos() + axis.e2 * phi.sin() + axis.pole * z;
            let w = cl.classify(d);
            if z <= 0.0 {
                assert_eq!(w, BEHIND);
                return;
            }
            tried += 1;
            let key = m.key(azimuth(axis.local(d)).unwrap()).rem_euclid(n as i64) as u32;
            if w == UNSURE {
                unsure += !near_side as usize;
            } else {
                assert!(!near_side, "n {n}: φ {phi} within 1e-12 of a meridian classified {w}");
                assert_eq!(w, key, "n {n}: φ {phi}");
            }
        };
        for _ in 0..20_000 {
            check(r() * TAU, r() * 2.0 - 0.5, false);
        }
        for j in 0..n {
            let side = (j as f64 + 0.5) * m.dphi;
            for off in [-1e-12, 0.0, 1e-12] {
                check(side + off, 0.3, true);
            }
        }
        assert!(unsure * 1000 < tried, "n {n}: {unsure} of {tried} unsure");
    }

    /// Away from edges, relative W plus the brute-force W at the pole equals the brute-force
    /// count of all ray–triangle hits, for points and normals all over the scene.
    #[test]
    fn depth_complexity_equals_brute_force_hit_count() {
        let meshes = scene();
        let dual = DualEdges::build(&meshes, &vec![true; meshes.len()]);
        let mut r = rng(1);
        let mut t = Traversal::default();
        let m = Meridians::new(48);
        let mut contours = Vec::new();
        let (mut checked, mut mismatched) = (0, 0);
        for _ in 0..60 {
            let p =
                dual.normalise(Vec3::new((r() * 2.4 - 1.2) as f32, (r() * 2.4 - 1.2) as f32, (r() * 2.0 - 0.3) as f32));
            let n = DVec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0).normalize();
            contours.clear();
            dual.contours(p, n, 1e-9, &mut contours);
            let frame = PoleFrame::for_normal(n);
            let vis = t.run(&contours, p, n, &frame, &m);
            mismatched += (vis.mismatches > 0) as usize;
            let w_pole = hit_count(&meshes, &dual, p, frame.pole);
            for iv in t.intervals.iter().step_by(7) {
                if iv.hi - iv.lo < 1e-3 {
                    continue;
                }
                let i = iv.meridian as usize;
                let d = frame.direction(m.cos[i], m.sin[i], 0.5 * (iv.lo + iv.hi));
                if n.dot(d) < 1e-6 {
                    continue;
                }
                assert_eq!(iv.w + w_pole, hit_count(&meshes, &dual, p, d), "at {p} towards {d}");
                checked += 1;
            }
        }
        assert!(checked > 500, "only {checked} intervals checked");
        assert_eq!(mismatched, 0, "points whose horizon check failed");
    }

    /// Dropping one contour whose arc ends on the horizon (a missed crossing) is caught by the
    /// horizon check at nearly every point.
    #[test]
    fn horizon_check_catches_a_missing_contour() {
        let meshes = scene();
        let dual = DualEdges::build(&meshes, &vec![true; meshes.len()]);
        let mut r = rng(4);
        let m = Meridians::new(48);
        let mut t = Traversal::default();
        let (mut tried, mut caught) = (0, 0);
        for _ in 0..80 {
            let p =
                dual.normalise(Vec3::new((r() * 2.4 - 1.2) as f32, (r() * 2.4 - 1.2) as f32, (r() * 2.0 - 0.3) as f32));
            let n = DVec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0).normalize();
            let mut contours = Vec::new();
            dual.contours(p, n, 1e-9, &mut contours);
            let frame = PoleFrame::for_normal(n);
            // A contour with one end behind the plane and one well in front.
            let Some(k) = contours.iter().position(|c| {
                let (ha, hb) = (n.dot(c.a - p), n.dot(c.b - p));
                ha.min(hb) < -0.05 && ha.max(hb) > 0.05
            }) else {
                continue;
            };
            contours.remove(k);
            tried += 1;
            caught += (t.run(&contours, p, n, &frame, &m).mismatches > 0) as usize;
        }
        assert!(tried > 20 && caught * 10 >= tried * 9, "caught {caught} of {tried}");
    }

    /// A vertical quad through the horizon: two arcs end on it, and the meridian ends inside
    /// the quad's azimuth range have W = 1.
    #[test]
    fn horizon_check_on_a_quad_through_the_tangent_plane() {
        let meshes = vec![quad([
            Vec3::new(1.0, -0.5, -0.5),
            Vec3::new(1.0, 0.5, -0.5),
            Vec3::new(1.0, 0.5, 0.5),
            Vec3::new(1.0, -0.5, 0.5),
        ])];
        let dual = DualEdges::build(&meshes, &[true]);
        let p = dual.normalise(Vec3::new(0.0, 0.1, 0.0));
        let mut contours = Vec::new();
        let m = Meridians::new(16);
        let mut t = Traversal::default();
        for n in [DVec3::Z, DVec3::new(-0.3, 0.2, 1.0).normalize()] {
            contours.clear();
            dual.contours(p, n, 1e-9, &mut contours);
            let frame = PoleFrame::for_normal(n);
            let vis = t.run(&contours, p, n, &frame, &m);
            assert_eq!(vis.mismatches, 0, "{vis:?} {:?} {:?}", t.end_w, t.horizon);
            assert_eq!(t.horizon.len(), 2, "two arcs end on the horizon");
            assert!(t.end_w.iter().any(|w| *w != t.end_w[0]), "the quad covers some meridian ends");
        }
    }

    /// With nothing in front, the visible intervals integrate `n·ω` to π (exact in `v`, the
    /// azimuth sum of a smooth periodic function).
    #[test]
    fn open_hemisphere_integrates_to_pi() {
        let mut r = rng(2);
        let m = Meridians::new(32);
        let mut t = Traversal::default();
        for _ in 0..50 {
            let n = DVec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0).normalize();
            let frame = PoleFrame::for_normal(n);
            let vis = t.run(&[], DVec3::ZERO, n, &frame, &m);
            assert_eq!(vis.min_w, 0);
            let ao: f64 =
                t.with_w(0).map(|iv| n.dot(moment(&frame, &m, iv.meridian as usize, iv.lo, iv.hi)) * m.dphi).sum();
            assert!((ao - PI).abs() < 1e-9, "{n}: {ao}");
        }
    }
}
