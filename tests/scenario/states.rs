//! `[[state]]` controller states: a first-order lag against its closed form
//! under each method family, a PD arm whose integral term removes the
//! steady-state error (the integral equal to ∫e dt from the output
//! columns), and errors naming the file and key.

use mbsolve::output::{columns, RowBuilder};
use mbsolve::scenario;
use mbsolve::simulation::{simulate, simulate_into, OutputQuantities, Sample, Sink, Trajectory};

use crate::common::setup::{docs_example, parse_error as err, scenario as parse};

/// The output table's rows, built as `mbsolve run` builds them.
struct Table<'s> {
    rows: Vec<Vec<f64>>,
    builder: RowBuilder<'s>,
}

impl Sink for Table<'_> {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.rows.push(self.builder.row(s).to_vec());
        Ok(())
    }
}

/// (column names, rows) of a run of `text`.
fn run(text: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let sc = parse(text);
    let o = OutputQuantities::default();
    let names = columns(&sc.system, &o, &sc.sensors)
        .into_iter()
        .map(|c| c.name)
        .collect();
    let mut t = Table {
        rows: Vec::new(),
        builder: RowBuilder::new(&sc.system, o, &sc.sensors),
    };
    let s = simulate_into(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [], &mut t).unwrap();
    assert_eq!(s.status, "completed", "{s:?}");
    (names, t.rows)
}

fn col(names: &[String], n: &str) -> usize {
    names
        .iter()
        .position(|c| c == n)
        .unwrap_or_else(|| panic!("no column {n} in {names:?}"))
}

/// A lag `ż = (u − z)/τ`, u = 1 − 0.5 m.x with a body m at rest at x = 0
/// (so u = 1): `z = 1 − e^{−t/τ}`, under an explicit method, generalized-α,
/// radau5 and BDF; the state is the column `lag`, and the body does not
/// move (the state carries no mass, gravity or energy of the bodies).
#[test]
fn a_first_order_lag_follows_its_closed_form_under_every_family() {
    for (integrator, bound) in [
        ("method = \"ode45\"\nrtol = 1e-10\natol = 1e-12", 1e-8),
        (
            "method = \"genalpha\"\nstep = 1e-3\nnewton_tol = 1e-10",
            1e-4,
        ),
        (
            "method = \"radau5\"\nadaptive = true\nrtol = 1e-9\natol = 1e-11",
            1e-6,
        ),
        ("method = \"bdf\"\nrtol = 1e-8\natol = 1e-10", 1e-4),
    ] {
        let text = format!(
            "gravity = [0.0, -9.81]\n[parameters]\ntau = 0.2\n\
             [[body]]\nname = \"m\"\nmass = 1.0\ninertia = 0.1\n\
             [[joint]]\ntype = \"revolute\"\nbody_i = \"ground\"\npoint_i = [0.0, 0.0]\n\
             body_j = \"m\"\npoint_j = [0.0, 0.0]\n\
             [[state]]\nname = \"lag\"\nderivative = \"(1 - 0.5*m.x - lag)/tau\"\n\
             [integrator]\n{integrator}\n[time]\nend = 1.0\n[output]\ndt = 0.02\n"
        );
        let (names, rows) = run(&text);
        let (k, x) = (col(&names, "lag"), col(&names, "m.x"));
        assert_eq!(names.len(), 6, "{names:?}");
        let mut e = 0.0f64;
        for r in &rows {
            e = e.max((r[k] - (1.0 - (-r[0] / 0.2).exp())).abs());
            assert!(r[x].abs() < 1e-8, "the body moved: {}", r[x]);
        }
        assert!(e < bound, "{integrator}: max |z − closed form| = {e:e}");
        assert!(rows.last().unwrap()[k] > 0.99);
    }
}

/// A one-link arm under gravity held at 0.5 rad by a `joint_torque`: PD
/// alone leaves the steady-state error `m g (l/2) cos θ / k_p`; with an
/// integral state `ie` (`ż = 0.5 − arm.phi`, the error) the error goes to
/// zero, and `ie` equals ∫e dt from the output columns (trapezoid).
#[test]
fn an_integral_state_removes_the_steady_state_error() {
    let arm = |ki: f64| {
        format!(
            "gravity = [0.0, -9.81]\n[parameters]\nkp = 50.0\nkd = 10.0\nki = {ki}\n\
             [[body]]\nname = \"arm\"\nmass = 1.0\ninertia = 0.0833333333333\nx = 0.5\n\
             [[joint]]\ntype = \"revolute\"\nname = \"shoulder\"\nbody_i = \"ground\"\n\
             point_i = [0.0, 0.0]\nbody_j = \"arm\"\npoint_j = [-0.5, 0.0]\n\
             [[state]]\nname = \"ie\"\nderivative = \"0.5 - arm.phi\"\n\
             [[force]]\ntype = \"joint_torque\"\njoint = \"shoulder\"\n\
             torque = \"kp*(0.5 - angle) - kd*rate + ki*ie\"\n\
             [integrator]\nmethod = \"ode45\"\nrtol = 1e-10\natol = 1e-12\n\
             [time]\nend = 12.0\n[output]\ndt = 0.005\n"
        )
    };
    let (names, pd) = run(&arm(0.0));
    let phi = col(&names, "arm.phi");
    let e_pd = 0.5 - pd.last().unwrap()[phi];
    let expected = 9.81 * 0.5 * (0.5 - e_pd).cos() / 50.0;
    assert!(
        (e_pd - expected).abs() < 1e-4,
        "PD error {e_pd} vs {expected}"
    );
    let (names, pid) = run(&arm(40.0));
    let (phi, ie) = (col(&names, "arm.phi"), col(&names, "ie"));
    let e_pid = 0.5 - pid.last().unwrap()[phi];
    assert!(e_pid.abs() < 1e-3 && e_pd > 0.05, "PID {e_pid}, PD {e_pd}");
    let mut integral = 0.0;
    for w in pid.windows(2) {
        integral += 0.5 * (w[1][0] - w[0][0]) * ((0.5 - w[0][phi]) + (0.5 - w[1][phi]));
    }
    let z = pid.last().unwrap()[ie];
    assert!((z - integral).abs() < 1e-5, "ie {z} vs ∫e dt {integral}");
    // at rest the integral carries the gravity torque: ki ie = m g (l/2) cos θ
    assert!((40.0 * z - 9.81 * 0.5 * 0.5f64.cos()).abs() < 0.05, "{z}");
}

/// Bad input names the file and the key.
#[test]
fn state_errors_name_the_file_and_key() {
    let base = "[[body]]\nname = \"m\"\nmass = 1.0\ninertia = 0.1\n[time]\nend = 0.1\n";
    let e = err(&format!(
        "{base}[[state]]\nname = \"z\"\nderivative = \"-zz\"\n"
    ));
    assert!(
        e.contains("test.toml") && e.contains("state[0].derivative") && e.contains("zz"),
        "{e}"
    );
    let e = err(&format!(
        "{base}[[state]]\nname = \"z\"\nderivative = \"-z\"\n[[state]]\nname = \"z\"\nderivative = \"1\"\n"
    ));
    assert!(
        e.contains("test.toml") && e.contains("state[1].name") && e.contains("duplicate"),
        "{e}"
    );
    let e = err(&format!(
        "{base}[[state]]\nname = \"m\"\nderivative = \"1\"\n"
    ));
    assert!(e.contains("state[0].name") && e.contains("body"), "{e}");
    // a parameter of the state's name would replace it in expressions
    let e = err(&format!(
        "{base}[parameters]\nz = 0.5\n[[state]]\nname = \"z\"\nderivative = \"-z\"\n"
    ));
    assert!(
        e.contains("test.toml") && e.contains("state[0].name") && e.contains("parameter"),
        "{e}"
    );
    // an expression force reading an unknown state
    let e = err(&format!(
        "{base}[[force]]\ntype = \"expression\"\nbody = \"m\"\ntorque = \"-2*integ\"\n"
    ));
    assert!(
        e.contains("test.toml") && e.contains("force[0].torque") && e.contains("integ"),
        "{e}"
    );
}

/// The state example of docs/scenarios.md parses and runs, and its arm
/// comes to the target (PID with a filtered rate).
#[test]
fn the_documented_state_example_runs() {
    let block = &docs_example("state example");
    let (names, rows) = run(block);
    let (phi, ie) = (col(&names, "arm.phi"), col(&names, "ie"));
    let last = rows.last().unwrap();
    assert!((last[phi] - 0.5).abs() < 0.01, "{}", last[phi]);
    assert!(last[ie] > 0.0);
    col(&names, "filtered");
}

/// The shipped user models in the new form run: the PID arm reaches its
/// three joint targets (its integral states carry gravity), the shaker's
/// payload rides its spring on the table.
#[test]
fn the_shipped_pid_arm_and_shaker_run() {
    let read = |f: &str| {
        std::fs::read_to_string(format!("{}/scenarios/{f}", env!("CARGO_MANIFEST_DIR"))).unwrap()
    };
    let (names, rows) = run(&read("pid_arm.toml"));
    let last = rows.last().unwrap();
    let phi = |k: usize| last[col(&names, &format!("link{k}.phi"))];
    for (got, want) in [
        (phi(1), 0.6),
        (phi(2) - phi(1), -0.4),
        (phi(3) - phi(2), 0.3),
    ] {
        assert!(
            (got - want).abs() < 5e-3,
            "joint angle {got} vs target {want}"
        );
    }
    assert!(last[col(&names, "e1")] > 0.0);
    let (names, rows) = run(&read("shaker.toml"));
    let (table, payload) = (col(&names, "table.y"), col(&names, "payload.y"));
    let stroke = rows
        .iter()
        .map(|r| r[table])
        .fold(f64::NEG_INFINITY, f64::max)
        - rows.iter().map(|r| r[table]).fold(f64::INFINITY, f64::min);
    assert!(
        (stroke - 0.1).abs() < 1e-3,
        "table stroke {stroke} (2 r = 0.1)"
    );
    assert!(rows.iter().all(|r| (r[payload] - r[table]).abs() < 0.05));
}

/// `scenarios/pid_arm.toml` written out: every link, joint, PID torque and
/// integral state as its own table (no `[[repeat]]`), the same
/// `[parameters]` and settings.
fn pid_arm_written_out() -> String {
    let mut s = String::from(
        "name = \"pid_arm\"\ngravity = [0.0, -9.81]\n\
         [parameters]\nkp = 200.0\nkd = 20.0\nki = 150.0\nr1 = 0.6\nr2 = -0.4\nr3 = 0.3\n",
    );
    for i in 1..=3 {
        s += &format!(
            "[[body]]\nname = \"link{i}\"\nmass = 1.0\ninertia = 0.0208333333333\nx = {}\n",
            0.5 * i as f64 - 0.25
        );
    }
    s += "[[joint]]\ntype = \"revolute\"\nname = \"joint1\"\nbody_i = \"ground\"\n\
          point_i = [0.0, 0.0]\nbody_j = \"link1\"\npoint_j = [-0.25, 0.0]\n";
    for i in 2..=3 {
        s += &format!(
            "[[joint]]\ntype = \"revolute\"\nname = \"joint{i}\"\nbody_i = \"link{}\"\n\
             point_i = [0.25, 0.0]\nbody_j = \"link{i}\"\npoint_j = [-0.25, 0.0]\n",
            i - 1
        );
    }
    for i in 1..=3 {
        s += &format!(
            "[[force]]\ntype = \"joint_torque\"\nname = \"pid{i}\"\njoint = \"joint{i}\"\n\
             torque = \"kp*(r{i} - angle) - kd*rate + ki*e{i}\"\n"
        );
    }
    s += "[[state]]\nname = \"e1\"\nunit = \"rad s\"\nderivative = \"r1 - link1.phi\"\n";
    for i in 2..=3 {
        s += &format!(
            "[[state]]\nname = \"e{i}\"\nunit = \"rad s\"\n\
             derivative = \"r{i} - (link{i}.phi - link{}.phi)\"\n",
            i - 1
        );
    }
    s + "[integrator]\nmethod = \"ode45\"\nrtol = 1e-6\n[time]\nend = 6.0\n[output]\ndt = 0.01\n"
}

/// A `[[repeat]]` holds `[[state]]`s: the shipped PID arm (its elbow and
/// wrist integrals copied by a repeat, `e{i}`) is the arm written out
/// state by state, bit for bit — the same states, units and generalized
/// forces at an arbitrary point, and the same run.
#[test]
fn a_repeated_pid_per_joint_is_the_written_out_one_bit_for_bit() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/pid_arm.toml");
    let set = ["time.end=0.5".to_string()];
    let a = scenario::load(std::path::Path::new(path), &set).unwrap();
    let b = scenario::parse(&pid_arm_written_out(), "long.toml", "long", &set).unwrap();
    let text = std::fs::read_to_string(path).unwrap();
    assert!(
        text.contains("state = [{ name = \"e{i}\""),
        "the file repeats its states"
    );
    let names = |s: &scenario::Scenario| {
        s.system
            .states()
            .iter()
            .map(|z| (z.name.clone(), z.unit.clone()))
            .collect::<Vec<_>>()
    };
    assert_eq!(names(&a).len(), 3);
    assert_eq!(names(&a), names(&b));
    assert_eq!((&a.q0, &a.qd0), (&b.q0, &b.qd0));
    let n = a.system.n_coords();
    assert_eq!(n, 12);
    let q: Vec<f64> = (0..n).map(|k| 0.3 * (k as f64 + 1.0).sin()).collect();
    let v: Vec<f64> = (0..n).map(|k| 0.7 * (k as f64 + 2.0).cos()).collect();
    let (mut ga, mut gb) = (vec![0.0; n], vec![0.0; n]);
    a.system.forces_into(0.2, &q, &v, &mut ga);
    b.system.forces_into(0.2, &q, &v, &mut gb);
    assert_eq!(ga, gb);
    assert!(
        ga[9..].iter().all(|g| *g != 0.0),
        "the states' rates {ga:?}"
    );
    let (ta, sa) =
        mbsolve::simulation::simulate(&a.system, &a.q0, &a.qd0, &a.run, &mut []).unwrap();
    let (tb, sb) =
        mbsolve::simulation::simulate(&b.system, &b.q0, &b.qd0, &b.run, &mut []).unwrap();
    assert_eq!(sa.status, "completed");
    assert_eq!(sa.steps, sb.steps);
    assert_eq!((&ta.t, &ta.q, &ta.qd), (&tb.t, &tb.q, &tb.qd));
}

/// A state's `unit` is its column's unit (default "1", dimensionless); a
/// bad unit names the file and key.
#[test]
fn a_state_column_carries_its_unit() {
    let base = "[[body]]\nname = \"m\"\nmass = 1.0\ninertia = 0.1\n[time]\nend = 0.1\n";
    let sc = parse(&format!(
        "{base}[[state]]\nname = \"ie\"\nunit = \"rad s\"\nderivative = \"-m.phi\"\n\
         [[state]]\nname = \"u\"\nderivative = \"-u\"\n"
    ));
    let cols = columns(&sc.system, &OutputQuantities::default(), &sc.sensors);
    let unit = |n: &str| cols.iter().find(|c| c.name == n).unwrap().unit.clone();
    assert_eq!((unit("ie"), unit("u")), ("rad s".into(), "1".into()));
    for bad in ["", "<b>", "a\\u0007"] {
        let e = err(&format!(
            "{base}[[state]]\nname = \"z\"\nunit = \"{bad}\"\nderivative = \"-z\"\n"
        ));
        assert!(
            e.contains("test.toml") && e.contains("state[0].unit"),
            "{bad}: {e}"
        );
    }
}

/// The Newton matrix of a system with controller states, factorised by the
/// symmetric LDLᵀ with the states' border, solves exactly as the sparse LU
/// of the full unsymmetric matrix (the arm's own Jacobians are symmetric:
/// joint torques' angle and rate terms), for generalized-α's and
/// radau5's coefficients at large steps; before the border the states'
/// one-way couplings (∂τ/∂z, ∂ż/∂φ) were dropped by the reciprocal part.
#[test]
fn the_states_border_solves_the_newton_matrix_exactly() {
    use mbsolve::formulation::{Index3, NewtonSolverKind};
    use mbsolve::linalg::SolverKind;
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/pid_arm.toml");
    let sc = scenario::load(std::path::Path::new(path), &[]).unwrap();
    let sys = &sc.system;
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut ldlt = Index3::new(sys, SolverKind::Auto).unwrap();
    let mut lu =
        Index3::with_newton_solver(sys, SolverKind::Auto, NewtonSolverKind::SparseLu).unwrap();
    let q: Vec<f64> = sc
        .q0
        .iter()
        .enumerate()
        .map(|(k, x)| x + 0.01 * k as f64)
        .collect();
    let v: Vec<f64> = (0..n).map(|k| 0.3 * (k as f64).cos()).collect();
    let lam: Vec<f64> = (0..m).map(|k| 2.0 * (k as f64).sin()).collect();
    for c in [[1.0, 0.05, 2.5e-3], [1.0, 0.5, 0.25], [1.0, 2.0, 4.0]] {
        ldlt.assemble_and_factorize(0.3, &q, &v, &lam, c[0], c[1], c[2])
            .unwrap();
        lu.assemble_and_factorize(0.3, &q, &v, &lam, c[0], c[1], c[2])
            .unwrap();
        let rhs: Vec<f64> = (0..n + m).map(|k| ((k * 7 + 3) as f64).sin()).collect();
        let (mut a, mut b) = (rhs.clone(), rhs);
        ldlt.solve_newton(0.3, &mut a).unwrap();
        lu.solve_newton(0.3, &mut b).unwrap();
        let scale = b.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        let d = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |s, (x, y)| s.max((x - y).abs()));
        assert!(
            d < 1e-11 * scale,
            "{c:?}: |LDLᵀ + border − LU| = {d:e} of {scale:e}"
        );
        // the states' corrections are coupled to the arm's
        assert!(a[9..12].iter().all(|x| x.abs() > 1e-6), "{a:?}");
    }
}

/// A column of a trajectory: its value at output row `i`.
type Reader = fn(&Trajectory, usize) -> f64;

/// On the documented PID example (an integral and a filtered rate, both
/// coupled one way to the arm), radau5, BDF and generalized-α converge
/// without a Newton failure (before the states' border of the Newton
/// matrix: 22, 157 and 17) and match an ode45 run at rtol 1e-10 within
/// 100 rtol of each column's largest value at every output row.
#[test]
fn implicit_methods_converge_on_states_and_match_ode45() {
    let block = &docs_example("state example");
    let run_with = |set: &[&str]| {
        let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
        let sc = scenario::parse(block, "f.toml", "f", &set).unwrap();
        simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap()
    };
    let (reference, _) = run_with(&[
        "integrator.method=ode45",
        "integrator.rtol=1e-10",
        "integrator.atol=1e-12",
    ]);
    for method in ["radau5", "bdf", "genalpha"] {
        let m = format!("integrator.method={method}");
        let set: Vec<&str> = if method == "bdf" {
            vec![&m]
        } else {
            vec![&m, "integrator.adaptive=true"]
        };
        let (tr, s) = run_with(&set);
        assert_eq!(s.status, "completed", "{method}");
        assert_eq!(s.extra["newton_failures"], 0, "{method}: {:?}", s.extra);
        assert_eq!(tr.t, reference.t);
        // arm.phi, ie, filtered: q[2], q̇[3], q̇[4]; each error against
        // the column's largest value
        let cols: [(&str, Reader); 3] = [
            ("arm.phi", |t, i| t.q[i][2]),
            ("ie", |t, i| t.qd[i][3]),
            ("filtered", |t, i| t.qd[i][4]),
        ];
        for (name, at) in cols {
            let rows = 0..tr.t.len();
            let scale = rows
                .clone()
                .map(|i| at(&reference, i).abs())
                .fold(0.0, f64::max);
            let e = rows
                .map(|i| (at(&tr, i) - at(&reference, i)).abs())
                .fold(0.0, f64::max);
            assert!(
                e < 1e-4 * scale,
                "{method}: {name} differs from ode45 by {e:e} (largest {scale:e})"
            );
        }
    }
}

/// The repeated-states example of docs/scenarios.md runs: three lags
/// `lag{i}` of time constants 0.1 i s, each its closed form
/// `1 − e^{−t/τ}`, each in volts.
#[test]
fn the_documented_repeated_states_example_runs() {
    let block = &docs_example("repeated states example");
    let sc = parse(block);
    let units: Vec<&str> = sc.system.states().iter().map(|s| s.unit.as_str()).collect();
    assert_eq!(units, ["V"; 3]);
    let (names, rows) = run(block);
    for i in 1..=3 {
        let k = col(&names, &format!("lag{i}"));
        let tau = 0.1 * i as f64;
        let e = rows
            .iter()
            .map(|r| (r[k] - (1.0 - (-r[0] / tau).exp())).abs())
            .fold(0.0, f64::max);
        assert!(e < 1e-6, "lag{i}: {e:e}");
    }
}

/// radau5's complex Newton matrix on the PID arm (a chain pattern: the
/// complex chain LDLᵀ with the states' border) solves as the sparse LU of
/// its real embedding (exact), at coefficients of radau5's form for three
/// step sizes.
#[test]
fn the_complex_states_border_solves_as_the_lu() {
    use mbsolve::formulation::{ComplexSolverKind, Index3Complex};
    use mbsolve::integrate::{ComplexNewton, StateView};
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/pid_arm.toml");
    let sc = scenario::load(std::path::Path::new(path), &[]).unwrap();
    let sys = &sc.system;
    let (n, m) = (sys.n_coords(), sys.n_constraints());
    let mut chain = Index3Complex::new(sys).unwrap();
    let mut lu = Index3Complex::with_solver(sys, ComplexSolverKind::SparseLu).unwrap();
    let q: Vec<f64> = sc
        .q0
        .iter()
        .enumerate()
        .map(|(k, x)| x + 0.01 * k as f64)
        .collect();
    let v: Vec<f64> = (0..n).map(|k| 0.3 * (k as f64).cos()).collect();
    let lam: Vec<f64> = (0..m).map(|k| 2.0 * (k as f64).sin()).collect();
    // c = [1, h μ, (h μ)²] as radau5 factorises, μ about its α + iβ
    let mu = [0.16, 0.18];
    for h in [0.01, 0.1, 0.5] {
        let c1 = [h * mu[0], h * mu[1]];
        let c2 = [c1[0] * c1[0] - c1[1] * c1[1], 2.0 * c1[0] * c1[1]];
        let c = [[1.0, 0.0], c1, c2];
        let x = StateView {
            t: 0.3,
            q: &q,
            qd: &v,
        };
        chain.factorize_complex(x, &lam, c).unwrap();
        lu.factorize_complex(x, &lam, c).unwrap();
        assert_eq!(chain.solver_name(), "complex-chain-ldlt");
        let re: Vec<f64> = (0..n + m).map(|k| ((k * 7 + 3) as f64).sin()).collect();
        let im: Vec<f64> = (0..n + m).map(|k| ((k * 5 + 1) as f64).cos()).collect();
        let (mut ar, mut ai, mut br, mut bi) = (re.clone(), im.clone(), re, im);
        chain.solve_complex(0.3, &mut ar, &mut ai).unwrap();
        lu.solve_complex(0.3, &mut br, &mut bi).unwrap();
        let scale = br.iter().chain(&bi).fold(0.0f64, |s, x| s.max(x.abs()));
        let d = ar
            .iter()
            .zip(&br)
            .chain(ai.iter().zip(&bi))
            .fold(0.0f64, |s, (x, y)| s.max((x - y).abs()));
        assert!(
            d < 1e-11 * scale,
            "h = {h}: |chain + border − LU| = {d:e} of {scale:e}"
        );
    }
}
