//! A composed variant as WGSL text, for WebGPU in a browser (wgpu's `webgpu` backend hands
//! the browser WGSL, not a naga module) and for checking the shaders with Chromium's compiler,
//! Tint (`tests/tint.rs`).
//!
//! naga writes an f32 literal as Rust prints the f32: the shortest decimal that reads back to
//! it, e.g. `340282350000000000000000000000000000000f` for f32::MAX. naga reads such a decimal
//! straight to the nearest f32. Tint reads it to an f64 first, rejects it where that f64 lies
//! beyond the f32 range (`value cannot be represented as 'f32'`, gfx-rs/wgpu#10106: f32::MAX's
//! shortest decimal is just above f32::MAX, and Tint rejects every composed variant on it),
//! and otherwise rounds the f64 to f32, a second rounding that can land one ULP from naga's.
//! So every f32 literal whose decimal is not exactly an f64 equal to its f32 is written here
//! as the exact hexadecimal float (`0x1.fffffep127f`), which both compilers read to the same
//! bits; the others (`0.5f`, `3f`) stay as naga wrote them. This is the shaders' own rule for
//! shared values ([`crate::shared`]: floats as exact hexadecimal literals), restored after
//! naga's writer. Integer literals need nothing: naga writes `i32::MIN` as `i32(-2147483648)`,
//! and Tint takes `4294967295u`.

use super::{Program, ShaderError, compose, validate};
use crate::shaders::FeatureKey;
use crate::shared::hex_float;

/// `program` composed for `key`, validated, and written as WGSL that naga and Tint both
/// accept and read alike ([`exact_f32_literals`]).
pub fn wgsl(program: Program, key: FeatureKey) -> Result<String, ShaderError> {
    let module = compose(program, key)?;
    let info = validate(program, key, &module)?;
    write_wgsl(program, key, &module, &info)
}

/// `module` (the variant of `program` for `key`, validated into `info`) as WGSL, its f32
/// literals exact ([`exact_f32_literals`]).
pub fn write_wgsl(
    program: Program,
    key: FeatureKey,
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
) -> Result<String, ShaderError> {
    let text = naga::back::wgsl::write_string(module, info, naga::back::wgsl::WriterFlags::empty())
        .map_err(|e| ShaderError::Write { program, key: key.label(), message: e.to_string() })?;
    Ok(exact_f32_literals(&text))
}

/// `text` (WGSL) with every decimal f32 literal (suffix `f`) that Tint could read otherwise
/// than naga written as the exact hexadecimal float of the f32 naga reads: those whose
/// decimal value, read as an f64, is not that f32. Works on tokens: identifiers (`vec3f`,
/// `_e340f`), comments, hexadecimal and integer literals and other suffixes pass unchanged.
pub fn exact_f32_literals(text: &str) -> String {
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut copied = 0; // bytes of `text` before this are in `out`
    let mut i = 0;
    let word = |b: u8| b.is_ascii_alphanumeric() || b == b'_' || b >= 0x80;
    let digits_from = |mut j: usize| {
        while j < bytes.len() && bytes[j].is_ascii_digit() {
            j += 1;
        }
        j
    };
    while i < bytes.len() {
        let b = bytes[i];
        if text[i..].starts_with("//") {
            i = text[i..].find('\n').map_or(bytes.len(), |n| i + n);
        } else if text[i..].starts_with("/*") {
            // WGSL block comments nest.
            let mut depth = 0;
            while i < bytes.len() {
                if text[i..].starts_with("/*") {
                    depth += 1;
                    i += 2;
                } else if text[i..].starts_with("*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if b.is_ascii_digit() || (b == b'.' && bytes.get(i + 1).is_some_and(u8::is_ascii_digit)) {
            let start = i;
            if text[i..].starts_with("0x") || text[i..].starts_with("0X") {
                // Hexadecimal: exact already. Its digits, point, exponent and suffix.
                i += 2;
                while i < bytes.len() && (bytes[i].is_ascii_hexdigit() || bytes[i] == b'.') {
                    i += 1;
                }
                if i < bytes.len() && matches!(bytes[i], b'p' | b'P') {
                    i += 1;
                    if i < bytes.len() && matches!(bytes[i], b'+' | b'-') {
                        i += 1;
                    }
                }
                while i < bytes.len() && word(bytes[i]) {
                    i += 1;
                }
                continue;
            }
            i = digits_from(i);
            if i < bytes.len() && bytes[i] == b'.' {
                i = digits_from(i + 1);
            }
            if i < bytes.len() && matches!(bytes[i], b'e' | b'E') {
                let sign = usize::from(bytes.get(i + 1).is_some_and(|&s| s == b'+' || s == b'-'));
                if bytes.get(i + 1 + sign).is_some_and(u8::is_ascii_digit) {
                    i = digits_from(i + 1 + sign);
                }
            }
            let body = &text[start..i];
            let suffix_start = i;
            while i < bytes.len() && word(bytes[i]) {
                i += 1;
            }
            if &text[suffix_start..i] == "f"
                && let Some(exact) = exact_spelling(body)
            {
                out.push_str(&text[copied..start]);
                out.push_str(&exact);
                copied = i;
            }
        } else if word(b) {
            while i < bytes.len() && word(bytes[i]) {
                i += 1;
            }
        } else {
            i += 1;
        }
    }
    out.push_str(&text[copied..]);
    out
}

/// The hexadecimal spelling of the decimal f32 literal `body` (without its suffix) where
/// Tint's reading (an f64, then f32) could differ from naga's (the nearest f32): where the
/// decimal's f64 is not the f32 itself. `None` where the decimal is exact, or not finite.
fn exact_spelling(body: &str) -> Option<String> {
    let as_f32: f32 = body.parse().ok()?;
    let as_f64: f64 = body.parse().ok()?;
    (as_f32.is_finite() && f64::from(as_f32) != as_f64).then(|| hex_float(as_f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tint's reading of a decimal f32 literal's digits (the WGSL lexer): an f64, refused
    /// where it lies beyond the f32 range, else rounded to f32. Hexadecimal floats are read
    /// exactly, as here.
    fn tint_reads(body: &str) -> Result<f32, String> {
        if let Some(hex) = body.strip_prefix("0x") {
            let (mantissa, exp) = hex.split_once('p').unwrap();
            let (int, frac) = mantissa.split_once('.').unwrap_or((mantissa, ""));
            let digits = u64::from_str_radix(&format!("{int}{frac}"), 16).unwrap();
            let value = digits as f64 * 2f64.powi(exp.parse::<i32>().unwrap() - 4 * frac.len() as i32);
            return Ok(value as f32);
        }
        let v: f64 = body.parse().unwrap();
        if v.abs() > f64::from(f32::MAX) {
            Err(format!("{body}: value cannot be represented as 'f32'"))
        } else {
            Ok(v as f32)
        }
    }

    #[test]
    fn f32_max_and_inexact_decimals_become_exact_hexadecimal_floats() {
        let cases = [
            ("const M: f32 = 340282350000000000000000000000000000000f;", "const M: f32 = 0x1.fffffep127f;"),
            ("x = -340282350000000000000000000000000000000f;", "x = -0x1.fffffep127f;"),
            ("vec3<f32>(0.1f, 0.5f, 3f)", "vec3<f32>(0x1.99999ap-4f, 0.5f, 3f)"),
            ("0.000000000000000000000000000000000000011754944f", "0x1.000000p-126f"),
            ("0.000000000000000000000000000000000000000000001f", "0x0.000002p-126f"),
            ("(1.5e-3f)", "(0x1.89374cp-10f)"),
            ("1e5f+2.5E+1f", "1e5f+2.5E+1f"),
        ];
        for (text, want) in cases {
            assert_eq!(exact_f32_literals(text), want, "{text}");
        }
    }

    #[test]
    fn identifiers_comments_integers_hexadecimals_and_other_suffixes_pass_unchanged() {
        let text = "let a = vec3f(1f); let _e340282350000000000000000000000000000000f = x1f; \
                    // 0.1f in a comment\n/* 0.1f /* nested 0.1f */ 0.1f */ 4294967295u i32(-2147483648) 2147483647i \
                    0x1.99999ap-4f 0X1P4f 0x10u 7li 7lu 0.1lf 0.1h 0.1 a.x 1.f";
        assert_eq!(exact_f32_literals(text), text);
        assert_eq!(exact_f32_literals(""), "");
        assert_eq!(exact_f32_literals("0.1f"), "0x1.99999ap-4f");
        assert_eq!(exact_f32_literals("é 0.1f"), "é 0x1.99999ap-4f");
    }

    /// For f32 values across the range (every exponent, random mantissas, the extremes and
    /// subnormals), naga's spelling after the rewrite is read by Tint's rule and by naga's
    /// (the nearest f32) to the same f32, and Tint accepts it; f32::MAX's own spelling is
    /// refused by Tint's rule, as Chromium does.
    #[test]
    fn every_rewritten_literal_reads_back_to_its_f32_in_both_compilers() {
        assert!(tint_reads(&f32::MAX.to_string()).is_err(), "the rule models Tint's refusal");
        let mut state = 0x9e37_79b9_u32;
        let mut values = vec![f32::MAX, f32::MIN_POSITIVE, f32::from_bits(1), f32::from_bits(0x7f_ffff), 0.1, 1.0];
        for exp in 0..255u32 {
            for _ in 0..64 {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                values.push(f32::from_bits(exp << 23 | state >> 9));
            }
        }
        for v in values {
            let naga = format!("{v}f");
            let written = exact_f32_literals(&naga);
            let body = written.strip_suffix('f').unwrap();
            assert_eq!(tint_reads(body), Ok(v), "{naga} written {written}");
            if !body.starts_with("0x") {
                assert_eq!(body.parse::<f32>(), Ok(v), "{naga}");
            }
        }
    }
}
