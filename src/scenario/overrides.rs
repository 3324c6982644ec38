//! Command-line overrides of a scenario: `--set KEY=VALUE`, `--param`,
//! `--unset KEY`; elements addressed by name (`force[shock].damping`); the
//! keys of another method dropped when an override chose the method; and
//! the attribution of an error to the override that wrote its key.

use super::*;

/// A `KEY=VALUE` override of a scenario key and the command-line flag it
/// came from (`--set`, `--param`), which labels its errors; with the flag
/// `--unset` the spec is a bare `KEY`, removed from the file.
#[derive(Debug, Clone, Copy)]
pub struct Override<'a> {
    /// The flag, e.g. `--param`.
    pub flag: &'a str,
    /// `KEY=VALUE`.
    pub spec: &'a str,
}

/// `--set` overrides.
pub(super) fn set_overrides(specs: &[String]) -> Vec<Override<'_>> {
    specs
        .iter()
        .map(|spec| Override {
            flag: "--set",
            spec,
        })
        .collect()
}

/// The overrides of a command line: the `--unset` keys, then the `--set`
/// `KEY=VALUE`s.
pub fn overrides<'a>(unset: &'a [String], set: &'a [String]) -> Vec<Override<'a>> {
    unset
        .iter()
        .map(|spec| Override { flag: UNSET, spec })
        .chain(set_overrides(set))
        .collect()
}

/// The flag of an override that removes a key.
pub const UNSET: &str = "--unset";

/// When an override chose the method: remove the file's keys that do not
/// apply to it (by the method table, [`crate::integrate::METHODS`]: the
/// `[integrator]` keys, Baumgarte's `stabilization.alpha`/`beta` for the
/// index-3 methods, a `formulation` of the other equations), except those
/// an override wrote (still errors); one note per removed key.
pub(super) fn foreign_keys(
    doc: &mut toml::Table,
    set_keys: &[(&str, String)],
    file: &str,
) -> Vec<String> {
    use crate::integrate::{Family, Method};
    let by_override = |k: &str| set_keys.iter().any(|(f, s)| *f != UNSET && s == k);
    let integrator = doc.get("integrator").and_then(toml::Value::as_table);
    let Some(name) = integrator
        .and_then(|t| t.get("method"))
        .and_then(toml::Value::as_str)
        .map(str::to_string)
    else {
        return Vec::new();
    };
    let trapezoidal = name.trim().eq_ignore_ascii_case("trapezoidal");
    let auto = name.trim().eq_ignore_ascii_case(run::AUTO);
    let method: Method = if trapezoidal {
        Method::Newmark
    } else if auto {
        Method::Ode45 // its step-control keys are auto's
    } else {
        match name.parse() {
            Ok(m) => m,
            Err(_) => return Vec::new(), // the typed parse names it
        }
    };
    let adaptive = integrator
        .and_then(|t| t.get("adaptive"))
        .and_then(toml::Value::as_bool)
        .unwrap_or(false);
    let row = method.info();
    let mut drop: Vec<String> = Vec::new();
    if let Some(t) = integrator {
        for k in t.keys() {
            let applies = k == "method"
                || k == "threads"
                || (row.takes(k, adaptive) && !(trapezoidal && k == "rho_inf"));
            if !applies && !by_override(&format!("integrator.{k}")) {
                // only keys some method takes: an unknown key stays an error
                if crate::integrate::METHODS
                    .iter()
                    .any(|m| m.key_use(k).is_some())
                {
                    drop.push(format!("integrator.{k}"));
                }
            }
        }
    }
    if method.is_index3() || auto {
        if let Some(st) = doc.get("stabilization").and_then(toml::Value::as_table) {
            let keys: Vec<&str> = if auto {
                st.keys().map(String::as_str).collect()
            } else {
                vec!["alpha", "beta"]
            };
            for k in keys {
                let key = format!("stabilization.{k}");
                if st.contains_key(k) && !by_override(&key) {
                    drop.push(key);
                }
            }
        }
    }
    if let Some(f) = doc.get("formulation").and_then(toml::Value::as_str) {
        let alpha = method.family() == Family::GeneralizedAlpha;
        let fits = match f {
            "augmented_lagrangian" => alpha && !auto,
            "saddle" => true,
            _ => !method.is_index3() && !auto,
        };
        if !fits && !by_override("formulation") {
            drop.push("formulation".into());
        }
    }
    let mut notes = Vec::new();
    for key in drop {
        let (table, k) = key
            .split_once('.')
            .map_or((None, key.as_str()), |(t, k)| (Some(t), k));
        let removed = match table {
            Some(t) => doc
                .get_mut(t)
                .and_then(toml::Value::as_table_mut)
                .and_then(|t| t.remove(k)),
            None => doc.remove(k),
        };
        if let Some(v) = removed {
            let v = match v {
                toml::Value::Float(f) => format!("{f:e}"),
                v => v.to_string(),
            };
            notes.push(format!(
                "{file}: {key} = {v} dropped: it does not apply to integrator.method = \"{name}\" \
                 chosen by an override"
            ));
        }
    }
    notes
}

/// Remove `key` (dotted, with `name[k]` indices as in [`apply_override`])
/// from the document; it must exist. Returns the key.
pub(super) fn unset(doc: &mut toml::Table, key: &str) -> Result<String, String> {
    let key = key.trim();
    if key.contains('=') {
        return Err("--unset takes a KEY, not KEY=VALUE".into());
    }
    let key = &named_indices(doc, key)?;
    let parts = key_parts(key)?;
    let missing = || format!("'{}' is not set", escape(key));
    let mut table = doc;
    let (last, intermediate) = parts.split_last().expect("a key has a segment");
    for &(p, index) in intermediate {
        let v = table.get_mut(p).ok_or_else(missing)?;
        let v = match index {
            None => v,
            Some(k) => v
                .as_array_mut()
                .and_then(|a| a.get_mut(k))
                .ok_or_else(missing)?,
        };
        table = v.as_table_mut().ok_or_else(missing)?;
    }
    match last.1 {
        None => table.remove(last.0).map(|_| ()).ok_or_else(missing)?,
        Some(k) => {
            let a = table
                .get_mut(last.0)
                .and_then(toml::Value::as_array_mut)
                .filter(|a| k < a.len())
                .ok_or_else(missing)?;
            a.remove(k);
        }
    }
    Ok(key.to_string())
}

/// The origin of an error at `key`: the file, or the file and the override
/// (`--set`, `--param`) that wrote the key (or a table or key below it).
pub(super) fn attribute(file: &str, key: &str, set_keys: &[(&str, String)]) -> String {
    let below =
        |a: &str, b: &str| a.starts_with(&format!("{b}.")) || a.starts_with(&format!("{b}["));
    let related = |k: &String| key == k || below(key, k) || below(k, key);
    match set_keys.iter().find(|(_, k)| related(k)) {
        Some((flag, k)) => format!("{file} ({flag} {k})"),
        None => file.to_string(),
    }
}

/// `key` with every element addressed by name (`force[shock].damping`:
/// the `[[force]]` whose `name = "shock"`) written with its 0-based index
/// (`force[1].damping`); an unknown name lists the names there are.
fn named_indices(doc: &toml::Table, key: &str) -> Result<String, String> {
    // the segments, split at the dots outside brackets
    let mut segments = Vec::new();
    let (mut depth, mut start) = (0usize, 0);
    for (i, c) in key.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth = depth.saturating_sub(1),
            '.' if depth == 0 => {
                segments.push(&key[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    segments.push(&key[start..]);
    let mut table = Some(doc);
    let mut out = Vec::with_capacity(segments.len());
    for seg in segments {
        let Some((name, rest)) = seg.split_once('[') else {
            table = table
                .and_then(|t| t.get(seg))
                .and_then(toml::Value::as_table);
            out.push(seg.to_string());
            continue;
        };
        let inner = rest.strip_suffix(']').unwrap_or(rest);
        let array = table
            .and_then(|t| t.get(name))
            .and_then(toml::Value::as_array);
        let named = |v: &toml::Value| {
            v.get("name")
                .and_then(toml::Value::as_str)
                .map(str::to_string)
        };
        let index = if inner.is_empty() || inner.chars().all(|c| c.is_ascii_digit()) {
            // positional (checked by key_parts)
            inner.parse::<usize>().ok()
        } else {
            let wanted = inner.trim_matches('"');
            let Some(a) = array else {
                return Err(format!(
                    "key '{}': there are no [[{}]] elements to find '{}' among",
                    escape(key),
                    escape(name),
                    escape(wanted)
                ));
            };
            let k = a
                .iter()
                .position(|v| named(v).as_deref() == Some(wanted))
                .ok_or_else(|| {
                    let names: Vec<String> = a
                        .iter()
                        .enumerate()
                        .map(|(k, v)| named(v).unwrap_or_else(|| format!("[{k}] unnamed")))
                        .collect();
                    format!(
                        "key '{}': no [[{}]] named '{}' (names: {})",
                        escape(key),
                        escape(name),
                        escape(wanted),
                        escape(&names.join(", "))
                    )
                })?;
            out.push(format!("{name}[{k}]"));
            table = a[k].as_table();
            continue;
        };
        out.push(seg.to_string());
        table = index
            .and_then(|k| array.and_then(|a| a.get(k)))
            .and_then(toml::Value::as_table);
    }
    Ok(out.join("."))
}

/// The segments of a dotted key (`rod[1].segments`): each a bare TOML
/// key with an optional 0-based array index; errors say what is wrong.
fn key_parts(key: &str) -> Result<Vec<(&str, Option<usize>)>, String> {
    let mut parts: Vec<(&str, Option<usize>)> = Vec::new();
    for (i, p) in key.split('.').enumerate() {
        if p.is_empty() {
            return Err(format!(
                "key '{}': segment {} is empty (keys are dotted names such as time.end)",
                escape(key),
                i + 1
            ));
        }
        let (name, index) = match p.split_once('[') {
            None => (p, None),
            Some((name, rest)) => {
                let k = rest
                    .strip_suffix(']')
                    .filter(|k| !k.is_empty() && k.chars().all(|c| c.is_ascii_digit()))
                    .and_then(|k| k.parse::<usize>().ok())
                    .ok_or_else(|| {
                        format!(
                            "key '{}': '{}' is not a key segment with an array index \
                             (written name[k], k = 0, 1, ...)",
                            escape(key),
                            escape(p)
                        )
                    })?;
                (name, Some(k))
            }
        };
        if let Some(c) = name
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
        {
            return Err(format!(
                "key '{}': '{}' is not allowed in a key segment (letters, digits, _ and -, \
                 and an array index such as body[0])",
                escape(key),
                escape(&c.to_string())
            ));
        }
        if name.is_empty() {
            return Err(format!(
                "key '{}': segment {} has an index but no name",
                escape(key),
                i + 1
            ));
        }
        parts.push((name, index));
    }
    Ok(parts)
}

/// Apply `a.b.c=VALUE` to the document; returns the key. VALUE is read as a
/// TOML value (number, boolean, quoted string, array) or else as a bare
/// string. Each segment of the key is a TOML bare key (letters, digits,
/// `_`, `-`), optionally with the 0-based index of an existing array of
/// tables (`rod[1].segments`, `body[0].mass`); tables on the way that do
/// not exist are created.
pub(super) fn apply_override(doc: &mut toml::Table, spec: &str) -> Result<String, String> {
    let (key, value) = spec
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE".to_string())?;
    let key = key.trim();
    let value = value.trim();
    if key.is_empty() {
        return Err("empty key: expected KEY=VALUE".into());
    }
    let key = &named_indices(doc, key)?;
    let parts = key_parts(key)?;
    let parsed: toml::Value = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    // The array element `name[k]` of `table`.
    fn element<'a>(
        table: &'a mut toml::Table,
        name: &str,
        k: usize,
    ) -> Result<&'a mut toml::Value, String> {
        let arr = table
            .get_mut(name)
            .and_then(toml::Value::as_array_mut)
            .ok_or_else(|| format!("'{name}' is not an array (of [[{name}]] tables)"))?;
        let n = arr.len();
        arr.get_mut(k).ok_or_else(|| {
            format!("{name}[{k}] does not exist: '{name}' has {n} elements (0-based)")
        })
    }
    let mut table = doc;
    let (last, intermediate) = parts.split_last().expect("a key has a segment");
    for &(p, index) in intermediate {
        let entry = match index {
            None => table
                .entry(p.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new())),
            Some(k) => element(table, p, k)?,
        };
        if entry.is_array() && index.is_none() {
            return Err(format!(
                "'{p}' is an array of tables [[{p}]]: name the element, e.g. {p}[0].{}",
                last.0
            ));
        }
        table = entry
            .as_table_mut()
            .ok_or_else(|| format!("'{p}' is not a table"))?;
    }
    match last.1 {
        None => {
            table.insert(last.0.to_string(), parsed);
        }
        Some(k) => *element(table, last.0, k)? = parsed,
    }
    Ok(key.to_string())
}
