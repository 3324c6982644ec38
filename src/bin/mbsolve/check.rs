//! `mbsolve check FILE [--set K=V]…`: validate a scenario without running
//! it and print the size of the system it describes.

#[cfg(test)]
use faer::Mat;
use mbsolve::model::System;
use mbsolve::scenario::{self, Scenario};
use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;

/// The numbers `check` reports.
pub struct Size {
    /// Bodies.
    pub bodies: usize,
    /// Coordinates n = 3 · bodies + states.
    pub coordinates: usize,
    /// Controller states (`[[state]]`), one coordinate each.
    pub states: usize,
    /// Constraint equations m.
    pub constraints: usize,
    /// rank Φ_q at the initial state.
    pub rank: usize,
    /// Mechanical degrees of freedom n − states − rank Φ_q.
    pub dof: usize,
    /// Redundant constraint equations m − rank Φ_q.
    pub redundant: usize,
}

/// Numerical rank of a dense matrix from its singular values (faer's SVD):
/// the number of σ_i > max(m, n) · ε · σ_max (the usual rule, as in
/// NumPy's `matrix_rank`).
#[cfg(test)]
pub fn rank(a: &Mat<f64>) -> Result<usize, String> {
    if a.nrows() == 0 || a.ncols() == 0 {
        return Ok(0);
    }
    let s = a
        .singular_values()
        .map_err(|e| format!("SVD of the constraint Jacobian failed: {e:?}"))?;
    let smax = s.iter().cloned().fold(0.0, f64::max);
    let tol = a.nrows().max(a.ncols()) as f64 * f64::EPSILON * smax;
    Ok(s.iter().filter(|&&v| v > tol).count())
}

/// Size of `sys` at positions `q`, time `t`: the rank of Φ_q from the
/// sparse LDLᵀ of the saddle matrix `[I Φ_qᵀ; Φ_q 0]` ([`sparse_rank`]),
/// O(nnz) for chains like every run's factorisation.
pub fn size(sys: &System, q: &[f64], t: f64) -> Result<Size, String> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let r = sparse_rank(sys, q, t)?;
    Ok(Size {
        bodies: sys.bodies().len(),
        coordinates: n,
        states: sys.states().len(),
        constraints: m,
        rank: r,
        dof: n - sys.states().len() - r,
        redundant: m - r,
    })
}

/// rank Φ_q at `(q, t)`: m minus the pivots the sparse LDLᵀ of
/// `[I Φ_qᵀ; Φ_q 0]` regularised (`linalg::SparseLdlt`, its rows scaled
/// to unit maximum, pivots of modulus below `linalg::sparse::DEFAULT_EPSILON`
/// = 1e-11 regularised: a multiplier pivot vanishes exactly where a row of
/// Φ_q depends on the rows eliminated before it). The same test as every
/// run's factorisation, at the system's full size.
pub fn sparse_rank(sys: &System, q: &[f64], t: f64) -> Result<usize, String> {
    use mbsolve::linalg::{SaddleMatrix, SaddlePointSolver, SparseLdlt};
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    if m == 0 {
        return Ok(0);
    }
    let pattern = sys.jacobian_pattern();
    let mut vals = vec![0.0; pattern.len()];
    sys.jacobian_values(q, t, &mut vals);
    if let Some(k) = vals.iter().position(|v| !v.is_finite()) {
        return Err(format!(
            "Φ_q at the initial state has a non-finite entry at {:?}",
            pattern[k]
        ));
    }
    let mut k = SaddleMatrix::new(n, m, &[], pattern);
    k.set_a_diagonal(&vec![1.0; n]);
    k.set_jacobian(&vals);
    let mut solver = SparseLdlt::default();
    let fail = |e: mbsolve::linalg::LinalgError| format!("factorising [I Φ_qᵀ; Φ_q 0]: {e}");
    solver.analyze(&k).map_err(fail)?;
    let info = solver.factorize(&k).map_err(fail)?;
    Ok(m - info.regularized_pivots.min(m))
}

/// `x` as Rust's shortest round-trip decimal where that is short, else in
/// exponent notation (never a 300-digit number).
fn short(x: f64) -> String {
    let plain = format!("{x}");
    if plain.len() <= 12 {
        plain
    } else {
        format!("{x:e}")
    }
}

/// The kind of an element from its description: the leading words up to
/// its name, body or parameters (`"revolute joint 'A'"` → `revolute joint`).
fn kind(name: &str) -> String {
    name.split(' ')
        .take_while(|w| {
            !["of", "on", "at"].contains(w)
                && w.starts_with(|c: char| c.is_lowercase())
                && w.chars().all(|c| c.is_alphabetic() || c == '-')
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The number of elements and their count by kind, as
/// `"3 (2 revolute joint, 1 drag)"` (`"0 (none)"`).
fn by_kind(names: impl Iterator<Item = String>) -> String {
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    for n in names {
        *counts.entry(kind(&n)).or_default() += 1;
    }
    let total: usize = counts.values().sum();
    let kinds = if counts.is_empty() {
        "none".into()
    } else {
        counts
            .iter()
            .map(|(k, c)| format!("{c} {k}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!("{total} ({kinds})")
}

/// The report printed for a valid scenario.
fn report(sc: &Scenario, s: &Size) -> String {
    let sys = &sc.system;
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("{k:<22}{v}\n"));
    line("scenario", sc.name.clone());
    line("bodies", s.bodies.to_string());
    // a count, with a note on the controller states when there are any
    let with_states = |n: usize, note: String| {
        if s.states > 0 {
            format!("{n} ({note})")
        } else {
            n.to_string()
        }
    };
    let bodies = s.coordinates - s.states;
    let note = format!("{bodies} of the bodies, {} controller states", s.states);
    line("coordinates", with_states(s.coordinates, note));
    line("constraint equations", s.constraints.to_string());
    line(
        "rank of Phi_q",
        format!(
            "{} (at the initial state; regularised pivots of a sparse LDLᵀ of [I Φ_qᵀ; Φ_q 0])",
            s.rank
        ),
    );
    let note = format!("besides the {} controller states", s.states);
    line("degrees of freedom", with_states(s.dof, note));
    line("redundant equations", s.redundant.to_string());
    line(
        "joints",
        by_kind(sys.constraints().iter().map(|c| c.name())),
    );
    line(
        "force elements",
        by_kind(sys.forces().iter().map(|f| f.name())),
    );
    let force_kernels = sys.force_kernel_names();
    line(
        "evaluation",
        if force_kernels.is_empty() {
            sys.evaluation_name()
        } else {
            format!(
                "{}; force Jacobians: {}",
                sys.evaluation_name(),
                force_kernels.join("+")
            )
        },
    );
    line(
        "method",
        format!(
            "{} (formulation {:?}, linear solver {:?})",
            sc.run.method.name(),
            sc.run.formulation.formulation,
            sc.run.formulation.linear_solver
        ),
    );
    line(
        "time",
        format!(
            "{} .. {} s, output every {} s",
            short(sc.run.t0),
            short(sc.run.t_end),
            short(sc.run.output_dt)
        ),
    );
    if let Some(a) = &sc.assembly {
        line(
            "initial state",
            format!(
                "assembled: |Phi| = {:.2e}, |Phi_q qd + Phi_t| = {:.2e} ({} Newton iterations)",
                a.position_residual, a.velocity_residual, a.iterations
            ),
        );
        if let Some((text, _)) = assembly_moves(sc) {
            line("assembly moved", text);
        }
    }
    out
}

/// `mbsolve check`: 0 and the report when the scenario is valid, 1 and the
/// error otherwise.
pub fn command(path: &Path, set: &[String], unset: &[String]) -> ExitCode {
    let checked = scenario::load_with(path, &scenario::overrides(unset, set))
        .map_err(|e| e.to_string())
        .and_then(|sc| {
            let s = size(&sc.system, &sc.q0, sc.run.t0)?;
            Ok((sc, s))
        });
    match checked {
        Ok((sc, s)) => {
            for n in &sc.notes {
                eprintln!("note: {n}");
            }
            say!("{}", report(&sc, &s).trim_end());
            say!("valid");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

/// How far the assembly moved the bodies (`None` without an assembly): a
/// line — the largest move of a centre of mass and the largest rotation,
/// with their bodies — and the summary's `initial_assembly` object (those
/// and `body_moves`: each body's `[|Δr| m, |Δφ| rad]`).
pub fn assembly_moves(sc: &Scenario) -> Option<(String, serde_json::Value)> {
    let a = sc.assembly.as_ref()?;
    let name = |i: usize| sc.system.bodies()[i].name.clone();
    let largest = |c: usize| {
        a.body_moves
            .iter()
            .enumerate()
            .fold(
                (0usize, 0.0f64),
                |m, (i, v)| if v[c] > m.1 { (i, v[c]) } else { m },
            )
    };
    let ((bd, d), (br, r)) = (largest(0), largest(1));
    let text = format!(
        "at most {d:.3e} m (body '{}') and {:.3e}° (body '{}')",
        name(bd),
        r.to_degrees(),
        name(br)
    );
    let moves: serde_json::Map<String, serde_json::Value> = a
        .body_moves
        .iter()
        .enumerate()
        .map(|(i, v)| (name(i), serde_json::json!(v)))
        .collect();
    let json = serde_json::json!({
        "position_residual": a.position_residual,
        "velocity_residual": a.velocity_residual,
        "iterations": a.iterations,
        "max_displacement_m": d,
        "max_displacement_body": name(bd),
        "max_rotation_rad": r,
        "max_rotation_body": name(br),
        "body_moves": moves,
    });
    Some((text, json))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_of_known_matrices_and_kinds() {
        // rank 2: third row = first + second
        let a = Mat::from_fn(3, 4, |i, j| match i {
            0 => (j + 1) as f64,
            1 => ((j * j) as f64).sin(),
            _ => (j + 1) as f64 + ((j * j) as f64).sin(),
        });
        assert_eq!(rank(&a).unwrap(), 2);
        assert_eq!(rank(&Mat::<f64>::identity(5, 5)).unwrap(), 5);
        assert_eq!(rank(&Mat::<f64>::zeros(0, 6)).unwrap(), 0);
        assert_eq!(kind("revolute joint 'A'"), "revolute joint");
        assert_eq!(kind("drag on body 3"), "drag");
        assert_eq!(
            kind("point spring-damper Ground [0.0, 0.0] - Body(0)"),
            "point spring-damper"
        );
        assert_eq!(kind("buoyancy (3 bodies)"), "buoyancy");
    }
}
