//! Canonical JSON as defined by RFC 8785 (JSON Canonicalization Scheme, JCS).
//!
//! Release ids are hashes of manifest bytes, so the bytes must not depend on the writer:
//! object members are sorted by their UTF-16 code units, there is no insignificant
//! whitespace, strings use the minimal JCS escapes, and numbers use the ECMAScript
//! shortest round-trip form (`1.5`, `1e-7`, `1e+21`). Integers outside ±2^53 are not
//! representable exactly in ECMAScript and are rejected by [`check`].

use serde::Serialize;
use serde_json::{Number, Value};

use crate::FormatError;

/// Serialises a JSON value canonically.
pub fn to_string(v: &Value) -> String {
    let mut out = String::new();
    write_value(v, &mut out);
    out
}

/// Serialises any `Serialize` value canonically (through `serde_json::Value`).
pub fn to_vec<T: Serialize>(v: &T) -> Result<Vec<u8>, FormatError> {
    let value = serde_json::to_value(v).map_err(|e| FormatError::InvalidJson {
        what: "canonical JSON input",
        message: e.to_string(),
    })?;
    check(&value)?;
    Ok(to_string(&value).into_bytes())
}

/// Rejects values that JCS cannot represent exactly (integers beyond ±2^53).
pub fn check(v: &Value) -> Result<(), FormatError> {
    const MAX_SAFE: u64 = (1 << 53) - 1;
    match v {
        Value::Number(n) => {
            let ok = if let Some(u) = n.as_u64() {
                u <= MAX_SAFE
            } else if let Some(i) = n.as_i64() {
                i.unsigned_abs() <= MAX_SAFE
            } else {
                n.as_f64().is_some_and(f64::is_finite)
            };
            if ok {
                Ok(())
            } else {
                Err(FormatError::InvalidJson {
                    what: "canonical JSON input",
                    message: format!("number {n} is not exactly representable (|n| > 2^53)"),
                })
            }
        }
        Value::Array(a) => a.iter().try_for_each(check),
        Value::Object(o) => o.values().try_for_each(check),
        _ => Ok(()),
    }
}

fn write_value(v: &Value, out: &mut String) {
    match v {
        Value::Null => out.push_str("null"),
        Value::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
        Value::Number(n) => write_number(n, out),
        Value::String(s) => write_string(s, out),
        Value::Array(a) => {
            out.push('[');
            for (i, x) in a.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_value(x, out);
            }
            out.push(']');
        }
        Value::Object(o) => {
            let mut keys: Vec<&String> = o.keys().collect();
            keys.sort_by(|a, b| a.encode_utf16().cmp(b.encode_utf16()));
            out.push('{');
            for (i, k) in keys.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                write_string(k, out);
                out.push(':');
                if let Some(x) = o.get(*k) {
                    write_value(x, out);
                }
            }
            out.push('}');
        }
    }
}

fn write_string(s: &str, out: &mut String) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\u{8}' => out.push_str("\\b"),
            '\t' => out.push_str("\\t"),
            '\n' => out.push_str("\\n"),
            '\u{c}' => out.push_str("\\f"),
            '\r' => out.push_str("\\r"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
}

fn write_number(n: &Number, out: &mut String) {
    if let Some(u) = n.as_u64() {
        out.push_str(&u.to_string());
    } else if let Some(i) = n.as_i64() {
        out.push_str(&i.to_string());
    } else if let Some(f) = n.as_f64() {
        out.push_str(&format_f64(f));
    }
}

/// Formats a finite `f64` as ECMAScript's `Number.prototype.toString` does (RFC 8785 §3.2.2.3).
pub fn format_f64(f: f64) -> String {
    if f == 0.0 || !f.is_finite() {
        return "0".to_string();
    }
    // Rust's `{:e}` gives the shortest round-trip digits: "d.ddddde[-]x".
    let s = format!("{:e}", f.abs());
    let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
    let k = digits.len() as i32;
    let n = exp + 1; // position of the decimal point relative to the digit string
    let mut out = String::new();
    if f < 0.0 {
        out.push('-');
    }
    if k <= n && n <= 21 {
        out.push_str(&digits);
        out.extend(std::iter::repeat_n('0', (n - k) as usize));
    } else if 0 < n && n <= 21 {
        let (a, b) = digits.split_at(n as usize);
        out.push_str(a);
        out.push('.');
        out.push_str(b);
    } else if -6 < n && n <= 0 {
        out.push_str("0.");
        out.extend(std::iter::repeat_n('0', (-n) as usize));
        out.push_str(&digits);
    } else {
        let e = n - 1;
        let sign = if e < 0 { '-' } else { '+' };
        let (a, b) = digits.split_at(1);
        out.push_str(a);
        if !b.is_empty() {
            out.push('.');
            out.push_str(b);
        }
        out.push('e');
        out.push(sign);
        out.push_str(&e.abs().to_string());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn ecmascript_number_forms() {
        let cases = [
            (1.5, "1.5"),
            (100.0, "100"),
            (1e21, "1e+21"),
            (1e20, "100000000000000000000"),
            (1e-7, "1e-7"),
            (0.000001, "0.000001"),
            (-0.015, "-0.015"),
            (123456.789, "123456.789"),
            (5e-324, "5e-324"),
            (1.7976931348623157e308, "1.7976931348623157e+308"),
            (0.1 + 0.2, "0.30000000000000004"),
        ];
        for (f, s) in cases {
            assert_eq!(format_f64(f), s, "{f:?}");
        }
    }

    #[test]
    fn rfc8785_example_sorting_and_escapes() {
        let v: Value = serde_json::from_str(
            r#"{"\ufb33":5,"\u20ac":1,"\r":2,"\ud83d\ude00":3,"1":4,"a\u0001":"x\u001f\"y"}"#,
        )
        .unwrap();
        assert_eq!(
            to_string(&v),
            "{\"\\r\":2,\"1\":4,\"a\\u0001\":\"x\\u001f\\\"y\",\"\u{20ac}\":1,\"\u{1f600}\":3,\"\u{fb33}\":5}"
        );
    }

    #[test]
    fn rejects_unsafe_integers() {
        assert!(check(&serde_json::json!({"a": 9007199254740993u64})).is_err());
        assert!(check(&serde_json::json!({"a": 9007199254740991u64})).is_ok());
    }

    proptest! {
        #[test]
        fn numbers_round_trip(f in proptest::num::f64::NORMAL | proptest::num::f64::SUBNORMAL) {
            let s = format_f64(f);
            let back: f64 = s.parse().unwrap();
            prop_assert_eq!(back.to_bits(), f.to_bits());
        }

        #[test]
        fn canonical_is_idempotent(m in proptest::collection::btree_map("[a-zA-Z0-9_\u{80}-\u{10ffff}]{0,6}", -1e9f64..1e9, 0..8)) {
            let v = serde_json::to_value(&m).unwrap();
            let once = to_string(&v);
            let reparsed: Value = serde_json::from_str(&once).unwrap();
            prop_assert_eq!(to_string(&reparsed), once);
        }
    }
}
