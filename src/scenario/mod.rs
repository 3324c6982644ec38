//! Scenario files (TOML): a model, its initial state and the run settings.
//!
//! A scenario lists bodies (`[[body]]`), joints (`[[joint]]`), force elements
//! (`[[force]]`), `gravity`, and the tables `[initial]`, `[stabilization]`,
//! `[integrator]`, `[time]`, `[output]`; see `scenarios/fourbar.toml`.
//! Angles are radians unless the key ends in `_deg`.
//!
//! Every error names the file, the key and the problem. `--set KEY=VALUE`
//! overrides are applied to the parsed document before validation, so they
//! obey the same rules (an unknown key is an error).
//!
//! The loader is split by what it builds: `model` (bodies, joints, forces,
//! the `[rod]`, the evaluation → [`System`]), `run` (integrator,
//! stabilization, formulation, time and output → [`RunConfig`]; keys that do
//! not apply to the chosen method are errors), `initial` (consistent initial
//! state and perturbations). This module parses, applies overrides,
//! attributes errors to the file or the `--set` that caused them, and
//! assembles the [`Scenario`].

use crate::builders::{ChainInfo, RodInfo};
use crate::formulation::ConsistentState;
use crate::model::{Sensor, System};
use crate::simulation::RunConfig;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

mod components;
mod element;
mod forces;
mod initial;
mod joints;
pub mod limits;
pub mod metric;
mod model;
mod parameters;
mod run;
mod sensor;
mod state;
mod templates;

use components::{RawChain, RawRods};
use element::RawTagged;
use initial::RawInitial;
use model::{RawBody, RawConstraints};
use run::{RawIntegrator, RawOutput, RawStabilization, RawTime};

/// The four-bar scenario shipped with the tool (docs/problems.md, problem A), embedded at
/// build time so that the binary needs no files.
pub const FOURBAR_TOML: &str = include_str!("../../scenarios/fourbar.toml");

/// The falling-rod scenario shipped with the tool (docs/problems.md, problem B), embedded
/// at build time.
pub const FALLING_ROD_TOML: &str = include_str!("../../scenarios/falling_rod.toml");

/// A scenario error: where (file and key) and what.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{file}: {key}: {message}")]
pub struct ScenarioError {
    /// The scenario file (or `--set`).
    pub file: String,
    /// Dotted key path, e.g. `body[1].mass`.
    pub key: String,
    /// What is wrong.
    pub message: String,
}

/// A loaded, validated scenario, ready to run.
#[derive(Debug)]
pub struct Scenario {
    /// Scenario name (file stem unless `name` is given).
    pub name: String,
    /// Free text.
    pub description: String,
    /// The model.
    pub system: System,
    /// Initial positions (after assembly and perturbation).
    pub q0: Vec<f64>,
    /// Initial velocities.
    pub qd0: Vec<f64>,
    /// The assembly report, when `initial.consistent` is true.
    pub assembly: Option<ConsistentState>,
    /// Integrator, formulation, time span and output times.
    pub run: RunConfig,
    /// The rod's bookkeeping when the scenario has a `[rod]` table.
    pub rod: Option<RodInfo>,
    /// Every rod (`[rod]` and `[[rod]]`) with its name.
    pub rods: Vec<(String, RodInfo)>,
    /// Every `[[chain]]` with its name.
    pub chains: Vec<(String, ChainInfo)>,
    /// The `[[sensor]]`s, in file order.
    pub sensors: Vec<Sensor>,
    /// File format of the run's table (`output.format`).
    pub format: crate::output::Format,
    /// The declared `shape` of each `[[body]]`, by body index (components'
    /// bodies are not listed); drawing only.
    pub shapes: Vec<Option<crate::drawing::BodyShape>>,
    /// Notes for the user about what loading did, e.g. the file's keys
    /// dropped because an override chose a method they do not apply to.
    pub notes: Vec<String>,
    /// The `[[metric]]`s, in file order, checked against the run's output
    /// columns and time span (a sweep writes one column per metric).
    pub metrics: Vec<crate::output::metrics::Metric>,
    /// Every `[[force]]`'s force elements: (its name, index into
    /// [`System::forces`]); the contacts among them are reported by
    /// [`crate::events::ElementContacts`].
    pub force_elements: Vec<(String, usize)>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    description: Option<String>,
    gravity: Option<[f64; 2]>,
    #[serde(default)]
    body: Vec<RawBody>,
    #[serde(default)]
    joint: Vec<RawTagged>,
    #[serde(default)]
    force: Vec<RawTagged>,
    #[serde(default)]
    initial: RawInitial,
    #[serde(default)]
    stabilization: RawStabilization,
    #[serde(default)]
    integrator: RawIntegrator,
    time: RawTime,
    #[serde(default)]
    output: RawOutput,
    formulation: Option<String>,
    linear_solver: Option<String>,
    /// `[rod]` or `[[rod]]`: taken out of the document before
    /// deserialisation and parsed by [`components::parse_rods`].
    #[serde(skip)]
    rod: Option<RawRods>,
    #[serde(default)]
    chain: Vec<RawChain>,
    #[serde(default)]
    constraints: RawConstraints,
    #[serde(default)]
    sensor: Vec<RawTagged>,
    #[serde(default)]
    metric: Vec<metric::RawMetric>,
    #[serde(default)]
    state: Vec<state::RawState>,
}

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
fn set_overrides(specs: &[String]) -> Vec<Override<'_>> {
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

/// Load a scenario file and apply `KEY=VALUE` overrides (`--set`).
pub fn load(path: &Path, overrides: &[String]) -> Result<Scenario, ScenarioError> {
    load_with(path, &set_overrides(overrides))
}

/// Load a scenario file and apply overrides labelled by their flag.
pub fn load_with(path: &Path, overrides: &[Override]) -> Result<Scenario, ScenarioError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ScenarioError {
        file: file.clone(),
        key: "-".into(),
        message: format!("cannot read the file: {e}"),
    })?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scenario".into());
    parse_with(&text, &file, &stem, overrides)
}

/// Parse scenario text. `file` names it in errors; `stem` is the default name.
pub fn parse(
    text: &str,
    file: &str,
    stem: &str,
    overrides: &[String],
) -> Result<Scenario, ScenarioError> {
    parse_with(text, file, stem, &set_overrides(overrides))
}

/// [`parse`] with overrides labelled by their flag.
pub fn parse_with(
    text: &str,
    file: &str,
    stem: &str,
    overrides: &[Override],
) -> Result<Scenario, ScenarioError> {
    let err = |key: &str, message: String| ScenarioError {
        file: file.to_string(),
        key: key.to_string(),
        message,
    };
    control_characters(text).map_err(|(line, m)| err(&format!("line {line}"), m))?;
    let mut doc: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        let key = e
            .span()
            .map(|s| {
                let line = text[..s.start].matches('\n').count() + 1;
                format!("line {line}")
            })
            .unwrap_or_else(|| "-".into());
        let m = e.message().trim();
        err(
            &key,
            if m.is_empty() {
                "invalid TOML".into()
            } else {
                m.to_string()
            },
        )
    })?;
    if doc.contains_key("include") {
        templates::includes(&mut doc, Path::new(file), &mut Vec::new())
            .map_err(|(file, key, message)| ScenarioError { file, key, message })?;
    }
    let declared: Vec<String> = match doc.get("parameters") {
        Some(toml::Value::Table(t)) => t.keys().cloned().collect(),
        _ => Vec::new(),
    };
    let mut set_keys = Vec::new();
    for o in overrides {
        let bad = |m: String| ScenarioError {
            file: o.flag.into(),
            key: escape(o.spec),
            message: m,
        };
        if o.flag == UNSET {
            let key = unset(&mut doc, o.spec)
                .map_err(|m| bad(format!("{m} (in {file} after the overrides before it)")))?;
            set_keys.push((o.flag, key));
            continue;
        }
        // An override changes the rod a scenario has; it never adds one.
        let head = o.spec.split(['.', '[', '=']).next().unwrap_or_default();
        if head.trim() == "rod" && !doc.contains_key("rod") {
            return Err(bad(format!(
                "{file} has no [rod] table: rod.* overrides change a scenario's rod and \
                 cannot add one"
            )));
        }
        // a bare parameter name addresses the parameter (`--param k=…`)
        let spec = match o.spec.split_once('=') {
            Some((k, v)) if declared.iter().any(|d| d == k.trim()) => {
                format!("parameters.{}={v}", k.trim())
            }
            _ => o.spec.to_string(),
        };
        if let Some(p) = spec
            .split_once('=')
            .and_then(|(k, _)| k.trim().strip_prefix("parameters."))
        {
            if !declared.iter().any(|d| d == p) {
                return Err(bad(format!(
                    "{file} has no parameter '{}' (parameters: {}): an override changes a \
                     parameter and never adds one",
                    escape(p),
                    if declared.is_empty() {
                        "none".to_string()
                    } else {
                        declared.join(", ")
                    }
                )));
            }
        }
        let key = apply_override(&mut doc, &spec).map_err(bad)?;
        set_keys.push((o.flag, key));
    }
    let substituted = parameters::apply(&mut doc).map_err(|(key, message)| ScenarioError {
        file: attribute(file, &key, &set_keys),
        key,
        message,
    })?;
    let notes = if set_keys
        .iter()
        .any(|(f, k)| *f != UNSET && k == "integrator.method")
    {
        foreign_keys(&mut doc, &set_keys, file)
    } else {
        Vec::new()
    };
    let mut notes = notes;
    notes.extend(angle_notes(&doc, file, &substituted));
    non_finite(&doc, "").map_err(|(key, message)| ScenarioError {
        file: attribute(file, &key, &set_keys),
        key,
        message,
    })?;
    let rods = doc.remove("rod");
    let mut raw: RawScenario = serde_path_to_error::deserialize(toml::Value::Table(doc)).map_err(
        |e: serde_path_to_error::Error<toml::de::Error>| {
            let mut key = e.path().to_string();
            let mut message = e.inner().message().to_string();
            // a required top-level table is missing (e.g. an empty file):
            // name it rather than the document's root "."
            if key == "." {
                if let Some(f) = message
                    .strip_prefix("missing field `")
                    .and_then(|m| m.split('`').next())
                {
                    key = f.to_string();
                    message = format!("missing: the [{f}] table is required");
                }
            }
            if let Some(m) = substituted.explain(&key, &message) {
                message = m;
            }
            let key = substituted.rekey(&key);
            let origin = attribute(file, &key, &set_keys);
            ScenarioError {
                file: origin,
                key,
                message,
            }
        },
    )?;
    raw.rod = rods
        .map(components::parse_rods)
        .transpose()
        .map_err(|(key, message)| ScenarioError {
            file: attribute(file, &key, &set_keys),
            key,
            message,
        })?;
    let mut sc = build(raw, file, stem).map_err(|mut e| {
        e.file = attribute(file, &e.key, &set_keys);
        if let Some(m) = substituted.explain(&e.key, &e.message) {
            e.message = m;
        }
        e.key = substituted.rekey(&e.key);
        e
    })?;
    sc.notes = notes;
    Ok(sc)
}

/// The keys given in radians whose values are angles of a position (not
/// rates): a value beyond 2π there is more likely degrees written in a
/// radians field. (table, key) pairs; the table an array of tables.
const RADIAN_KEYS: [(&str, &str); 3] = [
    ("body", "phi"),
    ("force", "rest_angle"),
    ("initial.joint", "angle"),
];

/// A note for every angle above 2π in magnitude in a field given in
/// radians ([`RADIAN_KEYS`]): legal (a wound-up spring, a start after
/// several turns) but often degrees in the wrong field; the note names the
/// key, the value and the `_deg` key.
fn angle_notes(
    doc: &toml::Table,
    file: &str,
    substituted: &parameters::Substituted,
) -> Vec<String> {
    let mut notes = Vec::new();
    for (table, key) in RADIAN_KEYS {
        let array = match table.split_once('.') {
            Some((t, a)) => doc
                .get(t)
                .and_then(toml::Value::as_table)
                .and_then(|t| t.get(a)),
            None => doc.get(table),
        };
        let Some(items) = array.and_then(toml::Value::as_array) else {
            continue;
        };
        for (i, item) in items.iter().enumerate() {
            let v = match item.get(key) {
                Some(toml::Value::Float(f)) => *f,
                Some(toml::Value::Integer(n)) => *n as f64,
                _ => continue,
            };
            if v.is_finite() && v.abs() > std::f64::consts::TAU {
                let at = substituted.rekey(&format!("{table}[{i}].{key}"));
                notes.push(format!(
                    "{file}: {at} = {v} rad is more than 2π ({:.1} turns): if degrees were \
                     meant, write {key}_deg = {v}",
                    v.abs() / std::f64::consts::TAU
                ));
            }
        }
    }
    notes
}

/// The flag of an override that removes a key.
pub const UNSET: &str = "--unset";

/// When an override chose the method: remove the file's keys that do not
/// apply to it (by the method table, [`crate::integrate::METHODS`]: the
/// `[integrator]` keys, Baumgarte's `stabilization.alpha`/`beta` for the
/// index-3 methods, a `formulation` of the other equations), except those
/// an override wrote (still errors); one note per removed key.
fn foreign_keys(doc: &mut toml::Table, set_keys: &[(&str, String)], file: &str) -> Vec<String> {
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
fn unset(doc: &mut toml::Table, key: &str) -> Result<String, String> {
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
fn attribute(file: &str, key: &str, set_keys: &[(&str, String)]) -> String {
    let below =
        |a: &str, b: &str| a.starts_with(&format!("{b}.")) || a.starts_with(&format!("{b}["));
    let related = |k: &String| key == k || below(key, k) || below(k, key);
    match set_keys.iter().find(|(_, k)| related(k)) {
        Some((flag, k)) => format!("{file} ({flag} {k})"),
        None => file.to_string(),
    }
}

/// The first ASCII control character of `text` that TOML forbids (all but
/// tab, line feed and carriage return; TOML 1.0 allows none of them, not
/// even in comments): its line and a message naming it.
fn control_characters(text: &str) -> Result<(), (usize, String)> {
    for (line, l) in text.split('\n').enumerate() {
        if let Some((col, c)) = l
            .chars()
            .enumerate()
            .find(|(_, c)| c.is_ascii_control() && !matches!(c, '\t' | '\r'))
        {
            return Err((
                line + 1,
                format!(
                    "column {}: control character U+{:04X} is not allowed in TOML (not even in \
                     a comment or a string; write it as an escape such as \\u{:04X} inside a string)",
                    col + 1,
                    c as u32,
                    c as u32
                ),
            ));
        }
    }
    Ok(())
}

/// `s` with control characters escaped, for messages.
fn escape(s: &str) -> String {
    s.chars().flat_map(char::escape_debug).collect()
}

/// The first non-finite number (nan, ±inf) in `v`, with its key path under
/// `path` (`joint[1].point_i[0]`): no scenario value may be non-finite, so
/// every one is checked here, before the model sees it.
fn non_finite(doc: &toml::Table, path: &str) -> Result<(), (String, String)> {
    fn walk(v: &toml::Value, path: &str) -> Result<(), (String, String)> {
        match v {
            toml::Value::Float(f) if !f.is_finite() => {
                Err((path.to_string(), format!("{f} is not a finite number")))
            }
            toml::Value::Datetime(d) => Err((
                path.to_string(),
                format!(
                    "{d} is a TOML date/time, which no scenario key takes (quote it for a text)"
                ),
            )),
            toml::Value::Table(t) => non_finite(t, path),
            toml::Value::Array(a) => a
                .iter()
                .enumerate()
                .try_for_each(|(i, x)| walk(x, &format!("{path}[{i}]"))),
            _ => Ok(()),
        }
    }
    doc.iter().try_for_each(|(k, v)| {
        let p = if path.is_empty() {
            k.clone()
        } else {
            format!("{path}.{k}")
        };
        walk(v, &p)
    })
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
fn apply_override(doc: &mut toml::Table, spec: &str) -> Result<String, String> {
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

fn build(raw: RawScenario, file: &str, stem: &str) -> Result<Scenario, ScenarioError> {
    // The run settings and the limits first: nothing that scales with the
    // input (bodies, output times) is allocated before they are checked.
    let run = run::build(&raw, file)?;
    let format = run::output_format(&raw, file)?;
    limits::check(&raw, &run, file)?;
    let model::Model {
        system,
        rod,
        rods,
        chains,
        names,
        forces,
        ends,
    } = model::build(&raw, file)?;
    let sensors = sensor::build(&raw.sensor, &system, &names, &forces, &ends, file)?;
    let (q0, qd0, assembly) = initial::build(&raw.initial, &system, &names, &run, file)?;
    let shapes = raw.body.iter().map(|b| b.shape.clone()).collect();
    let metrics = metric::build(&raw.metric, &system, &run, &sensors, file)?;
    let force_elements = forces
        .iter()
        .flat_map(|(n, r)| r.clone().map(move |i| (n.clone(), i)))
        .collect();
    Ok(Scenario {
        name: raw.name.unwrap_or_else(|| stem.to_string()),
        description: raw.description.unwrap_or_default(),
        system,
        q0,
        qd0,
        assembly,
        run,
        rod,
        rods,
        chains,
        sensors,
        format,
        shapes,
        notes: Vec::new(),
        metrics,
        force_elements,
    })
}

/// An error at `key` of `file`.
fn error(file: &str, key: impl Into<String>, message: impl Into<String>) -> ScenarioError {
    ScenarioError {
        file: file.to_string(),
        key: key.into(),
        message: message.into(),
    }
}

fn positive(v: f64) -> Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("{v} is invalid: must be finite and > 0"))
    }
}

/// The body names for messages, in body order; the numbered parts of a
/// rod or chain (`rod1.segment[k]`) as one range `rod1.segment[1..N]`.
fn list(names: &HashMap<String, usize>) -> String {
    let mut v: Vec<(&usize, &String)> = names.iter().map(|(k, v)| (v, k)).collect();
    v.sort();
    let mut out: Vec<String> = Vec::new();
    let mut ranges: HashMap<&str, usize> = HashMap::new();
    for (_, k) in v {
        match k.strip_suffix(']').and_then(|p| p.split_once('[')) {
            Some((base, _)) => {
                let n = ranges.entry(base).or_insert(0);
                *n += 1;
                if *n == 1 {
                    out.push(base.to_string());
                }
            }
            None => out.push(k.clone()),
        }
    }
    out.into_iter()
        .map(|n| match ranges.get(n.as_str()) {
            Some(c) => format!("{n}[1..{c}]"),
            None => n,
        })
        .collect::<Vec<_>>()
        .join(", ")
}
