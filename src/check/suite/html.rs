//! The suite's self-contained HTML report: a summary table, then per case the test,
//! reference and difference images, the p-value map, the failing mask and the signed-error
//! map side by side (PNG data URIs: no external assets, works offline), and the gate's numbers.

use super::junit::escape;
use super::{status_word, CaseResult, Status};

/// Standard base64 (RFC 4648, with padding).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

const STYLE: &str = "body{font-family:sans-serif;margin:1em;background:#fafafa}\
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}\
.PASS{color:#060}.FAIL{color:#b00;font-weight:bold}.ERROR{color:#b60;font-weight:bold}\
figure{display:inline-block;margin:4px;text-align:center}\
img{width:192px;image-rendering:pixelated;border:1px solid #999}\
pre{background:#eee;padding:6px;white-space:pre-wrap}";

fn figure(caption: &str, png: &[u8]) -> String {
    format!(
        "<figure><img alt=\"{caption}\" src=\"data:image/png;base64,{}\"><figcaption>{caption}</figcaption></figure>",
        base64(png)
    )
}

pub fn report(suite: &str, results: &[CaseResult]) -> String {
    let count = |s: Status| results.iter().filter(|r| r.status == s).count();
    let mut h = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>penumbra check: {0}</title><style>{STYLE}</style></head><body>\n<h1>penumbra check: {0}</h1>\n<p>{1} passed, {2} failed, {3} could not run, of {4}.</p>\n<table><tr><th>case</th><th>result</th><th>seconds</th><th>summary</th></tr>\n",
        escape(suite),
        count(Status::Pass),
        count(Status::Fail),
        count(Status::Error),
        results.len()
    );
    for r in results {
        let w = status_word(r.status);
        h += &format!(
            "<tr><td><a href=\"#{0}\">{0}</a></td><td class=\"{w}\">{w}</td><td>{1:.1}</td><td>{2}</td></tr>\n",
            escape(&r.name),
            r.seconds,
            escape(&r.summary)
        );
    }
    h += "</table>\n";
    for r in results {
        let w = status_word(r.status);
        h += &format!("<h2 id=\"{0}\">{0} <span class=\"{w}\">{w}</span></h2>\n", escape(&r.name));
        if let Some(i) = &r.images {
            for (caption, png) in [
                ("test", &i.test),
                ("reference", &i.reference),
                ("|difference| (max = white)", &i.difference),
                ("p-value (-log10, viridis)", &i.pvalue),
                ("failing values (white) and blocks (red)", &i.mask),
                ("signed error / noise (red brighter, blue darker, ±4)", &i.error),
            ] {
                if !png.is_empty() {
                    h += &figure(caption, png);
                }
            }
            h += "\n";
        }
        h += &format!("<pre>{}</pre>\n", escape(&r.detail));
    }
    h += "</body></html>\n";
    h
}

#[cfg(test)]
mod tests {
    use super::base64;

    #[test]
    fn base64_matches_rfc4648() {
        // RFC 4648 section 10's test vectors.
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }
}
