//! `[[state]]`: controller states, first-order `ż = f(t, q, q̇, z)` with
//! `f` an expression ([`crate::model::State`]: the velocity of an extra
//! coordinate of unit mass whose generalized force is f, so every
//! integrator handles them). Every expression of the scenario reads a
//! state by its name.

use super::forces::expression_names;
use super::{error, ScenarioError};
use crate::forces::ExpressionLoadBuilder;
use crate::model::SystemBuilder;
use serde::Deserialize;
use std::collections::HashMap;

/// One `[[state]]` table.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawState {
    /// Its name: letters, digits and `_`, starting with a letter or `_`.
    name: String,
    /// z(t0), default 0.
    initial: Option<f64>,
    /// ż: an expression of t, bodies' coordinates, states and parameters.
    derivative: String,
    /// The unit of z for its output column (`"rad s"`), default `"1"`.
    unit: Option<String>,
}

/// Most characters of a state's `unit`.
const MAX_UNIT_CHARS: usize = 32;

/// `Err(message)` unless `u` is a unit text: at most [`MAX_UNIT_CHARS`]
/// printable characters, none of `< > & " ' \` (it reaches HTML, SVG and
/// CSV headers' metadata).
fn check_unit(u: &str) -> Result<(), String> {
    if u.trim().is_empty() {
        return Err("an empty unit (leave the key out for \"1\", dimensionless)".into());
    }
    if u.chars().count() > MAX_UNIT_CHARS {
        return Err(format!(
            "\"{u}\" is longer than {MAX_UNIT_CHARS} characters"
        ));
    }
    if let Some(c) = u
        .chars()
        .find(|c| c.is_control() || "<>&\"'\\".contains(*c))
    {
        return Err(format!(
            "{:?} holds {c:?}: a unit is text such as \"rad s\" or \"N m/s\" (no control \
             characters, < > & \" ' \\)",
            u
        ));
    }
    Ok(())
}

/// A state may not share its name with a parameter: the parameter's value
/// would replace the state in every expression. `Err((key, message))` at
/// the first `[[state]]` whose name is in `parameters`.
pub(super) fn refuse_parameter_names(
    doc: &toml::Table,
    parameters: &[String],
) -> Result<(), (String, String)> {
    let Some(states) = doc.get("state").and_then(toml::Value::as_array) else {
        return Ok(());
    };
    for (k, st) in states.iter().enumerate() {
        if let Some(n) = st.get("name").and_then(toml::Value::as_str) {
            if parameters.iter().any(|p| p == n) {
                return Err((
                    format!("state[{k}].name"),
                    format!(
                        "'{n}' is also the name of a parameter: a state and a parameter \
                         cannot share a name (the parameter's value would replace the state \
                         in the expressions)"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Adds the states (after every body) and returns (name, coordinate w).
pub(super) fn add(
    raw: &[RawState],
    builder: &mut SystemBuilder,
    names: &HashMap<String, usize>,
    file: &str,
) -> Result<Vec<(String, usize)>, ScenarioError> {
    let mut out: Vec<(String, usize)> = Vec::with_capacity(raw.len());
    for (k, s) in raw.iter().enumerate() {
        let key = |f: &str| format!("state[{k}].{f}");
        let n = s.name.as_str();
        let word = n
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !word || n == "t" {
            return Err(error(
                file,
                key("name"),
                format!(
                    "'{n}' is not a state name (letters, digits and _, starting with a letter \
                     or _; not t)"
                ),
            ));
        }
        if out.iter().any(|o| o.0 == n) {
            return Err(error(
                file,
                key("name"),
                format!("duplicate state name '{n}'"),
            ));
        }
        if names.contains_key(n) {
            return Err(error(file, key("name"), format!("'{n}' is a body's name")));
        }
        let z0 = s.initial.unwrap_or(0.0);
        if !z0.is_finite() {
            return Err(error(file, key("initial"), format!("{z0} is not finite")));
        }
        let unit = s.unit.as_deref().unwrap_or("1");
        check_unit(unit).map_err(|m| error(file, key("unit"), m))?;
        out.push((n.to_string(), builder.add_state_with_unit(n, z0, unit)));
    }
    Ok(out)
}

/// Adds each state's derivative as the generalized force on its coordinate
/// (one expression load per state, exact symbolic Jacobians).
pub(super) fn add_rates(
    raw: &[RawState],
    states: &[(String, usize)],
    builder: &mut SystemBuilder,
    names: &HashMap<String, usize>,
    file: &str,
) -> Result<(), ScenarioError> {
    for (k, s) in raw.iter().enumerate() {
        let texts = [s.derivative.clone()];
        let (read, mut own) = expression_names(names, states, &texts);
        if !own.iter().any(|o| o.0 == s.name) {
            own.push((s.name.as_str(), states[k].1));
        }
        builder.add_force(
            ExpressionLoadBuilder::new(&format!("state {}", s.name), &read)
                .with_states(&own)
                .state_rate(&s.name, &s.derivative)
                .map_err(|e| {
                    error(
                        file,
                        format!("state[{k}].derivative"),
                        match e {
                            crate::forces::ExpressionError::Parse { source, .. } => format!(
                                "\"{}\": {source} (variables: t, bodies' B.x, B.y, B.phi, \
                                 B.vx, B.vy, B.omega, states by name)",
                                s.derivative
                            ),
                            other => other.to_string(),
                        },
                    )
                })?
                .build(),
        );
    }
    Ok(())
}
