//! Number tokens: floats through `fast-float2`, integers with a digit fast path.

/// A 32-bit float; non-finite results (overflow, `inf`, `nan`) are errors.
#[inline]
pub(crate) fn parse_f32(tok: &[u8]) -> Result<f32, String> {
    match fast_float2::parse::<f32, _>(tok) {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(non_finite(tok, "32-bit float")),
        Err(_) => Err(not_a_number(tok)),
    }
}

/// A 64-bit float (transform arguments); non-finite results are errors.
pub(crate) fn parse_f64(tok: &[u8]) -> Result<f64, String> {
    match fast_float2::parse::<f64, _>(tok) {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(non_finite(tok, "64-bit float")),
        Err(_) => Err(not_a_number(tok)),
    }
}

/// A 32-bit integer. Like pbrt-v3, an integral value written as a float (`2.0`, `1e3`)
/// is accepted; a fractional value or one beyond the i32 range is an error.
#[inline]
pub(crate) fn parse_i32(tok: &[u8]) -> Result<i32, String> {
    let (neg, digits) = match tok.first() {
        Some(b'-') => (true, &tok[1..]),
        Some(b'+') => (false, &tok[1..]),
        _ => (false, tok),
    };
    // Up to 9 digits cannot overflow: one pass, no checks.
    if !digits.is_empty() && digits.len() <= 9 {
        let mut v: i32 = 0;
        let mut ok = true;
        for &c in digits {
            let d = c.wrapping_sub(b'0');
            ok &= d <= 9;
            v = v.wrapping_mul(10).wrapping_add(d as i32);
        }
        if ok {
            return Ok(if neg { -v } else { v });
        }
    }
    if !digits.is_empty() && digits.iter().all(u8::is_ascii_digit) {
        let mut v: i64 = 0;
        for &d in digits {
            v = v * 10 + (d - b'0') as i64;
            if v > i32::MAX as i64 + 1 {
                return Err(out_of_range(tok));
            }
        }
        let v = if neg { -v } else { v };
        return i32::try_from(v).map_err(|_| out_of_range(tok));
    }
    match fast_float2::parse::<f64, _>(tok) {
        Ok(v) if !v.is_finite() => Err(out_of_range(tok)),
        Ok(v) if v.fract() != 0.0 => Err(format!("expected an integer, found \"{}\"", show(tok))),
        Ok(v) if v < i32::MIN as f64 || v > i32::MAX as f64 => Err(out_of_range(tok)),
        Ok(v) => Ok(v as i32),
        Err(_) => Err(not_a_number(tok)),
    }
}

/// Whether a bare token looks like the start of a number (used to tell values from directives).
pub(crate) fn looks_numeric(tok: &[u8]) -> bool {
    matches!(tok.first(), Some(b'0'..=b'9' | b'-' | b'+' | b'.'))
}

pub(crate) fn show(tok: &[u8]) -> String {
    let s = crate::diag::escape_lossy(tok);
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s
    }
}

fn not_a_number(tok: &[u8]) -> String {
    format!("expected a number, found \"{}\"", show(tok))
}

fn out_of_range(tok: &[u8]) -> String {
    format!("number \"{}\" is out of range for a 32-bit integer", show(tok))
}

fn non_finite(tok: &[u8], what: &str) -> String {
    if tok.iter().any(|c| c.is_ascii_alphabetic() && !matches!(c, b'e' | b'E')) {
        format!("\"{}\" is not a finite number", show(tok))
    } else {
        format!("number \"{}\" is out of range for a {what}", show(tok))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pbrt_number_forms() {
        assert_eq!(parse_f32(b"-5e-51").unwrap(), 0.0);
        assert!(parse_f32(b"-5e-51").unwrap().is_sign_negative());
        assert_eq!(parse_f32(b".5").unwrap(), 0.5);
        assert_eq!(parse_f32(b"+1").unwrap(), 1.0);
        assert_eq!(parse_f32(b"1.").unwrap(), 1.0);
        assert_eq!(parse_f32(b"1e+3").unwrap(), 1000.0);
        assert_eq!(parse_f32(b"0.1").unwrap(), 0.1f32);
        assert!(parse_f32(b"1e999").unwrap_err().contains("out of range"));
        assert!(parse_f32(b"1e39").unwrap_err().contains("out of range"));
        assert!(parse_f64(b"1e39").is_ok());
        assert!(parse_f32(b"inf").unwrap_err().contains("finite"));
        assert!(parse_f32(b"nan").unwrap_err().contains("finite"));
        assert!(parse_f32(b"1x").unwrap_err().contains("expected a number"));
        assert!(parse_f32(b"WorldBegin").is_err());
    }

    #[test]
    fn integers() {
        assert_eq!(parse_i32(b"42").unwrap(), 42);
        assert_eq!(parse_i32(b"-2147483648").unwrap(), i32::MIN);
        assert_eq!(parse_i32(b"+7").unwrap(), 7);
        assert_eq!(parse_i32(b"2.0").unwrap(), 2);
        assert_eq!(parse_i32(b"1e3").unwrap(), 1000);
        assert_eq!(parse_i32(b"0000000000000000012").unwrap(), 12);
        assert!(parse_i32(b"2147483648").unwrap_err().contains("out of range"));
        assert!(parse_i32(b"99999999999999999999").unwrap_err().contains("out of range"));
        assert!(parse_i32(b"1.5").unwrap_err().contains("expected an integer"));
        assert!(parse_i32(b"1e999").unwrap_err().contains("out of range"));
        assert!(parse_i32(b"-").is_err());
        assert!(parse_i32(b"abc").is_err());
    }
}
