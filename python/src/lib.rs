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
use mbsolve::forces::{CallbackError, CallbackForce, CallbackLaw};
use mbsolve::integrate::Stats;
use mbsolve::model::Sensor;
use mbsolve::output::{columns, RowBuilder};
use mbsolve::parallel::Threads;
use mbsolve::scenario::{self, Scenario};
use mbsolve::simulation::{self, Monitor, Sample, Sink};
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use sha2::Digest as _;
use std::ops::ControlFlow;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex, PoisonError};
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
            "states": size.states,
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
            "formulation": format!("{:?}", sc.run.formulation.formulation),
            "linear_solver": format!("{:?}", sc.run.formulation.linear_solver),
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
    /// The column names, in order.
    names: Vec<String>,
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

    /// `quantity` — a column name (or a positional name of earlier
    /// versions such as `phi1`) or an expression of column names — reduced
    /// by the library's metrics (`mbsolve::output::metrics`: `final`, `min`,
    /// `max`, `mean` and `rms` as time averages by the trapezoidal rule,
    /// `crossing` with `threshold` and `direction`) over the rows with
    /// `t_from <= t <= t_to` (open ends: `None`, the run's first and last
    /// row). A window without rows, an unknown reduction or column raise
    /// `ValueError`.
    #[pyo3(signature = (quantity, kind, t_from = None, t_to = None, threshold = None, direction = None))]
    fn reduce(
        &self,
        quantity: &str,
        kind: &str,
        t_from: Option<f64>,
        t_to: Option<f64>,
        threshold: Option<f64>,
        direction: Option<&str>,
    ) -> PyResult<f64> {
        use mbsolve::output::metrics::{check_window, evaluate, Metric, Reduction};
        let bad = |e: mbsolve::output::metrics::MetricError| PyValueError::new_err(e.to_string());
        let names: Vec<&str> = self.names.iter().map(String::as_str).collect();
        let col = |k: usize| &self.data[k * self.nrows..(k + 1) * self.nrows];
        let t = names
            .iter()
            .position(|n| *n == "t")
            .map(col)
            .ok_or_else(|| PyValueError::new_err("the table has no column 't'"))?;
        let (Some(&first), Some(&last)) = (t.first(), t.last()) else {
            return Err(PyValueError::new_err("the run has no output rows"));
        };
        let window = match (t_from, t_to) {
            (None, None) => None,
            (a, b) => {
                let w = [a.unwrap_or(first), b.unwrap_or(last)];
                Some(if w[0] == w[1] {
                    w
                } else {
                    check_window(w).map_err(bad)?
                })
            }
        };
        let metric = Metric {
            name: format!("{kind}({quantity})"),
            quantity: quantity.to_string(),
            reduction: Reduction::new(kind, threshold, direction).map_err(bad)?,
            window,
        };
        let columns: Vec<&[f64]> = (0..self.ncols).map(col).collect();
        evaluate(&metric, &names, &columns).map_err(bad)
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
    /// Python's `progress(t, t0, t_end)` [s], called at most every 100 ms
    /// of wall time.
    progress: Option<Py<PyAny>>,
    span: (f64, f64),
    last_progress: Instant,
}

impl Sink for Collect<'_> {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let row = self.builder.row(s);
        debug_assert_eq!(row.len(), self.ncols);
        self.rows.extend_from_slice(row);
        Ok(())
    }

    fn progress(&mut self, t: f64, _stats: &Stats) -> ControlFlow<String> {
        if let Some(p) = &self.progress {
            if self.last_progress.elapsed() >= Duration::from_millis(100) {
                self.last_progress = Instant::now();
                // a failing progress display must not end the run: it is
                // printed and not called again
                let failed = Python::attach(|py| {
                    p.call1(py, (t, self.span.0, self.span.1))
                        .map_err(|e| e.print(py))
                        .is_err()
                });
                if failed {
                    self.progress = None;
                }
            }
        }
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

/// Everything a run hands back to Python: the table, column names, units,
/// the summary JSON, and the first exception a Python force raised.
type RunOutput = (Table, Vec<String>, Vec<String>, String, Option<PyErr>);

/// What `run` returns to Python: [`RunOutput`] with the exception as a
/// Python object.
type PyRunOutput = (Table, Vec<String>, Vec<String>, String, Option<Py<PyAny>>);

/// A Python force as the Python layer hands it over (`PythonForce`): its
/// name, the names of its bodies, `force(t, q, qd) -> list` (k = 3 × bodies
/// values), optionally `jacobian(t, q, qd) -> list` (2k² values: ∂g/∂q then
/// ∂g/∂q̇, row-major) and `step(t, q, qd)` (after each accepted step).
type ForceSpec = (
    String,
    Vec<String>,
    Py<PyAny>,
    Option<Py<PyAny>>,
    Option<Py<PyAny>>,
);

/// Run scenario text with overrides: (table, column names, units, summary
/// JSON, first exception of a Python force). The summary records what
/// `mbsolve run` records (plus the provenance of the text: its SHA-256,
/// the overrides, the version).
#[pyfunction]
#[pyo3(signature = (text, file, stem, overrides, check_signals = true, forces = Vec::new(), progress = None, one_thread = false))]
#[allow(clippy::too_many_arguments)]
fn run(
    py: Python<'_>,
    text: String,
    file: String,
    stem: String,
    overrides: Vec<String>,
    check_signals: bool,
    forces: Vec<ForceSpec>,
    progress: Option<Py<PyAny>>,
    one_thread: bool,
) -> PyResult<PyRunOutput> {
    let (table, names, units, json, raised) = guarded(py, move || {
        let mut sc = parse(&text, &file, &stem, &overrides)?;
        // runs side by side (a sweep): each on one thread, as `mbsolve
        // sweep` does (the results do not depend on it)
        if one_thread && sc.run.threads == Threads::Auto {
            sc.run.threads = Threads::One;
        }
        let hooks = add_python_forces(&mut sc, forces)?;
        run_scenario(
            &sc,
            &text,
            &file,
            &overrides,
            check_signals,
            hooks,
            progress,
        )
    })?;
    let raised = raised.map(|e| e.into_value(py).into_any());
    Ok((table, names, units, json, raised))
}

/// The first exception raised by any Python force of a run, with the
/// message the summary gives.
type Raised = Arc<Mutex<Option<(String, PyErr)>>>;

/// What `add_python_forces` leaves for the run: the step hooks (monitors),
/// the forces' error slots and the first exception.
struct PythonHooks {
    steps: Vec<PyStep>,
    errors: Vec<CallbackError>,
    raised: Raised,
}

/// Record `e` (raised by Python force `name` at `t`) unless an exception
/// is recorded already; returns the message.
fn record(py: Python<'_>, raised: &Raised, name: &str, what: &str, t: f64, e: PyErr) -> String {
    let ty = e
        .get_type(py)
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "exception".into());
    let v = e.value(py).str().map(|s| s.to_string()).unwrap_or_default();
    let m = format!("python force '{name}': {what} raised {ty}: {v} (at t = {t:e})");
    let mut r = raised.lock().unwrap_or_else(PoisonError::into_inner);
    if r.is_none() {
        *r = Some((m.clone(), e));
    }
    m
}

/// A Python force's law: its `force` (and `jacobian`) callables, called
/// with the GIL taken for each evaluation.
struct PyLaw {
    name: String,
    force: Py<PyAny>,
    jacobian: Option<Py<PyAny>>,
    raised: Raised,
}

impl PyLaw {
    /// Call `f(t, q, qd)` and read `n` floats from what it returns.
    fn call(
        &self,
        py: Python<'_>,
        f: &Py<PyAny>,
        t: f64,
        q: &[f64],
        qd: &[f64],
        n: usize,
    ) -> PyResult<Vec<f64>> {
        let out = f.call1(py, (t, PyList::new(py, q)?, PyList::new(py, qd)?))?;
        let v: Vec<f64> = out.extract(py)?;
        if v.len() != n {
            return Err(PyValueError::new_err(format!(
                "returned {} values, expected {n}",
                v.len()
            )));
        }
        Ok(v)
    }
}

impl CallbackLaw for PyLaw {
    fn forces(&self, t: f64, q: &[f64], qd: &[f64], g: &mut [f64]) -> Result<(), String> {
        Python::attach(|py| match self.call(py, &self.force, t, q, qd, g.len()) {
            Ok(v) => {
                g.copy_from_slice(&v);
                Ok(())
            }
            Err(e) => Err(record(py, &self.raised, &self.name, "force", t, e)),
        })
    }

    fn jacobians(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        dq: &mut [f64],
        dqd: &mut [f64],
    ) -> Result<bool, String> {
        let Some(j) = &self.jacobian else {
            return Ok(false);
        };
        let kk = dq.len();
        Python::attach(|py| match self.call(py, j, t, q, qd, 2 * kk) {
            Ok(v) => {
                dq.copy_from_slice(&v[..kk]);
                dqd.copy_from_slice(&v[kk..]);
                Ok(true)
            }
            Err(e) => Err(record(py, &self.raised, &self.name, "jacobian", t, e)),
        })
    }
}

/// A Python force's `step(t, q, qd)`, called after each accepted step with
/// its bodies' coordinates; an exception stops the run through the force's
/// error slot.
struct PyStep {
    name: String,
    coords: Vec<usize>,
    step: Py<PyAny>,
    error: CallbackError,
    raised: Raised,
    q: Vec<f64>,
    qd: Vec<f64>,
}

impl Monitor for PyStep {
    fn step(&mut self, t: f64, q: &[f64], qd: &[f64]) {
        if self.error.get().is_some() {
            return;
        }
        for (i, &c) in self.coords.iter().enumerate() {
            self.q[i] = q[c];
            self.qd[i] = qd[c];
        }
        Python::attach(|py| {
            let r = PyList::new(py, &self.q)
                .and_then(|a| Ok((a, PyList::new(py, &self.qd)?)))
                .and_then(|(a, b)| self.step.call1(py, (t, a, b)));
            if let Err(e) = r {
                let m = record(py, &self.raised, &self.name, "step", t, e);
                self.error.set(m);
            }
        });
    }
    fn report(&self, _extra: &mut serde_json::Map<String, serde_json::Value>) {}
}

/// Add the Python forces to the scenario's system (bodies by name).
fn add_python_forces(sc: &mut Scenario, forces: Vec<ForceSpec>) -> Result<PythonHooks, Failure> {
    let raised: Raised = Arc::default();
    let mut hooks = PythonHooks {
        steps: Vec::new(),
        errors: Vec::new(),
        raised: raised.clone(),
    };
    for (name, bodies, force, jacobian, step) in forces {
        let bad = |message: String| {
            Failure::Scenario(scenario::ScenarioError {
                file: format!("<python force '{name}'>"),
                key: "bodies".into(),
                message,
            })
        };
        let all = sc.system.bodies();
        let mut coords = Vec::new();
        for b in &bodies {
            let Some(i) = all.iter().position(|x| &x.name == b) else {
                let names: Vec<&str> = all.iter().take(12).map(|x| x.name.as_str()).collect();
                let more = if all.len() > 12 { ", ..." } else { "" };
                return Err(bad(format!(
                    "no body '{b}' in the scenario (bodies: {}{more})",
                    names.join(", ")
                )));
            };
            coords.extend([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let law = PyLaw {
            name: name.clone(),
            force,
            jacobian,
            raised: raised.clone(),
        };
        let f = CallbackForce::new(&name, coords.clone(), law);
        let error = f.error_handle();
        sc.system
            .add_force(Box::new(f))
            .map_err(|e| bad(e.to_string()))?;
        if let Some(step) = step {
            let k = coords.len();
            hooks.steps.push(PyStep {
                name: name.clone(),
                coords,
                step,
                error: error.clone(),
                raised: raised.clone(),
                q: vec![0.0; k],
                qd: vec![0.0; k],
            });
        }
        hooks.errors.push(error);
    }
    Ok(hooks)
}

fn run_scenario(
    sc: &Scenario,
    text: &str,
    file: &str,
    overrides: &[String],
    check_signals: bool,
    mut hooks: PythonHooks,
    progress: Option<Py<PyAny>>,
) -> Result<RunOutput, Failure> {
    let sensors: &[Sensor] = &sc.sensors;
    let cols = columns(&sc.system, &sc.run.outputs, sensors);
    let mut sink = Collect {
        builder: RowBuilder::new(&sc.system, sc.run.outputs, sensors),
        rows: Vec::new(),
        ncols: cols.len(),
        last_signal_check: Instant::now(),
        check_signals,
        progress,
        span: (sc.run.t0, sc.run.t_end),
        last_progress: Instant::now(),
    };
    let mut contacts = ContactMonitor::for_rods(&sc.rods);
    let mut monitors: Vec<&mut dyn Monitor> = Vec::new();
    if let Some(c) = contacts.as_mut() {
        monitors.push(c);
    }
    for s in hooks.steps.iter_mut() {
        monitors.push(s);
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
    // a Python force raised: the run ended at that evaluation (its forces
    // came out NaN, or a step hook failed after the last step)
    let first = hooks
        .raised
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .take();
    let raised = match first {
        Some((m, e)) => {
            let interrupt = Python::attach(|py| e.is_instance_of::<PyKeyboardInterrupt>(py));
            summary.status = if interrupt { "interrupted" } else { "failed" }.into();
            summary.message = Some(m);
            Some(e)
        }
        None => {
            if let Some(m) = hooks.errors.iter().find_map(|e| e.get()) {
                summary.status = "failed".into();
                summary.message = Some(m);
            }
            None
        }
    };
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
    let names: Vec<String> = cols.iter().map(|c| c.name.clone()).collect();
    let units = cols.iter().map(|c| c.unit.to_string()).collect();
    let table = Table {
        data,
        ncols,
        nrows,
        names: names.clone(),
    };
    Ok((table, names, units, json, raised))
}

/// The index of the column `name` among `names` (a run's columns): the
/// name, or a positional name of earlier versions (`x1`, `phi3`) read as
/// that body's column (`mbsolve::output::find_column`); `None` if neither.
#[pyfunction]
fn find_column(names: Vec<String>, name: &str) -> Option<usize> {
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    mbsolve::output::find_column(&names, name)
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
    m.add_function(wrap_pyfunction!(find_column, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    Ok(())
}
