//! Parameter sweeps: the Cartesian product of scenario overrides, run in
//! parallel (rayon). Each run is independent and sequential inside, so the
//! results do not depend on the number of threads; they are returned in the
//! order of the product.
//!
//! Beyond one machine: `--shard I/N` runs the runs k of the product with
//! k mod N = I − 1 (round robin, so every shard gets a similar mix of
//! parameters) and writes a shard table with the run index k; `--merge`
//! joins the N shard tables into the table one unsharded sweep writes,
//! checking that every run is present exactly once.
//!
//! Bounded and interruptible: a product of more than [`MAX_RUNS`] runs is an
//! error before anything runs; SIGINT/SIGTERM end the runs in progress at
//! their next step (status `interrupted`), start no new ones (`not run`),
//! and the table (or shard table) and summaries of every finished run are
//! still written (exit 130).
//!
//! Results, not only statistics: the scenario's `[[metric]]`s and the
//! `--metric`s are reduced over each run's rows as they come
//! ([`mbsolve::output::metrics::Reducer`]) and written as columns after the
//! run statistics; `--keep runs` also writes each run's table as
//! `<stem>_sweep<k>.csv` (k: the run's index in the product) with its
//! `columns.json`, beside its `<stem>_sweep<k>.summary.json`.

use crate::output::{columns_json, create_fresh, sibling, write_atomic, write_summary_json};
use mbsolve::output::metrics::{Metric, Reducer};
use mbsolve::output::{columns, RowBuilder, TableWriter};
use mbsolve::parallel::Threads;
use mbsolve::scenario::{self, Override, Scenario, ScenarioError};
use mbsolve::simulation::{simulate_into, Sample, Sink, Summary};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Most runs of one sweep's product (10⁵): every combination is listed and
/// validated before the first run. Larger studies are split into several
/// sweeps.
pub const MAX_RUNS: usize = 100_000;

/// One parameter of a sweep: a scenario key and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepParam {
    /// Scenario key, e.g. `stabilization.alpha`.
    pub key: String,
    /// Values as they would be written after `--set KEY=`.
    pub values: Vec<String>,
}

impl std::str::FromStr for SweepParam {
    type Err = String;
    /// `KEY=v1,v2,…` (split at the commas outside brackets and quotes, so
    /// `"max(a, b)"` is one value), `KEY=[v1, v2, …]` (a TOML array: its
    /// elements are the values; an array value is written inside it,
    /// `[[0, -9.81], [0, -1.62]]`), `KEY=linspace(a, b, n)` (n values
    /// from a to b, both included) or `KEY=logspace(a, b, n)` (n values
    /// from a to b, geometric; a, b > 0).
    fn from_str(s: &str) -> Result<Self, String> {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| format!("--param {s}: expected KEY=v1,v2,..."))?;
        let v = v.trim();
        let values = sweep_values(v).map_err(|m| format!("--param {s}: {m}"))?;
        if k.trim().is_empty() || values.is_empty() || values.iter().any(|x| x.is_empty()) {
            return Err(format!(
                "--param {s}: expected KEY=v1,v2,..., KEY=[v1, v2, ...] or \
                 KEY=linspace(a, b, n), with non-empty values"
            ));
        }
        Ok(Self {
            key: k.trim().to_string(),
            values,
        })
    }
}

/// The values of `--param KEY=VALUES`, each as it would be written after
/// `--set KEY=` (see [`SweepParam`]'s `from_str`).
fn sweep_values(v: &str) -> Result<Vec<String>, String> {
    if v.starts_with('[') {
        let t: toml::Table = format!("v = {v}")
            .parse()
            .map_err(|e: toml::de::Error| format!("not a TOML array: {}", e.message().trim()))?;
        return match t.get("v") {
            Some(toml::Value::Array(a)) => Ok(a.iter().map(ToString::to_string).collect()),
            _ => Err("not a TOML array".into()),
        };
    }
    for (name, geometric) in [("linspace", false), ("logspace", true)] {
        let Some(args) = v
            .strip_prefix(name)
            .map(str::trim_start)
            .and_then(|r| r.strip_prefix('('))
            .and_then(|r| r.strip_suffix(')'))
        else {
            continue;
        };
        let parts = split_top(args)?;
        let bad = || format!("expected {name}(a, b, n) with numbers a, b and a count n ≥ 2");
        let [a, b, n] = parts.as_slice() else {
            return Err(bad());
        };
        let (a, b): (f64, f64) = (a.parse().map_err(|_| bad())?, b.parse().map_err(|_| bad())?);
        let n: usize = n.parse().map_err(|_| bad())?;
        if n < 2 || !a.is_finite() || !b.is_finite() {
            return Err(bad());
        }
        if n > MAX_RUNS {
            return Err(format!(
                "{n} values: more than the limit of {MAX_RUNS} runs"
            ));
        }
        if geometric && !(a > 0.0 && b > 0.0) {
            return Err(format!("{name}(a, b, n) needs a, b > 0"));
        }
        return Ok((0..n)
            .map(|i| {
                let x = if i == n - 1 {
                    b
                } else if geometric {
                    a * (b / a).powf(i as f64 / (n - 1) as f64)
                } else {
                    a + (b - a) * (i as f64 / (n - 1) as f64)
                };
                number(x)
            })
            .collect());
    }
    split_top(v)
}

/// `v` for `--set`: an integer when it is one (so that integer keys take
/// it), else the shortest text that reads back to the same bits.
fn number(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 9.0e15 {
        format!("{}", v as i64)
    } else {
        format!("{v:e}")
    }
}

/// `s` split at the commas outside brackets (`()`, `[]`, `{}`) and quotes
/// (`"…"`, `'…'`), each part trimmed; unbalanced brackets or quotes are
/// errors.
fn split_top(s: &str) -> Result<Vec<String>, String> {
    let mut parts = Vec::new();
    let mut depth: Vec<char> = Vec::new();
    let mut quote: Option<char> = None;
    let mut cur = String::new();
    let mut escaped = false;
    for c in s.chars() {
        if let Some(q) = quote {
            cur.push(c);
            if escaped {
                escaped = false;
            } else if c == '\\' && q == '"' {
                escaped = true;
            } else if c == q {
                quote = None;
            }
            continue;
        }
        match c {
            '"' | '\'' => quote = Some(c),
            '(' => depth.push(')'),
            '[' => depth.push(']'),
            '{' => depth.push('}'),
            ')' | ']' | '}' if depth.pop() != Some(c) => {
                return Err(format!("unbalanced '{c}' in '{s}'"));
            }
            ',' if depth.is_empty() => {
                parts.push(cur.trim().to_string());
                cur.clear();
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    if let Some(q) = quote {
        return Err(format!("unclosed {q} in '{s}'"));
    }
    if let Some(c) = depth.pop() {
        return Err(format!("missing '{c}' in '{s}'"));
    }
    parts.push(cur.trim().to_string());
    Ok(parts)
}

/// The outcome of one run of a sweep.
#[derive(Debug)]
pub struct SweepRun {
    /// The `KEY=VALUE` overrides of this run (sweep parameters only).
    pub point: Vec<String>,
    /// The summary, or why the run could not start.
    pub result: Result<Summary, String>,
    /// Each metric's value (NaN: a crossing that did not happen), or why it
    /// has none; empty when the run did not start.
    pub metrics: Vec<Result<f64, String>>,
}

/// What a sweep keeps of each run's rows: the metrics' reductions, and the
/// table itself with `--keep runs`. Without either, rows are dropped as
/// they come, so a sweep's memory does not grow with the output times.
struct Recorder<'s> {
    builder: Option<RowBuilder<'s>>,
    reducers: Vec<Reducer>,
    kept: Option<Kept>,
}

/// A run's table being kept: the writer, its temporary and final paths.
struct Kept {
    table: Box<dyn TableWriter + Send>,
    part: PathBuf,
    path: PathBuf,
}

impl<'s> Recorder<'s> {
    /// The recorder of run `sc` with `metrics`; with `keep`, the table is
    /// written to `keep` (`.part` until the run ends) and its columns to
    /// the `columns.json` beside it.
    fn new(sc: &'s Scenario, metrics: &[Metric], keep: Option<PathBuf>) -> Result<Self, String> {
        if metrics.is_empty() && keep.is_none() {
            return Ok(Self {
                builder: None,
                reducers: Vec::new(),
                kept: None,
            });
        }
        let cols = columns(&sc.system, &sc.run.outputs, &sc.sensors);
        let names: Vec<&str> = cols.iter().map(|c| c.name.as_str()).collect();
        let reducers = metrics
            .iter()
            .map(|m| Reducer::new(m, &names).map_err(|e| format!("metric '{}': {e}", m.name)))
            .collect::<Result<Vec<_>, _>>()?;
        let kept = match keep {
            None => None,
            Some(path) => {
                let part = sibling(&path, ".part");
                let file = create_fresh(&part).map_err(|e| e.to_string())?;
                let table = sc
                    .format
                    .writer(std::io::BufWriter::new(file), &cols)
                    .map_err(|e| format!("{}: {e}", part.display()))?;
                let stem = path.with_extension("");
                write_atomic(&sibling(&stem, ".columns.json"), &columns_json(&cols))
                    .map_err(|e| e.to_string())?;
                Some(Kept { table, part, path })
            }
        };
        Ok(Self {
            builder: Some(RowBuilder::new(
                &sc.system,
                sc.run.outputs,
                sc.sensors.as_slice(),
            )),
            reducers,
            kept,
        })
    }

    /// The metrics' values, and the kept table finished and renamed into
    /// place (whatever the run's status: its rows so far).
    fn finish(mut self) -> (Vec<Result<f64, String>>, Option<String>) {
        let values = self
            .reducers
            .iter()
            .map(|r| {
                r.finish()
                    .map_err(|e| format!("metric '{}': {e}", r.metric().name))
            })
            .collect();
        let kept = self.kept.take().and_then(|mut k| {
            let done = k
                .table
                .finish()
                .map_err(|e| e.to_string())
                .and_then(|()| std::fs::rename(&k.part, &k.path).map_err(|e| e.to_string()));
            done.err().map(|e| format!("{}: {e}", k.path.display()))
        });
        (values, kept)
    }
}

impl Sink for Recorder<'_> {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let Some(b) = self.builder.as_mut() else {
            return Ok(());
        };
        let row = b.row(s);
        for r in &mut self.reducers {
            r.push(row);
        }
        if let Some(k) = self.kept.as_mut() {
            k.table
                .write_row(row)
                .map_err(|e| format!("{}: {e}", k.part.display()))?;
        }
        Ok(())
    }
    fn progress(&mut self, t: f64, _: &mbsolve::integrate::Stats) -> std::ops::ControlFlow<String> {
        if crate::stream::INTERRUPTED.load(Ordering::Relaxed) {
            return std::ops::ControlFlow::Break(format!("interrupted by a signal at t = {t:e}"));
        }
        std::ops::ControlFlow::Continue(())
    }
}

/// The number of runs of the product, or an error naming the sizes when it
/// exceeds [`MAX_RUNS`].
pub fn product_size(params: &[SweepParam]) -> Result<usize, String> {
    let total = params
        .iter()
        .try_fold(1usize, |a, p| a.checked_mul(p.values.len()))
        .filter(|&n| n <= MAX_RUNS);
    total.ok_or_else(|| {
        let sizes: Vec<String> = params
            .iter()
            .map(|p| format!("{} ({})", p.key, p.values.len()))
            .collect();
        let product: f64 = params.iter().map(|p| p.values.len() as f64).product();
        format!(
            "--param: the sweep has {product:.3e} runs ({}), more than the limit of {MAX_RUNS}: \
             split it into several sweeps",
            sizes.join(" × ")
        )
    })
}

/// All combinations, first parameter slowest.
pub fn combinations(params: &[SweepParam]) -> Vec<Vec<String>> {
    let mut out = vec![Vec::new()];
    for p in params {
        out = out
            .into_iter()
            .flat_map(|prefix| {
                p.values.iter().map(move |v| {
                    let mut c = prefix.clone();
                    c.push(format!("{}={}", p.key, v));
                    c
                })
            })
            .collect();
    }
    out
}

/// Shard `i` of `n` (1-based), parsed from `I/N`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shard {
    /// This shard, 1 ≤ i ≤ n.
    pub i: usize,
    /// Number of shards.
    pub n: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("--shard {s}: expected I/N with 1 ≤ I ≤ N, e.g. --shard 3/8");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (i, n): (usize, usize) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if n == 0 || i == 0 || i > n {
            return Err(bad());
        }
        Ok(Shard { i, n })
    }
}

impl Shard {
    /// Does run `k` of the product belong to this shard?
    pub fn owns(&self, k: usize) -> bool {
        k % self.n == self.i - 1
    }
}

/// What each run of a sweep records besides its statistics.
pub struct Record<'a> {
    /// The `--metric`s (after the scenario's `[[metric]]`s).
    pub metrics: &'a [(String, Metric)],
    /// `--keep runs`: each run's table as `DIR/<stem>_sweep<k>.<ext>`.
    pub keep: Option<(&'a Path, &'a str)>,
}

/// The metrics of run `sc`: its `[[metric]]`s, then the `--metric`s
/// checked against its columns and time span (errors name the flag).
fn run_metrics(sc: &Scenario, cli: &[(String, Metric)]) -> Result<Vec<Metric>, ScenarioError> {
    let mut all = sc.metrics.clone();
    for (text, m) in cli {
        scenario::metric::check(m, &sc.system, &sc.run, &sc.sensors).map_err(|e| {
            ScenarioError {
                file: "--metric".into(),
                key: text.clone(),
                message: e.to_string(),
            }
        })?;
        all.push(m.clone());
    }
    Ok(all)
}

/// Run the sweep over `path` (with `base` overrides applied first), only
/// the runs of `shard` when given; returns (run index in the product, run).
/// Every combination is validated before anything runs (its metrics
/// included), so a bad key fails fast with the scenario's error. `progress`
/// labels a line on stderr per finished run.
pub fn run(
    path: &Path,
    base: &Base,
    params: &[SweepParam],
    shard: Option<Shard>,
    progress: &str,
    record: &Record,
) -> Result<Vec<(usize, SweepRun)>, ScenarioError> {
    let points: Vec<(usize, Vec<String>)> = combinations(params)
        .into_iter()
        .enumerate()
        .filter(|(k, _)| shard.is_none_or(|s| s.owns(*k)))
        .collect();
    for (k, (_, p)) in points.iter().enumerate() {
        let sc = scenario::load_with(path, &overrides(base, p))?;
        run_metrics(&sc, record.metrics)?;
        if k == 0 {
            for n in &sc.notes {
                eprintln!("note: {n}");
            }
        }
    }
    let total = points.len();
    // runs side by side on the pool's threads: each run on one thread
    // (unless its scenario forces two), not a team per run as well
    let side_by_side = total > 1 && rayon::current_num_threads() > 1;
    let done = AtomicUsize::new(0);
    let interrupted = || crate::stream::INTERRUPTED.load(Ordering::Relaxed);
    let start = std::time::Instant::now();
    Ok(points
        .into_par_iter()
        .map(|(k, point)| {
            if interrupted() {
                let result = Err(NOT_RUN.to_string());
                let metrics = Vec::new();
                return (k, SweepRun { point, result, metrics });
            }
            let mut metrics = Vec::new();
            let result = scenario::load_with(path, &overrides(base, &point))
                .map_err(|e| e.to_string())
                .and_then(|mut sc| {
                    if side_by_side && sc.run.threads == Threads::Auto {
                        sc.run.threads = Threads::One;
                    }
                    let wanted = run_metrics(&sc, record.metrics).map_err(|e| e.to_string())?;
                    let keep = record.keep.map(|(dir, stem)| {
                        dir.join(format!("{stem}_sweep{k}.{}", sc.format.extension()))
                    });
                    let mut rec = Recorder::new(&sc, &wanted, keep)?;
                    let summary = simulate_into(
                        &sc.system,
                        &sc.q0,
                        &sc.qd0,
                        &sc.run,
                        &mut [],
                        &mut rec,
                    )
                    .map_err(|e| e.to_string());
                    let (values, kept) = rec.finish();
                    metrics = values;
                    match (summary, kept) {
                        (Ok(mut s), Some(e)) => {
                            s.warnings.push(format!("the run's table was not kept: {e}"));
                            Ok(s)
                        }
                        (s, _) => s,
                    }
                });
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            let wall = start.elapsed().as_secs_f64();
            let eta = wall * (total - d) as f64 / d as f64;
            let outcome = match &result {
                Ok(s) if s.warnings.is_empty() => s.status.clone(),
                Ok(s) => format!("{}, {} warnings: {}", s.status, s.warnings.len(), s.warnings[0]),
                Err(e) if e == NOT_RUN => e.clone(),
                Err(e) => format!("error: {e}"),
            };
            eprintln!(
                "{progress}{d}/{total} runs done, {wall:.1} s, ETA {eta:.0} s (run {k}: {}: {outcome})",
                point.join(" ")
            );
            (k, SweepRun { point, result, metrics })
        })
        .collect())
}

/// The status of a run the sweep did not start because of a signal.
const NOT_RUN: &str = "not run: the sweep was interrupted by a signal";

/// The `--unset` keys and `--set` overrides, then one run's `--param`
/// values, each labelled by its flag for the scenario's errors.
fn overrides<'a>(base: &'a Base, point: &'a [String]) -> Vec<Override<'a>> {
    let tag = |flag: &'static str| move |spec: &'a String| Override { flag, spec };
    scenario::overrides(&base.1, &base.0)
        .into_iter()
        .chain(point.iter().map(tag("--param")))
        .collect()
}

/// The `--set` overrides and the `--unset` keys of every run.
pub type Base = (Vec<String>, Vec<String>);

/// What `--keep` keeps besides the sweep table and the summaries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Keep {
    /// Each run's table, `<stem>_sweep<k>.csv` (or `.arrow`), with its
    /// `columns.json`.
    Runs,
}

/// What `mbsolve sweep` was asked for.
pub struct SweepArgs {
    /// Scenario file.
    pub scenario: PathBuf,
    /// `--param KEY=v1,v2,…` arguments.
    pub params: Vec<String>,
    /// `--set` overrides of every run.
    pub set: Vec<String>,
    /// `--unset` keys of every run.
    pub unset: Vec<String>,
    /// `--metric [NAME=]REDUCE(QUANTITY[, T0, T1])` arguments.
    pub metrics: Vec<String>,
    /// `--keep runs`: keep each run's table.
    pub keep_runs: bool,
    /// Output directory.
    pub out: PathBuf,
    /// `--shard I/N`.
    pub shard: Option<String>,
    /// `--merge`.
    pub merge: bool,
}

/// Columns after the parameters in a sweep table; the metrics follow, then
/// [`MESSAGE_COLUMN`].
const RESULT_COLUMNS: [&str; 7] = [
    "status",
    "steps",
    "failed_steps",
    "rhs_evals",
    "wall_s",
    "max_constraint_norm",
    "final_constraint_norm",
];

/// The last column of a sweep table: why a run did not complete, or why a
/// metric has no value (empty otherwise).
const MESSAGE_COLUMN: &str = "message";

/// A metric's cell: `{:.12e}` as in run tables, empty for NaN.
fn metric_cell(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else {
        format!("{v:.12e}")
    }
}

/// `mbsolve sweep`: run (all or one shard) or merge.
pub fn command(a: &SweepArgs) -> Result<ExitCode, String> {
    let params = a
        .params
        .iter()
        .map(|p| p.parse::<SweepParam>())
        .collect::<Result<Vec<_>, _>>()?;
    for (k, p) in params.iter().enumerate() {
        if params[..k].iter().any(|q| q.key == p.key) {
            return Err(format!("--param {}: the key is given twice", p.key));
        }
        if let Some(s) = a
            .set
            .iter()
            .find(|s| s.split_once('=').is_some_and(|(k, _)| k.trim() == p.key))
        {
            return Err(format!(
                "--param {}: the key is also fixed by --set {s}",
                p.key
            ));
        }
    }
    let cli_metrics = a
        .metrics
        .iter()
        .map(|t| {
            Metric::parse(t)
                .map(|m| (t.clone(), m))
                .map_err(|e| format!("--metric {t}: {e}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    product_size(&params)?;
    let shard = a.shard.as_deref().map(str::parse::<Shard>).transpose()?;
    let stem = a
        .scenario
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scenario".into());
    let base = (a.set.clone(), a.unset.clone());
    // the metric columns: the file's [[metric]]s (as the first run loads
    // them), then the --metric names; every column name once
    let first = combinations(&params).into_iter().next().unwrap_or_default();
    let sc =
        scenario::load_with(&a.scenario, &overrides(&base, &first)).map_err(|e| e.to_string())?;
    let mut header: Vec<String> = params.iter().map(|p| p.key.clone()).collect();
    header.extend(RESULT_COLUMNS.map(String::from));
    let metric_names: Vec<String> = sc
        .metrics
        .iter()
        .map(|m| m.name.clone())
        .chain(cli_metrics.iter().map(|(_, m)| m.name.clone()))
        .collect();
    for (k, n) in metric_names.iter().enumerate() {
        if header.contains(n) || metric_names[..k].contains(n) || n == MESSAGE_COLUMN {
            return Err(format!(
                "metric '{n}': another column of the sweep table has this name: name the \
                 metric (--metric NAME=REDUCE(...), or name = ... in [[metric]])"
            ));
        }
    }
    drop(sc);
    header.extend(metric_names.iter().cloned());
    header.push(MESSAGE_COLUMN.into());
    let status_column = params.len();
    if a.merge {
        return merge(
            &a.out,
            &stem,
            &header,
            status_column,
            combinations(&params).len(),
        );
    }
    let label = shard.map_or(String::new(), |s| format!("shard {}/{}: ", s.i, s.n));
    crate::stream::install_interrupt_handler();
    crate::output::create_dir(&a.out)?;
    let record = Record {
        metrics: &cli_metrics,
        keep: a.keep_runs.then_some((a.out.as_path(), stem.as_str())),
    };
    let runs =
        run(&a.scenario, &base, &params, shard, &label, &record).map_err(|e| e.to_string())?;
    let table = match shard {
        None => a.out.join(format!("{stem}_sweep.csv")),
        Some(s) => a
            .out
            .join(format!("{stem}_sweep.shard-{}-of-{}.csv", s.i, s.n)),
    };
    let werr = |e: &dyn std::fmt::Display| format!("{}: {e}", table.display());
    let mut w = csv::Writer::from_path(&table).map_err(|e| werr(&e))?;
    let mut first: Vec<String> = if shard.is_some() {
        vec!["run".into()]
    } else {
        Vec::new()
    };
    first.extend(header.iter().cloned());
    w.write_record(&first).map_err(|e| werr(&e))?;
    let mut failures = 0;
    for (k, r) in &runs {
        let mut row: Vec<String> = if shard.is_some() {
            vec![k.to_string()]
        } else {
            Vec::new()
        };
        row.extend(
            r.point
                .iter()
                .map(|p| p.split_once('=').map_or(String::new(), |x| x.1.to_string())),
        );
        let mut messages: Vec<String> = Vec::new();
        match &r.result {
            Ok(s) => {
                write_summary_json(&a.out.join(format!("{stem}_sweep{k}.summary.json")), s)
                    .map_err(|e| e.to_string())?;
                if s.status != "completed" {
                    failures += 1;
                    messages.push(s.message.clone().unwrap_or_else(|| s.status.clone()));
                }
                row.extend([
                    s.status.clone(),
                    s.steps.to_string(),
                    s.failed_steps.to_string(),
                    s.rhs_evals.to_string(),
                    format!("{:.6}", s.wall_s),
                    format!("{:.6e}", s.max_constraint_norm),
                    format!("{:.6e}", s.final_constraint_norm),
                ]);
                // a run that did not complete has no final value, peak or
                // mean over its span: its metric cells stay empty
                let completed = s.status == "completed";
                for m in &r.metrics {
                    match m {
                        Ok(v) if completed => row.push(metric_cell(*v)),
                        Ok(_) => row.push(String::new()),
                        Err(e) => {
                            row.push(String::new());
                            if completed {
                                failures += 1;
                                messages.push(e.clone());
                            }
                        }
                    }
                }
                say!(
                    "{}: {} steps, max ‖Φ‖ = {:.3e}",
                    r.point.join(" "),
                    s.steps,
                    s.max_constraint_norm
                );
            }
            Err(e) => {
                failures += 1;
                let status = if e == NOT_RUN { "not run" } else { "error" };
                row.push(status.into());
                messages.push(e.clone());
                if e == NOT_RUN {
                    say!("{}: {e}", r.point.join(" "));
                } else {
                    say!("{}: {status}: {e}", r.point.join(" "));
                }
            }
        }
        row.resize(first.len() - 1, String::new());
        row.push(messages.join("; "));
        w.write_record(&row).map_err(|e| werr(&e))?;
    }
    w.flush().map_err(|e| werr(&e))?;
    say!("wrote {}", table.display());
    if crate::stream::INTERRUPTED.load(Ordering::Relaxed) {
        eprintln!(
            "sweep interrupted by a signal: the finished runs are in {}",
            table.display()
        );
        return Ok(ExitCode::from(130));
    }
    Ok(if failures == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// The members of `all` that are not `present`, as "a, b, c" (`None`:
/// none missing).
fn missing(all: impl Iterator<Item = usize>, present: impl Fn(usize) -> bool) -> Option<String> {
    let m: Vec<String> = all
        .filter(|&i| !present(i))
        .map(|i| i.to_string())
        .collect();
    (!m.is_empty()).then(|| m.join(", "))
}

/// Join the shard tables `<stem>_sweep.shard-I-of-N.csv` in `dir` into
/// `<stem>_sweep.csv` (product order, without the run column). Every run
/// 0 … total−1 must appear exactly once, all shards must share one N and
/// the sweep's columns. Exit status 1 when a merged run did not complete.
fn merge(
    dir: &Path,
    stem: &str,
    header: &[String],
    status: usize,
    total: usize,
) -> Result<ExitCode, String> {
    let prefix = format!("{stem}_sweep.shard-");
    let mut shards: Vec<(PathBuf, usize, usize)> = Vec::new();
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for e in entries {
        let path = e.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let Some(rest) = name
            .strip_prefix(&prefix)
            .and_then(|r| r.strip_suffix(".csv"))
        else {
            continue;
        };
        let parsed = rest
            .split_once("-of-")
            .and_then(|(i, n)| Some((i.parse().ok()?, n.parse().ok()?)));
        let (i, n) = parsed.ok_or_else(|| format!("{}: not a shard table name", path.display()))?;
        shards.push((path, i, n));
    }
    if shards.is_empty() {
        return Err(format!(
            "{}: no shard tables {prefix}I-of-N.csv to merge",
            dir.display()
        ));
    }
    shards.sort_by_key(|s| s.1);
    let n = shards[0].2;
    if let Some(s) = shards.iter().find(|s| s.2 != n) {
        return Err(format!(
            "{}: a shard of {} runs next to shards of {n}: remove stale tables",
            s.0.display(),
            s.2
        ));
    }
    if let Some(m) = missing(1..=n, |i| shards.iter().any(|s| s.1 == i)) {
        return Err(format!("{}: shard(s) {m} of {n} missing", dir.display()));
    }
    let mut rows: Vec<Option<csv::StringRecord>> = vec![None; total];
    for (path, _, _) in &shards {
        let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
        let mut r = csv::Reader::from_path(path).map_err(|e| err(&e))?;
        let h = r.headers().map_err(|e| err(&e))?.clone();
        if h.len() != header.len() + 1
            || &h[0] != "run"
            || h.iter().skip(1).zip(header).any(|(a, b)| a != b)
        {
            return Err(err(&format!(
                "columns {:?} are not those of this sweep (run, {})",
                h.iter().collect::<Vec<_>>(),
                header.join(", ")
            )));
        }
        for rec in r.records() {
            let rec = rec.map_err(|e| err(&e))?;
            let k: usize = rec[0]
                .parse()
                .ok()
                .filter(|k| *k < total)
                .ok_or_else(|| err(&format!("run index '{}' is not in 0..{total}", &rec[0])))?;
            if rows[k].is_some() {
                return Err(err(&format!("run {k} appears twice")));
            }
            rows[k] = Some(rec.iter().skip(1).collect());
        }
    }
    if let Some(m) = missing(0..total, |k| rows[k].is_some()) {
        return Err(format!(
            "{}: run(s) {m} of the sweep are in no shard table (a shard did not finish?)",
            dir.display(),
        ));
    }
    let table = dir.join(format!("{stem}_sweep.csv"));
    let werr = |e: &dyn std::fmt::Display| format!("{}: {e}", table.display());
    let mut w = csv::Writer::from_path(&table).map_err(|e| werr(&e))?;
    w.write_record(header).map_err(|e| werr(&e))?;
    let mut failures = 0;
    for rec in rows.into_iter().flatten() {
        if &rec[status] != "completed" || rec.get(rec.len() - 1).is_some_and(|m| !m.is_empty()) {
            failures += 1;
        }
        w.write_record(&rec).map_err(|e| werr(&e))?;
    }
    w.flush().map_err(|e| werr(&e))?;
    say!(
        "merged {n} shards, {total} runs ({failures} not completed) into {}",
        table.display()
    );
    Ok(if failures == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_split_outside_brackets_and_quotes() {
        let p: SweepParam = "k=1, \"max(a, b)\", [1, 2], 'x,y'".parse().unwrap();
        assert_eq!(p.values, ["1", "\"max(a, b)\"", "[1, 2]", "'x,y'"]);
        let p: SweepParam = "k=[1e3, \"a, b\", [0, -1.5]]".parse().unwrap();
        assert_eq!(p.values, ["1000.0", "\"a, b\"", "[0, -1.5]"]);
    }

    #[test]
    fn ranges_include_both_ends_and_read_back_exactly() {
        let p: SweepParam = "k=linspace(1e3, 4e3, 7)".parse().unwrap();
        assert_eq!(
            p.values,
            ["1000", "1500", "2000", "2500", "3000", "3500", "4000"]
        );
        let p: SweepParam = "k=linspace(0, 1, 4)".parse().unwrap();
        let back: Vec<f64> = p.values.iter().map(|v| v.parse().unwrap()).collect();
        assert_eq!(back, [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0]);
        let p: SweepParam = "k=logspace(1, 1000, 4)".parse().unwrap();
        let back: Vec<f64> = p.values.iter().map(|v| v.parse().unwrap()).collect();
        for (b, w) in back.iter().zip([1.0, 10.0, 100.0, 1000.0]) {
            assert!((b - w).abs() < 1e-12 * w, "{back:?}");
        }
    }
}
