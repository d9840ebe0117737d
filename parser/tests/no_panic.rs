//! Random bytes and mutated corpus scenes never make the parser panic.

use proptest::prelude::*;
use std::path::{Path, PathBuf};

fn corpus() -> Vec<(PathBuf, Vec<u8>)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/suite");
    let mut out = vec![];
    let mut stack = vec![root];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else { continue };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "pbrt") {
                if let Ok(b) = std::fs::read(&p) {
                    out.push((p, b));
                }
            }
        }
    }
    out.sort();
    out
}

#[derive(Debug, Clone)]
enum Mutation {
    Flip(usize, u8),
    Truncate(usize),
    Duplicate(usize, usize, usize),
    Delete(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Mutation::Flip(i, b)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), 0usize..200, any::<usize>()).prop_map(|(a, n, at)| Mutation::Duplicate(a, n, at)),
        (any::<usize>(), 0usize..50).prop_map(|(a, n)| Mutation::Delete(a, n)),
    ]
}

fn apply(mut b: Vec<u8>, m: &Mutation) -> Vec<u8> {
    if b.is_empty() {
        return b;
    }
    let n = b.len();
    match *m {
        Mutation::Flip(i, v) => b[i % n] = v,
        Mutation::Truncate(i) => b.truncate(i % n),
        Mutation::Duplicate(a, len, at) => {
            let a = a % n;
            let chunk = b[a..(a + len).min(n)].to_vec();
            let at = at % n;
            b.splice(at..at, chunk);
        }
        Mutation::Delete(a, len) => {
            let a = a % n;
            b.drain(a..(a + len).min(n));
        }
    }
    b
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_bytes_do_not_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = penumbra_parser::parse_str(&text, "random.pbrt", None);
    }

    #[test]
    fn token_soup_does_not_panic(toks in proptest::collection::vec(prop_oneof![
        Just("WorldBegin"), Just("WorldEnd"), Just("AttributeBegin"), Just("AttributeEnd"), Just("Shape"),
        Just("\"sphere\""), Just("\"float radius\""), Just("\"rgb Kd\""), Just("["), Just("]"), Just("1"),
        Just("-5e-51"), Just("\"true\""), Just("ObjectBegin"), Just("ObjectEnd"), Just("ObjectInstance"),
        Just("\"a\""), Just("Material"), Just("NamedMaterial"), Just("MakeNamedMaterial"), Just("\"string type\""),
        Just("Texture"), Just("\"float\""), Just("\"texture Kd\""), Just("TransformBegin"), Just("TransformEnd"),
        Just("Translate"), Just("Scale"), Just("0"), Just("LookAt"), Just("Camera"), Just("# c\n"), Just("\"x"),
        Just("ActiveTransform"), Just("EndTime"), Just("CoordinateSystem"), Just("CoordSysTransform"),
        Just("AreaLightSource"), Just("Include"), Just("1e999"), Just("Option"),
    ], 0..60)) {
        let text = toks.join(" ");
        let _ = penumbra_parser::parse_str(&text, "soup.pbrt", None);
    }

    #[test]
    fn mutated_corpus_does_not_panic(which in any::<usize>(), ms in proptest::collection::vec(mutation(), 1..4)) {
        let files = corpus();
        prop_assume!(!files.is_empty());
        let (path, bytes) = &files[which % files.len()];
        let mut b = bytes.clone();
        for m in &ms {
            b = apply(b, m);
        }
        let text = String::from_utf8_lossy(&b);
        let _ = penumbra_parser::parse_str(&text, "mutated.pbrt", path.parent());
    }
}
