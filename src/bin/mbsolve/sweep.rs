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

use crate::output::write_summary_json;
use mbsolve::parallel::Threads;
use mbsolve::scenario::{self, Override, ScenarioError};
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
}

/// A sweep keeps only each run's summary: its output rows are dropped as
/// they come, so a sweep's memory does not grow with the output times.
struct SummaryOnly;

impl Sink for SummaryOnly {
    fn output(&mut self, _: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
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

/// Run the sweep over `path` (with `base` overrides applied first), only
/// the runs of `shard` when given; returns (run index in the product, run).
/// Every combination is validated before anything runs, so a bad key fails
/// fast with the scenario's error. `progress` labels a line on stderr per
/// finished run.
pub fn run(
    path: &Path,
    base: &Base,
    params: &[SweepParam],
    shard: Option<Shard>,
    progress: &str,
) -> Result<Vec<(usize, SweepRun)>, ScenarioError> {
    let points: Vec<(usize, Vec<String>)> = combinations(params)
        .into_iter()
        .enumerate()
        .filter(|(k, _)| shard.is_none_or(|s| s.owns(*k)))
        .collect();
    for (k, (_, p)) in points.iter().enumerate() {
        let sc = scenario::load_with(path, &overrides(base, p))?;
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
                let result = Err("not run: the sweep was interrupted by a signal".to_string());
                return (k, SweepRun { point, result });
            }
            let result = scenario::load_with(path, &overrides(base, &point))
                .map_err(|e| e.to_string())
                .and_then(|mut sc| {
                    if side_by_side && sc.run.threads == Threads::Auto {
                        sc.run.threads = Threads::One;
                    }
                    simulate_into(
                        &sc.system,
                        &sc.q0,
                        &sc.qd0,
                        &sc.run,
                        &mut [],
                        &mut SummaryOnly,
                    )
                    .map_err(|e| e.to_string())
                });
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            let wall = start.elapsed().as_secs_f64();
            let eta = wall * (total - d) as f64 / d as f64;
            let outcome = match &result {
                Ok(s) if s.warnings.is_empty() => s.status.clone(),
                Ok(s) => format!("{}, {} warnings: {}", s.status, s.warnings.len(), s.warnings[0]),
                Err(e) => format!("error: {e}"),
            };
            eprintln!(
                "{progress}{d}/{total} runs done, {wall:.1} s, ETA {eta:.0} s (run {k}: {}: {outcome})",
                point.join(" ")
            );
            (k, SweepRun { point, result })
        })
        .collect())
}

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
    /// Output directory.
    pub out: PathBuf,
    /// `--shard I/N`.
    pub shard: Option<String>,
    /// `--merge`.
    pub merge: bool,
}

/// Columns after the parameters in a sweep table.
const RESULT_COLUMNS: [&str; 7] = [
    "status",
    "steps",
    "failed_steps",
    "rhs_evals",
    "wall_s",
    "max_constraint_norm",
    "final_constraint_norm",
];

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
    product_size(&params)?;
    let shard = a.shard.as_deref().map(str::parse::<Shard>).transpose()?;
    let stem = a
        .scenario
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scenario".into());
    let mut header: Vec<String> = params.iter().map(|p| p.key.clone()).collect();
    header.extend(RESULT_COLUMNS.map(String::from));
    if a.merge {
        return merge(&a.out, &stem, &header, combinations(&params).len());
    }
    let label = shard.map_or(String::new(), |s| format!("shard {}/{}: ", s.i, s.n));
    crate::stream::install_interrupt_handler();
    let base = (a.set.clone(), a.unset.clone());
    let runs = run(&a.scenario, &base, &params, shard, &label).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
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
        match &r.result {
            Ok(s) => {
                write_summary_json(&a.out.join(format!("{stem}_sweep{k}.summary.json")), s)
                    .map_err(|e| e.to_string())?;
                if s.status != "completed" {
                    failures += 1;
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
                say!(
                    "{}: {} steps, max ‖Φ‖ = {:.3e}",
                    r.point.join(" "),
                    s.steps,
                    s.max_constraint_norm
                );
            }
            Err(e) => {
                failures += 1;
                row.extend(["error".to_string(), e.clone()]);
                row.resize(first.len(), String::new());
                say!("{}: error: {e}", r.point.join(" "));
            }
        }
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

/// Join the shard tables `<stem>_sweep.shard-I-of-N.csv` in `dir` into
/// `<stem>_sweep.csv` (product order, without the run column). Every run
/// 0 … total−1 must appear exactly once, all shards must share one N and
/// the sweep's columns. Exit status 1 when a merged run did not complete.
fn merge(dir: &Path, stem: &str, header: &[String], total: usize) -> Result<ExitCode, String> {
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
    let missing: Vec<String> = (1..=n)
        .filter(|i| !shards.iter().any(|s| s.1 == *i))
        .map(|i| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{}: shard(s) {} of {n} missing",
            dir.display(),
            missing.join(", ")
        ));
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
    let missing: Vec<String> = (0..total)
        .filter(|k| rows[*k].is_none())
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{}: run(s) {} of the sweep are in no shard table (a shard did not finish?)",
            dir.display(),
            missing.join(", ")
        ));
    }
    let table = dir.join(format!("{stem}_sweep.csv"));
    let werr = |e: &dyn std::fmt::Display| format!("{}: {e}", table.display());
    let mut w = csv::Writer::from_path(&table).map_err(|e| werr(&e))?;
    w.write_record(header).map_err(|e| werr(&e))?;
    let status = header.len() - RESULT_COLUMNS.len();
    let mut failures = 0;
    for rec in rows.into_iter().flatten() {
        if &rec[status] != "completed" {
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
