//! A PLY reader (ascii, binary_little_endian, binary_big_endian) for
//! `Shape "plymesh"`, keeping what pbrt-v3 keeps: positions, normals, texture
//! coordinates and triangle/quad faces. Everything else is skipped.
//!
//! Reservations are capped by the bytes actually present, so a header that
//! lies about its counts yields an error, never a huge allocation.

use super::{loc_or_entity, read_alpha, ObjMesh, ShapeContext};
use crate::parser::{Diagnostic, ShapeDesc};

/// The parts of a PLY file a mesh needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyData {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    /// Triangles; quads `(v0 v1 v2 v3)` become `(v0 v1 v2)` and `(v3 v0 v2)` as in pbrt-v3.
    pub tris: Vec<[u32; 3]>,
    /// Faces with fewer than 3 or more than 4 vertices, skipped (pbrt-v3 warns and ignores them).
    pub skipped_faces: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
enum PropKind {
    Scalar(Ty),
    List(Ty, Ty),
}

#[derive(Clone, Debug)]
struct Prop {
    name: String,
    kind: PropKind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Prop>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    Le,
    Be,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    data_start: usize,
}

fn parse_header(bytes: &[u8]) -> Result<Header, String> {
    let mut pos = 0;
    let mut next_line = || -> Option<String> {
        if pos >= bytes.len() {
            return None;
        }
        let end = bytes[pos..].iter().position(|&b| b == b'\n').map(|e| pos + e);
        let (line, np) = match end {
            Some(e) => (&bytes[pos..e], e + 1),
            None => (&bytes[pos..], bytes.len()),
        };
        pos = np;
        Some(String::from_utf8_lossy(line).trim_end_matches('\r').to_string())
    };
    if next_line().as_deref().map(str::trim) != Some("ply") {
        return Err("not a PLY file (missing \"ply\" magic)".into());
    }
    let mut format = None;
    let mut elements: Vec<Element> = vec![];
    let mut lines = 1;
    loop {
        let Some(line) = next_line() else {
            return Err("header has no \"end_header\"".into());
        };
        lines += 1;
        if lines > 100_000 {
            return Err("header too long".into());
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        match toks.as_slice() {
            [] => {}
            ["end_header", ..] => break,
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, ..] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Le,
                    "binary_big_endian" => Format::Be,
                    _ => return Err(format!("unknown format \"{f}\"")),
                })
            }
            ["element", name, count] => {
                let count: u64 = count.parse().map_err(|_| format!("bad element count \"{count}\""))?;
                elements.push(Element { name: name.to_string(), count, props: vec![] });
            }
            ["property", "list", ct, it, name] => {
                let el = elements.last_mut().ok_or("property before any element")?;
                let ct = Ty::parse(ct).ok_or_else(|| format!("unknown type \"{ct}\""))?;
                let it = Ty::parse(it).ok_or_else(|| format!("unknown type \"{it}\""))?;
                if matches!(ct, Ty::F32 | Ty::F64) {
                    return Err(format!("list property \"{name}\" has a floating-point count type"));
                }
                el.props.push(Prop { name: name.to_string(), kind: PropKind::List(ct, it) });
            }
            ["property", ty, name] => {
                let el = elements.last_mut().ok_or("property before any element")?;
                let ty = Ty::parse(ty).ok_or_else(|| format!("unknown type \"{ty}\""))?;
                el.props.push(Prop { name: name.to_string(), kind: PropKind::Scalar(ty) });
            }
            _ => return Err(format!("malformed header line \"{line}\"")),
        }
    }
    let format = format.ok_or("header has no \"format\" line")?;
    Ok(Header { format, elements, data_start: pos })
}

/// Reads values from the data section.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    format: Format,
}

impl Reader<'_> {
    fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    fn token(&mut self) -> Result<&str, String> {
        let d = self.data;
        while self.pos < d.len() && d[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < d.len() && !d[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if start == self.pos {
            return Err("unexpected end of data (file truncated or counts too large)".into());
        }
        std::str::from_utf8(&d[start..self.pos]).map_err(|_| "non-ASCII data in an ascii PLY".to_string())
    }

    fn read(&mut self, ty: Ty) -> Result<f64, String> {
        if self.format == Format::Ascii {
            let t = self.token()?;
            return t.parse::<f64>().map_err(|_| format!("bad number \"{t}\""));
        }
        let n = ty.size();
        if self.remaining() < n {
            return Err("unexpected end of data (file truncated or counts too large)".into());
        }
        let b = &self.data[self.pos..self.pos + n];
        self.pos += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.format == Format::Be {
            a[..n].reverse();
        }
        Ok(match ty {
            Ty::I8 => a[0] as i8 as f64,
            Ty::U8 => a[0] as f64,
            Ty::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Ty::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Ty::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Ty::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Ty::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Ty::F64 => f64::from_le_bytes(a),
        })
    }

    fn read_count(&mut self, ty: Ty, item: Ty) -> Result<usize, String> {
        let c = self.read(ty)?;
        if !(c >= 0.0 && c.fract() == 0.0) {
            return Err(format!("bad list count {c}"));
        }
        let c = c as usize;
        let fits = if self.format == Format::Ascii {
            c.saturating_mul(2) <= self.remaining() + 1
        } else {
            c.saturating_mul(item.size()) <= self.remaining()
        };
        if !fits {
            return Err(format!("list of {c} items exceeds the remaining data"));
        }
        Ok(c)
    }

    fn skip(&mut self, kind: &PropKind) -> Result<(), String> {
        match *kind {
            PropKind::Scalar(ty) => self.read(ty).map(|_| ()),
            PropKind::List(ct, it) => {
                let c = self.read_count(ct, it)?;
                if self.format == Format::Ascii {
                    for _ in 0..c {
                        self.token()?;
                    }
                } else {
                    self.pos += c * it.size(); // checked by read_count
                }
                Ok(())
            }
        }
    }
}

fn min_size(format: Format, el: &Element) -> usize {
    el.props
        .iter()
        .map(|p| match (format, &p.kind) {
            (Format::Ascii, _) => 2,
            (_, PropKind::Scalar(t)) => t.size(),
            (_, PropKind::List(c, _)) => c.size(),
        })
        .sum()
}

/// Parses a PLY file held in memory.
pub fn parse_ply(bytes: &[u8]) -> Result<PlyData, String> {
    let h = parse_header(bytes)?;
    let data = &bytes[h.data_start..];
    // Early plausibility check of the counts against the data size.
    let mut need: u128 = 0;
    for el in &h.elements {
        need += el.count as u128 * min_size(h.format, el) as u128;
    }
    let slack = if h.format == Format::Ascii { 1 } else { 0 };
    if need > data.len() as u128 + slack {
        return Err(format!("the header announces at least {need} bytes of data but only {} are present", data.len()));
    }
    let vertex_count = h.elements.iter().find(|e| e.name == "vertex").map_or(0, |e| e.count);
    let face_count = h.elements.iter().find(|e| e.name == "face").map_or(0, |e| e.count);
    if vertex_count == 0 || face_count == 0 {
        return Err("no vertex or face elements found".into());
    }
    if vertex_count > u32::MAX as u64 {
        return Err("too many vertices".into());
    }
    let mut out = PlyData::default();
    let mut r = Reader { data, pos: 0, format: h.format };
    for el in &h.elements {
        let cap = |per: usize| (el.count as usize).min(r.remaining() / min_size(h.format, el).max(1) + 1) * per;
        if el.name == "vertex" {
            let find = |n: &str| -> Option<usize> {
                el.props.iter().position(|p| p.name == n && matches!(p.kind, PropKind::Scalar(_)))
            };
            let xyz = [find("x"), find("y"), find("z")];
            let [Some(x), Some(y), Some(z)] = xyz else {
                return Err("vertex coordinate properties x, y, z not found".into());
            };
            let nrm = match [find("nx"), find("ny"), find("nz")] {
                [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                _ => None,
            };
            let uv = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")]
                .iter()
                .find_map(|(a, b)| Some([find(a)?, find(b)?]));
            out.positions.reserve(cap(1));
            let mut normals = nrm.map(|_| Vec::with_capacity(cap(1)));
            let mut uvs = uv.map(|_| Vec::with_capacity(cap(1)));
            let mut vals = vec![0.0f64; el.props.len()];
            for _ in 0..el.count {
                for (i, p) in el.props.iter().enumerate() {
                    match p.kind {
                        PropKind::Scalar(ty) => vals[i] = r.read(ty)?,
                        ref k => r.skip(k)?,
                    }
                }
                let pt = [vals[x] as f32, vals[y] as f32, vals[z] as f32];
                if !pt.iter().all(|c| c.is_finite()) {
                    return Err(format!("vertex {} has a non-finite coordinate", out.positions.len()));
                }
                out.positions.push(pt);
                if let (Some(ns), Some([a, b, c])) = (normals.as_mut(), nrm) {
                    ns.push([vals[a] as f32, vals[b] as f32, vals[c] as f32]);
                }
                if let (Some(us), Some([a, b])) = (uvs.as_mut(), uv) {
                    us.push([vals[a] as f32, vals[b] as f32]);
                }
            }
            out.normals = normals;
            out.uvs = uvs;
        } else if el.name == "face" {
            let idx = el.props.iter().position(|p| {
                (p.name == "vertex_indices" || p.name == "vertex_index") && matches!(p.kind, PropKind::List(..))
            });
            let Some(idx) = idx else {
                return Err("face element has no \"vertex_indices\" list".into());
            };
            out.tris.reserve(cap(1));
            for _ in 0..el.count {
                for (i, p) in el.props.iter().enumerate() {
                    match p.kind {
                        PropKind::List(ct, it) if i == idx => {
                            let c = r.read_count(ct, it)?;
                            let mut f = [0u32; 4];
                            for k in 0..c {
                                let v = r.read(it)?;
                                if let Some(slot) = f.get_mut(k) {
                                    if !(v >= 0.0 && (v as u64) < vertex_count) {
                                        return Err(format!(
                                            "vertex reference {v} is out of bounds (valid range [0..{vertex_count}))"
                                        ));
                                    }
                                    *slot = v as u32;
                                }
                            }
                            match c {
                                3 => out.tris.push([f[0], f[1], f[2]]),
                                4 => {
                                    out.tris.push([f[0], f[1], f[2]]);
                                    out.tris.push([f[3], f[0], f[2]]);
                                }
                                _ => out.skipped_faces += 1,
                            }
                        }
                        ref k => r.skip(k)?,
                    }
                }
            }
        } else {
            for _ in 0..el.count {
                for p in &el.props {
                    r.skip(&p.kind)?;
                }
            }
        }
    }
    Ok(out)
}

pub(crate) fn build(desc: &ShapeDesc, ctx: &ShapeContext) -> Result<Option<ObjMesh>, Diagnostic> {
    let ps = &desc.entity.params;
    let name = ps.get_one_string("filename", "");
    if name.is_empty() {
        return Err(Diagnostic::error(Some(desc.entity.loc.clone()), "plymesh: no \"filename\" given"));
    }
    let path = ctx.resolve_path(&name);
    let loc = loc_or_entity(desc, "filename");
    let bytes = std::fs::read(&path)
        .map_err(|e| Diagnostic::error(loc.clone(), format!("couldn't read PLY file \"{}\": {e}", path.display())))?;
    let ply = parse_ply(&bytes)
        .map_err(|e| Diagnostic::error(loc.clone(), format!("PLY file \"{}\": {e}", path.display())))?;
    if ply.skipped_faces > 0 {
        ctx.warnings.warn(
            loc.clone(),
            format!(
                "PLY file \"{}\": ignored {} face(s) with other than 3 or 4 vertices",
                path.display(),
                ply.skipped_faces
            ),
        );
    }
    let alpha = read_alpha(desc, ctx, "alpha");
    let shadow_alpha = read_alpha(desc, ctx, "shadowalpha");
    let mut uv = ply.uvs;
    let normals = ply.normals.filter(|n| {
        let ok = n.iter().flatten().all(|c| c.is_finite());
        if !ok {
            ctx.warnings.warn(loc.clone(), format!("PLY file \"{}\": non-finite normals discarded", path.display()));
        }
        ok
    });
    if ps.get_one_bool("discarddegenerateUVs", false) && normals.is_some() {
        if let Some(u) = &uv {
            let p = &ply.positions;
            let degenerate = ply.tris.iter().any(|t| {
                let [a, b, c] = t.map(|i| glam::Vec3::from(p[i as usize]));
                let area = 0.5 * (a - b).cross(c - b).length();
                area >= 1e-7 && {
                    let [ua, ub, uc] = t.map(|i| u[i as usize]);
                    ua == ub || ub == uc || uc == ua
                }
            });
            if degenerate {
                ctx.warnings.warn(loc.clone(), "degenerate uv coordinates in triangle mesh; discarding all uv");
                uv = None;
            }
        }
    }
    Ok(Some(ObjMesh {
        p: ply.positions.iter().map(|v| v.map(|c| c as f64)).collect(),
        n: normals.map(|n| n.iter().map(|v| v.map(|c| c as f64)).collect()),
        s: None,
        uv,
        tris: ply.tris,
        alpha,
        shadow_alpha,
        quadric: None,
        surface_n: None,
    }))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::*;
    use super::super::*;
    use super::*;
    use crate::parser::ParamValue;
    use proptest::prelude::*;

    /// A quad (two triangles), a triangle, a pentagon (skipped); vertices with normals
    /// and uv, an extra scalar and list property, and an extra element in between.
    struct Sample;
    impl Sample {
        const P: [[f32; 3]; 5] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.], [2., 0., 0.]];
        fn header(format: &str, uv: (&str, &str)) -> String {
            format!(
                "ply\r\nformat {format} 1.0\ncomment made by a test\nelement vertex 5\nproperty float x\n\
                 property float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
                 property uchar red\nproperty list uchar int extra\nproperty float {}\nproperty float {}\n\
                 element material 2\nproperty list int double weights\nproperty short id\n\
                 element face 3\nproperty int flags\nproperty list uchar uint vertex_indices\nend_header\n",
                uv.0, uv.1
            )
        }
        fn ascii() -> Vec<u8> {
            let mut s = Self::header("ascii", ("u", "v"));
            for (i, p) in Self::P.iter().enumerate() {
                s += &format!("{} {} {} 0 0 1 255 2 7 8 {} {}\n", p[0], p[1], p[2], p[0] * 0.5, i as f32 * 0.25);
            }
            s += "3 0.5 1.5 2.5 7\n0 -3\n";
            s += "9 4 0 1 2 3\n1 3 1 4 2\n2 5 0 1 2 3 4\n";
            s.into_bytes()
        }
        fn binary(be: bool) -> Vec<u8> {
            let fmt = if be { "binary_big_endian" } else { "binary_little_endian" };
            let mut b = Self::header(fmt, ("texture_s", "texture_t")).into_bytes();
            macro_rules! put {
                ($v:expr) => {
                    if be {
                        b.extend_from_slice(&$v.to_be_bytes())
                    } else {
                        b.extend_from_slice(&$v.to_le_bytes())
                    }
                };
            }
            for (i, p) in Self::P.iter().enumerate() {
                for c in p {
                    put!(*c);
                }
                for c in [0f32, 0., 1.] {
                    put!(c);
                }
                b.push(255);
                b.push(2);
                put!(7i32);
                put!(8i32);
                put!(p[0] * 0.5);
                put!(i as f32 * 0.25);
            }
            put!(3i32);
            for w in [0.5f64, 1.5, 2.5] {
                put!(w);
            }
            put!(7i16);
            put!(0i32);
            put!(-3i16);
            for f in [&[0u32, 1, 2, 3][..], &[1, 4, 2], &[0, 1, 2, 3, 4]] {
                put!(9i32);
                b.push(f.len() as u8);
                for v in f {
                    put!(*v);
                }
            }
            b
        }
    }

    fn check(d: &PlyData) {
        assert_eq!(d.positions, Sample::P.to_vec());
        assert_eq!(d.tris, vec![[0, 1, 2], [3, 0, 2], [1, 4, 2]]);
        assert_eq!(d.skipped_faces, 1);
        assert_eq!(d.normals.as_ref().unwrap()[3], [0., 0., 1.]);
        assert_eq!(d.uvs.as_ref().unwrap()[4], [1.0, 1.0]);
    }

    #[test]
    fn reads_ascii_le_be() {
        check(&parse_ply(&Sample::ascii()).unwrap());
        check(&parse_ply(&Sample::binary(false)).unwrap());
        check(&parse_ply(&Sample::binary(true)).unwrap());
        // The other face property name, and s/t texture coordinates.
        let s = String::from_utf8(Sample::ascii()).unwrap();
        let s = s
            .replace("vertex_indices", "vertex_index")
            .replace("float u\n", "float s\n")
            .replace("float v\n", "float t\n");
        check(&parse_ply(s.as_bytes()).unwrap());
    }

    #[test]
    fn plymesh_shape_from_file() {
        let dir = temp_dir("ply");
        std::fs::write(dir.join("le.ply"), Sample::binary(false)).unwrap();
        let sink = DiagSink::new();
        let ctx = ShapeContext::new(&dir, &sink);
        let d = shape("plymesh", vec![("filename", ParamValue::String(vec!["le.ply".into()]))]);
        let m = build_shape(&d, &ctx).unwrap().unwrap();
        assert_eq!(m.triangle_count(), 3);
        assert!((m.total_area() - 1.5).abs() < 1e-6);
        assert!(m.normals.is_some() && m.uvs.is_some());
        assert_eq!(sink.len(), 1); // the pentagon
                                   // Missing file: error naming it.
        let d = shape("plymesh", vec![("filename", ParamValue::String(vec!["nope.ply".into()]))]);
        let e = build_shape(&d, &ctx).unwrap_err();
        assert!(e.message.contains("nope.ply"));
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn lying_headers_are_errors() {
        // Huge counts, no data: rejected before any allocation.
        let h = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n\
                 property float y\nproperty float z\nelement face 4000000000\nproperty list uchar int vertex_indices\nend_header\n";
        assert!(parse_ply(h.as_bytes()).unwrap_err().contains("announces"));
        // Truncated binary and ascii data.
        for full in [Sample::binary(false), Sample::binary(true), Sample::ascii()] {
            for cut in [full.len() - 3, full.len() - 9, full.len() / 2 + 17] {
                assert!(parse_ply(&full[..cut]).is_err(), "cut at {cut}");
            }
        }
        // A list count larger than the data.
        let mut b = Sample::binary(false);
        let n = b.len();
        b[n - 4 * 5 - 1] = 250; // the pentagon's count
        assert!(parse_ply(&b).is_err());
        // Out-of-range index.
        let s = String::from_utf8(Sample::ascii()).unwrap().replace("1 3 1 4 2", "1 3 1 5 2");
        assert!(parse_ply(s.as_bytes()).unwrap_err().contains("out of bounds"));
        // Missing pieces.
        assert!(parse_ply(b"ply\nformat ascii 1.0\nelement vertex 0\nend_header\n").is_err());
        assert!(parse_ply(b"plx\n").is_err());
        assert!(parse_ply(b"ply\nformat ascii 1.0\nelement vertex 1\n").is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
        #[test]
        fn random_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..400)) {
            let _ = parse_ply(&data);
        }

        #[test]
        fn random_data_after_a_valid_header_never_panics(
            which in 0usize..3,
            data in proptest::collection::vec(any::<u8>(), 0..300),
        ) {
            let fmt = ["ascii", "binary_little_endian", "binary_big_endian"][which];
            let mut b = Sample::header(fmt, ("u", "v")).into_bytes();
            b.extend_from_slice(&data);
            let _ = parse_ply(&b);
        }

        #[test]
        fn mutated_files_never_panic(which in 0usize..3, pos in any::<proptest::sample::Index>(), byte in any::<u8>()) {
            let mut b = match which { 0 => Sample::ascii(), 1 => Sample::binary(false), _ => Sample::binary(true) };
            let i = pos.index(b.len());
            b[i] = byte;
            let _ = parse_ply(&b);
        }
    }
}
