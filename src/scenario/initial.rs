//! The initial-state part of a scenario: `[initial]` → positions and
//! velocities (assembled onto the constraints, then perturbed).

use super::model::body_index;
use super::{error, positive, ScenarioError};
use crate::formulation::{
    consistent_initial_state_locked, ConsistentState, InitialOptions, Lock, LockKind,
};
use crate::model::{joint_short_name, BodyRef, JointGeometry, System};
use crate::simulation::RunConfig;
use serde::Deserialize;
use std::collections::HashMap;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInitial {
    #[serde(default = "yes")]
    consistent: bool,
    #[serde(default)]
    independent: Vec<String>,
    #[serde(default)]
    incorrect: bool,
    #[serde(default)]
    perturbation: Vec<RawPerturbation>,
    #[serde(default = "default_ic_tol")]
    tol: f64,
    #[serde(default)]
    joint: Vec<RawJointInit>,
    #[serde(default)]
    allow_branch_flip: bool,
    /// A state file (JSON `{"q": [...], "qd": [...]}`, `qd` optional)
    /// replacing the bodies' initial positions and velocities, e.g. the
    /// equilibrium `mbsolve static` writes; relative to the scenario file.
    state: Option<String>,
}

/// `[[initial.joint]]`: a revolute joint's relative angle `φ_j − φ_i`
/// (`angle`/`angle_deg`, rate `rate`/`rate_deg`, default 0) or a
/// translational joint's slide (`displacement`, `velocity`, default 0).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawJointInit {
    name: String,
    angle: Option<f64>,
    angle_deg: Option<f64>,
    rate: Option<f64>,
    rate_deg: Option<f64>,
    displacement: Option<f64>,
    velocity: Option<f64>,
}

impl Default for RawInitial {
    fn default() -> Self {
        Self {
            joint: Vec::new(),
            allow_branch_flip: false,
            state: None,
            consistent: true,
            independent: Vec::new(),
            incorrect: false,
            perturbation: Vec::new(),
            tol: default_ic_tol(),
        }
    }
}

fn yes() -> bool {
    true
}
fn default_ic_tol() -> f64 {
    1e-12
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPerturbation {
    coordinate: String,
    delta: f64,
}

/// Initial positions, velocities and the assembly report (when assembled).
pub(super) type Initial = (Vec<f64>, Vec<f64>, Option<ConsistentState>);

/// Initial positions and velocities of `system` from `raw` (and the
/// assembly report); errors name keys of `file`.
pub(super) fn build(
    raw: &RawInitial,
    system: &System,
    names: &HashMap<String, usize>,
    run: &RunConfig,
    file: &str,
) -> Result<Initial, ScenarioError> {
    let err = |key: String, message: String| error(file, key, message);
    let body_index = |key: String, name: &str| body_index(names, file, key, name);
    let (t0, linear_solver) = (run.t0, run.formulation.linear_solver);
    let coord = |key: String, spec: &str| -> Result<usize, ScenarioError> {
        let (b, c) = spec.rsplit_once('.').ok_or_else(|| {
            err(
                key.clone(),
                format!("'{spec}' is not of the form BODY.x|y|phi"),
            )
        })?;
        let bi = body_index(key.clone(), b)?;
        let ci = match c {
            "x" => 0,
            "y" => 1,
            "phi" => 2,
            o => return Err(err(key, format!("'{o}' is not one of x, y, phi"))),
        };
        Ok(3 * bi + ci)
    };
    let independent = raw
        .independent
        .iter()
        .enumerate()
        .map(|(i, s)| coord(format!("initial.independent[{i}]"), s))
        .collect::<Result<Vec<_>, _>>()?;
    positive(raw.tol).map_err(|m| err("initial.tol".into(), m))?;
    let (mut q0, mut qd0) = system.initial_state();
    if let Some(path) = &raw.state {
        read_state(path, file, &mut q0, &mut qd0)?;
    }
    let mut locks: Vec<Lock> = independent
        .iter()
        .map(|&k| Lock {
            kind: LockKind::Coordinate(k),
            value: q0[k],
            rate: qd0[k],
        })
        .collect();
    let mut locked_joints = Vec::new();
    for (i, j) in raw.joint.iter().enumerate() {
        let (lock, joint) = joint_lock(j, i, system, &q0, file)?;
        if locked_joints.contains(&joint) {
            return Err(err(
                format!("initial.joint[{i}].name"),
                format!("joint '{}' is given twice", j.name),
            ));
        }
        locked_joints.push(joint);
        locks.push(lock);
    }
    if !raw.joint.is_empty() && !raw.consistent {
        return Err(err(
            "initial.joint".into(),
            "joint coordinates are imposed by the assembly: initial.consistent must be true".into(),
        ));
    }
    if raw.allow_branch_flip && !raw.consistent {
        return Err(err(
            "initial.allow_branch_flip".into(),
            "applies to the assembly only: initial.consistent is false".into(),
        ));
    }
    let mut assembly = None;
    if raw.consistent && system.n_constraints() > 0 {
        let st = consistent_initial_state_locked(
            system,
            t0,
            &q0,
            &qd0,
            &locks,
            InitialOptions {
                tol: raw.tol,
                linear_solver,
                ..Default::default()
            },
        )
        .map_err(|e| err("initial".into(), e.to_string()))?;
        // The velocity solve is least squares: a residual left means the
        // given independent velocities are incompatible with the
        // constraints (a locked mechanism, dependent "independent" ones).
        let vscale = st.qd.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let vtol = 1e3 * raw.tol * vscale;
        // the kept values must have been kept (least squares gives up a
        // lock row when the constraints contradict it)
        let moved = independent.iter().find(|&&k| {
            (st.q[k] - q0[k]).abs() > 1e-9 * (1.0 + q0[k].abs())
                || (st.qd[k] - qd0[k]).abs() > 1e-9 * (1.0 + qd0[k].abs())
        });
        if let Some(&k) = moved {
            return Err(err(
                "initial.independent".into(),
                format!(
                    "{} cannot keep its given value: position {} → {}, rate {} → {} in the \
                     assembly; the constraints fix it (a locked mechanism, or the independent \
                     coordinates {:?} are not independent)",
                    System::coordinate_name(k),
                    q0[k],
                    st.q[k],
                    qd0[k],
                    st.qd[k],
                    raw.independent
                ),
            ));
        }
        if st.lock_residual
            > 1e-9
                * (1.0
                    + locks
                        .iter()
                        .fold(0.0f64, |a, l| a.max(l.value.abs()).max(l.rate.abs())))
        {
            return Err(err(
                "initial.joint".into(),
                format!(
                    "the joint coordinates cannot all be kept (largest error {:.3e} after the \
                     assembly): the constraints fix some of them, or they contradict \
                     initial.independent",
                    st.lock_residual
                ),
            ));
        }
        if !raw.allow_branch_flip {
            if let Some(m) = branch_flip(system, &q0, &st.q, &locked_joints) {
                return Err(err("initial.allow_branch_flip".into(), m));
            }
        }
        if st.velocity_residual > vtol {
            return Err(err(
                "initial.independent".into(),
                format!(
                    "the initial velocities cannot satisfy the velocity constraints Φ_q q̇ = −Φ_t: \
                     residual ‖Φ_q q̇ + Φ_t‖ = {:.3e} > {vtol:.1e} (1e3 initial.tol max(1, |q̇|)); \
                     the mechanism is locked or the independent coordinates {:?} are not \
                     independent",
                    st.velocity_residual, raw.independent
                ),
            ));
        }
        q0.clone_from(&st.q);
        qd0.clone_from(&st.qd);
        assembly = Some(st);
    }
    if raw.incorrect {
        if raw.perturbation.is_empty() {
            return Err(err(
                "initial.incorrect".into(),
                "true, but the scenario gives no initial.perturbation".into(),
            ));
        }
        for (i, p) in raw.perturbation.iter().enumerate() {
            let c = coord(
                format!("initial.perturbation[{i}].coordinate"),
                &p.coordinate,
            )?;
            if !p.delta.is_finite() {
                return Err(err(
                    format!("initial.perturbation[{i}].delta"),
                    format!("{} is not finite", p.delta),
                ));
            }
            q0[c] += p.delta;
        }
    }
    Ok((q0, qd0, assembly))
}

/// The lock of `initial.joint[i]` and the index of its joint.
fn joint_lock(
    j: &RawJointInit,
    i: usize,
    system: &System,
    q0: &[f64],
    file: &str,
) -> Result<(Lock, usize), ScenarioError> {
    let key = |f: &str| format!("initial.joint[{i}].{f}");
    let err = |f: &str, message: String| error(file, key(f), message);
    let names: Vec<String> = system
        .constraints()
        .iter()
        .filter_map(|c| joint_short_name(c.as_ref()))
        .collect();
    let k = system
        .constraints()
        .iter()
        .position(|c| joint_short_name(c.as_ref()).as_deref() == Some(j.name.as_str()))
        .ok_or_else(|| {
            err(
                "name",
                format!("no joint named '{}' (joints: {})", j.name, names.join(", ")),
            )
        })?;
    let one = |a: Option<f64>, b: Option<f64>, fa: &str, fb: &str| match (a, b) {
        (Some(_), Some(_)) => Err(err(fb, format!("give either {fa} or {fb}, not both"))),
        (v, None) => Ok(v),
        (None, Some(d)) => Ok(Some(d.to_radians())),
    };
    let angle = one(j.angle, j.angle_deg, "angle", "angle_deg")?;
    let rate = one(j.rate, j.rate_deg, "rate", "rate_deg")?;
    let finite = |f: &str, v: Option<f64>| match v {
        Some(x) if !x.is_finite() => Err(err(f, format!("{x} is not finite"))),
        _ => Ok(()),
    };
    finite("displacement", j.displacement)?;
    finite("velocity", j.velocity)?;
    let lock = match system.constraints()[k].geometry() {
        JointGeometry::Revolute { i: pin_i, j: pin_j } => {
            for (f, v) in [("displacement", j.displacement), ("velocity", j.velocity)] {
                if v.is_some() {
                    return Err(err(f, "not a key of a revolute joint (angle, rate)".into()));
                }
            }
            let kind = LockKind::RelativeAngle {
                body_i: pin_i.body,
                body_j: pin_j.body,
            };
            let theta = angle.ok_or_else(|| {
                err(
                    "angle_deg",
                    "missing: a revolute joint needs angle or angle_deg".into(),
                )
            })?;
            // the 2π-equivalent nearest the given relative angle: the
            // assembly does not spin a body by whole turns
            let now = kind.eval(q0, &mut [0.0; 2]);
            let tau = std::f64::consts::TAU;
            let value = theta + ((now - theta) / tau).round() * tau;
            Lock {
                kind,
                value,
                rate: rate.unwrap_or(0.0),
            }
        }
        JointGeometry::Translational(slide) => {
            for (f, v) in [
                ("angle", j.angle),
                ("angle_deg", j.angle_deg),
                ("rate", j.rate),
                ("rate_deg", j.rate_deg),
            ] {
                if v.is_some() {
                    return Err(err(
                        f,
                        "not a key of a translational joint (displacement, velocity)".into(),
                    ));
                }
            }
            let d = j.displacement.ok_or_else(|| {
                err(
                    "displacement",
                    "missing: a translational joint needs displacement".into(),
                )
            })?;
            Lock {
                kind: LockKind::Slide(slide),
                value: d,
                rate: j.velocity.unwrap_or(0.0),
            }
        }
        JointGeometry::Other => {
            return Err(err(
                "name",
                format!(
                    "'{}' is a {}: only revolute and translational joints take joint coordinates \
                     (a drive already prescribes its own)",
                    j.name,
                    system.constraints()[k].name()
                ),
            ))
        }
    };
    for (f, v) in [("angle", lock.value), ("rate", lock.rate)] {
        if !v.is_finite() {
            return Err(err(f, format!("{v} is not finite")));
        }
    }
    Ok((lock, k))
}

/// A revolute joint: its index, body i and its pin, body j and its pin.
type Pin = (usize, BodyRef, [f64; 2], BodyRef, [f64; 2]);

/// Smallest |sin| of a bend counted as bent (≈ 1.1°): closer to straight,
/// a sign change is a pass through the stretched position, not a flip.
const BEND_MIN: f64 = 0.02;

/// A branch flip between the given positions `q_given` and the assembled
/// `q` (`None`: none found).
///
/// The *bend* of a revolute joint P between bodies i and j is the sign of
/// `(A − P) × (B − P)`, where A and B are the pins of the first other
/// revolute joint on body i and on body j (ground pins included): the
/// side to which the two links meeting at P fold. On one assembly branch of
/// a closed loop the bend of a joint between two unlocked links cannot
/// change without passing a stretched (singular) position — for a
/// four-bar it is the sign of the transmission angle. A joint is checked
/// when neither it nor the joints at A and B are locked, and it counts as a
/// flip when its bend changes with |sin| > 0.02 on both sides.
fn branch_flip(system: &System, q_given: &[f64], q: &[f64], locked: &[usize]) -> Option<String> {
    let pins: Vec<Pin> = system
        .constraints()
        .iter()
        .enumerate()
        .filter_map(|(k, c)| match c.geometry() {
            JointGeometry::Revolute { i, j } => Some((k, i.body, i.point, j.body, j.point)),
            _ => None,
        })
        .collect();
    let at = |q: &[f64], b: BodyRef, s: [f64; 2]| b.point_at(q, s);
    // the pin of the first other revolute joint on body b (its point on b)
    let other = |me: usize, b: BodyRef| {
        pins.iter().find_map(|&(k, bi, si, bj, sj)| {
            if k == me {
                None
            } else if bi == b {
                Some((k, si))
            } else if bj == b {
                Some((k, sj))
            } else {
                None
            }
        })
    };
    for &(k, bi, _, bj, sj) in &pins {
        let (Some((ka, sa)), Some((kb, sb))) = (other(k, bi), other(k, bj)) else {
            continue;
        };
        if [k, ka, kb].iter().any(|j| locked.contains(j)) {
            continue;
        }
        // (sin, angle) of the bend
        let bend = |q: &[f64]| {
            let p = at(q, bj, sj);
            let a = at(q, bi, sa);
            let b = at(q, bj, sb);
            let (u, v) = ([a[0] - p[0], a[1] - p[1]], [b[0] - p[0], b[1] - p[1]]);
            let (cross, dot) = (u[0] * v[1] - u[1] * v[0], u[0] * v[0] + u[1] * v[1]);
            (
                cross / (u[0].hypot(u[1]) * v[0].hypot(v[1])),
                cross.atan2(dot),
            )
        };
        let ((before, a0), (after, a1)) = (bend(q_given), bend(q));
        if before.abs() > BEND_MIN && after.abs() > BEND_MIN && before.signum() != after.signum() {
            let name = joint_short_name(system.constraints()[k].as_ref())
                .unwrap_or_else(|| format!("joint{}", k + 1));
            return Some(format!(
                "the assembly flipped the mechanism to its other branch: the bend at joint \
                 '{name}' changed from {:.1}° to {:.1}° (the angle between the links to joints \
                 '{}' and '{}'); give body positions closer to the intended branch, or set \
                 initial.allow_branch_flip = true to accept it",
                a0.to_degrees(),
                a1.to_degrees(),
                joint_short_name(system.constraints()[ka].as_ref()).unwrap_or_default(),
                joint_short_name(system.constraints()[kb].as_ref()).unwrap_or_default(),
            ));
        }
    }
    None
}

/// `initial.state`: positions (and velocities, default 0) from a JSON file
/// `{"q": [...], "qd": [...]}` of the system's length, finite; a relative
/// path is taken from the scenario file's directory.
fn read_state(
    path: &str,
    file: &str,
    q0: &mut [f64],
    qd0: &mut [f64],
) -> Result<(), ScenarioError> {
    let key = "initial.state";
    let err = |m: String| error(file, key.to_string(), m);
    let mut p = std::path::PathBuf::from(path);
    if p.is_relative() {
        if let Some(dir) = std::path::Path::new(file).parent() {
            if dir.is_dir() {
                p = dir.join(p);
            }
        }
    }
    let text = std::fs::read_to_string(&p)
        .map_err(|e| err(format!("cannot read '{}': {e}", p.display())))?;
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct State {
        q: Vec<f64>,
        #[serde(default)]
        qd: Option<Vec<f64>>,
        #[serde(default, rename = "t")]
        _t: Option<f64>,
    }
    let st: State = serde_json::from_str(&text)
        .map_err(|e| err(format!("'{}' is not a state file: {e}", p.display())))?;
    let n = q0.len();
    if st.q.len() != n {
        return Err(err(format!(
            "'{}': q has {} entries, the model {n} coordinates",
            p.display(),
            st.q.len()
        )));
    }
    let qd = st.qd.unwrap_or_else(|| vec![0.0; n]);
    if qd.len() != n {
        return Err(err(format!(
            "'{}': qd has {} entries, the model {n} coordinates",
            p.display(),
            qd.len()
        )));
    }
    if let Some(k) = st.q.iter().chain(&qd).position(|v| !v.is_finite()) {
        return Err(err(format!("'{}': entry {k} is not finite", p.display())));
    }
    q0.copy_from_slice(&st.q);
    qd0.copy_from_slice(&qd);
    Ok(())
}
