#![no_main]
//! `cargo +nightly fuzz run parse`: arbitrary bytes into the pbrt-v3 parser.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = penumbra_parser::parse_str(&text, "fuzz.pbrt", None);
});
