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
mod overrides;
mod parameters;
mod run;
mod sensor;
mod state;
mod templates;

use overrides::{apply_override, attribute, foreign_keys, set_overrides, unset};
pub use overrides::{overrides, Override, UNSET};

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
    state::refuse_parameter_names(&doc, &substituted.names).map_err(|(key, message)| {
        ScenarioError {
            file: attribute(file, &key, &set_keys),
            key,
            message,
        }
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
