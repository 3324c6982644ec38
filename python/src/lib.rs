//! `mbsolve._mbsolve`: the Rust side of the Python package `mbsolve`.
//!
//! A thin layer over the library's public entry points — the same ones the
//! `mbsolve` binary uses: [`mbsolve::scenario::parse`] (with `--set`
//! overrides), [`mbsolve::simulation::simulate_into`], the output columns
//! and rows of [`mbsolve::output`], and the binary's own `check` module
//! (compiled in from `src/bin/mbsolve/check.rs`, not copied). Nothing is
//! computed here that the library or the binary does not compute.
//!
//! Every entry point parses its scenario text anew (no state is shared
//! between calls or threads), runs with the GIL released, and turns a Rust
//! panic into a Python `RuntimeError` instead of a crash.

use mbsolve::events::ContactMonitor;
use mbsolve::integrate::Stats;
use mbsolve::model::Sensor;
use mbsolve::output::{columns, RowBuilder};
use mbsolve::scenario::{self, Scenario};
use mbsolve::simulation::{self, Monitor, Sample, Sink};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sha2::Digest as _;
use std::ops::ControlFlow;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

/// `say!` for the binary's `check` module compiled in below (its
/// printing `command` is not used here).
#[allow(unused_macros)]
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

/// The binary's `mbsolve check` (size, rank of Φ_q, assembly moves).
#[allow(dead_code)]
#[path = "../../src/bin/mbsolve/check.rs"]
mod check;

pyo3::create_exception!(
    _mbsolve,
    ScenarioError,
    PyValueError,
    "A scenario (file, text, override or model) is invalid: attributes `file`, `key` (dotted \
     key path, e.g. `body[1].mass`) and `problem` say where and what."
);

pyo3::create_exception!(
    _mbsolve,
    RunError,
    PyRuntimeError,
    "A run could not start (e.g. an inconsistent initial state). A run that fails midway is \
     not an exception: its `Result` has status \"failed\" and keeps its rows."
);

/// The scenario error as a Python `ScenarioError` with `file`, `key` and
/// `problem` attributes.
fn scenario_err(py: Python<'_>, e: &scenario::ScenarioError) -> PyErr {
    let err = ScenarioError::new_err(e.to_string());
    let v = err.value(py);
    let _ = v.setattr("file", e.file.clone());
    let _ = v.setattr("key", e.key.clone());
    let _ = v.setattr("problem", e.message.clone());
    err
}

/// What a call inside `detach` returns: its value, a scenario error, a run
/// error, or a caught panic.
enum Failure {
    Scenario(scenario::ScenarioError),
    Run(String),
    Panic(String),
}

/// Run `f` with the GIL released, catching a panic.
fn guarded<T: Send>(py: Python<'_>, f: impl FnOnce() -> Result<T, Failure> + Send) -> PyResult<T> {
    let out = py.detach(|| {
        catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|p| {
            let what = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "(no message)".into());
            Err(Failure::Panic(what))
        })
    });
    out.map_err(|f| match f {
        Failure::Scenario(e) => scenario_err(py, &e),
        Failure::Run(m) => RunError::new_err(m),
        Failure::Panic(m) => PyRuntimeError::new_err(format!(
            "mbsolve: internal error (a Rust panic, caught; please report it): {m}"
        )),
    })
}

fn parse(text: &str, file: &str, stem: &str, overrides: &[String]) -> Result<Scenario, Failure> {
    scenario::parse(text, file, stem, overrides).map_err(Failure::Scenario)
}

/// Validate scenario text with overrides; returns the scenario's name.
#[pyfunction]
#[pyo3(signature = (text, file, stem, overrides))]
fn validate(
    py: Python<'_>,
    text: String,
    file: String,
    stem: String,
    overrides: Vec<String>,
) -> PyResult<String> {
    guarded(py, || Ok(parse(&text, &file, &stem, &overrides)?.name))
}

/// What `mbsolve check` reports, as a JSON text.
#[pyfunction]
#[pyo3(signature = (text, file, stem, overrides))]
fn check_json(
    py: Python<'_>,
    text: String,
    file: String,
    stem: String,
    overrides: Vec<String>,
) -> PyResult<String> {
    guarded(py, || {
        let sc = parse(&text, &file, &stem, &overrides)?;
        let size = check::size(&sc.system, &sc.q0, sc.run.t0).map_err(Failure::Run)?;
        let sys = &sc.system;
        let mut v = serde_json::json!({
            "scenario": sc.name,
            "description": sc.description,
            "bodies": size.bodies,
            "coordinates": size.coordinates,
            "constraint_equations": size.constraints,
            "rank": size.rank,
            "dof": size.dof,
            "redundant": size.redundant,
            "joints": sys.constraints().iter().map(|c| c.name()).collect::<Vec<_>>(),
            "forces": sys.forces().iter().map(|f| f.name()).collect::<Vec<_>>(),
            "sensors": sc.sensors.iter().map(|s| s.name.clone()).collect::<Vec<_>>(),
            "evaluation": sys.evaluation_name(),
            "force_kernels": sys.force_kernel_names(),
            "method": sc.run.method.name(),
            "formulation": format!("{:?}", sc.run.index1.formulation),
            "linear_solver": format!("{:?}", sc.run.index1.linear_solver),
            "t0": sc.run.t0,
            "t_end": sc.run.t_end,
            "output_dt": sc.run.output_dt,
        });
        if let Some((_, a)) = check::assembly_moves(&sc) {
            v["initial_assembly"] = a;
        }
        Ok(v.to_string())
    })
}

/// A run's table, column-major (`data[k * nrows + i]` is column k, row i),
/// exposed to NumPy without a copy through `__array_interface__`.
#[pyclass(frozen, module = "mbsolve._mbsolve")]
struct Table {
    data: Vec<f64>,
    ncols: usize,
    nrows: usize,
}

#[pymethods]
impl Table {
    /// NumPy's array interface (version 3): shape (columns, rows), float64,
    /// read-only; `numpy.asarray(table)` is a view that keeps the table alive.
    #[getter]
    fn __array_interface__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("shape", (self.ncols, self.nrows))?;
        d.set_item("typestr", "<f8")?;
        d.set_item("data", (self.data.as_ptr() as usize, true))?;
        d.set_item("version", 3)?;
        Ok(d)
    }

    /// (columns, rows).
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (self.ncols, self.nrows)
    }
}

/// The in-memory sink: rows through the library's `RowBuilder` (the CLI's
/// columns), row-major while running; interrupts from Python's signal
/// handlers (Ctrl-C) checked at most every 50 ms.
struct Collect<'s> {
    builder: RowBuilder<'s>,
    rows: Vec<f64>,
    ncols: usize,
    last_signal_check: Instant,
    check_signals: bool,
}

impl Sink for Collect<'_> {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let row = self.builder.row(s);
        debug_assert_eq!(row.len(), self.ncols);
        self.rows.extend_from_slice(row);
        Ok(())
    }

    fn progress(&mut self, t: f64, _stats: &Stats) -> ControlFlow<String> {
        if self.check_signals && self.last_signal_check.elapsed() >= Duration::from_millis(50) {
            self.last_signal_check = Instant::now();
            let interrupted = Python::attach(|py| py.check_signals().is_err());
            if interrupted {
                return ControlFlow::Break(format!("interrupted (KeyboardInterrupt) at t = {t:e}"));
            }
        }
        ControlFlow::Continue(())
    }
}

/// Everything a run hands back to Python.
type RunOutput = (Table, Vec<String>, Vec<String>, String);

/// Run scenario text with overrides: (table, column names, units, summary
/// JSON). The summary records what `mbsolve run` records (plus the
/// provenance of the text: its SHA-256, the overrides, the version).
#[pyfunction]
#[pyo3(signature = (text, file, stem, overrides, check_signals = true))]
fn run(
    py: Python<'_>,
    text: String,
    file: String,
    stem: String,
    overrides: Vec<String>,
    check_signals: bool,
) -> PyResult<RunOutput> {
    guarded(py, move || {
        let sc = parse(&text, &file, &stem, &overrides)?;
        run_scenario(&sc, &text, &file, &overrides, check_signals)
    })
}

fn run_scenario(
    sc: &Scenario,
    text: &str,
    file: &str,
    overrides: &[String],
    check_signals: bool,
) -> Result<RunOutput, Failure> {
    let sensors: &[Sensor] = &sc.sensors;
    let cols = columns(&sc.system, &sc.run.outputs, sensors);
    let mut sink = Collect {
        builder: RowBuilder::new(&sc.system, sc.run.outputs, sensors),
        rows: Vec::new(),
        ncols: cols.len(),
        last_signal_check: Instant::now(),
        check_signals,
    };
    let mut contacts = ContactMonitor::for_rods(&sc.rods);
    let mut monitors: Vec<&mut dyn Monitor> = Vec::new();
    if let Some(c) = contacts.as_mut() {
        monitors.push(c);
    }
    let mut summary = simulation::simulate_into(
        &sc.system,
        &sc.q0,
        &sc.qd0,
        &sc.run,
        &mut monitors,
        &mut sink,
    )
    .map_err(|e| Failure::Run(e.to_string()))?;
    let hash: String = sha2::Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let mut extra = vec![
        ("scenario", serde_json::json!(file)),
        ("scenario_sha256", serde_json::json!(hash)),
        ("overrides", serde_json::json!(overrides)),
        (
            "mbsolve_version",
            serde_json::json!(env!("CARGO_PKG_VERSION")),
        ),
    ];
    if let Some((_, json)) = check::assembly_moves(sc) {
        extra.push(("initial_assembly", json));
    }
    for (k, v) in extra {
        summary.extra.insert(k.into(), v);
    }
    let json = serde_json::to_string(&summary).map_err(|e| Failure::Run(e.to_string()))?;
    // column-major: each column contiguous for NumPy, pandas and Arrow
    let (ncols, rows) = (sink.ncols, sink.rows);
    let nrows = rows.len().checked_div(ncols).unwrap_or(0);
    let mut data = vec![0.0; rows.len()];
    for (i, row) in rows.chunks_exact(ncols.max(1)).enumerate() {
        for (k, v) in row.iter().enumerate() {
            data[k * nrows + i] = *v;
        }
    }
    let names = cols.iter().map(|c| c.name.clone()).collect();
    let units = cols.iter().map(|c| c.unit.to_string()).collect();
    Ok((Table { data, ncols, nrows }, names, units, json))
}

/// The scenario shipped with the tool: `fourbar` or `falling_rod`.
#[pyfunction]
fn builtin_scenario(name: &str) -> PyResult<&'static str> {
    match name {
        "fourbar" => Ok(scenario::FOURBAR_TOML),
        "falling_rod" => Ok(scenario::FALLING_ROD_TOML),
        other => Err(PyValueError::new_err(format!(
            "no built-in scenario '{other}' (fourbar, falling_rod)"
        ))),
    }
}

/// Raise a caught Rust panic (tests of the boundary only).
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    guarded(py, || -> Result<(), Failure> {
        panic!("a deliberate panic")
    })
}

/// The extension module.
#[pymodule]
fn _mbsolve(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("ScenarioError", m.py().get_type::<ScenarioError>())?;
    m.add("RunError", m.py().get_type::<RunError>())?;
    m.add_class::<Table>()?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(check_json, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_scenario, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    Ok(())
}
