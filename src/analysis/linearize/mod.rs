//! Linearisation about a state: the state-space model
//! `ẋ = A x + B u`, `y = C x + D u` in independent coordinates.
//!
//! # Coordinates
//!
//! The state is `x = (z, ż)`, `z` a set of `f` independent coordinates
//! (coordinate partitioning, Wehage & Haug 1982: the non-pivot columns of
//! a sparse elimination of Φ_q, [`super::partitioning`], or chosen by the
//! caller). The chart
//! `q(z)` holds `q_I = z` and solves `Φ(q, t) = 0` for the rest by Newton;
//! its tangent is the null-space basis `V` of Φ_q with `V_I = 1`:
//! `Φ̃ V = [0; 1]`, `Φ̃ = [Φ_q; E_Iᵀ]` (square, regular when the
//! independent coordinates are admissible). Each column is one sparse
//! solve of the saddle-point matrix `[1 Φ̃ᵀ; Φ̃ 0]`, factorised once
//! (`O(N)` per column for chains). Velocities: `Φ̃ q̇ = [−Φ_t; ż]`.
//!
//! # Equations
//!
//! With `M q̈ + Φ_qᵀλ = g + E u` (our λ, see [`super::tangent`]) and `u`
//! generalized forces on chosen coordinates ([`Input`]), perturbing a
//! state at rest in equilibrium (`q̇ = 0`, `q̈ = 0`, `Φ_t = 0`;
//! [`LinearizeOptions::rest_tol`]) by
//! `δq = V δz` gives, after `Vᵀ` removes `δλ`,
//!
//! ```text
//! M̂ δz̈ + Ĉ δż + K̂ δz = Vᵀ E δu,   M̂ = VᵀMV, Ĉ = VᵀCV, K̂ = VᵀKV
//! A = [0 1; −M̂⁻¹K̂ −M̂⁻¹Ĉ],  B = [0; M̂⁻¹VᵀE]
//! ```
//!
//! with `C = −∂g/∂q̇`, `K = −∂g/∂q + (Φ_qᵀλ)_q` exact from the symbolic
//! Jacobians ([`super::Tangent`]) — [`Method::Tangent`]. Away from
//! equilibrium the linearisation also holds derivatives of `γ`, of
//! `Φ_q q̇ + Φ_t` and of `Φ_q q̈` (second and third derivatives of Φ)
//! that the model does not provide; there ([`Method::FiniteDifferences`])
//! `A` is the central difference of the reduced dynamics
//! `(z, ż) ↦ (ż, z̈)` through the chart (Newton positions, velocity solve,
//! the saddle-point solve of eq. (5) for `q̈`), step `h (1 + |x_j|)`.
//! `B` is exact on both paths (`q̈` is affine in the loads): the rows `I`
//! of `[M Φ_qᵀ; Φ_q 0]⁻¹ [E; 0]`.
//!
//! Outputs ([`Output`]) are coordinates, velocities and sensor readings;
//! `C` is exact for coordinates and velocities on the tangent path
//! (rows of `V`) and otherwise the central difference through the chart;
//! `D = 0` (no output reads the force inputs directly).
//!
//! # Drive inputs
//!
//! A drive `Φ_r = ±q_k − f(t)` ([`Input::Drive`]) is perturbed as
//! `f(t) + σ(t)`, and the input is its acceleration `u = σ̈` (a motion
//! command a control engineer integrates twice: a cart's or a road's
//! acceleration). The offset `σ` and rate `σ̇` become states after the
//! mechanism's, `x = (z, ż, σ, σ̇)`, with `dσ/dt = σ̇`, `dσ̇/dt = u`. The chart
//! solves `Φ(q, t) = σ e_r` and `Φ_q q̇ + Φ_t = σ̇ e_r`; its tangent along
//! `σ` is `W`, `Φ̃ W = [e_r; 0]` (the mechanism follows the drive with
//! `z` held). At an equilibrium at rest, `δq = V δz + W δσ` and
//!
//! ```text
//! M̂ δz̈ + Ĉ δż + K̂ δz = −VᵀKW δσ − VᵀCW δσ̇ − VᵀMW u
//! ```
//!
//! (the tangent path); elsewhere the `σ, σ̇` columns of `A` are central
//! differences through the chart like the others. `B`'s column of `u` is
//! exact on both paths: the rows `I` of `[M Φ_qᵀ; Φ_q 0]⁻¹ [0; e_r]`
//! (`Φ_q q̈ = γ + σ̈ e_r`). Coordinate and velocity outputs read `W` in
//! the `σ` and `σ̇` columns.
//!
//! # Controller states
//!
//! A controller state z (`ż = f(t, q, q̇, z)`, [`crate::model::State`]) is
//! the velocity of a coordinate w that no constraint and no force reads.
//! w is independent in every chart (it is appended when the caller's list
//! lacks it), so the model above carries the rows `ẇ = z` and
//! `ż = f`, and the columns of `w` are zero (nothing depends on it). They
//! are dropped: the state is `x = (z_b, ż_b, σ, σ̇, z_c)`, `z_b` the
//! bodies' independent coordinates and `z_c` the controller states, and
//! `A`'s rows of `z_c` hold `∂f/∂(q, q̇, z)` through the chart (exact on the
//! tangent path: `−K`'s and `−C`'s rows of w, [`super::Tangent`]), its
//! columns of `z_c` the forces' dependence on z (`−C`'s columns of w).
//! "At rest" asks `q̇ = 0` of the bodies only (z need not vanish) and
//! `ż = 0` with the accelerations. [`Output::State`] reads a state.
//!
//! Away from an equilibrium the result depends on the chosen independent
//! coordinates (a state-dependent change of chart adds `z̈`-terms); at an
//! equilibrium the eigenvalues of `A` do not.

mod chart;

use super::inverse::coordinate_label;
use super::Tangent;
use crate::formulation::FormulationError;
use crate::linalg::LinalgError;
use crate::model::{Sensor, System};
use crate::simulation::check_state;
use chart::{project, Chart};
use faer::linalg::solvers::Solve;
use faer::Mat;

/// A model input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Generalized force on coordinate `k` (global index): a force along
    /// global x or y at a body's centre of mass \[N\], or a torque on it
    /// \[N m\], added to `g`.
    Force {
        /// The coordinate.
        coordinate: usize,
    },
    /// The acceleration of a drive's prescribed motion `f(t)` \[m/s² or
    /// rad/s²\]: the drive follows `f(t) + σ(t)` with `σ̈ = u`; its offset
    /// `σ` and rate `σ̇` join the state (module docs, "Drive inputs").
    Drive {
        /// The drive's joint (index into [`System::constraints`]).
        joint: usize,
    },
}

/// The motion units of a drive whose generalized force is in `force_unit`
/// (`"N"`: a translation; `"N m"`: an angle): offset, rate, acceleration.
/// Central differences of `fun` at `x0`: for every entry `j` (step
/// `h = step(j)`) and every value `i` of `fun`,
/// `put(i, j, (fun(x0 + h e_j)_i − fun(x0 − h e_j)_i) / 2h)`.
fn central_differences(
    x0: &[f64],
    step: impl Fn(usize) -> f64,
    chart: &mut Chart,
    mut fun: impl FnMut(&[f64], &mut Chart) -> Result<Vec<f64>, LinearizeError>,
    mut put: impl FnMut(usize, usize, f64),
) -> Result<(), LinearizeError> {
    let mut xp = x0.to_vec();
    for j in 0..x0.len() {
        let h = step(j);
        xp[j] = x0[j] + h;
        let up = fun(&xp, chart)?;
        xp[j] = x0[j] - h;
        let dn = fun(&xp, chart)?;
        xp[j] = x0[j];
        for (i, (u, d)) in up.iter().zip(&dn).enumerate() {
            put(i, j, (u - d) / (2.0 * h));
        }
    }
    Ok(())
}

fn drive_units(force_unit: &str) -> [&'static str; 3] {
    if force_unit == "N" {
        ["m", "m/s", "m/s^2"]
    } else {
        ["rad", "rad/s", "rad/s^2"]
    }
}

/// A joint's name as the scenario gives it (its description when unnamed).
fn joint_label(sys: &System, joint: usize) -> String {
    let c = &sys.constraints()[joint];
    crate::model::joint_short_name(c.as_ref()).unwrap_or_else(|| c.name())
}

impl Input {
    /// Name (`BODY.fx`, `BODY.fy`, `BODY.mz`, `DRIVE.acc`) and unit.
    pub fn name(&self, sys: &System) -> (String, &'static str) {
        match *self {
            Input::Force { coordinate: k } => {
                let body = &sys.bodies()[k / 3].name;
                match k % 3 {
                    0 => (format!("{body}.fx"), "N"),
                    1 => (format!("{body}.fy"), "N"),
                    _ => (format!("{body}.mz"), "N m"),
                }
            }
            Input::Drive { joint } => {
                let unit = sys.constraints()[joint].drive_unit().unwrap_or("N m");
                (
                    format!("{}.acc", joint_label(sys, joint)),
                    drive_units(unit)[2],
                )
            }
        }
    }
}

/// A model output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// Coordinate `k` \[m or rad\].
    Coordinate(usize),
    /// Velocity of coordinate `k` \[m/s or rad/s\].
    Velocity(usize),
    /// Controller state `k` (index into [`System::states`]) \[its own
    /// unit\].
    State(usize),
    /// Reading `index` of sensor `sensor` (its [`Sensor::quantities`]).
    Sensor {
        /// Index into the sensor list.
        sensor: usize,
        /// Index into its quantities.
        index: usize,
    },
}

impl Output {
    /// Name (`BODY.x`, `BODY.vx`, `S.QUANTITY`) and unit.
    pub fn name(&self, sys: &System, sensors: &[Sensor]) -> (String, &'static str) {
        match *self {
            Output::Coordinate(k) => (
                coordinate_label(sys, k),
                if k % 3 == 2 { "rad" } else { "m" },
            ),
            // a controller state's coordinate: its velocity is the state
            Output::Velocity(k) if k >= sys.n_body_coords() => {
                Output::State(k - sys.n_body_coords()).name(sys, sensors)
            }
            Output::Velocity(k) => {
                let body = &sys.bodies()[k / 3].name;
                let (n, u) = [("vx", "m/s"), ("vy", "m/s"), ("omega", "rad/s")][k % 3];
                (format!("{body}.{n}"), u)
            }
            Output::State(k) => (sys.states()[k].name.clone(), ""),
            Output::Sensor { sensor, index } => {
                let s = &sensors[sensor];
                let (q, u) = s.quantities(sys)[index];
                (format!("{}.{q}", s.name), u)
            }
        }
    }
}

/// How `A` is obtained (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The tangent path at an equilibrium at rest, central differences
    /// elsewhere.
    #[default]
    Auto,
    /// Exact tangent matrices; an error away from an equilibrium at rest.
    Tangent,
    /// Central differences of the reduced dynamics through the chart.
    FiniteDifferences,
}

impl Method {
    /// Its name in outputs.
    pub fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Tangent => "tangent",
            Method::FiniteDifferences => "finite_differences",
        }
    }
}

/// Options of [`linearize`].
#[derive(Debug, Clone, PartialEq)]
pub struct LinearizeOptions {
    /// Independent coordinates (global indices); `None`: the non-pivot
    /// columns of the sparse coordinate partitioning of Φ_q
    /// ([`independent_coordinates`]).
    pub independent: Option<Vec<usize>>,
    /// How `A` is obtained; default [`Method::Auto`].
    pub method: Method,
    /// A state counts as at rest in equilibrium when `‖q̇‖∞` and `‖Φ_t‖∞`
    /// are at most this (SI units of each) and `‖q̈‖∞` at most this times
    /// `max(1, ‖M⁻¹g‖∞)` (the accelerations the loads alone would cause);
    /// default 1e-8.
    pub rest_tol: f64,
    /// Relative step of the central differences, `h (1 + |x_j|)`;
    /// default 1e-6.
    pub fd_step: f64,
    /// Newton tolerance of the chart's positions on ‖Φ‖∞ \[m\];
    /// default 1e-13.
    pub newton_tol: f64,
}

impl Default for LinearizeOptions {
    fn default() -> Self {
        Self {
            independent: None,
            method: Method::Auto,
            rest_tol: 1e-8,
            fd_step: 1e-6,
            newton_tol: 1e-13,
        }
    }
}

/// Why a linearisation failed.
#[derive(Debug, Clone, thiserror::Error)]
pub enum LinearizeError {
    /// Bad arguments (names the argument and value).
    #[error("linearize: {0}")]
    Invalid(String),
    /// The chart's Newton iteration did not converge.
    #[error(
        "linearize: Newton on Phi(q, t) = 0 with the independent coordinates held stopped at \
         |Phi|inf = {residual:.3e} after {iterations} iterations at t = {t} s"
    )]
    Chart {
        /// Time \[s\].
        t: f64,
        /// Residual \[m\].
        residual: f64,
        /// Iterations.
        iterations: usize,
    },
    /// A linear solve failed (e.g. inadmissible independent coordinates).
    #[error("linearize: linear solve at t = {t} s: {source}")]
    Linear {
        /// Time \[s\].
        t: f64,
        /// The solver's error.
        source: LinalgError,
    },
    /// An evaluation failed.
    #[error(transparent)]
    Formulation(#[from] FormulationError),
}

/// The linear model about one state.
#[derive(Debug, Clone)]
pub struct StateSpace {
    /// Time of the state \[s\].
    pub t: f64,
    /// Positions of the state (consistent: the chart at `z`).
    pub q: Vec<f64>,
    /// Velocities of the state.
    pub qd: Vec<f64>,
    /// Multipliers λ of the state (our sign).
    pub lambda: Vec<f64>,
    /// Accelerations q̈ of the state.
    pub qdd: Vec<f64>,
    /// Independent coordinates (global indices), `f` of them (the
    /// bodies': the controller states' coordinates are not among them).
    pub independent: Vec<usize>,
    /// Number of controller states, the last entries of the state `x`
    /// (module docs, "Controller states").
    pub controller_states: usize,
    /// Method used ([`Method::Tangent`] or [`Method::FiniteDifferences`]).
    pub method: Method,
    /// State names: `z` then `ż` (`BODY.x` …, `BODY.vx` …), then the
    /// offsets and rates of the driven inputs (`DRIVE.offset` …,
    /// `DRIVE.rate` …), in input order, then the controller states by
    /// name.
    pub states: Vec<(String, &'static str)>,
    /// Input names and units.
    pub inputs: Vec<(String, &'static str)>,
    /// Output names and units.
    pub outputs: Vec<(String, &'static str)>,
    /// `A` (s × s, s = 2f + 2 × drive inputs + controller states).
    pub a: Mat<f64>,
    /// `B` (s × inputs).
    pub b: Mat<f64>,
    /// `C` (outputs × s).
    pub c: Mat<f64>,
    /// `D` (outputs × inputs), zero.
    pub d: Mat<f64>,
    /// The null-space basis `V` (n × f), `Φ_q V = 0`, `V_I = 1`.
    pub basis: Mat<f64>,
    /// `M̂, Ĉ, K̂` (f × f) on the tangent path, of the bodies' independent
    /// coordinates (controller states held fixed).
    pub reduced: Option<[Mat<f64>; 3]>,
}

/// The independent coordinates of `sys` at `(q, t)`: the columns of Φ_q
/// without a pivot in the sparse coordinate partitioning
/// ([`super::partitioning::partition`], relative tolerance
/// [`super::inverse::RANK_TOL`]), ascending. `O(nnz Φ_q)` for chains.
pub fn independent_coordinates(sys: &System, q: &[f64], t: f64) -> Vec<usize> {
    super::inverse::partition_at(sys, q, t).independent
}

/// Linearise `sys` about `(t, q, q̇)` (module docs): inputs `inputs`,
/// outputs `outputs` (sensors from `sensors`). The state is first made
/// consistent through the chart (positions by Newton with the independent
/// coordinates held, velocities with theirs).
#[allow(clippy::too_many_arguments)]
pub fn linearize(
    sys: &System,
    sensors: &[Sensor],
    t: f64,
    q: &[f64],
    qd: &[f64],
    inputs: &[Input],
    outputs: &[Output],
    opts: &LinearizeOptions,
) -> Result<StateSpace, LinearizeError> {
    check_state(sys, q, qd).map_err(LinearizeError::Invalid)?;
    let n = sys.n_coords();
    let mut drive_rows = Vec::new();
    let mut drive_inputs = Vec::new();
    let all_drives = crate::model::drives(sys);
    for inp in inputs {
        match *inp {
            Input::Force { coordinate } => {
                if coordinate >= sys.n_body_coords() {
                    return Err(LinearizeError::Invalid(format!(
                        "input coordinate {coordinate} out of range (the bodies have {})",
                        sys.n_body_coords()
                    )));
                }
            }
            Input::Drive { joint } => {
                let Some(d) = all_drives.iter().find(|d| d.joint == joint) else {
                    return Err(LinearizeError::Invalid(
                        if joint < sys.constraints().len() {
                            format!(
                                "input joint '{}' is not a drive (drive_coordinate or drive_angle)",
                                joint_label(sys, joint)
                            )
                        } else {
                            format!("input joint {joint} out of range")
                        },
                    ));
                };
                if drive_rows.contains(&d.row) {
                    return Err(LinearizeError::Invalid(format!(
                        "drive '{}' is an input twice",
                        joint_label(sys, joint)
                    )));
                }
                drive_rows.push(d.row);
                drive_inputs.push(*d);
            }
        }
    }
    let nb = sys.n_body_coords();
    for out in outputs {
        let ok = match *out {
            // a state's coordinate w is not an output (its velocity is)
            Output::Coordinate(k) => k < nb,
            Output::Velocity(k) => k < n,
            Output::State(k) => k < n - nb,
            Output::Sensor { sensor, index } => {
                sensor < sensors.len() && index < sensors[sensor].quantities(sys).len()
            }
        };
        if !ok {
            return Err(LinearizeError::Invalid(format!(
                "output {out:?} out of range"
            )));
        }
    }
    let independent = match &opts.independent {
        Some(v) => {
            let mut s = v.clone();
            s.sort_unstable();
            s.dedup();
            if s.len() != v.len() || s.iter().any(|&k| k >= n) {
                return Err(LinearizeError::Invalid(format!(
                    "independent coordinates {v:?}: must be distinct and below {n}"
                )));
            }
            v.clone()
        }
        None => independent_coordinates(sys, q, t),
    };
    // the controller states' coordinates w: always independent (no
    // constraint holds them), dropped from the model at the end
    let mut independent = independent;
    for w in nb..n {
        if !independent.contains(&w) {
            independent.push(w);
        }
    }
    let outputs_named = outputs;
    let outputs: Vec<Output> = outputs
        .iter()
        .map(|o| match *o {
            Output::State(k) => Output::Velocity(nb + k),
            other => other,
        })
        .collect();
    let outputs = &outputs[..];
    let f = independent.len();
    let nd = drive_rows.len();
    // state layout: z (f), ż (f), σ (nd), σ̇ (nd)
    let ns = 2 * f + 2 * nd;
    let mut chart = Chart::new(
        sys,
        t,
        independent.clone(),
        opts.newton_tol,
        drive_rows.clone(),
    )?;
    let z0: Vec<f64> = independent.iter().map(|&k| q[k]).collect();
    let zd0: Vec<f64> = independent.iter().map(|&k| qd[k]).collect();
    let no_shift = vec![0.0; nd];
    let q0 = chart.positions(q, &z0, &no_shift)?;
    let qd0 = chart.velocities(&q0, &zd0, &no_shift)?;
    let v = chart.basis(&q0)?;
    // the chart's tangent along each drive offset: Φ̃ W = [e_r; 0]
    let w = {
        chart.factor_lock(&q0)?;
        let mut e = vec![0.0; sys.n_constraints()];
        let zero = vec![0.0; f];
        let mut cols = Vec::with_capacity(nd);
        for &r in &drive_rows {
            e.fill(0.0);
            e[r] = 1.0;
            cols.push(chart.solve_lock(&e, &zero)?);
        }
        cols
    };
    // a basis that misses the null space: inadmissible independent set
    {
        let mut r = vec![0.0; sys.n_constraints()];
        let mut jac = vec![0.0; sys.jacobian_pattern().len()];
        sys.jacobian_values(&q0, t, &mut jac);
        for col in &v {
            sys.jacobian_mul(&jac, col, &mut r);
            let scale = col.iter().fold(1.0_f64, |a, x| a.max(x.abs()));
            let res = r.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
            if res.is_nan() || res > 1e-8 * scale {
                return Err(LinearizeError::Invalid(format!(
                    "the independent coordinates {} do not parametrise the constraint manifold \
                     (Phi_q V = {res:.2e} for a basis column)",
                    independent
                        .iter()
                        .map(|&k| coordinate_label(sys, k))
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
        }
    }
    let (qdd0, lambda0) = chart.accelerations(&q0, &qd0)?;
    let mut phi_t = vec![0.0; sys.n_constraints()];
    sys.phi_t(&q0, t, &mut phi_t);
    let inf = |x: &[f64]| x.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    // the accelerations the loads alone would cause: the scale of q̈
    let mut g = vec![0.0; n];
    sys.forces_into(t, &q0, &qd0, &mut g);
    let load_acc = g
        .iter()
        .zip(sys.mass_diagonal())
        .fold(0.0_f64, |a, (f, m)| a.max((f / m).abs()));
    let acc_tol = opts.rest_tol * load_acc.max(1.0);
    // the bodies at rest (a controller state's value z is a velocity
    // that need not vanish; its rate is in q̈)
    let at_rest =
        inf(&qd0[..nb]) <= opts.rest_tol && inf(&phi_t) <= opts.rest_tol && inf(&qdd0) <= acc_tol;
    let method = match opts.method {
        Method::Auto if at_rest => Method::Tangent,
        Method::Auto => Method::FiniteDifferences,
        Method::Tangent if !at_rest => {
            return Err(LinearizeError::Invalid(format!(
                "the tangent linearisation needs a state at rest in equilibrium; here \
                 |qd|inf = {:.2e}, |Phi_t|inf = {:.2e} (tolerance {:.1e}), |qdd|inf = {:.2e} \
                 (tolerance {:.1e})",
                inf(&qd0[..nb]),
                inf(&phi_t),
                opts.rest_tol,
                inf(&qdd0),
                acc_tol
            )))
        }
        m => m,
    };
    // B: rows I of [M Φ_qᵀ; Φ_q 0]⁻¹ [E; 0] for forces and
    // [M Φ_qᵀ; Φ_q 0]⁻¹ [0; e_r] for drive accelerations (exact), and
    // σ̈ = u for the latter
    let nu = inputs.len();
    let mut b = Mat::<f64>::zeros(ns, nu);
    chart.factor_dyn(&q0)?;
    let zero_m = vec![0.0; sys.n_constraints()];
    let zero_n = vec![0.0; n];
    let mut slot = 0;
    for (k, inp) in inputs.iter().enumerate() {
        let x = match *inp {
            Input::Force { coordinate } => {
                let mut e = vec![0.0; n];
                e[coordinate] = 1.0;
                chart.solve_dyn(&e, &zero_m)?
            }
            Input::Drive { .. } => {
                let mut e = vec![0.0; sys.n_constraints()];
                e[drive_rows[slot]] = 1.0;
                b[(2 * f + nd + slot, k)] = 1.0;
                slot += 1;
                chart.solve_dyn(&zero_n, &e)?
            }
        };
        for (i, &c) in independent.iter().enumerate() {
            b[(f + i, k)] = x[c];
        }
    }
    let mut a = Mat::<f64>::zeros(ns, ns);
    for i in 0..f {
        a[(i, f + i)] = 1.0;
    }
    for i in 0..nd {
        a[(2 * f + i, 2 * f + nd + i)] = 1.0;
    }
    let mut reduced = None;
    let x0: Vec<f64> = z0
        .iter()
        .chain(&zd0)
        .copied()
        .chain(std::iter::repeat_n(0.0, 2 * nd))
        .collect();
    let step = |j: usize| opts.fd_step * (1.0 + x0[j].abs());
    // the chart at a state x = (z, ż, σ, σ̇): positions and velocities
    let at_state = |x: &[f64], chart: &mut Chart| -> Result<(Vec<f64>, Vec<f64>), LinearizeError> {
        let qx = chart.positions(&q0, &x[..f], &x[2 * f..2 * f + nd])?;
        let qdx = chart.velocities(&qx, &x[f..2 * f], &x[2 * f + nd..])?;
        Ok((qx, qdx))
    };
    match method {
        Method::Tangent => {
            let mut tan = Tangent::new(sys);
            tan.evaluate(t, &q0, &qd0, &lambda0)?;
            let (mass, damping, stiffness) = (tan.mass(), tan.damping(), tan.stiffness());
            let mh = project(&mass, &v, &v);
            let ch = project(&damping, &v, &v);
            let kh = project(&stiffness, &v, &v);
            if f > 0 {
                let lu = mh.partial_piv_lu();
                let mk = lu.solve(&kh);
                let mc = lu.solve(&ch);
                // the drive offsets and rates: −M̂⁻¹VᵀKW, −M̂⁻¹VᵀCW
                let mkw = lu.solve(&project(&stiffness, &v, &w));
                let mcw = lu.solve(&project(&damping, &v, &w));
                for i in 0..f {
                    for j in 0..f {
                        a[(f + i, j)] = -mk[(i, j)];
                        a[(f + i, f + j)] = -mc[(i, j)];
                    }
                    for j in 0..nd {
                        a[(f + i, 2 * f + j)] = -mkw[(i, j)];
                        a[(f + i, 2 * f + nd + j)] = -mcw[(i, j)];
                    }
                }
            }
            reduced = Some([mh, ch, kh]);
        }
        _ => {
            // central differences of x ↦ z̈ through the chart
            let zdd = |x: &[f64], chart: &mut Chart| -> Result<Vec<f64>, LinearizeError> {
                let (qx, qdx) = at_state(x, chart)?;
                let (qdd, _) = chart.accelerations(&qx, &qdx)?;
                Ok(independent.iter().map(|&c| qdd[c]).collect())
            };
            if f > 0 {
                central_differences(&x0, step, &mut chart, zdd, |i, j, d| {
                    a[(f + i, j)] = d;
                })?;
            }
        }
    }
    // C
    let ny = outputs.len();
    let mut c = Mat::<f64>::zeros(ny, ns);
    let mut exact = vec![false; ny];
    if method == Method::Tangent {
        for (r, out) in outputs.iter().enumerate() {
            match *out {
                Output::Coordinate(k) => {
                    for j in 0..f {
                        c[(r, j)] = v[j][k];
                    }
                    for j in 0..nd {
                        c[(r, 2 * f + j)] = w[j][k];
                    }
                    exact[r] = true;
                }
                Output::Velocity(k) => {
                    for j in 0..f {
                        c[(r, f + j)] = v[j][k];
                    }
                    for j in 0..nd {
                        c[(r, 2 * f + nd + j)] = w[j][k];
                    }
                    exact[r] = true;
                }
                // mapped to the velocity of w above
                Output::State(_) | Output::Sensor { .. } => {}
            }
        }
    }
    if exact.iter().any(|e| !e) {
        let read = |x: &[f64], chart: &mut Chart| -> Result<Vec<f64>, LinearizeError> {
            let (qx, qdx) = at_state(x, chart)?;
            let mut all = Vec::new();
            let mut y = Vec::with_capacity(ny);
            for out in outputs {
                y.push(match *out {
                    Output::Coordinate(k) => qx[k],
                    Output::Velocity(k) => qdx[k],
                    Output::State(k) => qdx[nb + k],
                    Output::Sensor { sensor, index } => {
                        all.clear();
                        sensors[sensor].evaluate(sys, t, &qx, &qdx, &mut all);
                        all[index]
                    }
                });
            }
            Ok(y)
        };
        central_differences(&x0, step, &mut chart, read, |r, j, d| {
            if !exact[r] {
                c[(r, j)] = d;
            }
        })?;
    }
    let mut basis = Mat::<f64>::zeros(n, f);
    for (j, col) in v.iter().enumerate() {
        for (i, &x) in col.iter().enumerate() {
            basis[(i, j)] = x;
        }
    }
    let mut states: Vec<(String, &'static str)> = independent
        .iter()
        .map(|&k| match k < nb {
            true => Output::Coordinate(k).name(sys, sensors),
            // a state's coordinate w: dropped below
            false => (String::new(), ""),
        })
        .collect();
    states.extend(independent.iter().map(|&k| match k < nb {
        true => Output::Velocity(k).name(sys, sensors),
        false => (String::new(), ""),
    }));
    for (slot, suffix) in [(0, "offset"), (1, "rate")] {
        for d in &drive_inputs {
            states.push((
                format!("{}.{suffix}", joint_label(sys, d.joint)),
                drive_units(d.unit)[slot],
            ));
        }
    }
    // drop the controller states' coordinates w (module docs): keep the
    // bodies' z and ż, the drives' σ, σ̇, then the states' values (ż of w)
    let body: Vec<usize> = (0..f).filter(|&i| independent[i] < nb).collect();
    let ctrl: Vec<usize> = (0..f).filter(|&i| independent[i] >= nb).collect();
    let keep: Vec<usize> = body
        .iter()
        .copied()
        .chain(body.iter().map(|&i| f + i))
        .chain(2 * f..2 * f + 2 * nd)
        .chain(ctrl.iter().map(|&i| f + i))
        .collect();
    let rows =
        |m: &Mat<f64>, r: &[usize]| Mat::<f64>::from_fn(r.len(), m.ncols(), |i, j| m[(r[i], j)]);
    let cols =
        |m: &Mat<f64>, c: &[usize]| Mat::<f64>::from_fn(m.nrows(), c.len(), |i, j| m[(i, c[j])]);
    let a = cols(&rows(&a, &keep), &keep);
    let b = rows(&b, &keep);
    let c = cols(&c, &keep);
    let states: Vec<(String, &'static str)> = body
        .iter()
        .map(|&i| states[i].clone())
        .chain(body.iter().map(|&i| states[f + i].clone()))
        .chain(states[2 * f..2 * f + 2 * nd].iter().cloned())
        .chain(
            ctrl.iter()
                .map(|&i| (sys.states()[independent[i] - nb].name.clone(), "")),
        )
        .collect();
    let basis = cols(&basis, &body);
    let reduced = reduced.map(|r| r.map(|m| cols(&rows(&m, &body), &body)));
    let independent: Vec<usize> = body.iter().map(|&i| independent[i]).collect();
    Ok(StateSpace {
        t,
        q: q0,
        qd: qd0,
        lambda: lambda0,
        qdd: qdd0,
        independent,
        controller_states: ctrl.len(),
        method,
        states,
        inputs: inputs.iter().map(|i| i.name(sys)).collect(),
        outputs: outputs_named.iter().map(|o| o.name(sys, sensors)).collect(),
        a,
        b,
        c,
        d: Mat::<f64>::zeros(ny, nu),
        basis,
        reduced,
    })
}
