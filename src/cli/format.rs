//! Number formats and the colour map of the reports (`diff`, `sweep`, `stability`).

// One JSON number format and one colour map for every report, `check`'s included (which lives
// in the library crate, so it owns them).
pub use crate::check::maps::viridis;
pub use crate::check::report::num;

/// Formats like C's `%.{prec}g` (and C++ streams' default): `prec` significant
/// digits, scientific notation when the exponent is < -4 or >= prec, trailing
/// zeros removed; "inf", "-inf", "nan" for non-finite values.
pub fn fmt_g(v: f64, prec: usize) -> String {
    if v.is_nan() {
        return "nan".into();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf".into() } else { "-inf".into() };
    }
    if v == 0.0 {
        return "0".into();
    }
    let prec = prec.max(1);
    // Exponent after rounding to `prec` significant digits.
    let sci = format!("{:.*e}", prec - 1, v);
    let (mant, exp) = sci.split_once('e').unwrap_or((&sci, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let strip = |m: &str| -> String {
        if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            m.to_string()
        }
    };
    if exp < -4 || exp >= prec as i32 {
        format!("{}e{}{:02}", strip(mant), if exp < 0 { '-' } else { '+' }, exp.abs())
    } else {
        let decimals = (prec as i32 - 1 - exp).max(0) as usize;
        strip(&format!("{:.*}", decimals, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fmt_g_matches_c() {
        assert_eq!(fmt_g(0.0333333333, 6), "0.0333333");
        assert_eq!(fmt_g(34.31363, 6), "34.3136");
        assert_eq!(fmt_g(1e-6, 6), "1e-06");
        assert_eq!(fmt_g(100.0, 3), "100");
        assert_eq!(fmt_g(0.0999999, 6), "0.0999999");
        assert_eq!(fmt_g(123456789.0, 6), "1.23457e+08");
        assert_eq!(fmt_g(0.0001, 6), "0.0001");
        assert_eq!(fmt_g(0.00001234, 6), "1.234e-05");
        assert_eq!(fmt_g(999999.5, 6), "1e+06");
        assert_eq!(fmt_g(-2.5, 6), "-2.5");
        assert_eq!(fmt_g(f64::INFINITY, 6), "inf");
        assert_eq!(fmt_g(6.25, 3), "6.25");
    }

    #[test]
    fn viridis_endpoints_and_monotone_luma() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(f64::NAN), [68, 1, 84]);
        let luma = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
        let mut prev = -1.0;
        for i in 0..=100 {
            let l = luma(viridis(i as f64 / 100.0));
            assert!(l > prev, "luma not increasing at {i}");
            prev = l;
        }
    }
}
