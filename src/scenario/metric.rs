//! `[[metric]]`: quantities a sweep reduces over each run and writes as
//! columns of its table ([`crate::output::metrics`]). Checked when the
//! scenario loads: the reduction, the window against the time span, and the
//! column or expression against the run's output columns, so `mbsolve
//! check` names a bad metric before any run.

use super::{error, ScenarioError};
use crate::model::{Sensor, System};
use crate::output::metrics::{check_window, Metric, MetricError, Reducer, Reduction};
use crate::simulation::RunConfig;
use serde::Deserialize;

/// One `[[metric]]` table as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMetric {
    /// Column name in the sweep table; default `REDUCE(QUANTITY)`.
    name: Option<String>,
    /// A column of the run's table, e.g. `phi1`.
    column: Option<String>,
    /// An expression of the run's columns, e.g. `"y2 - y1"`.
    expression: Option<String>,
    /// `final`, `min`, `max`, `mean`, `rms` or `crossing`.
    reduce: String,
    /// `[t0, t1]` \[s\]; default: the whole run.
    window: Option<[f64; 2]>,
    /// The level of `reduce = "crossing"`.
    threshold: Option<f64>,
    /// `up`, `down` or `either` (default) for `reduce = "crossing"`.
    direction: Option<String>,
}

/// Check `metric` against the run: its window holds at least one output
/// time, its quantity reads the run's output columns (an unknown name lists
/// them). The scenario's metrics are checked when it loads; a sweep's
/// `--metric`s with this against each run's scenario.
pub fn check(
    metric: &Metric,
    system: &System,
    run: &RunConfig,
    sensors: &[Sensor],
) -> Result<(), MetricError> {
    if let Some([a, b]) = metric.window {
        // the output times: t0 + k·dt for k < n, then t_end
        let tol = 1e-9 * a.abs().max(b.abs());
        let n = run.output_intervals();
        let k = ((a - tol - run.t0) / run.output_dt).ceil().max(0.0);
        let t = run.t0 + k * run.output_dt;
        let hit = (k < n && t <= b + tol) || (a - tol..=b + tol).contains(&run.t_end);
        if !hit {
            return Err(MetricError {
                field: "window",
                message: format!(
                    "[{a}, {b}] holds no output time of the run (time [{}, {}], output.dt = {}): \
                     the metric would have no rows",
                    run.t0, run.t_end, run.output_dt
                ),
            });
        }
    }
    let cols = crate::output::columns(system, &run.outputs, sensors);
    let names: Vec<&str> = cols.iter().map(|c| c.name.as_str()).collect();
    Reducer::new(metric, &names).map(|_| ())
}

/// The scenario's metrics, checked ([`check`]); names unique.
pub(super) fn build(
    raw: &[RawMetric],
    system: &System,
    run: &RunConfig,
    sensors: &[Sensor],
    file: &str,
) -> Result<Vec<Metric>, ScenarioError> {
    let mut out: Vec<Metric> = Vec::with_capacity(raw.len());
    for (i, m) in raw.iter().enumerate() {
        let key = format!("metric[{i}]");
        let at = |e: MetricError| error(file, format!("{key}.{}", e.field), e.message);
        let (quantity, field) = match (&m.column, &m.expression) {
            (Some(c), None) => (c.clone(), "column"),
            (None, Some(e)) => (e.clone(), "expression"),
            (Some(_), Some(_)) => {
                return Err(error(
                    file,
                    format!("{key}.expression"),
                    "give either column or expression, not both",
                ))
            }
            (None, None) => {
                return Err(error(
                    file,
                    format!("{key}.column"),
                    "missing: a metric reduces a column (column = \"phi1\") or an expression \
                     (expression = \"y2 - y1\")",
                ))
            }
        };
        if quantity.trim().is_empty() {
            return Err(error(file, format!("{key}.{field}"), "is empty"));
        }
        let reduction =
            Reduction::new(&m.reduce, m.threshold, m.direction.as_deref()).map_err(at)?;
        let window = m.window.map(check_window).transpose().map_err(at)?;
        let name = m
            .name
            .clone()
            .unwrap_or_else(|| format!("{}({})", reduction.name(), quantity.trim()));
        if name.trim().is_empty() {
            return Err(error(file, format!("{key}.name"), "is empty"));
        }
        if let Some(j) = out.iter().position(|o| o.name == name) {
            return Err(error(
                file,
                format!("{key}.name"),
                format!("'{name}' is also the name of metric[{j}]: give each metric its own name"),
            ));
        }
        let metric = Metric {
            name,
            quantity,
            reduction,
            window,
        };
        // a bad quantity is reported under the field the file used
        check(&metric, system, run, sensors).map_err(|e| match e.field {
            "column" | "expression" => error(file, format!("{key}.{field}"), e.message),
            _ => at(e),
        })?;
        out.push(metric);
    }
    Ok(out)
}
