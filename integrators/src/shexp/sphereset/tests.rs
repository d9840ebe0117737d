use super::fit::{inner_grid, mesh_volume, FitParams};
use super::*;
use glam::Vec3;
use std::f64::consts::PI;

fn mesh(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> TriangleMesh {
    TriangleMesh { positions, indices, ..Default::default() }
}

/// An axis-aligned box, outward winding.
pub(crate) fn boxed(lo: Vec3, hi: Vec3) -> TriangleMesh {
    let p = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut idx = Vec::new();
    for q in quads {
        idx.push([q[0], q[1], q[2]]);
        idx.push([q[0], q[2], q[3]]);
    }
    mesh(p, idx)
}

/// A torus about +y (major radius `big`, minor `small`), `n × m` quads.
pub(crate) fn torus(big: f32, small: f32, n: u32, m: u32) -> TriangleMesh {
    let mut p = Vec::new();
    for i in 0..n {
        let u = 2.0 * std::f32::consts::PI * i as f32 / n as f32;
        for j in 0..m {
            let v = 2.0 * std::f32::consts::PI * j as f32 / m as f32;
            let r = big + small * v.cos();
            p.push(Vec3::new(r * u.cos(), small * v.sin(), r * u.sin()));
        }
    }
    let mut idx = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let a = i * m + j;
            let b = ((i + 1) % n) * m + j;
            let c = ((i + 1) % n) * m + (j + 1) % m;
            let d = i * m + (j + 1) % m;
            idx.push([a, b, c]);
            idx.push([a, c, d]);
        }
    }
    mesh(p, idx)
}

/// A UV sphere with its vertices on the sphere.
fn uv_sphere(c: Vec3, r: f32) -> TriangleMesh {
    let (n, m) = (16u32, 32u32);
    let mut p = vec![c + Vec3::Y * r];
    for i in 1..n {
        let t = std::f32::consts::PI * i as f32 / n as f32;
        for j in 0..m {
            let f = 2.0 * std::f32::consts::PI * j as f32 / m as f32;
            p.push(c + r * Vec3::new(t.sin() * f.cos(), t.cos(), t.sin() * f.sin()));
        }
    }
    p.push(c - Vec3::Y * r);
    let ring = |i: u32, j: u32| 1 + (i - 1) * m + j % m;
    let mut idx = Vec::new();
    for j in 0..m {
        idx.push([0, ring(1, j + 1), ring(1, j)]);
        idx.push([p.len() as u32 - 1, ring(n - 1, j), ring(n - 1, j + 1)]);
    }
    for i in 1..n - 1 {
        for j in 0..m {
            idx.push([ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)]);
            idx.push([ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)]);
        }
    }
    mesh(p, idx)
}

fn object(kind: &str) -> SceneObject {
    SceneObject {
        kind: kind.into(),
        loc: penumbra_parser::FileLoc::new("test".into(), 1, 1),
        material: Some(0),
        area_light: None,
        instance: None,
        occluder: true,
    }
}

fn small() -> FitParams {
    FitParams { spheres: 12, inner_points: 2000, surface_points: 1000, iterations: 6, teleports: 4 }
}

fn assert_bounds(m: &TriangleMesh, spheres: &[Sphere]) {
    for p in &m.positions {
        let p = p.as_dvec3();
        assert!(spheres.iter().any(|s| s.contains(p)), "vertex {p} outside every sphere");
    }
}

#[test]
fn grid_points_are_inside_and_fill_the_volume() {
    let t = torus(1.0, 0.3, 48, 24);
    let v = mesh_volume(&t);
    // 2π²Rr² for the smooth torus; the tessellation is slightly smaller.
    let smooth = 2.0 * PI * PI * 1.0 * 0.09;
    assert!((v - smooth).abs() < 0.03 * smooth, "{v} {smooth}");
    let (pts, cell) = inner_grid(&t, 5000, v);
    assert!((pts.len() as f64 * cell - v).abs() < 0.08 * v, "{} cells of {cell}: {v}", pts.len());
    for p in &pts {
        let ring = (p.x * p.x + p.z * p.z).sqrt() - 1.0;
        // Chords around the axis bulge into the hole by R(1 − cos(π/48)) ≈ 0.002.
        assert!(ring * ring + p.y * p.y <= 0.303f64.powi(2), "{p} not inside the torus");
    }
}

#[test]
fn every_leaf_set_bounds_its_mesh() {
    let meshes = [boxed(Vec3::ZERO, Vec3::new(2.0, 0.5, 1.0)), torus(1.0, 0.3, 32, 16), uv_sphere(Vec3::ONE, 0.7)];
    for m in &meshes {
        assert!(is_closed(m));
        let f = fit_closed(m, &small());
        assert!(!f.spheres.is_empty() && f.spheres.len() <= 12);
        assert_bounds(m, &f.spheres);
        let h = hierarchy::build(&f.spheres);
        // Every node bounds its children, so every level bounds the mesh.
        for n in &h.nodes {
            for &c in &n.children {
                let s = h.nodes[c as usize].sphere;
                assert!(n.sphere.center.distance(s.center) + s.radius <= n.sphere.radius * (1.0 + 1e-9));
            }
        }
        let mut count = 0;
        h.for_each_leaf(&mut |_| true, &mut |_| count += 1);
        assert_eq!(count, f.spheres.len());
    }
}

#[test]
fn outside_volume_of_fits() {
    // A torus: one bounding sphere sticks out by far more than the solid's volume; the
    // variational fit must do much better (measured: see the commit message).
    let t = torus(1.0, 0.3, 32, 16);
    let one = fit_closed(&t, &FitParams { spheres: 1, ..small() });
    let many = fit_closed(&t, &small());
    let v = many.volume;
    eprintln!("torus: 1 sphere outside {:.3} V, 12 spheres {:.3} V", one.outside_volume / v, many.outside_volume / v);
    assert!(one.outside_volume > 3.0 * v);
    assert!(many.outside_volume < 1.5 * v, "{} vs {v}", many.outside_volume);
    // An elongated box: 12 spheres beat the single one by a wide margin.
    let b = boxed(Vec3::ZERO, Vec3::new(4.0, 1.0, 1.0));
    let one = fit_closed(&b, &FitParams { spheres: 1, ..small() });
    let many = fit_closed(&b, &small());
    eprintln!(
        "box 4x1x1: 1 sphere outside {:.3} V, 12 spheres {:.3} V",
        one.outside_volume / 4.0,
        many.outside_volume / 4.0
    );
    assert!(many.outside_volume < 0.5 * one.outside_volume);
}

#[test]
fn spheres_map_to_their_exact_sphere() {
    let m = uv_sphere(Vec3::new(1.0, -2.0, 3.0), 0.5);
    let s = exact_sphere(&m).unwrap();
    assert!(s.center.distance(DVec3::new(1.0, -2.0, 3.0)) < 1e-6);
    assert!((s.radius - 0.5).abs() < 1e-6);
    let sets = build_for_scene(&[m], &[object("sphere")], &small(), OpenMeshes::Shells, None);
    assert_eq!(sets.sets.len(), 1);
    assert_eq!(sets.sets[0].source, Source::Exact);
    assert_eq!(sets.sets[0].leaves, vec![s]);
    // A non-uniformly scaled `sphere` (an ellipsoid) is fitted like any closed mesh.
    let mut e = uv_sphere(Vec3::ZERO, 0.5);
    e.positions.iter_mut().for_each(|p| p.x *= 2.0);
    assert!(exact_sphere(&e).is_none());
    let sets = build_for_scene(std::slice::from_ref(&e), &[object("sphere")], &small(), OpenMeshes::Shells, None);
    assert_eq!(sets.sets[0].source, Source::Fitted);
    assert_bounds(&e, &sets.sets[0].leaves);
}

#[test]
fn ground_plane_and_shells() {
    let plane = mesh(
        vec![
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(-5.0, 0.0, 5.0),
            Vec3::new(5.0, 0.0, 5.0),
            Vec3::new(5.0, 0.0, -5.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    let wall = mesh(
        vec![Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0), Vec3::new(1.0, 1.0, 2.0), Vec3::new(-1.0, 1.0, 2.0)],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    let cube = boxed(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 1.0, 0.5));
    let objs = [object("trianglemesh"), object("trianglemesh"), object("trianglemesh")];
    let sets = build_for_scene(&[plane, wall.clone(), cube], &objs, &small(), OpenMeshes::Shells, None);
    let g = sets.ground.unwrap();
    assert_eq!(g.object, 0);
    assert!((g.normal - DVec3::Y).length() < 1e-12, "{}", g.normal);
    let shell = sets.sets.iter().find(|s| s.object == 1).unwrap();
    assert_eq!(shell.source, Source::Shell);
    assert_bounds(&wall, &shell.leaves);
    // A planar shell does not shadow its own surface (its centres are in the wall's plane).
    assert!(shell.convex);
    assert_eq!(sets.sets.iter().find(|s| s.object == 2).unwrap().source, Source::Fitted);
}

#[test]
fn cache_round_trip_and_unwritable_dir() {
    let dir = std::env::temp_dir().join(format!("penumbra-sphereset-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let t = torus(1.0, 0.3, 24, 12);
    let objs = [object("trianglemesh")];
    let first = build_for_scene(std::slice::from_ref(&t), &objs, &small(), OpenMeshes::Shells, Some(&dir));
    assert_eq!((first.cache_hits, first.cache_misses, first.cache_error.clone()), (0, 1, None));
    let second = build_for_scene(std::slice::from_ref(&t), &objs, &small(), OpenMeshes::Shells, Some(&dir));
    assert_eq!((second.cache_hits, second.cache_misses), (1, 0));
    assert_eq!(second.sets[0].source, Source::Cached);
    assert_eq!(second.sets[0].leaves, first.sets[0].leaves);
    assert_eq!(second.sets[0].outside_volume, first.sets[0].outside_volume);
    // Another leaf count is another key.
    let other = build_for_scene(
        std::slice::from_ref(&t),
        &objs,
        &FitParams { spheres: 5, ..small() },
        OpenMeshes::Shells,
        Some(&dir),
    );
    assert_eq!(other.cache_misses, 1);
    // A corrupt file is refitted, not trusted.
    let key = cache::key(&Canonical::of(&t).local, &small());
    std::fs::write(dir.join(format!("{key:016x}.spheres")), "penumbra spheres v1 garbage\n").unwrap();
    assert_eq!(
        build_for_scene(std::slice::from_ref(&t), &objs, &small(), OpenMeshes::Shells, Some(&dir)).cache_misses,
        1
    );
    // A directory that cannot be created (below a regular file) fails nothing.
    let file = dir.join("not-a-dir");
    std::fs::write(&file, "x").unwrap();
    let blocked =
        build_for_scene(std::slice::from_ref(&t), &objs, &small(), OpenMeshes::Shells, Some(&file.join("sub")));
    assert!(blocked.cache_error.is_some());
    assert_eq!(blocked.sets[0].leaves, first.sets[0].leaves);
    let _ = std::fs::remove_dir_all(&dir);
}

/// An open cylinder about +z (radius `r`, height `h`, `n` segments, `m` rings): a shell.
fn open_cylinder(r: f32, h: f32, n: u32, m: u32) -> TriangleMesh {
    let mut p = Vec::new();
    for j in 0..=m {
        for i in 0..n {
            let u = 2.0 * std::f32::consts::PI * i as f32 / n as f32;
            p.push(Vec3::new(r * u.cos(), r * u.sin(), h * j as f32 / m as f32));
        }
    }
    let mut idx = Vec::new();
    for j in 0..m {
        for i in 0..n {
            let (a, b) = (j * n + i, j * n + (i + 1) % n);
            idx.push([a, b, b + n]);
            idx.push([a, b + n, a + n]);
        }
    }
    mesh(p, idx)
}

/// A mesh scaled by `s` and turned 37° about (1, 2, 3) gets the same spheres, scaled and
/// turned, up to rounding. Before the canonical frame, the tie-robust choices, the dithered
/// surface sampling and the continuous inner-point count, rounding alone (the f32 positions of
/// the transformed mesh) moved leaves by up to a full radius: the variational fit's grid is
/// axis-aligned, a tessellated quadric's equal triangles made the carried sample count an
/// exact integer that rounding decided, and symmetric shapes tie everywhere.
#[test]
fn fits_and_shells_do_not_depend_on_scale_or_orientation() {
    let moved = |m: &TriangleMesh, f: &dyn Fn(DVec3) -> DVec3| TriangleMesh {
        positions: m.positions.iter().map(|p| f(p.as_dvec3()).as_vec3()).collect(),
        ..m.clone()
    };
    let offset = DVec3::new(2.0, -1.0, 0.5);
    let torus = moved(&torus(1.0, 0.3, 24, 12), &|p| p + offset);
    let cylinder = moved(&open_cylinder(0.75, 2.0, 24, 4), &|p| p - offset);
    let objs = [object("trianglemesh"), object("trianglemesh")];
    let fitted = |meshes: [TriangleMesh; 2]| build_for_scene(&meshes, &objs, &small(), OpenMeshes::Shells, None);
    let base = fitted([torus.clone(), cylinder.clone()]);
    assert_eq!(base.sets.iter().map(|s| s.source).collect::<Vec<_>>(), [Source::Fitted, Source::Shell]);
    let rot = glam::DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 37f64.to_radians());
    type Map = Box<dyn Fn(DVec3) -> DVec3>;
    type Back = Box<dyn Fn(Sphere) -> Sphere>;
    let variants: [(&str, Map, Back); 3] = [
        ("scale 1e-4", Box::new(|p| p * 1e-4), Box::new(|s| Sphere { center: s.center * 1e4, radius: s.radius * 1e4 })),
        ("scale 1e4", Box::new(|p| p * 1e4), Box::new(|s| Sphere { center: s.center * 1e-4, radius: s.radius * 1e-4 })),
        ("turned", Box::new(move |p| rot * p), Box::new(move |s| Sphere { center: rot.transpose() * s.center, ..s })),
    ];
    let mut worst: Vec<String> = Vec::new();
    for (name, forward, back) in &variants {
        let v = fitted([moved(&torus, forward), moved(&cylinder, forward)]);
        for (a, b) in base.sets.iter().zip(&v.sets) {
            let ext = a.leaves.iter().map(|s| s.radius).fold(0.0, f64::max);
            assert_eq!(a.leaves.len(), b.leaves.len(), "{name}, object {}", a.object);
            let d = a
                .leaves
                .iter()
                .zip(&b.leaves)
                .map(|(x, y)| {
                    let y = back(*y);
                    (x.center.distance(y.center) + (x.radius - y.radius).abs()) / ext
                })
                .fold(0.0, f64::max);
            eprintln!("{name}, object {} ({:?}): leaves moved by {d:.1e} of the largest radius", a.object, a.source);
            if !(d < 1e-4) {
                worst.push(format!("{name}, object {}: {d:.1e}", a.object));
            }
        }
    }
    assert!(worst.is_empty(), "{worst:?}");
}

#[test]
fn zz_debug_canonical() {
    let t = torus(1.0, 0.3, 24, 12);
    let rot = glam::DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 37f64.to_radians());
    let moved = TriangleMesh {
        positions: t
            .positions
            .iter()
            .map(|p| (rot * (p.as_dvec3() * 3.0) + DVec3::new(5.0, -2.0, 1.0)).as_vec3())
            .collect(),
        ..t.clone()
    };
    let (a, b) = (Canonical::of(&t), Canonical::of(&moved));
    let mut diff = 0;
    let mut worst = 0.0f64;
    for (p, q) in a.local.positions.iter().zip(&b.local.positions) {
        for c in 0..3 {
            if p[c] != q[c] {
                diff += 1;
                worst = worst.max((p[c] - q[c]).abs() as f64);
            }
        }
    }
    eprintln!("frames {:?} {:?}", a.frame.axes, b.frame.axes);
    eprintln!("differing coords {diff}, worst {worst}");
}
