//! A small walker over a `serde_json::Value` that collects every error with its JSON pointer.
//!
//! Written by hand because serde's derive stops at the first error and reports line/column, while
//! the contract asks for every error of a document at once, each named by its JSON path.

use super::FieldError;
use serde_json::{Map, Value};

/// JSON pointer of a child: `/scene` + `surfaces` → `/scene/surfaces` (RFC 6901 escaping).
pub(super) fn child(path: &str, key: &str) -> String {
    format!("{path}/{}", key.replace('~', "~0").replace('/', "~1"))
}

pub(super) fn index(path: &str, i: usize) -> String {
    format!("{path}/{i}")
}

#[derive(Default)]
pub(super) struct Walker {
    pub(super) errors: Vec<FieldError>,
}

impl Walker {
    pub(super) fn error(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.errors.push(FieldError {
            path: path.into(),
            message: message.into(),
        });
    }

    /// An object whose fields are all in `allowed`; every other field is an error.
    pub(super) fn object<'v>(
        &mut self,
        v: &'v Value,
        path: &str,
        allowed: &[&str],
    ) -> Option<&'v Map<String, Value>> {
        let Some(map) = v.as_object() else {
            self.error(path, format!("expected an object, found {}", kind_of(v)));
            return None;
        };
        for key in map.keys() {
            if !allowed.contains(&key.as_str()) {
                self.error(
                    child(path, key),
                    format!(
                        "unknown field `{key}`; expected one of: {}",
                        allowed.join(", ")
                    ),
                );
            }
        }
        Some(map)
    }

    /// A required field: an error when absent.
    pub(super) fn required<'v>(
        &mut self,
        map: &'v Map<String, Value>,
        path: &str,
        key: &str,
    ) -> Option<&'v Value> {
        let v = map.get(key);
        if v.is_none() {
            self.error(child(path, key), format!("missing required field `{key}`"));
        }
        v
    }

    /// A finite number.
    fn number(&mut self, v: &Value, path: &str) -> Option<f64> {
        match v.as_f64() {
            Some(x) if x.is_finite() => Some(x),
            // numbers are kept as written, so a JSON number beyond f64 (1e999) reaches here
            // as a number that does not read as a finite f64
            Some(_) => {
                self.error(path, "expected a finite number");
                None
            }
            None if v.is_number() => {
                self.error(
                    path,
                    format!("{v} is not a finite number (beyond ±1.8e308)"),
                );
                None
            }
            None => {
                self.error(path, format!("expected a number, found {}", kind_of(v)));
                None
            }
        }
    }

    /// A number checked against a predicate, with `what` describing the allowed range.
    pub(super) fn number_in(
        &mut self,
        v: &Value,
        path: &str,
        ok: impl Fn(f64) -> bool,
        what: &str,
    ) -> Option<f64> {
        let x = self.number(v, path)?;
        if ok(x) {
            Some(x)
        } else {
            self.error(path, format!("{x} is out of range: {what}"));
            None
        }
    }

    /// A non-negative integer in `lo..=hi`.
    pub(super) fn integer(&mut self, v: &Value, path: &str, lo: u64, hi: u64) -> Option<usize> {
        let Some(n) = v.as_u64().or_else(|| {
            // Accept 16.0 as 16, refuse 16.5.
            v.as_f64()
                .filter(|x| x.fract() == 0.0 && *x >= 0.0 && *x < 9.0e15)
                .map(|x| x as u64)
        }) else {
            self.error(
                path,
                format!("expected a whole number, found {}", describe(v)),
            );
            return None;
        };
        if n < lo || n > hi {
            self.error(
                path,
                format!("{n} is out of range: must be from {lo} to {hi}"),
            );
            return None;
        }
        usize::try_from(n).ok()
    }

    pub(super) fn boolean(&mut self, v: &Value, path: &str) -> Option<bool> {
        let b = v.as_bool();
        if b.is_none() {
            self.error(
                path,
                format!("expected true or false, found {}", kind_of(v)),
            );
        }
        b
    }

    pub(super) fn string<'v>(&mut self, v: &'v Value, path: &str) -> Option<&'v str> {
        let s = v.as_str();
        if s.is_none() {
            self.error(path, format!("expected a string, found {}", kind_of(v)));
        }
        s
    }

    /// An array of `N` coordinates, each within ±1e12 (beyond that, squared distances overflow).
    pub(super) fn coordinates<const N: usize>(
        &mut self,
        v: &Value,
        path: &str,
    ) -> Option<[f64; N]> {
        let c = self.numbers::<N>(v, path)?;
        for (i, x) in c.iter().enumerate() {
            if x.abs() > 1e12 {
                self.error(
                    index(path, i),
                    format!("{x} is out of range: coordinates are within ±1e12"),
                );
                return None;
            }
        }
        Some(c)
    }

    /// An array of exactly `n` finite numbers.
    pub(super) fn numbers<const N: usize>(&mut self, v: &Value, path: &str) -> Option<[f64; N]> {
        let arr = self.array_len(v, path, N)?;
        let mut out = [0.0; N];
        let mut ok = true;
        for (i, x) in arr.iter().enumerate() {
            match self.number(x, &index(path, i)) {
                Some(x) => out[i] = x,
                None => ok = false,
            }
        }
        ok.then_some(out)
    }

    pub(super) fn array_len<'v>(
        &mut self,
        v: &'v Value,
        path: &str,
        n: usize,
    ) -> Option<&'v [Value]> {
        let Some(arr) = v.as_array() else {
            self.error(
                path,
                format!("expected an array of {n}, found {}", kind_of(v)),
            );
            return None;
        };
        if arr.len() != n {
            self.error(path, format!("expected {n} elements, found {}", arr.len()));
            return None;
        }
        Some(arr)
    }

    /// One of the given strings.
    pub(super) fn choice<'c>(
        &mut self,
        v: &Value,
        path: &str,
        choices: &[&'c str],
    ) -> Option<&'c str> {
        let s = self.string(v, path)?;
        let found = choices.iter().find(|c| **c == s).copied();
        if found.is_none() {
            let list: Vec<String> = choices.iter().map(|c| format!("\"{c}\"")).collect();
            self.error(path, format!("\"{s}\" is not one of {}", list.join(", ")));
        }
        found
    }
}

fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn describe(v: &Value) -> String {
    match v {
        Value::Number(n) => n.to_string(),
        _ => kind_of(v).to_string(),
    }
}
