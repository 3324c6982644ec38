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

use crate::builders::RodInfo;
use crate::formulation::ConsistentState;
use crate::model::{Sensor, System};
use crate::simulation::RunConfig;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::Path;

mod initial;
pub mod limits;
mod model;
mod run;
mod sensor;

use initial::RawInitial;
use model::{RawBody, RawConstraints, RawForce, RawJoint, RawRod};
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
    /// The `[[sensor]]`s, in file order.
    pub sensors: Vec<Sensor>,
    /// File format of the run's table (`output.format`).
    pub format: crate::output::Format,
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
    joint: Vec<RawJoint>,
    #[serde(default)]
    force: Vec<RawForce>,
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
    rod: Option<RawRod>,
    #[serde(default)]
    constraints: RawConstraints,
    #[serde(default)]
    sensor: Vec<sensor::RawSensor>,
}

/// A `KEY=VALUE` override of a scenario key and the command-line flag it
/// came from (`--set`, `--param`), which labels its errors.
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
    let mut set_keys = Vec::new();
    for o in overrides {
        let key = apply_override(&mut doc, o.spec).map_err(|m| ScenarioError {
            file: o.flag.into(),
            key: escape(o.spec),
            message: m,
        })?;
        set_keys.push((o.flag, key));
    }
    non_finite(&doc, "").map_err(|(key, message)| ScenarioError {
        file: attribute(file, &key, &set_keys),
        key,
        message,
    })?;
    let raw: RawScenario = serde_path_to_error::deserialize(toml::Value::Table(doc)).map_err(
        |e: serde_path_to_error::Error<toml::de::Error>| {
            let key = e.path().to_string();
            let origin = attribute(file, &key, &set_keys);
            let message = e.inner().message().to_string();
            ScenarioError {
                file: origin,
                key,
                message,
            }
        },
    )?;
    build(raw, file, stem).map_err(|mut e| {
        e.file = attribute(file, &e.key, &set_keys);
        e
    })
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

/// Apply `a.b.c=VALUE` to the document; returns the key. VALUE is read as a
/// TOML value (number, boolean, quoted string, array) or else as a bare
/// string. Each segment of the key is a TOML bare
/// key (letters, digits, `_`, `-`).
fn apply_override(doc: &mut toml::Table, spec: &str) -> Result<String, String> {
    let (key, value) = spec
        .split_once('=')
        .ok_or_else(|| "expected KEY=VALUE".to_string())?;
    let key = key.trim();
    let value = value.trim();
    if key.is_empty() {
        return Err("empty key: expected KEY=VALUE".into());
    }
    let parts: Vec<&str> = key.split('.').collect();
    for (i, p) in parts.iter().enumerate() {
        if p.is_empty() {
            return Err(format!(
                "key '{}': segment {} is empty (keys are dotted names such as time.end)",
                escape(key),
                i + 1
            ));
        }
        if let Some(c) = p
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
        {
            return Err(format!(
                "key '{}': '{}' is not allowed in a key segment (letters, digits, _ and -; \
                 array elements such as body[0] cannot be set)",
                escape(key),
                escape(&c.to_string())
            ));
        }
    }
    let parsed: toml::Value = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    let mut table = doc;
    for p in &parts[..parts.len() - 1] {
        let entry = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        table = entry
            .as_table_mut()
            .ok_or_else(|| format!("'{p}' is not a table"))?;
    }
    table.insert(parts[parts.len() - 1].to_string(), parsed);
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
        names,
        forces,
    } = model::build(&raw, file)?;
    let sensors = sensor::build(&raw.sensor, &system, &names, &forces, file)?;
    let (q0, qd0, assembly) = initial::build(&raw.initial, &system, &names, &run, file)?;
    Ok(Scenario {
        name: raw.name.unwrap_or_else(|| stem.to_string()),
        description: raw.description.unwrap_or_default(),
        system,
        q0,
        qd0,
        assembly,
        run,
        rod,
        sensors,
        format,
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

fn list(names: &HashMap<String, usize>) -> String {
    let mut v: Vec<(&usize, &String)> = names.iter().map(|(k, v)| (v, k)).collect();
    v.sort();
    v.into_iter()
        .map(|(_, k)| k.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}
