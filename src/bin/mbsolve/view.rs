//! `mbsolve view RESULT_DIR` (and `run --view`): one self-contained HTML
//! file — the script, the style and the data inline, nothing loaded from
//! the network — showing the mechanism on a canvas (play/pause, time
//! slider, speed, zoom and pan) beside plots of chosen columns whose
//! cursor follows the animation.
//!
//! The page draws the library's drawing model ([`mbsolve::drawing`]),
//! serialised to JSON; `assets/viewer.js` resolves its parts into marks
//! exactly as [`mbsolve::drawing::Drawing::marks`] does, on a canvas of
//! the size `animate` uses, so a still PNG of `animate` and the page's
//! frame agree (tests/cli/view.rs compares them in headless Chromium).
//! `view.html#t=0.5` opens paused at the output time nearest 0.5 s.
//! A "forces" toggle draws the contact forces and joint reactions as
//! arrows with their key ([`mbsolve::drawing::arrows`], as `animate
//! --forces` draws them; the page's box stays the motion's).
//! Everything from user files reaches the page as JSON text or escaped
//! HTML and is shown through `textContent`, never as markup.

use crate::animate;
use crate::plot::Table;
use mbsolve::scenario;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// What `mbsolve view` was asked for.
pub struct ViewArgs {
    /// The run's output directory.
    pub dir: PathBuf,
    /// The run's file stem (default: the only `*.summary.json` in `dir`).
    pub stem: Option<String>,
    /// The scenario (default: the one the summary records).
    pub scenario: Option<PathBuf>,
    /// Columns plotted at first (default: the first three columns that
    /// vary, coordinates first).
    pub columns: Vec<String>,
    /// Output (default: `DIR/<stem>.view.html`).
    pub out: Option<PathBuf>,
}

/// At most this many numbers of table data in a page (≈ 40 MB of text):
/// longer runs are thinned to every k-th row, which the page states.
const MAX_NUMBERS: usize = 4_000_000;

const HTML: &str = include_str!("../../../assets/viewer.html");
const CSS: &str = include_str!("../../../assets/viewer.css");
const JS: &str = include_str!("../../../assets/viewer.js");

/// Write the viewer page; returns its path.
pub fn view(a: &ViewArgs) -> Result<PathBuf, String> {
    let dir = &a.dir;
    let stem = match &a.stem {
        Some(s) => s.clone(),
        None => {
            let mut stems: Vec<String> = std::fs::read_dir(dir)
                .map_err(|e| format!("{}: {e}", dir.display()))?
                .filter_map(|e| e.ok())
                .filter_map(|e| {
                    e.file_name()
                        .to_str()
                        .and_then(|n| n.strip_suffix(".summary.json"))
                        .map(str::to_string)
                })
                .collect();
            stems.sort();
            match stems.len() {
                1 => stems.remove(0),
                0 => {
                    return Err(format!(
                        "{}: no <stem>.summary.json: not the output directory of `mbsolve run`",
                        dir.display()
                    ))
                }
                _ => {
                    return Err(format!(
                        "{}: several runs ({}): choose one with --stem",
                        dir.display(),
                        stems.join(", ")
                    ))
                }
            }
        }
    };
    let summary_path = dir.join(format!("{stem}.summary.json"));
    let summary: Value = serde_json::from_str(
        &std::fs::read_to_string(&summary_path)
            .map_err(|e| format!("{}: {e}", summary_path.display()))?,
    )
    .map_err(|e| format!("{}: {e}", summary_path.display()))?;
    let overrides: Vec<String> = summary["overrides"]
        .as_array()
        .map(|v| {
            v.iter()
                .filter_map(|s| s.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    let scenario_path = match &a.scenario {
        Some(p) => p.clone(),
        None => PathBuf::from(summary["scenario"].as_str().ok_or_else(|| {
            format!(
                "{}: records no scenario: give it with --scenario",
                summary_path.display()
            )
        })?),
    };
    if !scenario_path.is_file() {
        return Err(format!(
            "{}: the scenario {} recorded in {} is not there (run from another directory?): give it with --scenario",
            scenario_path.display(),
            scenario_path.display(),
            summary_path.display()
        ));
    }
    let csv = dir.join(format!("{stem}.csv"));
    if !csv.is_file() {
        let arrow = dir.join(format!("{stem}.arrow"));
        return Err(if arrow.is_file() {
            format!(
                "{}: the viewer reads CSV tables: run with --set output.format=\"csv\"",
                arrow.display()
            )
        } else {
            format!("{}: no such table", csv.display())
        });
    }
    let sc = scenario::load(&scenario_path, &overrides).map_err(|e| e.to_string())?;
    let table = Table::read(&csv)?;
    let mut scene = animate::scene(&sc, &table, &csv)?;
    let all = mbsolve::drawing::arrows::ArrowSet {
        contacts: true,
        reactions: true,
    };
    match animate::add_arrows(&mut scene, &sc, &table, all, false) {
        Ok(Some(note)) => eprintln!("{note}"),
        Ok(None) => {}
        Err(e) => eprintln!("{}: no force arrows in the viewer: {e}", csv.display()),
    }
    let units = read_units(&dir.join(format!("{stem}.columns.json")));
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| dir.join(format!("{stem}.view.html")));
    let page = page(&sc, &scene, &table, &units, &a.columns, &stem)?;
    std::fs::write(&out, page).map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(out)
}

/// Column units from `<stem>.columns.json` (empty when absent).
fn read_units(path: &Path) -> Vec<(String, String)> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Vec::new();
    };
    let Ok(Value::Array(v)) = serde_json::from_str::<Value>(&text) else {
        return Vec::new();
    };
    v.iter()
        .filter_map(|c| Some((c["name"].as_str()?.into(), c["unit"].as_str()?.into())))
        .collect()
}

/// HTML-escape text for element content and attribute values.
pub fn escape_html(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

/// JSON text safe inside a `<script>` element: every `<` (only possible
/// inside strings) and the line separators as escapes.
fn script_json(v: &Value) -> String {
    v.to_string()
        .replace('<', "\\u003c")
        .replace('\u{2028}', "\\u2028")
        .replace('\u{2029}', "\\u2029")
}

/// The page: template with its style, script and data.
fn page(
    sc: &scenario::Scenario,
    s: &animate::Scene,
    table: &Table,
    units: &[(String, String)],
    wanted: &[String],
    stem: &str,
) -> Result<String, String> {
    let n = s.t.len();
    let per_row = table.names.len() + s.poses.first().map_or(0, |p| p.len());
    let stride = (n * per_row).div_ceil(MAX_NUMBERS).max(1);
    let rows: Vec<usize> = (0..n).step_by(stride).collect();
    let unit_of = |name: &str| {
        units
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, u)| u.clone())
            .unwrap_or_default()
    };
    for w in wanted {
        if !table.names.iter().any(|n| n == w) {
            return Err(format!(
                "--plot {w}: no such column (columns: {})",
                table.names.join(", ")
            ));
        }
    }
    let coords = 3 * sc.system.bodies().len();
    let default_plot: Vec<String> = if wanted.is_empty() {
        let varying = |k: &usize| {
            let c = &table.columns[*k];
            c.iter().any(|v| *v != c[0])
        };
        let end = (1 + coords).min(table.names.len());
        (1..end)
            .filter(varying)
            .chain((end..table.names.len()).filter(varying))
            .filter(|&k| table.names[k] != "constraint_norm")
            .take(3)
            .map(|k| table.names[k].clone())
            .collect()
    } else {
        wanted.to_vec()
    };
    let columns: Vec<Value> = table
        .names
        .iter()
        .zip(&table.columns)
        .filter(|(name, _)| name.as_str() != "t")
        .map(|(name, c)| {
            json!({
                "name": name,
                "unit": unit_of(name),
                "values": rows.iter().map(|&r| finite(c[r])).collect::<Vec<_>>(),
            })
        })
        .collect();
    let data = json!({
        "title": sc.name,
        "stem": stem,
        "description": sc.description,
        "canvas": [s.size.0, s.size.1],
        "drawing": s.drawing,
        "t": rows.iter().map(|&r| s.t[r]).collect::<Vec<_>>(),
        "q": rows.iter().map(|&r| &s.poses[r]).collect::<Vec<_>>(),
        "stride": stride,
        "arrows": s.arrows.as_ref().map(|a| json!({
            "names": a.rows[0].iter().map(|x| x.name.as_str()).collect::<Vec<_>>(),
            "kinds": a.rows[0].iter().map(|x| x.kind).collect::<Vec<_>>(),
            "rows": rows.iter().map(|&r| a.rows[r].iter().map(|x| [x.at[0], x.at[1], x.force[0], x.force[1]].map(finite)).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "metres_per_newton": a.key.metres_per_newton,
            "key_force": a.key.key_force,
            "label": a.key.label(),
            "head": a.head,
        })),
        "columns": columns,
        "plot": default_plot,
    });
    let title = escape_html(&format!("{} — mbsolve viewer", sc.name));
    Ok(fill(
        HTML,
        &[
            ("TITLE", &title),
            ("STYLE", CSS),
            ("DATA", &script_json(&data)),
            ("SCRIPT", JS),
        ],
    ))
}

/// Replace each `{{KEY}}` of `template` in one pass (so that text put in
/// is never searched for placeholders again).
fn fill(template: &str, values: &[(&str, &str)]) -> String {
    let mut o =
        String::with_capacity(template.len() + values.iter().map(|v| v.1.len()).sum::<usize>());
    let mut rest = template;
    while let Some(i) = rest.find("{{") {
        o.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        match after.find("}}").and_then(|j| {
            values
                .iter()
                .find(|(k, _)| *k == &after[..j])
                .map(|v| (j, v.1))
        }) {
            Some((j, v)) => {
                o.push_str(v);
                rest = &after[j + 2..];
            }
            None => {
                o.push_str("{{");
                rest = after;
            }
        }
    }
    o.push_str(rest);
    o
}

/// A table value as JSON: non-finite values (a failed run's last rows)
/// as null, which the plots leave as gaps.
fn finite(v: f64) -> Value {
    if v.is_finite() {
        json!(v)
    } else {
        Value::Null
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_text_is_escaped() {
        assert_eq!(
            escape_html(r#"<b a="x">&'"#),
            "&lt;b a=&quot;x&quot;&gt;&amp;&#39;"
        );
        let v = json!({"name": "</script><script>alert(1)</script>\u{2028}"});
        let s = script_json(&v);
        assert!(!s.contains('<') && !s.contains('\u{2028}'), "{s}");
        let back: Value = serde_json::from_str(&s).unwrap();
        assert_eq!(back, v);
        assert_eq!(
            fill("a{{X}}b{{Y}}{{Z}}", &[("X", "{{Y}}"), ("Y", "y")]),
            "a{{Y}}by{{Z}}"
        );
    }
}
