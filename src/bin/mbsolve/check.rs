//! `mbsolve check FILE [--set K=V]…`: validate a scenario without running
//! it and print the size of the system it describes.

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
    /// Coordinates n = 3 · bodies.
    pub coordinates: usize,
    /// Constraint equations m.
    pub constraints: usize,
    /// rank Φ_q at the initial state.
    pub rank: usize,
    /// Degrees of freedom n − rank Φ_q.
    pub dof: usize,
    /// Redundant constraint equations m − rank Φ_q.
    pub redundant: usize,
}

/// Numerical rank of a dense matrix from its singular values (faer's SVD):
/// the number of σ_i > max(m, n) · ε · σ_max (the usual rule, as in
/// NumPy's `matrix_rank`).
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

/// Size of `sys` at positions `q`, time `t`: Φ_q assembled dense (fine for
/// the systems one checks by hand; O(m n min(m, n)) for the SVD).
pub fn size(sys: &System, q: &[f64], t: f64) -> Result<Size, String> {
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let pattern = sys.jacobian_pattern();
    let mut vals = vec![0.0; pattern.len()];
    sys.jacobian_values(q, t, &mut vals);
    let mut a = Mat::<f64>::zeros(m, n);
    for (&(r, c), &v) in pattern.iter().zip(&vals) {
        a[(r, c)] += v;
    }
    let r = rank(&a)?;
    Ok(Size {
        bodies: sys.bodies().len(),
        coordinates: n,
        constraints: m,
        rank: r,
        dof: n - r,
        redundant: m - r,
    })
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

/// Count the elements by kind, as `"2 revolute joint, 1 drag"`.
fn by_kind(names: impl Iterator<Item = String>) -> String {
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    for n in names {
        *counts.entry(kind(&n)).or_default() += 1;
    }
    if counts.is_empty() {
        return "none".into();
    }
    counts
        .iter()
        .map(|(k, c)| format!("{c} {k}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The report printed for a valid scenario.
fn report(sc: &Scenario, s: &Size) -> String {
    let sys = &sc.system;
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("{k:<22}{v}\n"));
    line("scenario", sc.name.clone());
    line("bodies", s.bodies.to_string());
    line("coordinates", s.coordinates.to_string());
    line("constraint equations", s.constraints.to_string());
    line(
        "rank of Phi_q",
        format!("{} (at the initial state)", s.rank),
    );
    line("degrees of freedom", s.dof.to_string());
    line("redundant equations", s.redundant.to_string());
    line(
        "joints",
        format!(
            "{} ({})",
            sys.constraints().len(),
            by_kind(sys.constraints().iter().map(|c| c.name()))
        ),
    );
    line(
        "force elements",
        format!(
            "{} ({})",
            sys.forces().len(),
            by_kind(sys.forces().iter().map(|f| f.name()))
        ),
    );
    line("evaluation", sys.evaluation_name());
    line(
        "method",
        format!(
            "{} (formulation {:?}, linear solver {:?})",
            sc.run.method.name(),
            sc.run.index1.formulation,
            sc.run.index1.linear_solver
        ),
    );
    line(
        "time",
        format!(
            "{} .. {} s, output every {} s",
            sc.run.t0, sc.run.t_end, sc.run.output_dt
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
pub fn command(path: &Path, set: &[String]) -> ExitCode {
    let checked = scenario::load(path, set)
        .map_err(|e| e.to_string())
        .and_then(|sc| {
            let s = size(&sc.system, &sc.q0, sc.run.t0)?;
            Ok((sc, s))
        });
    match checked {
        Ok((sc, s)) => {
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
