//! Metrics of a run: a column of its table, or an expression of columns,
//! reduced over the run (or a time window of it) to one number — the final
//! value, the minimum, the maximum, the time mean, the RMS, or the first
//! time a threshold is crossed. A sweep writes one column per metric.
//!
//! The reductions are pure functions of the table's rows: [`evaluate`]
//! takes a finished table's columns; a [`Reducer`] takes the rows one at a
//! time as a run writes them (so a sweep keeps no rows). Both give the same
//! number for the same rows.
//!
//! Rules (documented in `docs/scenarios.md`, "Metrics"):
//! - the rows counted are those with `t0 ≤ t ≤ t1` of the window (all rows
//!   without one), within a tolerance of 10⁻⁹·max(|t0|, |t1|); the window's
//!   ends are not interpolated;
//! - `mean` is the time average by the trapezoidal rule over those rows,
//!   `(1/(t_last − t_first)) ∫ v dt`, and `rms` is `√(mean of v²)` the same
//!   way; a window holding one row gives that row's value;
//! - `crossing` is the first time, linearly interpolated between two
//!   consecutive rows of the window, at which the value passes the
//!   threshold (`up`: from below to at-or-above, `down`: from above to
//!   at-or-below, `either`); a value that starts beyond the threshold has
//!   not crossed it; never crossed: NaN (an empty cell in a table);
//! - a window holding no row is an error naming the metric.

use mbsolve_codegen::tape::Tape;
use mbsolve_codegen::{parse, Ctx};

/// How a metric reduces its values over the window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reduction {
    /// The value of the last row of the window.
    Final,
    /// The smallest value.
    Min,
    /// The largest value.
    Max,
    /// The time average (trapezoidal rule, module docs).
    Mean,
    /// The root of the time average of the square (trapezoidal rule).
    Rms,
    /// The first time \[s\] the value crosses `threshold` in `direction`.
    Crossing {
        /// The level crossed, in the quantity's unit.
        threshold: f64,
        /// Which crossings count.
        direction: Direction,
    },
}

/// Which crossings of a threshold count (default [`Direction::Either`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Direction {
    /// From below the threshold to at or above it.
    Up,
    /// From above the threshold to at or below it.
    Down,
    /// Either way.
    #[default]
    Either,
}

impl Direction {
    /// Parse `up`, `down` or `either`.
    pub fn parse(s: &str) -> Result<Self, String> {
        match s.trim() {
            "up" => Ok(Direction::Up),
            "down" => Ok(Direction::Down),
            "either" => Ok(Direction::Either),
            other => Err(format!(
                "'{other}' is not a direction: expected up, down or either"
            )),
        }
    }
}

/// The reductions' names, as written in scenarios and on the command line.
pub const REDUCTIONS: [&str; 6] = ["final", "min", "max", "mean", "rms", "crossing"];

/// One metric: a name (its column in a sweep table), the quantity reduced
/// (a column name of the run's table, or an expression of column names and
/// `t`, `docs/expressions.md`), the reduction and an optional time window.
#[derive(Debug, Clone, PartialEq)]
pub struct Metric {
    /// Column name in the sweep table, e.g. `rms_acc`.
    pub name: String,
    /// A column name (`crank.phi`) or an expression of columns
    /// (`rod.y - crank.y`); positional names of earlier versions (`phi1`)
    /// are read as the body's named column ([`super::find_column`]).
    pub quantity: String,
    /// The reduction.
    pub reduction: Reduction,
    /// The window `[t0, t1]` \[s\], t0 < t1; `None`: the whole run.
    pub window: Option<[f64; 2]>,
}

/// Why a metric cannot be evaluated; `field` names the offending part
/// (`column`, `window`, `threshold`, …) for the caller's key path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct MetricError {
    /// The part of the metric at fault: `column`, `expression`, `reduce`,
    /// `window`, `threshold` or `direction`.
    pub field: &'static str,
    /// What is wrong.
    pub message: String,
}

fn err(field: &'static str, message: impl Into<String>) -> MetricError {
    MetricError {
        field,
        message: message.into(),
    }
}

impl Reduction {
    /// The reduction named `name` ([`REDUCTIONS`]); `threshold` and
    /// `direction` are required / allowed for `crossing` only.
    pub fn new(
        name: &str,
        threshold: Option<f64>,
        direction: Option<&str>,
    ) -> Result<Self, MetricError> {
        let r = match name.trim() {
            "final" => Reduction::Final,
            "min" => Reduction::Min,
            "max" => Reduction::Max,
            "mean" => Reduction::Mean,
            "rms" => Reduction::Rms,
            "crossing" => {
                let threshold = threshold.ok_or_else(|| {
                    err(
                        "threshold",
                        "missing: reduce = \"crossing\" needs a threshold",
                    )
                })?;
                if !threshold.is_finite() {
                    return Err(err("threshold", format!("{threshold} is not finite")));
                }
                let direction = direction
                    .map(Direction::parse)
                    .transpose()
                    .map_err(|m| err("direction", m))?
                    .unwrap_or_default();
                return Ok(Reduction::Crossing {
                    threshold,
                    direction,
                });
            }
            other => {
                return Err(err(
                    "reduce",
                    format!(
                        "'{other}' is not a reduction: expected one of {}",
                        REDUCTIONS.join(", ")
                    ),
                ))
            }
        };
        if threshold.is_some() {
            return Err(err("threshold", "applies to reduce = \"crossing\" only"));
        }
        if direction.is_some() {
            return Err(err("direction", "applies to reduce = \"crossing\" only"));
        }
        Ok(r)
    }

    /// The reduction's name ([`REDUCTIONS`]).
    pub fn name(&self) -> &'static str {
        match self {
            Reduction::Final => "final",
            Reduction::Min => "min",
            Reduction::Max => "max",
            Reduction::Mean => "mean",
            Reduction::Rms => "rms",
            Reduction::Crossing { .. } => "crossing",
        }
    }
}

/// A window `[t0, t1]` checked: finite, t0 < t1.
pub fn check_window(w: [f64; 2]) -> Result<[f64; 2], MetricError> {
    let [a, b] = w;
    if !(a.is_finite() && b.is_finite()) {
        return Err(err("window", format!("[{a}, {b}] is not finite")));
    }
    if a >= b {
        return Err(err(
            "window",
            format!("[{a}, {b}] is empty: the window needs t0 < t1"),
        ));
    }
    Ok(w)
}

impl Metric {
    /// Parse the command-line form `[NAME=]REDUCE(QUANTITY[, T0, T1])`, or
    /// `[NAME=]crossing(QUANTITY, THRESHOLD[, up|down|either][, T0, T1])`;
    /// the name defaults to the text after `NAME=`, e.g. `rms(y2, 1, 5)`.
    /// Commas inside brackets of the quantity (`max(a, b)`) do not split.
    pub fn parse(text: &str) -> Result<Self, MetricError> {
        let text = text.trim();
        let (name, call) = match text.split_once('=') {
            Some((n, c)) if is_name(n.trim()) => (Some(n.trim().to_string()), c.trim()),
            _ => (None, text),
        };
        let bad = || {
            err(
                "reduce",
                format!(
                    "'{text}': expected [NAME=]REDUCE(QUANTITY[, T0, T1]) with REDUCE one of {} \
                     (crossing(QUANTITY, THRESHOLD[, up|down|either][, T0, T1]))",
                    REDUCTIONS.join(", ")
                ),
            )
        };
        let (reduce, args) = call
            .split_once('(')
            .and_then(|(r, a)| Some((r.trim(), a.trim_end().strip_suffix(')')?)))
            .ok_or_else(bad)?;
        if !REDUCTIONS.contains(&reduce) {
            return Err(Reduction::new(reduce, None, None).err().unwrap_or_else(bad));
        }
        let args = split_args(args).ok_or_else(bad)?;
        let (quantity, mut rest) = args.split_first().ok_or_else(bad)?;
        if quantity.is_empty() {
            return Err(bad());
        }
        let number = |s: &str, field: &'static str| {
            s.parse::<f64>()
                .map_err(|_| err(field, format!("'{s}' is not a number")))
        };
        let (mut threshold, mut direction) = (None, None);
        if reduce == "crossing" {
            let (t, r) = rest.split_first().ok_or_else(|| {
                err(
                    "threshold",
                    format!("'{text}': crossing(QUANTITY, THRESHOLD, …)"),
                )
            })?;
            threshold = Some(number(t, "threshold")?);
            rest = r;
            if let Some((d, r)) = rest.split_first() {
                if d.parse::<f64>().is_err() {
                    direction = Some(d.as_str());
                    rest = r;
                }
            }
        }
        let window = match rest {
            [] => None,
            [a, b] => Some(check_window([number(a, "window")?, number(b, "window")?])?),
            _ => {
                return Err(err(
                    "window",
                    format!("'{text}': give both ends of the window, T0, T1"),
                ))
            }
        };
        Ok(Metric {
            name: name.unwrap_or_else(|| call.to_string()),
            quantity: quantity.clone(),
            reduction: Reduction::new(reduce, threshold, direction)?,
            window,
        })
    }
}

/// A metric or column name: a letter or `_`, then letters, digits, `_`,
/// `.` and indices `[k]` ([`super::is_column_name`]).
fn is_name(s: &str) -> bool {
    s == "t" || super::is_column_name(s)
}

/// Split at the commas outside brackets; `None` when brackets are unbalanced.
fn split_args(s: &str) -> Option<Vec<String>> {
    let (mut parts, mut cur, mut depth) = (Vec::new(), String::new(), 0i32);
    for c in s.chars() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => {
                depth -= 1;
                if depth < 0 {
                    return None;
                }
            }
            ',' if depth == 0 => {
                parts.push(cur.trim().to_string());
                cur.clear();
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    if depth != 0 {
        return None;
    }
    parts.push(cur.trim().to_string());
    Some(parts)
}

/// How the quantity is read from a row.
#[derive(Debug, Clone)]
enum Source {
    /// Column number.
    Column(usize),
    /// An expression: its tape, the columns of its variables in the
    /// context's variable order, and the variables' values.
    Expression {
        tape: Tape,
        columns: Vec<usize>,
        vars: Vec<f64>,
        out: [f64; 1],
    },
}

/// A metric bound to a table's columns, taking rows one at a time
/// ([`Reducer::push`]) and giving the value at the end ([`Reducer::finish`]).
#[derive(Debug, Clone)]
pub struct Reducer {
    metric: Metric,
    source: Source,
    t_column: usize,
    rows: usize,
    first_t: f64,
    last: (f64, f64),
    min: f64,
    max: f64,
    /// ∫ v dt and ∫ v² dt by the trapezoidal rule.
    integral: f64,
    integral_sq: f64,
    crossing: f64,
}

impl Reducer {
    /// Bind `metric` to a table with the columns `names` (which must hold
    /// `t`): the quantity is a column name, or an expression whose names
    /// are column names. An unknown name is an error listing the columns.
    pub fn new(metric: &Metric, names: &[&str]) -> Result<Self, MetricError> {
        let t_column = names
            .iter()
            .position(|n| *n == "t")
            .ok_or_else(|| err("column", "the table has no time column 't'"))?;
        let q = metric.quantity.trim();
        let listing = || {
            let shown: Vec<&str> = names.iter().copied().take(40).collect();
            format!(
                "{}{}",
                shown.join(", "),
                if names.len() > 40 { ", …" } else { "" }
            )
        };
        let source = if let Some(k) = super::find_column(names, q) {
            Source::Column(k)
        } else {
            let mut ctx = Ctx::new();
            // variables in the context's order: (column, its variable)
            let mut bound: Vec<(usize, mbsolve_codegen::Id)> = Vec::new();
            let mut unknown = None;
            let e = parse(&mut ctx, q, |n, ctx| match super::find_column(names, n) {
                Some(k) => match bound.iter().find(|b| b.0 == k) {
                    Some(b) => Some(b.1),
                    None => {
                        let v = ctx.var(n);
                        bound.push((k, v));
                        Some(v)
                    }
                },
                None => {
                    unknown = Some(n.to_string());
                    None
                }
            });
            let field = if is_name(q) { "column" } else { "expression" };
            let e = match (e, unknown) {
                (Err(_), Some(n)) => {
                    return Err(err(
                        field,
                        format!(
                            "'{q}': no column '{n}' in the run's table (columns: {}); \
                             velocities, accelerations, reactions and energies are columns \
                             when output.quantities selects them",
                            listing()
                        ),
                    ))
                }
                (Err(p), None) => return Err(err(field, format!("'{q}': {p}"))),
                (Ok(e), _) => e,
            };
            let order: Vec<usize> = bound.iter().map(|b| b.0).collect();
            let tape = Tape::new(&ctx, &[e]);
            Source::Expression {
                tape,
                vars: vec![0.0; order.len()],
                columns: order,
                out: [0.0],
            }
        };
        Ok(Self {
            metric: metric.clone(),
            source,
            t_column,
            rows: 0,
            first_t: f64::NAN,
            last: (f64::NAN, f64::NAN),
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            integral: 0.0,
            integral_sq: 0.0,
            crossing: f64::NAN,
        })
    }

    /// The metric.
    pub fn metric(&self) -> &Metric {
        &self.metric
    }

    /// Take one row of the table (values in the order of the names given
    /// to [`Reducer::new`]); rows come in increasing time.
    pub fn push(&mut self, row: &[f64]) {
        let t = row[self.t_column];
        if let Some([a, b]) = self.metric.window {
            let tol = 1e-9 * a.abs().max(b.abs());
            if t < a - tol || t > b + tol {
                return;
            }
        }
        let v = match &mut self.source {
            Source::Column(k) => row[*k],
            Source::Expression {
                tape,
                columns,
                vars,
                out,
            } => {
                for (x, &k) in vars.iter_mut().zip(columns.iter()) {
                    *x = row[k];
                }
                tape.eval(vars, out);
                out[0]
            }
        };
        if self.rows == 0 {
            self.first_t = t;
        } else {
            let (tp, vp) = self.last;
            let h = t - tp;
            self.integral += 0.5 * h * (vp + v);
            self.integral_sq += 0.5 * h * (vp * vp + v * v);
            if let Reduction::Crossing {
                threshold: c,
                direction,
            } = self.metric.reduction
            {
                let up = vp < c && v >= c;
                let down = vp > c && v <= c;
                let counts = match direction {
                    Direction::Up => up,
                    Direction::Down => down,
                    Direction::Either => up || down,
                };
                if counts && self.crossing.is_nan() {
                    self.crossing = tp + (c - vp) / (v - vp) * h;
                }
            }
        }
        // NaN propagates into min/max (f64::min would skip it)
        self.min = if v < self.min || v.is_nan() {
            v
        } else {
            self.min
        };
        self.max = if v > self.max || v.is_nan() {
            v
        } else {
            self.max
        };
        if self.min.is_nan() || self.max.is_nan() {
            self.min = f64::NAN;
            self.max = f64::NAN;
        }
        self.last = (t, v);
        self.rows += 1;
    }

    /// The metric's value over the rows taken; an error when no row fell
    /// in the window. A crossing that never happened is NaN.
    pub fn finish(&self) -> Result<f64, MetricError> {
        if self.rows == 0 {
            return Err(match self.metric.window {
                Some([a, b]) => err(
                    "window",
                    format!(
                        "no output row in the window [{a}, {b}] of metric '{}' (the run's \
                         output times do not reach it; see time.end and output.dt)",
                        self.metric.name
                    ),
                ),
                None => err(
                    "column",
                    format!("metric '{}': the run wrote no rows", self.metric.name),
                ),
            });
        }
        let span = self.last.0 - self.first_t;
        let mean = |integral: f64, one: f64| {
            if self.rows == 1 || span <= 0.0 {
                one
            } else {
                integral / span
            }
        };
        let v = self.last.1;
        Ok(match self.metric.reduction {
            Reduction::Final => v,
            Reduction::Min => self.min,
            Reduction::Max => self.max,
            Reduction::Mean => mean(self.integral, v),
            Reduction::Rms => mean(self.integral_sq, v * v).sqrt(),
            Reduction::Crossing { .. } => self.crossing,
        })
    }
}

/// The value of `metric` over a finished table: `names` are its column
/// names (with `t`), `columns` the columns' values (all of one length).
pub fn evaluate(metric: &Metric, names: &[&str], columns: &[&[f64]]) -> Result<f64, MetricError> {
    let mut r = Reducer::new(metric, names)?;
    let n = columns.first().map_or(0, |c| c.len());
    let mut row = vec![0.0; columns.len()];
    for i in 0..n {
        for (x, c) in row.iter_mut().zip(columns) {
            *x = c.get(i).copied().unwrap_or(f64::NAN);
        }
        r.push(&row);
    }
    r.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> (Vec<&'static str>, Vec<Vec<f64>>) {
        let t: Vec<f64> = (0..=100).map(|k| k as f64 * 0.01).collect();
        let x: Vec<f64> = t.iter().map(|t| t * t).collect();
        let y: Vec<f64> = t.iter().map(|t| 1.0 - t).collect();
        (vec!["t", "x", "y"], vec![t, x, y])
    }

    fn value(text: &str) -> f64 {
        let (n, c) = table();
        let cols: Vec<&[f64]> = c.iter().map(|c| c.as_slice()).collect();
        evaluate(&Metric::parse(text).unwrap(), &n, &cols).unwrap()
    }

    #[test]
    fn reductions_against_closed_forms() {
        assert_eq!(value("final(x)"), 1.0);
        assert_eq!(value("max(y)"), 1.0);
        assert_eq!(value("min(x - y)"), -1.0);
        // ∫₀¹ t² dt = 1/3; trapezoid error h²/12·(f'(1) − f'(0)) = h²/6
        assert!((value("mean(x)") - (1.0 / 3.0 + 1e-4 / 6.0)).abs() < 1e-13);
        // window [0.5, 1]: rows 0.5 … 1.0 of y = 1 − t, exact for a line
        assert!((value("mean(y, 0.5, 1)") - 0.25).abs() < 1e-14);
        // rms of 1 − t over [0, 1]: √(1/3) up to the trapezoid's h²/6
        assert!((value("rms(y)") - (1.0 / 3.0 + 1e-4 / 6.0_f64).sqrt()).abs() < 1e-13);
        // x = t² crosses 0.25 at t = 0.5 exactly (a row), y crosses 0.5 down
        assert!((value("crossing(x, 0.25)") - 0.5).abs() < 1e-14);
        assert!((value("c=crossing(y, 0.505, down)") - 0.495).abs() < 1e-14);
        assert!(value("crossing(y, 0.5, up)").is_nan());
        // a single row in the window gives its value
        assert_eq!(value("rms(y, 0.999, 1.001)"), 0.0);
    }

    #[test]
    fn bad_metrics_name_the_part() {
        let (n, c) = table();
        let cols: Vec<&[f64]> = c.iter().map(|c| c.as_slice()).collect();
        let e = evaluate(&Metric::parse("max(z)").unwrap(), &n, &cols).unwrap_err();
        assert_eq!(e.field, "column");
        assert!(e.message.contains("no column 'z'"), "{e}");
        let e = evaluate(&Metric::parse("mean(x, 2, 3)").unwrap(), &n, &cols).unwrap_err();
        assert_eq!(e.field, "window");
        assert_eq!(Metric::parse("mean(x, 3, 2)").unwrap_err().field, "window");
        assert_eq!(Metric::parse("median(x)").unwrap_err().field, "reduce");
        assert_eq!(Metric::parse("crossing(x)").unwrap_err().field, "threshold");
        assert_eq!(
            Metric::parse("crossing(x, 1, sideways)").unwrap_err().field,
            "direction"
        );
        let m = Metric::parse("peak = max(max(x, y), 0, 1)").unwrap();
        assert_eq!(m.name, "peak");
        assert_eq!(m.quantity, "max(x, y)");
        assert_eq!(m.window, Some([0.0, 1.0]));
    }
}
