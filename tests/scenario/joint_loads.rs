//! `joint_torque` and `joint_force`: the same loads as opposite `expression`
//! terms written out by hand (forces, Jacobians and runs), Jacobians against
//! finite differences, PD joints against their closed-form responses, and
//! errors naming the file and key.

use mbsolve::forces::{FdWorkspace, ForceJacobians};
use mbsolve::model::System;
use mbsolve::scenario;
use mbsolve::simulation::{simulate_into, Sample, Sink};

use crate::common::setup::{parse_error as err, scenario as parse};

/// (t, q) at every output time.
#[derive(Default)]
struct Rows(Vec<(f64, Vec<f64>)>);

impl Sink for Rows {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.0.push((s.t, s.q.to_vec()));
        Ok(())
    }
}

fn run(sc: &scenario::Scenario) -> Rows {
    let mut rows = Rows::default();
    let s = simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut rows).unwrap();
    assert_eq!(s.status, "completed", "{s:?}");
    assert!(rows.0.len() > 10);
    rows
}

/// ∂g/∂q and ∂g/∂q̇ of every force element, dense n × n row-major.
fn jacobians(sys: &System, t: f64, q: &[f64], qd: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = q.len();
    let (mut jq, mut jqd) = (vec![0.0; n * n], vec![0.0; n * n]);
    let mut ws = FdWorkspace::default();
    for f in sys.forces() {
        let cols = f.jacobian_coordinates();
        let k = cols.len();
        let (mut dq, mut dqd) = (vec![0.0; k * k], vec![0.0; k * k]);
        f.add_jacobians(
            t,
            q,
            qd,
            ForceJacobians {
                dq: &mut dq,
                dqd: &mut dqd,
                ws: &mut ws,
            },
        );
        for (r, &i) in cols.iter().enumerate() {
            for (c, &j) in cols.iter().enumerate() {
                jq[i * n + j] += dq[r * k + c];
                jqd[i * n + j] += dqd[r * k + c];
            }
        }
    }
    (jq, jqd)
}

/// Central differences of g, dense n × n row-major.
fn fd_jacobians(sys: &System, t: f64, q: &[f64], qd: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = q.len();
    let (mut jq, mut jqd) = (vec![0.0; n * n], vec![0.0; n * n]);
    let g = |q: &[f64], qd: &[f64]| {
        let mut g = vec![0.0; n];
        sys.forces_into(t, q, qd, &mut g);
        g
    };
    for j in 0..n {
        for velocity in [false, true] {
            let (mut qp, mut qdp) = (q.to_vec(), qd.to_vec());
            let (mut qm, mut qdm) = (q.to_vec(), qd.to_vec());
            let h = 1e-6;
            if velocity {
                qdp[j] += h;
                qdm[j] -= h;
            } else {
                qp[j] += h;
                qm[j] -= h;
            }
            let (gp, gm) = (g(&qp, &qdp), g(&qm, &qdm));
            let out = if velocity { &mut jqd } else { &mut jq };
            for i in 0..n {
                out[i * n + j] = (gp[i] - gm[i]) / (2.0 * h);
            }
        }
    }
    (jq, jqd)
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Two links on revolutes (ground–a "hip", a–b "knee") with gravity, and
/// `forces` appended.
fn two_links(forces: &str, integrator: &str) -> String {
    format!(
        "gravity = [0.0, -9.81]\n\
         [[body]]\nname = \"a\"\nmass = 1.0\ninertia = 0.08\nx = 0.5\n\
         [[body]]\nname = \"b\"\nmass = 0.7\ninertia = 0.05\nx = 1.5\n\
         [[joint]]\ntype = \"revolute\"\nname = \"hip\"\nbody_i = \"ground\"\npoint_i = [0.0, 0.0]\n\
         body_j = \"a\"\npoint_j = [-0.5, 0.0]\n\
         [[joint]]\ntype = \"revolute\"\nname = \"knee\"\nbody_i = \"a\"\npoint_i = [0.5, 0.0]\n\
         body_j = \"b\"\npoint_j = [-0.5, 0.0]\n\
         {forces}\n{integrator}\n[time]\nend = 1.0\n[output]\ndt = 0.05\n"
    )
}

const SHORT: &str = "[[force]]\ntype = \"joint_torque\"\njoint = \"knee\"\n\
    torque = \"-5*angle - 0.3*rate + 2*sin(3*t)\"\n\
    [[force]]\ntype = \"joint_torque\"\njoint = \"hip\"\ntorque = \"-2*(angle + 0.2) - 0.1*rate*abs(rate)\"\n";

const LONG: &str = "[[force]]\ntype = \"expression\"\nbody = \"b\"\n\
    torque = \"-5*(b.phi - a.phi) - 0.3*(b.omega - a.omega) + 2*sin(3*t)\"\n\
    [[force]]\ntype = \"expression\"\nbody = \"a\"\n\
    torque = \"5*(b.phi - a.phi) + 0.3*(b.omega - a.omega) - 2*sin(3*t)\"\n\
    [[force]]\ntype = \"expression\"\nbody = \"a\"\ntorque = \"-2*(a.phi + 0.2) - 0.1*a.omega*abs(a.omega)\"\n";

/// `joint_torque` is the two opposite `expression` torques written out:
/// generalized forces and Jacobians at arbitrary states to rounding, and
/// runs (fixed-step rk4, and generalized-α which uses the Jacobians) to
/// rounding.
#[test]
fn joint_torque_equals_the_long_way() {
    let rk4 = "[integrator]\nmethod = \"rk4\"\nstep = 1e-3\n";
    let (short, long) = (parse(&two_links(SHORT, rk4)), parse(&two_links(LONG, rk4)));
    for (k, (q, qd)) in [
        (
            [0.5, 0.1, 0.3, 1.4, 0.2, -0.7],
            [0.1, -0.2, 1.5, 0.3, 0.4, -2.0],
        ),
        (
            [0.2, -0.4, -1.1, 0.9, -0.8, 2.4],
            [-0.3, 0.2, -0.5, 0.1, 0.0, 0.9],
        ),
    ]
    .iter()
    .enumerate()
    {
        let t = 0.37 * k as f64;
        let (mut g1, mut g2) = (vec![0.0; 6], vec![0.0; 6]);
        short.system.forces_into(t, q, qd, &mut g1);
        long.system.forces_into(t, q, qd, &mut g2);
        assert!(max_diff(&g1, &g2) < 1e-13, "{g1:?} vs {g2:?}");
        let (a, b) = (
            jacobians(&short.system, t, q, qd),
            jacobians(&long.system, t, q, qd),
        );
        assert!(max_diff(&a.0, &b.0) < 1e-13 && max_diff(&a.1, &b.1) < 1e-13);
        // the knee torque really acts: not the zero load
        assert!(g1[5].abs() > 0.1, "{g1:?}");
    }
    let (r1, r2) = (run(&short), run(&long));
    let d =
        r1.0.iter()
            .zip(&r2.0)
            .map(|(a, b)| max_diff(&a.1, &b.1))
            .fold(0.0, f64::max);
    assert!(d < 1e-11, "rk4: max |Δq| = {d:e}");
    let ga = "[integrator]\nmethod = \"genalpha\"\nstep = 2e-3\nnewton_tol = 1e-10\n";
    let (r1, r2) = (
        run(&parse(&two_links(SHORT, ga))),
        run(&parse(&two_links(LONG, ga))),
    );
    let d =
        r1.0.iter()
            .zip(&r2.0)
            .map(|(a, b)| max_diff(&a.1, &b.1))
            .fold(0.0, f64::max);
    assert!(d < 1e-9, "genalpha: max |Δq| = {d:e}");
}

/// The symbolic Jacobians of a `joint_force` on a rail carried by a
/// turning body (the axis turns with it) and of a `joint_torque` match
/// central differences of the generalized forces.
#[test]
fn joint_load_jacobians_match_finite_differences() {
    let text = "gravity = [0.0, 0.0]\n\
         [[body]]\nname = \"a\"\nmass = 1.0\ninertia = 0.1\n\
         [[body]]\nname = \"b\"\nmass = 0.5\ninertia = 0.02\nx = 0.3\n\
         [[joint]]\ntype = \"revolute\"\nname = \"pivot\"\nbody_i = \"ground\"\npoint_i = [0.0, 0.0]\n\
         body_j = \"a\"\npoint_j = [0.0, 0.0]\n\
         [[joint]]\ntype = \"translational\"\nname = \"rail\"\nbody_i = \"a\"\npoint_i = [0.1, 0.05]\n\
         axis_i = [2.0, 1.0]\nbody_j = \"b\"\npoint_j = [0.02, -0.01]\n\
         [[force]]\ntype = \"joint_force\"\njoint = \"rail\"\n\
         force = \"-50*(slide - 0.2) - 3*speed*abs(speed) + a.phi*slide + sin(t)\"\n\
         [[force]]\ntype = \"joint_torque\"\njoint = \"pivot\"\ntorque = \"-4*sin(angle) - rate + b.x\"\n\
         [initial]\nconsistent = false\n[time]\nend = 1.0\n";
    let sc = parse(text);
    let q = [0.01, -0.02, 0.7, 0.35, 0.2, 0.65];
    let qd = [0.1, 0.2, -1.3, 0.4, -0.5, 0.8];
    let (a, b) = (
        jacobians(&sc.system, 0.3, &q, &qd),
        fd_jacobians(&sc.system, 0.3, &q, &qd),
    );
    let scale = a.0.iter().chain(&a.1).fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(scale > 1.0);
    let (dq, dqd) = (max_diff(&a.0, &b.0), max_diff(&a.1, &b.1));
    assert!(
        dq < 1e-7 * scale && dqd < 1e-7 * scale,
        "∂g/∂q {dq:e}, ∂g/∂q̇ {dqd:e}"
    );
    // the pair is equal and opposite along the axis: no net force on the
    // two bodies when only the rail force acts on them (at rest: speed 0)
    let mut g = vec![0.0; 6];
    let only_rail = text.replace("-4*sin(angle) - rate + b.x", "0");
    parse(&only_rail)
        .system
        .forces_into(0.0, &q, &[0.0; 6], &mut g);
    assert!(
        (g[0] + g[3]).abs() < 1e-13 && (g[1] + g[4]).abs() < 1e-13,
        "{g:?}"
    );
    assert!(g[3].hypot(g[4]) > 1.0, "{g:?}");
    // ... and no net moment (both act at the same point)
    let moment = g[2] + q[0] * g[1] - q[1] * g[0] + g[5] + q[3] * g[4] - q[4] * g[3];
    assert!(moment.abs() < 1e-13, "net moment {moment:e}");
}

/// θ(t) of `I θ̈ + c θ̇ + k θ = k θr` from rest at 0 (underdamped).
fn pd_response(k: f64, c: f64, inertia: f64, target: f64, t: f64) -> f64 {
    let wn = (k / inertia).sqrt();
    let zeta = c / (2.0 * (k * inertia).sqrt());
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    target * (1.0 - (-zeta * wn * t).exp() * ((wd * t).cos() + zeta * wn / wd * (wd * t).sin()))
}

/// A PD joint `k (θr − angle) − c rate` on a body pinned at its centre of
/// mass (no gravity: the equation is linear, `I θ̈ + c θ̇ + k θ = k θr`)
/// follows the closed-form damped response, with an explicit and an
/// implicit method; the gains come from `[parameters]`.
#[test]
fn pd_joint_torque_follows_the_closed_form() {
    for integrator in [
        "method = \"ode45\"\nrtol = 1e-10\natol = 1e-12",
        "method = \"radau5\"\nadaptive = true\nrtol = 1e-9\natol = 1e-11",
    ] {
        let text = format!(
            "gravity = [0.0, 0.0]\n[parameters]\nk = 4.0\nc = 0.4\ntarget = 0.3\n\
             [[body]]\nname = \"arm\"\nmass = 1.0\ninertia = 0.2\n\
             [[joint]]\ntype = \"revolute\"\nname = \"pin\"\nbody_i = \"ground\"\npoint_i = [0.0, 0.0]\n\
             body_j = \"arm\"\npoint_j = [0.0, 0.0]\n\
             [[force]]\ntype = \"joint_torque\"\njoint = \"pin\"\ntorque = \"k*(target - angle) - c*rate\"\n\
             [integrator]\n{integrator}\n[time]\nend = 3.0\n[output]\ndt = 0.05\n"
        );
        let rows = run(&parse(&text));
        let e = rows
            .0
            .iter()
            .map(|(t, q)| (q[2] - pd_response(4.0, 0.4, 0.2, 0.3, *t)).abs())
            .fold(0.0, f64::max);
        assert!(e < 1e-6, "{integrator}: max |θ − closed form| = {e:e}");
        // it moved: overshoot above the target near the first peak
        assert!(rows.0.iter().any(|(_, q)| q[2] > 0.35));
    }
}

/// A PD `joint_force` on a slider on a ground rail at 30°: the slide
/// follows the closed-form damped response `m s̈ + c ṡ + k s = k s_r`,
/// and the slider stays on the rail.
#[test]
fn pd_joint_force_follows_the_closed_form() {
    let (m, k, c, target) = (2.0, 50.0, 2.0, 0.1);
    let a = 30f64.to_radians();
    let text = format!(
        "gravity = [0.0, 0.0]\n\
         [[body]]\nname = \"s\"\nmass = {m}\ninertia = 0.1\n\
         [[joint]]\ntype = \"translational\"\nname = \"rail\"\nbody_i = \"ground\"\npoint_i = [0.0, 0.0]\n\
         axis_i = [{}, {}]\nbody_j = \"s\"\npoint_j = [0.0, 0.0]\n\
         [[force]]\ntype = \"joint_force\"\njoint = \"rail\"\nforce = \"{k}*({target} - slide) - {c}*speed\"\n\
         [integrator]\nmethod = \"ode45\"\nrtol = 1e-10\natol = 1e-12\n[time]\nend = 2.0\n[output]\ndt = 0.05\n",
        2.0 * a.cos(),
        2.0 * a.sin()
    );
    let rows = run(&parse(&text));
    let mut e = 0.0f64;
    for (t, q) in &rows.0 {
        let slide = q[0] * a.cos() + q[1] * a.sin();
        let off = -q[0] * a.sin() + q[1] * a.cos();
        e = e.max((slide - pd_response(k, c, m, target, *t)).abs());
        assert!(off.abs() < 1e-8, "off the rail by {off:e}");
    }
    assert!(e < 1e-7, "max |slide − closed form| = {e:e}");
}

/// Bad input names the file and the key.
#[test]
fn joint_load_errors_name_the_file_and_key() {
    let e = err(&two_links(
        "[[force]]\ntype = \"joint_torque\"\njoint = \"kne\"\ntorque = \"-angle\"\n",
        "",
    ));
    assert!(
        e.contains("test.toml")
            && e.contains("force[0].joint")
            && e.contains("no joint named 'kne'"),
        "{e}"
    );
    assert!(e.contains("hip, knee"), "{e}");
    let e = err(&two_links(
        "[[force]]\ntype = \"joint_force\"\njoint = \"knee\"\nforce = \"-slide\"\n",
        "",
    ));
    assert!(
        e.contains("test.toml")
            && e.contains("force[0].joint")
            && e.contains("is a revolute joint"),
        "{e}"
    );
    // the variables of the other kind are unknown names at the expression's key
    let e = err(&two_links(
        "[[force]]\ntype = \"joint_torque\"\njoint = \"knee\"\ntorque = \"-slide\"\n",
        "",
    ));
    assert!(
        e.contains("test.toml") && e.contains("force[0].torque") && e.contains("slide"),
        "{e}"
    );
    // a number is not an expression string
    let e = err(&two_links(
        "[[force]]\ntype = \"joint_torque\"\njoint = \"knee\"\ntorque = 1.0\n",
        "",
    ));
    assert!(
        e.contains("test.toml") && e.contains("force[0].torque"),
        "{e}"
    );
}
