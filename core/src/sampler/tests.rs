//! Cross-sampler tests: stratification (elementary intervals), pbrt-v3 values, determinism,
//! uniformity, arrays and the factory.

use super::lowdiscrepancy::sobol_sample_bits;
use super::*;
use crate::goodness_of_fit::chi2_test;
use penumbra_parser::{Param, ParamSet, ParamValue};

fn entity(kind: &str, ints: &[(&str, i32)]) -> Entity {
    let mut ps = ParamSet::new();
    for (k, v) in ints {
        ps.add(Param::new(*k, ParamValue::Int(vec![*v]), FileLoc::new("scene.pbrt".into(), 3, 9)));
    }
    Entity::new(kind, ps, FileLoc::new("scene.pbrt".into(), 3, 1))
}

fn make(kind: &str, ints: &[(&str, i32)], spp: Option<u32>, seed: u64) -> Box<dyn Sampler> {
    create_sampler(&entity(kind, ints), spp, seed, &DiagSink::new()).unwrap()
}

const ALL: [&str; 6] = ["random", "stratified", "halton", "sobol", "02sequence", "maxmindist"];

/// Asserts that `points` (2^m of them, in [0,1)²) have exactly one point in every elementary
/// interval [a/2^k, (a+1)/2^k) × [b/2^(m-k), (b+1)/2^(m-k)), k = 0..=m.
fn assert_0m2_net(points: &[(f64, f64)], m: u32, what: &str) {
    assert_eq!(points.len(), 1 << m, "{what}");
    for k in 0..=m {
        let (nx, ny) = (1usize << k, 1usize << (m - k));
        let mut counts = vec![0u32; nx * ny];
        for &(x, y) in points {
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y), "{what}: ({x},{y})");
            counts[(y * ny as f64) as usize * nx + (x * nx as f64) as usize] += 1;
        }
        assert!(counts.iter().all(|&c| c == 1), "{what}: m={m} k={k} counts {counts:?}");
    }
}

fn assert_stratified_1d(values: &[f32], what: &str) {
    let n = values.len();
    let mut strata: Vec<usize> = values.iter().map(|&v| (v as f64 * n as f64) as usize).collect();
    strata.sort();
    assert_eq!(strata, (0..n).collect::<Vec<_>>(), "{what}");
}

#[test]
fn sobol_dims_01_are_a_02_sequence() {
    for m in 1..=12u32 {
        // The first 2^m points and also an aligned later block.
        for start in [0u64, 5 << m] {
            let pts: Vec<(f64, f64)> = (start..start + (1 << m))
                .map(|i| (sobol_sample_bits(i, 0) as f64 / 4294967296.0, sobol_sample_bits(i, 1) as f64 / 4294967296.0))
                .collect();
            assert_0m2_net(&pts, m, "sobol (0,1)");
        }
    }
}

#[test]
fn sobol_sampler_pixels_are_nets() {
    let mut s = make("sobol", &[("pixelsamples", 256)], None, 0);
    s.set_sample_bounds(IVec2::new(-2, -2), IVec2::new(37, 23));
    let mut s = s.clone_box();
    for pixel in [IVec2::new(-2, -2), IVec2::new(10, 5), IVec2::new(36, 22)] {
        for m in [4u32, 8] {
            let pts: Vec<(f64, f64)> = (0..1u32 << m)
                .map(|i| {
                    s.start_pixel_sample(pixel, i);
                    let p = s.get_2d();
                    (p.x as f64, p.y as f64)
                })
                .collect();
            assert_0m2_net(&pts, m, "sobol pixel");
        }
    }
}

#[test]
fn zero_two_sequence_is_stratified() {
    let mut s = make("02sequence", &[("pixelsamples", 256)], None, 7);
    assert_eq!(s.round_count(12), 16);
    s.request_1d_array(8);
    s.request_2d_array(16);
    let mut s = s.clone_box();
    for pixel in [IVec2::new(0, 0), IVec2::new(-4, 9)] {
        let mut film = vec![];
        let mut time = vec![];
        let mut lens = vec![];
        for i in 0..256 {
            s.start_pixel_sample(pixel, i);
            let p = s.get_2d();
            film.push((p.x as f64, p.y as f64));
            time.push(s.get_1d());
            let l = s.get_2d();
            lens.push((l.x as f64, l.y as f64));
            let a1 = s.get_1d_array(8).expect("1d array").to_vec();
            assert_stratified_1d(&a1, "02 1d array");
            let a2: Vec<(f64, f64)> =
                s.get_2d_array(16).expect("2d array").iter().map(|q| (q.x as f64, q.y as f64)).collect();
            assert_0m2_net(&a2, 4, "02 2d array");
        }
        assert_0m2_net(&film, 8, "02 film");
        assert_0m2_net(&lens, 8, "02 lens");
        assert_stratified_1d(&time, "02 time");
    }
}

#[test]
fn maxmindist_matrices_make_nets_and_film_samples_too() {
    for (m, c) in C_MAX_MIN_DIST.iter().enumerate().take(13) {
        let n = 1u32 << m;
        let pts: Vec<(f64, f64)> = (0..n)
            .map(|i| (i as f64 / n as f64, lowdiscrepancy::multiply_generator(c, i) as f64 / 4294967296.0))
            .collect();
        assert_0m2_net(&pts, m as u32, "maxmin matrix");
    }
    let mut s = make("maxmindist", &[("pixelsamples", 64)], None, 1);
    let pts: Vec<(f64, f64)> = (0..64)
        .map(|i| {
            s.start_pixel_sample(IVec2::new(3, 3), i);
            let p = s.get_2d();
            (p.x as f64, p.y as f64)
        })
        .collect();
    assert_0m2_net(&pts, 6, "maxmin film");
}

#[test]
fn maxmin_search_beats_hammersley() {
    // The searched matrix for 64 points must keep points further apart than the plain
    // Hammersley (bit-reversal) net, whose minimum distance is poor.
    let m = 6;
    let hammersley = maxmin_matrices::min_toroidal_distance2(&lowdiscrepancy::C_VAN_DER_CORPUT, m, 0.0);
    let table = maxmin_matrices::min_toroidal_distance2(&C_MAX_MIN_DIST[m as usize], m, 0.0);
    assert!(table > hammersley * 1.5, "table {table} hammersley {hammersley}");
}

#[test]
fn stratified_sampler_strata() {
    let mut s = make("stratified", &[("xsamples", 4), ("ysamples", 3)], None, 5);
    assert_eq!(s.samples_per_pixel(), 12);
    s.request_1d_array(5);
    s.request_2d_array(6);
    let mut s = s.clone_box();
    let (mut film, mut one) = (vec![], vec![]);
    for i in 0..12 {
        s.start_pixel_sample(IVec2::new(9, -1), i);
        let p = s.get_2d();
        film.push(((p.x * 4.0) as usize, (p.y * 3.0) as usize));
        one.push(s.get_1d());
        assert_stratified_1d(s.get_1d_array(5).unwrap(), "stratified 1d array");
        let a2 = s.get_2d_array(6).unwrap().to_vec();
        assert_stratified_1d(&a2.iter().map(|q| q.x).collect::<Vec<_>>(), "latin hypercube x");
        assert_stratified_1d(&a2.iter().map(|q| q.y).collect::<Vec<_>>(), "latin hypercube y");
    }
    film.sort();
    let all: Vec<(usize, usize)> = (0..4).flat_map(|x| (0..3).map(move |y| (x, y))).collect();
    assert_eq!(film, all);
    assert_stratified_1d(&one, "stratified 1d");
    // No jitter: cell centres.
    let mut s = StratifiedSampler::stratified(2, 2, false, 4, 0);
    s.start_pixel_sample(IVec2::ZERO, 0);
    let p = s.get_2d();
    assert!([0.25, 0.75].contains(&p.x) && [0.25, 0.75].contains(&p.y));
}

#[test]
fn halton_first_dimensions_are_radical_inverses() {
    fn ri(base: u64, mut a: u64) -> f64 {
        let (mut r, mut f) = (0.0, 1.0 / base as f64);
        while a > 0 {
            r += (a % base) as f64 * f;
            a /= base;
            f /= base as f64;
        }
        r
    }
    let mut s = make("halton", &[], None, 0);
    s.set_sample_bounds(IVec2::ZERO, IVec2::new(640, 480));
    for i in 0..64u64 {
        s.start_pixel_sample(IVec2::ZERO, i as u32);
        let p = s.get_2d();
        // Pixel (0,0) has offset 0, so its i-th sample is global index i·128·243; its film
        // offset is the radical inverse of the index with the pixel-selecting digits removed.
        assert!((p.x as f64 - ri(2, i * 243)).abs() < 1e-7, "x {i}");
        assert!((p.y as f64 - ri(3, i * 128)).abs() < 1e-7, "y {i}");
    }
    // samplepixelcenter
    let mut ps = ParamSet::new();
    ps.add(Param::new("samplepixelcenter", ParamValue::Bool(vec![true]), FileLoc::builtin()));
    let mut c = create_sampler(&Entity::new("halton", ps, FileLoc::builtin()), None, 0, &DiagSink::new()).unwrap();
    c.start_pixel_sample(IVec2::new(4, 4), 3);
    assert_eq!(c.get_2d(), Vec2::splat(0.5));
    assert!(c.get_1d() != 0.5);
}

/// Draws a fixed pattern of dimensions and arrays for one pixel sample, as bit patterns.
fn draw(s: &mut dyn Sampler, pixel: IVec2, index: u32) -> Vec<u32> {
    s.start_pixel_sample(pixel, index);
    let mut out = vec![];
    let p = s.get_2d();
    out.extend([p.x.to_bits(), p.y.to_bits(), s.get_1d().to_bits()]);
    out.extend(s.get_1d_array(4).expect("1d array").iter().map(|v| v.to_bits()));
    out.extend(s.get_2d_array(8).expect("2d array").iter().flat_map(|v| [v.x.to_bits(), v.y.to_bits()]));
    for _ in 0..12 {
        let q = s.get_2d();
        out.extend([q.x.to_bits(), q.y.to_bits(), s.get_1d().to_bits()]);
    }
    out
}

#[test]
fn deterministic_whatever_the_visit_order_or_clone() {
    let pixels: Vec<IVec2> = (0..5).flat_map(|y| (0..4).map(move |x| IVec2::new(x * 3 - 2, y * 7 - 5))).collect();
    for kind in ALL {
        let mut proto = make(kind, &[], Some(8), 42);
        proto.set_sample_bounds(IVec2::new(-2, -5), IVec2::new(20, 30));
        proto.request_1d_array(4);
        proto.request_2d_array(8);
        let mut a = proto.clone_box();
        let mut b = proto.clone_box();
        let mut forward = std::collections::HashMap::new();
        for &p in &pixels {
            for i in 0..8 {
                forward.insert((p, i), draw(a.as_mut(), p, i));
            }
        }
        // Reverse pixel order, interleaved samples, and a third clone for half of them.
        let mut c = proto.clone_box();
        for (k, &p) in pixels.iter().rev().enumerate() {
            for i in [7u32, 0, 5, 2, 1, 6, 3, 4] {
                let s = if (k + i as usize) & 1 == 0 { b.as_mut() } else { c.as_mut() };
                assert_eq!(draw(s, p, i), forward[&(p, i)], "{kind} {p} {i}");
            }
        }
        // A different seed changes the random samplers (Sobol/Halton change beyond dims 0-1).
        let mut other = make(kind, &[], Some(8), 43);
        other.set_sample_bounds(IVec2::new(-2, -5), IVec2::new(20, 30));
        other.request_1d_array(4);
        other.request_2d_array(8);
        assert_ne!(draw(other.as_mut(), pixels[3], 1), forward[&(pixels[3], 1)], "{kind}");
    }
}

#[test]
fn every_dimension_is_uniform() {
    // 16 bins = spp: pbrt-v3's per-pixel XOR scrambles move all of a pixel's points together
    // within their strata, so finer bins would see pixel-level clumping, not non-uniformity.
    let (nbins, side) = (16usize, 16i32);
    for kind in ALL {
        let mut s = make(kind, &[], Some(16), 9);
        s.set_sample_bounds(IVec2::ZERO, IVec2::splat(side));
        let ndims = 16;
        let mut hist = vec![vec![0.0f64; nbins]; ndims];
        let mut sums = vec![0.0f64; ndims];
        let mut n = 0usize;
        for y in 0..side {
            for x in 0..side {
                for i in 0..16 {
                    s.start_pixel_sample(IVec2::new(x, y), i);
                    // 2D, 1D, 2D, 1D, then 2D pairs: 16 values, beyond the pre-generated dimensions.
                    let mut vals = vec![];
                    let p = s.get_2d();
                    vals.extend([p.x, p.y, s.get_1d()]);
                    let q = s.get_2d();
                    vals.extend([q.x, q.y, s.get_1d()]);
                    while vals.len() < ndims {
                        let r = s.get_2d();
                        vals.extend([r.x, r.y]);
                    }
                    for (d, &v) in vals.iter().take(ndims).enumerate() {
                        assert!((0.0..1.0).contains(&v), "{kind} dim {d}: {v}");
                        hist[d][(v as f64 * nbins as f64) as usize] += 1.0;
                        sums[d] += v as f64;
                    }
                    n += 1;
                }
            }
        }
        let expected = vec![n as f64 / nbins as f64; nbins];
        for d in 0..ndims {
            let (chi2, dof, p) = chi2_test(&hist[d], &expected, 5.0);
            // Šidák-style margin for the 6×16 tests.
            assert!(p > 1e-5, "{kind} dim {d}: chi2 {chi2} dof {dof} p {p}");
            let mean = sums[d] / n as f64;
            // pbrt-v3's maxmindist puts film x at i / spp (the left edge of each stratum).
            let expect = if kind == "maxmindist" && d == 0 { 0.5 - 0.5 / 16.0 } else { 0.5 };
            assert!((mean - expect).abs() < 0.02, "{kind} dim {d}: mean {mean}");
        }
    }
}

#[test]
fn arrays_have_the_requested_sizes() {
    for kind in ALL {
        let mut s = make(kind, &[], Some(4), 3);
        let n1 = s.round_count(3);
        let n2 = s.round_count(5);
        s.request_1d_array(n1);
        s.request_2d_array(n2);
        s.request_2d_array(1);
        let mut s = s.clone_box();
        for i in 0..4 {
            s.start_pixel_sample(IVec2::new(1, 2), i);
            assert!(s.get_1d_array(n1 + 1).is_none(), "{kind}: wrong size must give None");
            let a = s.get_1d_array(n1).expect("1d").to_vec();
            assert_eq!(a.len(), n1 as usize);
            assert!(a.iter().all(|v| (0.0..1.0).contains(v)));
            assert_eq!(s.get_2d_array(n2).expect("2d").len(), n2 as usize);
            assert_eq!(s.get_2d_array(1).expect("2d").len(), 1);
            assert!(s.get_2d_array(1).is_none(), "{kind}: arrays are handed out once per sample");
            assert!(s.get_1d_array(n1).is_none());
        }
        // Before any start_pixel_sample and past spp, nothing panics.
        let mut fresh = make(kind, &[], Some(4), 3);
        let _ = (fresh.get_1d(), fresh.get_2d(), fresh.get_1d_array(2));
        fresh.start_pixel_sample(IVec2::new(-100, 1 << 20), 1000);
        let v = fresh.get_2d();
        assert!((0.0..1.0).contains(&v.x) && (0.0..1.0).contains(&v.y), "{kind}");
    }
}

#[test]
fn factory_parameters_and_errors() {
    let sink = DiagSink::new();
    let s = create_sampler(&entity("lowdiscrepancy", &[("pixelsamples", 12)]), None, 0, &sink).unwrap();
    assert_eq!(s.samples_per_pixel(), 16);
    assert_eq!(s.name(), "02sequence");
    assert_eq!(sink.len(), 1);
    assert!(sink.snapshot()[0].message.contains("from 12 to 16"));
    let defaults: Vec<u32> = ALL.iter().map(|k| make(k, &[], None, 0).samples_per_pixel()).collect();
    assert_eq!(defaults, vec![4, 16, 16, 16, 16, 16]);
    assert_eq!(make("sobol", &[("pixelsamples", 5)], None, 0).samples_per_pixel(), 8);
    assert_eq!(make("halton", &[("pixelsamples", 5)], None, 0).samples_per_pixel(), 5);
    assert_eq!(make("halton", &[], Some(7), 0).samples_per_pixel(), 7);
    assert_eq!(make("stratified", &[], Some(12), 0).samples_per_pixel(), 12);
    assert_eq!(make("stratified", &[], Some(7), 0).samples_per_pixel(), 7);
    assert_eq!(make("maxmindist", &[("pixelsamples", 1 << 20)], None, 0).samples_per_pixel(), 1 << 16);

    match create_sampler(&entity("best", &[]), None, 0, &sink) {
        Err(SamplerError::Unknown { name, valid, loc }) => {
            assert_eq!(name, "best");
            assert!(valid.contains("halton") && valid.contains("maxmindist"));
            assert_eq!(loc.line, 3);
        }
        other => panic!("{:?}", other.map(|s| s.name())),
    }
    for bad in [0, -4, (1 << 24) + 1] {
        match create_sampler(&entity("halton", &[("pixelsamples", bad)]), None, 0, &sink) {
            Err(SamplerError::InvalidParameter { param, loc, .. }) => {
                assert_eq!(param, "pixelsamples");
                assert_eq!((loc.line, loc.column), (3, 9));
            }
            other => panic!("{bad}: {:?}", other.map(|s| s.name())),
        }
    }
    assert!(create_sampler(&entity("stratified", &[("xsamples", 0)]), None, 0, &sink).is_err());
    assert!(create_sampler(&entity("stratified", &[("xsamples", 8192), ("ysamples", 8192)]), None, 0, &sink).is_err());
    assert!(create_sampler(&entity("02sequence", &[("dimensions", -1)]), None, 0, &sink).is_err());
    assert!(create_sampler(&entity("sobol", &[]), Some(0), 0, &sink).is_err());

    // Unused parameters are left for the caller to report; used ones are marked.
    let e = entity("halton", &[("pixelsamples", 8), ("pixelsampels", 8)]);
    create_sampler(&e, None, 0, &sink).unwrap();
    let unused = e.params.report_unused("sampler \"halton\"");
    assert_eq!(unused.len(), 1);
    assert!(unused[0].message.contains("pixelsampels"));
}

#[test]
fn skipping_dimensions_leaves_the_same_sequence() {
    for kind in ALL {
        let mut a = make(kind, &[], Some(4), 3);
        a.request_2d_array(2);
        let mut b = a.clone_box();
        for index in 0..4 {
            let pixel = IVec2::new(5, 9);
            a.start_pixel_sample(pixel, index);
            b.start_pixel_sample(pixel, index);
            let film = (a.get_2d(), b.get_2d());
            assert_eq!(film.0, film.1, "{kind}");
            a.get_1d();
            b.skip_1d();
            a.get_2d();
            b.skip_2d();
            assert_eq!(a.get_2d_array(2).unwrap(), b.get_2d_array(2).unwrap(), "{kind}");
            for _ in 0..6 {
                assert_eq!(a.get_1d().to_bits(), b.get_1d().to_bits(), "{kind}");
                assert_eq!(a.get_2d(), b.get_2d(), "{kind}");
                a.get_2d();
                b.skip_2d();
                a.get_1d();
                b.skip_1d();
            }
        }
    }
}

/// `samples_independent_of_count` is what `--spp-offset` relies on: for the samplers that
/// claim it, sample `8 + i` of a 16-spp sampler equals sample `i` of a 4-spp sampler offset
/// by 8 (dimensions and arrays); for the others the values really do depend on the count.
#[test]
fn offset_samples_equal_the_longer_sequence_exactly_where_claimed() {
    let draw = |s: &mut dyn Sampler, p: IVec2, i: u32| {
        s.start_pixel_sample(p, i);
        let mut v = vec![s.get_1d(), s.get_2d().x, s.get_1d()];
        // (A pixel sampler asked for a sample past its count has no arrays: NaN is unequal.)
        v.extend(s.get_1d_array(4).map_or(vec![f32::NAN], |a| a.to_vec()));
        v.extend(s.get_2d_array(2).map_or(vec![f32::NAN], |a| a.iter().flat_map(|q| [q.x, q.y]).collect()));
        v.push(s.get_1d());
        v
    };
    let prepare = |mut s: Box<dyn Sampler>| {
        s.set_sample_bounds(IVec2::ZERO, IVec2::new(40, 30));
        s.request_1d_array(4);
        s.request_2d_array(2);
        s
    };
    for kind in ALL {
        let mut long = prepare(make(kind, &[], Some(16), 5));
        let mut short = prepare(Box::new(OffsetSampler::new(make(kind, &[], Some(4), 5), 8).unwrap()));
        let mut same = true;
        for p in [IVec2::new(0, 0), IVec2::new(17, 3), IVec2::new(39, 29)] {
            for i in 0..4 {
                same &= draw(long.as_mut(), p, 8 + i) == draw(short.as_mut(), p, i);
            }
        }
        assert_eq!(same, short.samples_independent_of_count(), "{kind}: equal samples {same}");
    }
    assert!(OffsetSampler::new(make("random", &[], Some(4), 0), u32::MAX - 2).is_none());
}
