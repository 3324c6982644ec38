//! Templates and includes: `[[repeat]]` groups of elements copied with an
//! index, and `include = ["other.toml"]`, both expanded on the parsed
//! document before the typed parse (so every key of the copies is checked
//! as if written out).
//!
//! A `[[repeat]]` has `index` (the index's name, default `"i"`), `from`
//! and `to` (integers or parameter expressions, both included) and arrays
//! of tables `body`, `joint`, `force`, `sensor`, `chain`, `rod`, `metric`,
//! `state` — written
//! `[[repeat.body]]` etc. For each index value every table of the group is
//! copied with `{EXPR}` in its strings replaced by the value of EXPR (an
//! expression of the index and the parameters, `"crank{i+1}"`), and the
//! index usable like a parameter in its numeric fields (`x = "i*L"`). The
//! copies are appended after the file's own elements, repeat by repeat,
//! index by index.

use super::parameters::{evaluate, number_text, walk, Substituted};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The groups a `[[repeat]]` may hold.
const GROUPS: &[&str] = &[
    "body", "joint", "force", "sensor", "chain", "rod", "metric", "state",
];

/// Most copies of all `[[repeat]]`s of a scenario (10⁶, as many as
/// [`super::limits::MAX_BODIES`]).
pub(crate) const MAX_COPIES: usize = 1_000_000;

/// `text` with every `{EXPR}` replaced by the value of EXPR under `values`
/// (an integer when it is one); errors name the expression.
fn braces(text: &str, values: &HashMap<String, f64>) -> Result<String, String> {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let close = rest[open..]
            .find('}')
            .ok_or_else(|| format!("\"{text}\": '{{' without a closing '}}'"))?;
        let expr = &rest[open + 1..open + close];
        let v = evaluate(expr, values).map_err(|e| match e {
            Ok(unknown) => format!(
                "\"{text}\": unknown name '{}' in {{{expr}}} (the index and the parameters)",
                unknown[0]
            ),
            Err(m) => format!("\"{text}\": {{{expr}}}: {m}"),
        })?;
        if v.fract() == 0.0 && v.abs() < 9.0e15 {
            out.push_str(&format!("{}", v as i64));
        } else {
            out.push_str(&number_text(v));
        }
        rest = &rest[open + close + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// Replace `{EXPR}` in every string of `v` (key path `path` for errors).
fn brace_all(
    v: &mut toml::Value,
    path: &str,
    values: &HashMap<String, f64>,
) -> Result<(), (String, String)> {
    match v {
        toml::Value::String(s) if s.contains('{') => {
            *s = braces(s, values).map_err(|m| (path.to_string(), m))?;
        }
        toml::Value::Table(t) => {
            for (k, x) in t.iter_mut() {
                brace_all(x, &format!("{path}.{k}"), values)?;
            }
        }
        toml::Value::Array(a) => {
            for (i, x) in a.iter_mut().enumerate() {
                brace_all(x, &format!("{path}[{i}]"), values)?;
            }
        }
        _ => {}
    }
    Ok(())
}

/// An integer bound `from`/`to` of repeat `r`.
fn bound(
    rep: &toml::Table,
    r: usize,
    k: &str,
    values: &HashMap<String, f64>,
) -> Result<i64, (String, String)> {
    let key = format!("repeat[{r}].{k}");
    let v = match rep.get(k) {
        Some(toml::Value::Integer(i)) => *i as f64,
        Some(toml::Value::Float(f)) => *f,
        Some(toml::Value::String(s)) => evaluate(s, values).map_err(|e| {
            (
                key.clone(),
                match e {
                    Ok(u) => format!("unknown parameter '{}' in \"{s}\"", u[0]),
                    Err(m) => format!("\"{s}\": {m}"),
                },
            )
        })?,
        Some(v) => return Err((key, format!("expected an integer, got {}", v.type_str()))),
        None => return Err((key, "missing: a repeat needs from and to".into())),
    };
    if v.fract() != 0.0 || v.abs() > 1e15 {
        return Err((key, format!("{v} is not an integer")));
    }
    Ok(v as i64)
}

/// Expand the `[[repeat]]`s of `doc` (module doc) with the parameter
/// values `values`; records in `done` where each copy came from.
pub(super) fn expand_repeats(
    doc: &mut toml::Table,
    values: &HashMap<String, f64>,
    done: &mut Substituted,
) -> Result<(), (String, String)> {
    let reps = match doc.remove("repeat") {
        None => return Ok(()),
        Some(toml::Value::Array(a)) => a,
        Some(_) => {
            return Err((
                "repeat".into(),
                "expected [[repeat]] tables (an array of tables)".into(),
            ))
        }
    };
    let mut copies = 0usize;
    for (r, rep) in reps.into_iter().enumerate() {
        let toml::Value::Table(rep) = rep else {
            return Err((format!("repeat[{r}]"), "expected a table".into()));
        };
        let index = match rep.get("index") {
            None => "i".to_string(),
            Some(toml::Value::String(s)) if super::parameters::is_name(s) => s.clone(),
            Some(v) => {
                return Err((
                    format!("repeat[{r}].index"),
                    format!("{v} is not a name (a letter or _, then letters, digits and _)"),
                ))
            }
        };
        if values.contains_key(&index) {
            return Err((
                format!("repeat[{r}].index"),
                format!("'{index}' is a parameter: name the index differently"),
            ));
        }
        for k in rep.keys() {
            if !(["index", "from", "to"].contains(&k.as_str()) || GROUPS.contains(&k.as_str())) {
                return Err((
                    format!("repeat[{r}].{k}"),
                    format!(
                        "unknown key: a repeat takes index, from, to and arrays of {}",
                        GROUPS.join(", ")
                    ),
                ));
            }
        }
        let (from, to) = (
            bound(&rep, r, "from", values)?,
            bound(&rep, r, "to", values)?,
        );
        if to < from {
            return Err((
                format!("repeat[{r}].to"),
                format!("{to} < from = {from}: the range is empty"),
            ));
        }
        let n = (to - from + 1) as usize;
        copies = copies.saturating_add(n);
        if copies > MAX_COPIES {
            return Err((
                format!("repeat[{r}].to"),
                format!("more than {MAX_COPIES} copies in all repeats"),
            ));
        }
        let mut vals = values.clone();
        for i in from..=to {
            vals.insert(index.clone(), i as f64);
            for g in GROUPS {
                let Some(items) = rep.get(*g) else { continue };
                let items = items.as_array().ok_or_else(|| {
                    (
                        format!("repeat[{r}].{g}"),
                        format!("expected [[repeat.{g}]] tables"),
                    )
                })?;
                let target = doc
                    .entry(g.to_string())
                    .or_insert_with(|| toml::Value::Array(Vec::new()));
                let Some(target) = target.as_array_mut() else {
                    return Err((
                        g.to_string(),
                        format!("'{g}' is not an array of [[{g}]] tables (a repeat adds to it)"),
                    ));
                };
                for (j, item) in items.iter().enumerate() {
                    let origin = format!("repeat[{r}].{g}[{j}]");
                    let mut item = item.clone();
                    brace_all(&mut item, &origin, &vals)?;
                    let at = format!("{g}[{}]", target.len());
                    walk(&mut item, &at, g, false, &vals, done);
                    done.origins.push((at, format!("{origin} ({index} = {i})")));
                    target.push(item);
                }
            }
        }
    }
    Ok(())
}

/// Merge the files named by `include = [...]` of `doc` (relative to the
/// directory of `path`, recursively) into `doc`: their arrays of tables
/// come before the file's own elements, their tables and keys are
/// overridden key by key by the file's. `stack` holds the files being
/// included (a cycle is an error naming them).
pub(super) fn includes(
    doc: &mut toml::Table,
    path: &Path,
    stack: &mut Vec<PathBuf>,
) -> Result<(), (String, String, String)> {
    let file = path.display().to_string();
    let names = match doc.remove("include") {
        None => return Ok(()),
        Some(toml::Value::Array(a)) => a,
        Some(toml::Value::String(s)) => vec![toml::Value::String(s)],
        Some(v) => {
            return Err((
                file,
                "include".into(),
                format!("expected an array of file names, got {}", v.type_str()),
            ))
        }
    };
    let me = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    stack.push(me);
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut merged = toml::Table::new();
    for (k, n) in names.iter().enumerate() {
        let key = format!("include[{k}]");
        let Some(n) = n.as_str() else {
            return Err((file, key, format!("{n} is not a file name")));
        };
        let p = dir.join(n);
        let canon = p.canonicalize().unwrap_or_else(|_| p.clone());
        if let Some(at) = stack.iter().position(|s| *s == canon) {
            let chain: Vec<String> = stack[at..]
                .iter()
                .map(|s| s.display().to_string())
                .chain([canon.display().to_string()])
                .collect();
            return Err((
                file,
                key,
                format!("\"{n}\" includes itself: {}", chain.join(" → ")),
            ));
        }
        let text = std::fs::read_to_string(&p).map_err(|e| {
            (
                file.clone(),
                key.clone(),
                format!("cannot read \"{}\": {e}", p.display()),
            )
        })?;
        let mut sub: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            (
                p.display().to_string(),
                "-".to_string(),
                e.message().trim().to_string(),
            )
        })?;
        includes(&mut sub, &p, stack)?;
        merge(&mut merged, sub);
    }
    stack.pop();
    let own = std::mem::take(doc);
    merge(&mut merged, own);
    *doc = merged;
    Ok(())
}

/// Merge `b` into `a`: arrays of tables are concatenated (a's first),
/// tables merged key by key, other values of `b` replace those of `a`.
fn merge(a: &mut toml::Table, b: toml::Table) {
    for (k, v) in b {
        match (a.get_mut(&k), v) {
            (Some(toml::Value::Table(x)), toml::Value::Table(y)) => merge(x, y),
            (Some(toml::Value::Array(x)), toml::Value::Array(y))
                if x.iter().chain(&y).all(toml::Value::is_table) =>
            {
                x.extend(y)
            }
            (_, v) => {
                a.insert(k, v);
            }
        }
    }
}
