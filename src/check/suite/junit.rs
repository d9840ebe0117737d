//! The suite's results as JUnit XML: one `<testcase>` per case, a failing gate as
//! `<failure>`, a case that could not run as `<error>`. It follows the Ant JUnit schema that
//! CI services read (`junit-4.xsd`: every attribute and element that schema requires is
//! written, `timestamp` as an ISO 8601 date-time without zone, in UTC).

use super::{CaseResult, Status};
use std::time::{SystemTime, UNIX_EPOCH};

/// Escapes text for XML attributes and content (and drops the characters XML 1.0 forbids).
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' | '\n' | '\r' => out.push(c),
            c if (c as u32) < 0x20 || c == '\u{fffe}' || c == '\u{ffff}' => out.push('\u{fffd}'),
            c => out.push(c),
        }
    }
    out
}

/// Now as `YYYY-MM-DDTHH:MM:SS` (UTC).
pub fn timestamp() -> String {
    iso8601(SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0))
}

/// Seconds since 1970 as `YYYY-MM-DDTHH:MM:SS` (UTC).
pub fn iso8601(secs: u64) -> String {
    let (days, rem) = ((secs / 86400) as i64, secs % 86400);
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}", rem / 3600, rem % 3600 / 60, rem % 60)
}

pub fn xml(suite: &str, results: &[CaseResult]) -> String {
    let count = |s: Status| results.iter().filter(|r| r.status == s).count();
    let time: f64 = results.iter().map(|r| r.seconds).sum();
    let suite = escape(suite);
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n");
    x += &format!(
        "  <testsuite name=\"{suite}\" package=\"penumbra.check\" id=\"0\" tests=\"{}\" failures=\"{}\" errors=\"{}\" time=\"{time:.3}\" timestamp=\"{}\" hostname=\"localhost\">\n    <properties/>\n",
        results.len(),
        count(Status::Fail),
        count(Status::Error),
        timestamp()
    );
    for r in results {
        x += &format!(
            "    <testcase name=\"{}\" classname=\"penumbra.check.{suite}\" time=\"{:.3}\"",
            escape(&r.name),
            r.seconds
        );
        let (tag, kind) = match r.status {
            Status::Pass => {
                x += "/>\n";
                continue;
            }
            Status::Fail => ("failure", "gate"),
            Status::Error => ("error", "could-not-run"),
        };
        x += &format!(
            ">\n      <{tag} message=\"{}\" type=\"{kind}\">{}</{tag}>\n    </testcase>\n",
            escape(&r.summary),
            escape(&r.detail)
        );
    }
    x += "    <system-out/>\n    <system-err/>\n  </testsuite>\n</testsuites>\n";
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::suite::{CaseResult, Status};

    fn case(name: &str, status: Status, summary: &str) -> CaseResult {
        CaseResult {
            name: name.into(),
            status,
            summary: summary.into(),
            detail: "d<1>".into(),
            seconds: 0.5,
            images: None,
        }
    }

    #[test]
    fn dates_and_counts() {
        assert_eq!(iso8601(0), "1970-01-01T00:00:00");
        assert_eq!(iso8601(951_782_400), "2000-02-29T00:00:00");
        assert_eq!(iso8601(1_796_256_000 + 3661), "2026-12-03T01:01:01");
        let x = xml(
            "s",
            &[case("a", Status::Pass, ""), case("b", Status::Fail, "p < 1e-3 & \"x\""), case("c", Status::Error, "no")],
        );
        assert!(x.contains("tests=\"3\" failures=\"1\" errors=\"1\" time=\"1.500\""), "{x}");
        assert!(
            x.contains("<failure message=\"p &lt; 1e-3 &amp; &quot;x&quot;\" type=\"gate\">d&lt;1&gt;</failure>"),
            "{x}"
        );
        assert!(x.contains("<error message=\"no\" type=\"could-not-run\">"), "{x}");
        assert_eq!(x.matches("<testcase ").count(), 3);
        assert_eq!(escape("a\u{1}b"), "a\u{fffd}b");
    }
}
