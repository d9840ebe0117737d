//! A normal cubemap's addressing: `res`² texels per face, texel index `face · res² + j · res + i`,
//! the direction of a texel's centre and bilinear lookups (the residual `R(N)` of
//! [`super::lighting`] and the bright regions' irradiance of [`super::bright`] are tabulated on
//! such maps).

use glam::DVec3;

/// The direction of texel `(face, i, j)`'s centre.
pub fn texel_dir(face: usize, i: usize, j: usize, res: usize) -> DVec3 {
    let u = 2.0 * (i as f64 + 0.5) / res as f64 - 1.0;
    let v = 2.0 * (j as f64 + 0.5) / res as f64 - 1.0;
    let d = match face {
        0 => DVec3::new(1.0, v, -u),
        1 => DVec3::new(-1.0, v, u),
        2 => DVec3::new(u, 1.0, -v),
        3 => DVec3::new(u, -1.0, v),
        4 => DVec3::new(u, v, 1.0),
        _ => DVec3::new(-u, v, -1.0),
    };
    d.normalize()
}

/// The face and continuous texel coordinates of direction `d` (inverse of [`texel_dir`]).
fn face_coords(d: DVec3, res: usize) -> (usize, f64, f64) {
    let a = d.abs();
    let (face, u, v) = if a.x >= a.y && a.x >= a.z {
        if d.x > 0.0 {
            (0, -d.z / a.x, d.y / a.x)
        } else {
            (1, d.z / a.x, d.y / a.x)
        }
    } else if a.y >= a.z {
        if d.y > 0.0 {
            (2, d.x / a.y, -d.z / a.y)
        } else {
            (3, d.x / a.y, d.z / a.y)
        }
    } else if d.z > 0.0 {
        (4, d.x / a.z, d.y / a.z)
    } else {
        (5, -d.x / a.z, d.y / a.z)
    };
    let r = res as f64;
    (face, (u + 1.0) * 0.5 * r - 0.5, (v + 1.0) * 0.5 * r - 0.5)
}
/// Bilinear interpolation on a normal cubemap of `res`² texels per face (texel index
/// `face · res² + j · res + i`, centres at [`texel_dir`]): the four texels around unit `n` with
/// their weights, clamped at the face's edges.
pub fn cubemap_bilinear(n: DVec3, res: usize) -> [(usize, f64); 4] {
    let (face, u, v) = face_coords(n, res);
    let clamp = |x: f64| x.clamp(0.0, (res - 1) as f64);
    let (u, v) = (clamp(u), clamp(v));
    let (i0, j0) = (u.floor() as usize, v.floor() as usize);
    let (i1, j1) = ((i0 + 1).min(res - 1), (j0 + 1).min(res - 1));
    let (fu, fv) = (u - i0 as f64, v - j0 as f64);
    let at = |i: usize, j: usize| face * res * res + j * res + i;
    [
        (at(i0, j0), (1.0 - fu) * (1.0 - fv)),
        (at(i1, j0), fu * (1.0 - fv)),
        (at(i0, j1), (1.0 - fu) * fv),
        (at(i1, j1), fu * fv),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubemap_coordinates_round_trip() {
        let res = 7;
        for face in 0..6 {
            for j in 0..res {
                for i in 0..res {
                    let d = texel_dir(face, i, j, res);
                    let (f, u, v) = face_coords(d, res);
                    assert_eq!(f, face);
                    assert!((u - i as f64).abs() < 1e-9 && (v - j as f64).abs() < 1e-9, "{face} {i} {j}: {u} {v}");
                }
            }
        }
    }
}
