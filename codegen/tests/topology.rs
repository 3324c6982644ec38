//! Symbolic Φ_q, Φ_t, γ, (Φ_qᵀλ)_q and force Jacobians of a mixed topology
//! against finite differences of the interpreted Φ and g.

mod common;
use common::Rng;
use mbsolve_codegen::{ForceKind, Id, JointKind, PlanarModel, Side, Topology};

fn mixed() -> Topology {
    common::mixed_topology("mixed").joint("E", JointKind::DriveAngle, Side::Ground, Side::Body(1))
}

/// Prescribed drive f(t) = a sin(2t) + b t and its derivatives.
fn drive(t: f64, a: f64, b: f64) -> [f64; 3] {
    [
        a * (2.0 * t).sin() + b * t,
        2.0 * a * (2.0 * t).cos() + b,
        -4.0 * a * (2.0 * t).sin(),
    ]
}

struct Env<'a> {
    m: &'a PlanarModel,
    v: Vec<f64>,
}

impl<'a> Env<'a> {
    fn new(m: &'a PlanarModel, r: &mut Rng) -> Self {
        let mut v: Vec<f64> = (0..m.ctx.n_vars()).map(|_| r.uniform(-1.0, 1.0)).collect();
        // unit sliding axes
        for j in &m.joints {
            if j.jac.len() >= 4 && j.params.len() == 7 {
                let (ux, uy) = (j.params.start + 2, j.params.start + 3);
                let (a, b) = (
                    v[m.ctx.var_number(m.p[ux]).unwrap()],
                    v[m.ctx.var_number(m.p[uy]).unwrap()],
                );
                let n = (a * a + b * b).sqrt();
                v[m.ctx.var_number(m.p[ux]).unwrap()] = a / n;
                v[m.ctx.var_number(m.p[uy]).unwrap()] = b / n;
            }
        }
        let mut e = Env { m, v };
        e.set_time(0.37);
        e
    }
    fn set(&mut self, id: Id, x: f64) {
        self.v[self.m.ctx.var_number(id).unwrap()] = x;
    }
    fn get(&self, id: Id) -> f64 {
        self.v[self.m.ctx.var_number(id).unwrap()]
    }
    fn set_time(&mut self, t: f64) {
        self.set(self.m.t, t);
        for (k, j) in self.m.joints.iter().enumerate() {
            if !j.time_inputs.is_empty() {
                let f = drive(t, 0.3 + 0.1 * k as f64, 0.2);
                for (d, &fd) in f.iter().enumerate() {
                    self.set(self.m.tf[j.time_inputs.start + d], fd);
                }
            }
        }
    }
    fn eval(&self, ids: &[Id]) -> Vec<f64> {
        self.m.ctx.eval(ids, &self.v)
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn jacobian_phi_t_and_hessian_match_finite_differences() {
    let m = PlanarModel::new(&mixed());
    let mut r = Rng(77);
    let n = m.n_coords();
    let pat = m.jac_pattern();
    let hp = m.hess_pattern();
    for _ in 0..20 {
        let mut env = Env::new(&m, &mut r);
        let jac = env.eval(&m.jac());
        let hess = env.eval(&m.hess());
        let lam: Vec<f64> = m.lambda.iter().map(|&l| env.get(l)).collect();
        let h = 1e-6;
        for c in 0..n {
            let x0 = env.get(m.q[c]);
            env.set(m.q[c], x0 + h);
            let (pp, jp) = (env.eval(&m.phi()), env.eval(&m.jac()));
            env.set(m.q[c], x0 - h);
            let (pm, jm) = (env.eval(&m.phi()), env.eval(&m.jac()));
            env.set(m.q[c], x0);
            for row in 0..m.n_rows() {
                let num = (pp[row] - pm[row]) / (2.0 * h);
                let sym: f64 = pat
                    .iter()
                    .zip(&jac)
                    .filter(|(&(rr, cc), _)| rr == row && cc == c)
                    .map(|(_, v)| v)
                    .sum();
                assert!(close(sym, num, 1e-8), "Φ_q[{row},{c}] = {sym} vs {num}");
            }
            // (Φ_qᵀλ)_q[a][c] = ∂/∂q_c Σ_r λ_r Φ_q[r][a]  (lower triangle a ≥ c)
            for a in c..n {
                let num: f64 = pat
                    .iter()
                    .enumerate()
                    .filter(|(_, &(_, cc))| cc == a)
                    .map(|(k, &(rr, _))| lam[rr] * (jp[k] - jm[k]) / (2.0 * h))
                    .sum();
                let sym: f64 = hp
                    .iter()
                    .zip(&hess)
                    .filter(|(&(ra, cb), _)| ra == a && cb == c)
                    .map(|(_, v)| v)
                    .sum();
                assert!(close(sym, num, 1e-7), "H[{a},{c}] = {sym} vs {num}");
            }
        }
        // Φ_t: difference in t with q fixed (drives move)
        let t0 = env.get(m.t);
        let phi_t = env.eval(&m.phi_t());
        env.set_time(t0 + h);
        let pp = env.eval(&m.phi());
        env.set_time(t0 - h);
        let pm = env.eval(&m.phi());
        env.set_time(t0);
        for row in 0..m.n_rows() {
            let num = (pp[row] - pm[row]) / (2.0 * h);
            assert!(
                close(phi_t[row], num, 1e-8),
                "Φ_t[{row}] {} vs {num}",
                phi_t[row]
            );
        }
    }
}

/// Along q(t) = q0 + v (t−t0) + ½ a (t−t0)²: d²Φ/dt² = Φ_q a − γ.
#[test]
fn gamma_is_the_acceleration_right_hand_side() {
    let m = PlanarModel::new(&mixed());
    let mut r = Rng(4242);
    let n = m.n_coords();
    let pat = m.jac_pattern();
    for _ in 0..20 {
        let mut env = Env::new(&m, &mut r);
        let q0: Vec<f64> = m.q.iter().map(|&x| env.get(x)).collect();
        let v: Vec<f64> = m.qd.iter().map(|&x| env.get(x)).collect();
        let a: Vec<f64> = (0..n).map(|_| r.uniform(-1.0, 1.0)).collect();
        let t0 = env.get(m.t);
        let gamma = env.eval(&m.gamma());
        let jac = env.eval(&m.jac());
        let at = |env: &mut Env, dt: f64| {
            for c in 0..n {
                env.set(m.q[c], q0[c] + v[c] * dt + 0.5 * a[c] * dt * dt);
            }
            env.set_time(t0 + dt);
            env.eval(&m.phi())
        };
        let h = 1e-4;
        let (pp, p0, pm) = (at(&mut env, h), at(&mut env, 0.0), at(&mut env, -h));
        for row in 0..m.n_rows() {
            let num = (pp[row] - 2.0 * p0[row] + pm[row]) / (h * h);
            let qa: f64 = pat
                .iter()
                .zip(&jac)
                .filter(|(&(rr, _), _)| rr == row)
                .map(|(&(_, c), j)| j * a[c])
                .sum();
            let sym = qa - gamma[row];
            assert!(
                close(sym, num, 1e-5),
                "row {row}: Φ_q a − γ = {sym} vs d²Φ/dt² = {num}"
            );
        }
    }
}

#[test]
fn force_jacobians_match_finite_differences() {
    let m = PlanarModel::new(&mixed());
    let mut r = Rng(99);
    for _ in 0..20 {
        let mut env = Env::new(&m, &mut r);
        for f in &m.forces {
            let k = f.coords.len();
            let (dq, dqd) = (env.eval(&f.dq), env.eval(&f.dqd));
            for (which, vars, sym) in [(0, &m.q, &dq), (1, &m.qd, &dqd)] {
                for (ci, &c) in f.coords.iter().enumerate() {
                    let h = 1e-6;
                    let x0 = env.get(vars[c]);
                    env.set(vars[c], x0 + h);
                    let gp = env.eval(&f.g);
                    env.set(vars[c], x0 - h);
                    let gm = env.eval(&f.g);
                    env.set(vars[c], x0);
                    for ri in 0..k {
                        let num = (gp[ri] - gm[ri]) / (2.0 * h);
                        assert!(
                            close(sym[ri * k + ci], num, 1e-7),
                            "force {which} [{ri},{ci}]: {} vs {num}",
                            sym[ri * k + ci]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn revolute_gamma_is_the_textbook_formula() {
    // γ = R_i s_i φ̇_i² − R_j s_j φ̇_j², derived here by differentiation only.
    let m = PlanarModel::new(&Topology::new("pair", 2).revolute("B", Side::Body(0), Side::Body(1)));
    let mut r = Rng(5);
    let env = Env::new(&m, &mut r);
    let g = env.eval(&m.gamma());
    let q = |k: usize| env.get(m.q[k]);
    let w = |k: usize| env.get(m.qd[k]);
    let p = |k: usize| env.get(m.p[k]);
    let rot = |phi: f64, s: [f64; 2]| {
        let (sn, cs) = phi.sin_cos();
        [cs * s[0] - sn * s[1], sn * s[0] + cs * s[1]]
    };
    let (ri, rj) = (rot(q(2), [p(0), p(1)]), rot(q(5), [p(2), p(3)]));
    for a in 0..2 {
        let want = ri[a] * w(2) * w(2) - rj[a] * w(5) * w(5);
        assert_eq!(g[a], want, "bitwise equal to the hand formula");
    }
}

/// Hunt–Crossley wall contact: forces and Jacobians against finite
/// differences on states with penetrating corners (away from the kinks).
#[test]
fn wall_contact_matches_finite_differences() {
    let topo =
        Topology::new("contact", 1).force("c", ForceKind::WallContact, Side::Body(0), Side::Ground);
    let m = PlanarModel::new(&topo);
    let f = &m.forces[0];
    let mut r = Rng(123);
    let mut active = 0;
    for _ in 0..200 {
        let mut v = vec![0.0; m.ctx.n_vars()];
        let mut set = |id: Id, x: f64| v[m.ctx.var_number(id).unwrap()] = x;
        // hw, hl, x_l, x_r, k_h, χ, μ, v_s
        let p = [0.015, 0.05, -0.025, 0.025, 1e9, 0.75, 0.3, 1e-3];
        for (k, &x) in p.iter().enumerate() {
            set(m.fp[k], x);
        }
        set(m.q[0], r.uniform(-0.02, 0.02));
        set(m.q[1], r.uniform(-1.0, 1.0));
        set(m.q[2], r.uniform(-0.3, 0.3));
        set(m.qd[0], r.uniform(-0.2, 0.2));
        set(m.qd[1], r.uniform(-5e-3, 5e-3));
        set(m.qd[2], r.uniform(-1.0, 1.0));
        let g = m.ctx.eval(&f.g, &v);
        if g[0] == 0.0 {
            continue;
        }
        active += 1;
        let (dq, dqd) = (m.ctx.eval(&f.dq, &v), m.ctx.eval(&f.dqd, &v));
        for (vars, sym, h) in [(&m.q, &dq, 1e-9), (&m.qd, &dqd, 1e-8)] {
            for c in 0..3 {
                let k = m.ctx.var_number(vars[c]).unwrap();
                let x0 = v[k];
                v[k] = x0 + h;
                let gp = m.ctx.eval(&f.g, &v);
                v[k] = x0 - h;
                let gm = m.ctx.eval(&f.g, &v);
                v[k] = x0;
                for row in 0..3 {
                    let num = (gp[row] - gm[row]) / (2.0 * h);
                    let s = sym[row * 3 + c];
                    // truncation + rounding (ε |g| / h, large where tanh saturates)
                    let tol = 1e-5 * (1.0 + s.abs().max(num.abs()))
                        + 1e3 * f64::EPSILON * g[row].abs().max(gp[row].abs()) / h;
                    assert!(
                        (s - num).abs() <= tol,
                        "∂g{row}/∂{c} (h = {h}): {s:e} vs {num:e}"
                    );
                }
            }
        }
    }
    assert!(active > 50, "only {active} states in contact");
}
