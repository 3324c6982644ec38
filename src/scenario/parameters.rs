//! `[parameters]`: named values and expressions of them, substituted into
//! the parsed document before the typed parse, so that every numeric field
//! takes them and errors keep their key paths.
//!
//! A parameter is a number or a string expression of other parameters
//! (`k = "4 * pi^2 * m"`, the grammar of `docs/expressions.md`, evaluated
//! with the symbolic engine's constant folding). After the overrides
//! (`--set parameters.k=…`) are applied, the pass
//!
//! - evaluates every parameter in dependency order (a cycle is an error
//!   naming the chain of keys),
//! - replaces every string value made only of parameters (`mass = "m"`,
//!   `point_i = ["-l/2", 0]`) by its number (an integer when the value is
//!   one, so that counts such as `segments` take it too),
//! - and inside the expressions of `type = "expression"` forces writes each
//!   parameter as its value in brackets (`"-k*crank.phi"` →
//!   `"-(1000)*crank.phi"`).
//!
//! Keys holding names or choices (`name`, `type`, `body`, `method`, …) are
//! never touched.

use codegen::{parse, Ctx};
use mbsolve_codegen as codegen;
use std::collections::{BTreeMap, HashMap};

/// Keys whose string values are names or choices, never parameter
/// expressions.
const TEXT_KEYS: &[&str] = &[
    "name",
    "description",
    "type",
    "body",
    "body_i",
    "body_j",
    "bodies",
    "joint",
    "force",
    "coordinate",
    "method",
    "formulation",
    "linear_solver",
    "evaluation",
    "format",
    "state",
    "key",
    "quantities",
    "independent",
    "correction",
    "rule",
    "kind",
    "file",
    "include",
    "index",
    "column",
    "reduce",
    "direction",
    "unit",
];

/// Keys of a `type = "expression"` force that hold expressions of t and
/// coordinates, and the `expression` of a `[[metric]]`: parameters are
/// substituted inside them.
const EXPRESSION_KEYS: &[&str] = &[
    "torque",
    "fx",
    "fy",
    "force",
    "expression",
    "actuator",
    "derivative",
];

/// Keys that hold expressions of t wherever they occur (a drive's
/// `motion`, a contact's `wall_motion` and `road`): parameters are substituted inside them.
const FUNCTION_KEYS: &[&str] = &["motion", "wall_motion", "road"];

/// Top-level keys and tables of a scenario: no parameter may be named
/// like one (`--param NAME=…` addresses a parameter by its bare name).
const RESERVED: &[&str] = &[
    "t",
    "name",
    "description",
    "gravity",
    "formulation",
    "linear_solver",
    "body",
    "joint",
    "force",
    "initial",
    "stabilization",
    "integrator",
    "time",
    "output",
    "rod",
    "chain",
    "constraints",
    "sensor",
    "parameters",
    "include",
    "repeat",
    "metric",
    "state",
];

/// What the pass did: the original text of each replaced value by key path
/// (to explain errors at those keys), and the names in strings that were
/// neither parameters nor anything else (for "unknown parameter" errors).
#[derive(Debug, Default)]
pub(super) struct Substituted {
    /// Key path → the string it held.
    pub(super) texts: HashMap<String, String>,
    /// Key path → the unknown plain names of its string.
    pub(super) unknown: HashMap<String, Vec<String>>,
    /// The parameter names, sorted (for messages).
    pub(super) names: Vec<String>,
    /// Copies made by `[[repeat]]`: (their key, e.g. `body[41]`; where
    /// they come from, e.g. `repeat[1].body[0] (i = 3)`).
    pub(super) origins: Vec<(String, String)>,
}

impl Substituted {
    /// `key` named after the template it was copied from, when it was.
    pub(super) fn rekey(&self, key: &str) -> String {
        for (at, origin) in &self.origins {
            if let Some(rest) = key.strip_prefix(at.as_str()) {
                if rest.is_empty() || rest.starts_with('.') || rest.starts_with('[') {
                    return format!("{origin}{rest}");
                }
            }
        }
        key.to_string()
    }

    /// An explanation to add to an error at `key`, if its value came from
    /// parameters or names an unknown one.
    pub(super) fn explain(&self, key: &str, message: &str) -> Option<String> {
        if let Some(u) = self.unknown.get(key) {
            if message.contains("invalid type: string") {
                let names = if self.names.is_empty() {
                    "the file has no [parameters]".to_string()
                } else {
                    format!("parameters: {}", self.names.join(", "))
                };
                return Some(format!(
                    "{message}: unknown parameter '{}' in \"{}\" ({names})",
                    u[0],
                    self.texts.get(key).map_or("", String::as_str)
                ));
            }
        }
        self.texts
            .get(key)
            .map(|t| format!("{message} (the value of \"{t}\")"))
    }
}

/// Is `s` a parameter name: a letter or `_`, then letters, digits, `_`?
pub(super) fn is_name(s: &str) -> bool {
    let mut c = s.chars();
    c.next()
        .is_some_and(|f| f.is_ascii_alphabetic() || f == '_')
        && c.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Evaluate `text` with the parameter values `values`; `Err` lists the
/// names that are not parameters (or gives the parse error).
pub(super) fn evaluate(
    text: &str,
    values: &HashMap<String, f64>,
) -> Result<f64, Result<Vec<String>, String>> {
    let mut ctx = Ctx::new();
    let mut unknown = Vec::new();
    let r = parse(&mut ctx, text, |n, c| match values.get(n) {
        Some(&v) => Some(c.constant(v)),
        None => {
            if !unknown.iter().any(|u| u == n) {
                unknown.push(n.to_string());
            }
            Some(c.var(n))
        }
    });
    match r {
        Err(e) => Err(Err(e.to_string())),
        Ok(_) if !unknown.is_empty() => Err(Ok(unknown)),
        Ok(e) => Ok(ctx.eval(&[e], &[])[0]),
    }
}

/// The names in `text` (the expression grammar's names, dotted ones
/// included), each with its byte range; numbers are skipped whole so that
/// the `e` of `1e3` is no name.
fn names_in(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_digit() || (c == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit)) {
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                let mut j = i + 1;
                if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                    j += 1;
                }
                if j < b.len() && b[j].is_ascii_digit() {
                    i = j;
                    while i < b.len() && b[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let s = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.') {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

/// `text` with every parameter name (not a function call) written as its
/// value in brackets; `None` when it names no parameter.
fn substitute(text: &str, values: &HashMap<String, f64>) -> Option<String> {
    let mut out = String::with_capacity(text.len());
    let mut last = 0;
    let mut any = false;
    for (s, e) in names_in(text) {
        let call = text[e..].trim_start().starts_with('(');
        if let Some(v) = values.get(&text[s..e]).filter(|_| !call) {
            out.push_str(&text[last..s]);
            out.push_str(&format!("({})", number_text(*v)));
            last = e;
            any = true;
        }
    }
    out.push_str(&text[last..]);
    any.then_some(out)
}

/// `v` as expression text that parses back to the same bits.
pub(super) fn number_text(v: f64) -> String {
    // `{:e}` is the shortest round-trip form and has no leading sign issue
    // for the parser (a minus is a unary minus in brackets)
    format!("{v:e}")
}

/// `v` as a TOML value: an integer when it is one (|v| < 2⁵³, not −0), so
/// that integer keys (`segments`) take it; a float otherwise.
fn toml_number(v: f64) -> toml::Value {
    if v.fract() == 0.0 && v.abs() < 9.0e15 && !(v == 0.0 && v.is_sign_negative()) {
        toml::Value::Integer(v as i64)
    } else {
        toml::Value::Float(v)
    }
}

/// Evaluate `[parameters]` of `doc` and substitute them everywhere (see the
/// module doc). The `[parameters]` table is removed. Errors: (key, message).
pub(super) fn apply(doc: &mut toml::Table) -> Result<Substituted, (String, String)> {
    let raw = match doc.remove("parameters") {
        None => toml::Table::new(),
        Some(toml::Value::Table(t)) => t,
        Some(v) => {
            return Err((
                "parameters".into(),
                format!(
                    "expected a table [parameters] of name = value, got {}",
                    v.type_str()
                ),
            ))
        }
    };
    let values = evaluate_all(&raw)?;
    let mut done = Substituted {
        names: {
            let mut n: Vec<String> = values.keys().cloned().collect();
            n.sort();
            n
        },
        ..Substituted::default()
    };
    for (k, v) in doc.iter_mut() {
        walk(v, k, k, false, &values, &mut done);
    }
    super::templates::expand_repeats(doc, &values, &mut done)?;
    Ok(done)
}

/// Every parameter's value, in dependency order; errors name the key.
fn evaluate_all(raw: &toml::Table) -> Result<HashMap<String, f64>, (String, String)> {
    let key = |n: &str| format!("parameters.{n}");
    let mut texts: BTreeMap<&str, &str> = BTreeMap::new();
    let mut values: HashMap<String, f64> = HashMap::new();
    for (n, v) in raw {
        if !is_name(n) {
            return Err((
                key(n),
                format!(
                    "'{n}' is not a parameter name (a letter or _, then letters, digits and _)"
                ),
            ));
        }
        if RESERVED.contains(&n.as_str()) {
            return Err((
                key(n),
                format!(
                    "'{n}' is reserved (t is time in expressions; top-level keys and tables \
                     cannot be parameter names)"
                ),
            ));
        }
        match v {
            toml::Value::Integer(i) => {
                values.insert(n.clone(), *i as f64);
            }
            toml::Value::Float(f) => {
                values.insert(n.clone(), *f);
            }
            toml::Value::String(s) => {
                texts.insert(n, s);
            }
            v => {
                return Err((
                    key(n),
                    format!(
                        "a parameter is a number or an expression string, got {}",
                        v.type_str()
                    ),
                ))
            }
        }
    }
    // depth-first evaluation; `path` is the chain being evaluated
    fn visit(
        n: &str,
        texts: &BTreeMap<&str, &str>,
        values: &mut HashMap<String, f64>,
        path: &mut Vec<String>,
    ) -> Result<(), (String, String)> {
        if values.contains_key(n) {
            return Ok(());
        }
        let key = format!("parameters.{n}");
        if let Some(at) = path.iter().position(|p| p == n) {
            let mut cycle: Vec<String> = path[at..].to_vec();
            cycle.push(n.to_string());
            return Err((
                format!("parameters.{}", path[at]),
                format!("cyclic definition: {}", cycle.join(" → ")),
            ));
        }
        let text = texts[n];
        path.push(n.to_string());
        for (s, e) in names_in(text) {
            let m = &text[s..e];
            if texts.contains_key(m) && !text[e..].trim_start().starts_with('(') {
                visit(m, texts, values, path)?;
            }
        }
        path.pop();
        let v = evaluate(text, values).map_err(|e| {
            let known: Vec<&str> = {
                let mut k: Vec<&str> = values
                    .keys()
                    .map(String::as_str)
                    .chain(texts.keys().copied())
                    .collect();
                k.sort();
                k.dedup();
                k
            };
            (
                key.clone(),
                match e {
                    Ok(unknown) => format!(
                        "unknown parameter '{}' in \"{text}\" (parameters: {})",
                        unknown[0],
                        known.join(", ")
                    ),
                    Err(parse) => format!("\"{text}\": {parse}"),
                },
            )
        })?;
        if !v.is_finite() {
            return Err((
                key,
                format!("\"{text}\" evaluates to {v}, not a finite number"),
            ));
        }
        values.insert(n.to_string(), v);
        Ok(())
    }
    for n in texts.keys() {
        visit(n, &texts, &mut values, &mut Vec::new())?;
    }
    Ok(values)
}

/// Substitute parameters in `v` at `path` (last key segment `key`);
/// `expression` is set inside a force element whose loads may be expressions
/// (`expression`, `joint_torque`, `joint_force`, and the functions of t of
/// `torque`, `force` and `spring`).
pub(super) fn walk(
    v: &mut toml::Value,
    path: &str,
    key: &str,
    expression: bool,
    values: &HashMap<String, f64>,
    done: &mut Substituted,
) {
    match v {
        toml::Value::Table(t) => {
            let expr = matches!(
                t.get("type").and_then(toml::Value::as_str),
                Some("expression" | "joint_torque" | "joint_force" | "torque" | "force" | "spring")
            ) || path.starts_with("metric[")
                || path.starts_with("state[");
            for (k, x) in t.iter_mut() {
                walk(x, &format!("{path}.{k}"), k, expr, values, done);
            }
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter_mut().enumerate() {
                walk(x, &format!("{path}[{i}]"), key, expression, values, done);
            }
        }
        toml::Value::String(s) => {
            if (expression && EXPRESSION_KEYS.contains(&key)) || FUNCTION_KEYS.contains(&key) {
                if let Some(n) = substitute(s, values) {
                    done.texts.insert(path.to_string(), s.clone());
                    *s = n;
                }
                return;
            }
            if TEXT_KEYS.contains(&key) {
                return;
            }
            match evaluate(s, values) {
                Ok(x) => {
                    let uses = names_in(s)
                        .iter()
                        .any(|&(a, b)| values.contains_key(&s[a..b]));
                    if uses {
                        done.texts.insert(path.to_string(), s.clone());
                        *v = toml_number(x);
                    }
                }
                Err(Ok(unknown)) => {
                    let plain: Vec<String> =
                        unknown.into_iter().filter(|u| !u.contains('.')).collect();
                    if !plain.is_empty() {
                        done.texts.insert(path.to_string(), s.clone());
                        done.unknown.insert(path.to_string(), plain);
                    }
                }
                Err(Err(_)) => {}
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_skip_numbers_and_keep_dots() {
        let t = "1e3*k + crank.phi - 2.5E-2*k_2";
        let n: Vec<&str> = names_in(t).iter().map(|&(a, b)| &t[a..b]).collect();
        assert_eq!(n, ["k", "crank.phi", "k_2"]);
    }

    #[test]
    fn substitution_keeps_calls_and_bits() {
        let v: HashMap<String, f64> = [("k".to_string(), 0.1), ("max".to_string(), 3.0)].into();
        let s = substitute("-k*max(k, x)", &v).unwrap();
        assert_eq!(s, "-(1e-1)*max((1e-1), x)");
        let back: f64 = number_text(0.1 + 0.2).parse().unwrap();
        assert_eq!(back.to_bits(), (0.1f64 + 0.2).to_bits());
    }
}
