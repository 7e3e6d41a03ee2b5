//! Expressions of the `fredholm` kind (`"x^2 + x*y"`), parsed once by `exmex` into a flat
//! expression and evaluated without heap allocation.

use exmex::{Express, FlatEx};

/// A parsed expression in the variables `x` and (for kernels) `y`.
#[derive(Clone)]
pub(crate) struct Expr {
    text: String,
    /// Boxed: exmex keeps its nodes in large inline arrays.
    flat: Box<FlatEx<f64>>,
    /// For each variable of `flat` in its order: 0 for `x`, 1 for `y`.
    slots: [usize; 2],
    arity: usize,
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub(crate) struct ExprError(pub(super) String);

const FUNCTIONS: &[&str] = &["sin", "cos", "tan", "exp", "ln", "sqrt", "abs"];

impl Expr {
    /// Parses `text`, allowing only the variables in `vars` (`["x"]` or `["x", "y"]`).
    pub(super) fn parse(text: &str, vars: &[&str]) -> Result<Expr, ExprError> {
        let normalized = normalize(text, vars)?;
        let flat = exmex::parse::<f64>(&normalized)
            .map_err(|e| ExprError(format!("cannot parse `{text}`: {}", e.msg())))?;
        let mut slots = [0; 2];
        let names = flat.var_names();
        for (k, name) in names.iter().enumerate() {
            match vars.iter().position(|v| v == name) {
                Some(p) => slots[k] = p,
                None => {
                    return Err(ExprError(format!(
                        "unknown name `{name}`; the variables here are {}",
                        vars.join(", ")
                    )))
                }
            }
        }
        let e = Expr {
            text: text.to_string(),
            arity: names.len(),
            flat: Box::new(flat),
            slots,
        };
        // Evaluate once so that an expression that cannot be evaluated fails here, not in a solve.
        e.try_eval(0.5, 0.5)?;
        Ok(e)
    }

    fn try_eval(&self, x: f64, y: f64) -> Result<f64, ExprError> {
        let xy = [x, y];
        let vars = [xy[self.slots[0]], xy[self.slots[1]]];
        self.flat
            .eval(&vars[..self.arity])
            .map_err(|e| ExprError(e.msg().to_string()))
    }

    /// The value at (x, y); NaN if the expression cannot be evaluated there.
    #[inline]
    pub(crate) fn eval(&self, x: f64, y: f64) -> f64 {
        self.try_eval(x, y).unwrap_or(f64::NAN)
    }
}

/// Checks the identifiers against the spec's grammar (numbers, `x`, `y`, `pi`, `+ - * / ^`,
/// parentheses and a few functions) and rewrites `pi` into exmex's `PI`.
fn normalize(text: &str, vars: &[&str]) -> Result<String, ExprError> {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        if c.is_ascii_alphabetic() || c == '_' {
            let mut end = i + c.len_utf8();
            while let Some(&(j, d)) = chars.peek() {
                if d.is_ascii_alphanumeric() || d == '_' {
                    end = j + d.len_utf8();
                    chars.next();
                } else {
                    break;
                }
            }
            let word = &text[i..end];
            if word == "pi" {
                out.push_str("PI");
            } else if vars.contains(&word) || FUNCTIONS.contains(&word) {
                out.push_str(word);
            } else {
                return Err(ExprError(format!(
                    "unknown name `{word}`; allowed are {}, pi and the functions {}",
                    vars.join(", "),
                    FUNCTIONS.join(", ")
                )));
            }
        } else if c.is_ascii_digit() || c == '.' {
            // A number literal, with an optional exponent (1e-3), written out in plain decimal
            // notation, which is what exmex reads.
            let rest = &text[i..];
            let mut len = rest
                .find(|d: char| !(d.is_ascii_digit() || d == '.'))
                .unwrap_or(rest.len());
            let tail = &rest[len..];
            if tail.starts_with(['e', 'E']) {
                let exp = &tail[1..];
                let sign = usize::from(exp.starts_with(['+', '-']));
                let digits = exp[sign..]
                    .find(|d: char| !d.is_ascii_digit())
                    .unwrap_or(exp.len() - sign);
                if digits > 0 {
                    len += 1 + sign + digits;
                }
            }
            let literal = &rest[..len];
            let value: f64 = literal
                .parse()
                .map_err(|_| ExprError(format!("`{literal}` is not a number")))?;
            if !value.is_finite() {
                return Err(ExprError(format!("`{literal}` is out of range")));
            }
            out.push_str(&format!("{value}"));
            while let Some(&(j, _)) = chars.peek() {
                if j < i + len {
                    chars.next();
                } else {
                    break;
                }
            }
        } else if "+-*/^() \t\n".contains(c) {
            out.push(c);
        } else {
            return Err(ExprError(format!("unexpected character `{c}`")));
        }
    }
    if out.trim().is_empty() {
        return Err(ExprError("empty expression".into()));
    }
    Ok(out)
}

impl std::fmt::Debug for Expr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Expr({:?})", self.text)
    }
}

impl PartialEq for Expr {
    fn eq(&self, other: &Self) -> bool {
        self.text == other.text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evaluates_the_spec_grammar() {
        let k = Expr::parse("x^2 + x*y", &["x", "y"]).unwrap();
        assert_eq!(k.eval(0.5, 2.0), 0.25 + 1.0);
        let e = Expr::parse("sin(pi*x) + ln(exp(2)) + sqrt(abs(-4)) + 1e-1", &["x"]).unwrap();
        assert!((e.eval(0.5, 0.0) - (1.0 + 2.0 + 2.0 + 0.1)).abs() < 1e-14);
        let only_y = Expr::parse("y", &["x", "y"]).unwrap();
        assert_eq!(only_y.eval(1.0, 3.0), 3.0);
        let constant = Expr::parse("1", &["x"]).unwrap();
        assert_eq!(constant.eval(7.0, 0.0), 1.0);
    }

    #[test]
    fn refuses_unknown_names_and_bad_syntax() {
        assert!(Expr::parse("x + z", &["x", "y"]).is_err());
        assert!(Expr::parse("y", &["x"]).is_err());
        assert!(Expr::parse("x +* (", &["x"]).is_err());
        assert!(Expr::parse("", &["x"]).is_err());
        assert!(Expr::parse("x; 2", &["x"]).is_err());
    }
}
