//! Static equilibrium against references mbsolve does not compute: the
//! discrete cantilever solved by hand (linear tip load: closed form; a
//! large tip load: the equilibrium equations in absolute angles, Newton in
//! the test) and the Euler–Bernoulli deflection; the four-bar's joint
//! reactions at rest against a Newton–Euler balance of its three links;
//! stability counts; the error when there is no equilibrium.

// matrices are indexed by row and column throughout
#![allow(clippy::needless_range_loop)]

use crate::common::rod::cantilever_at;
use faer::Mat;
use mbsolve::analysis::{stability, static_equilibrium, StaticError, StaticOptions};
use mbsolve::builders::{cantilever, RodParams};
use mbsolve::scenario;
use std::f64::consts::PI;

/// A horizontal cantilever along +x (tilt −π/2: segment axes along +x).
fn horizontal(n: usize, tip: [f64; 2]) -> (mbsolve::model::System, Vec<f64>, RodParams) {
    cantilever_at(n, -PI / 2.0, tip)
}

/// Tip (free end) position from the coordinates.
fn tip(q: &[f64], ls: f64) -> [f64; 2] {
    let b = q.len() / 3 - 1;
    let phi = q[3 * b + 2];
    // local +y (0, l/2) is the free end: e = (−sin φ, cos φ)
    [
        q[3 * b] - 0.5 * ls * phi.sin(),
        q[3 * b + 1] + 0.5 * ls * phi.cos(),
    ]
}

#[test]
fn small_tip_load_matches_the_discrete_closed_form_and_euler_bernoulli() {
    let p_load = 1.0;
    let mut errs = Vec::new();
    for n in [10, 40, 160] {
        let (sys, q0, p) = horizontal(n, [0.0, -p_load]);
        let eq = static_equilibrium(&sys, &q0, StaticOptions::default()).unwrap();
        let ls = p.segment_length();
        let d = -tip(&eq.q, ls)[1];
        // joint i carries M_i = P (N − i + 1) l_s, turns M_i / k and moves
        // the tip by that times (N − i + 1) l_s: δ = P l_s²/k Σ j²
        let k = p.spring_stiffness();
        let nn = n as f64;
        let discrete = p_load * ls * ls / k * nn * (nn + 1.0) * (2.0 * nn + 1.0) / 6.0;
        // the linear value; the geometric nonlinearity is O((δ/l)²) ~ 1e-9
        assert!(
            (d - discrete).abs() < 1e-8 * discrete,
            "N = {n}: {d} vs {discrete}"
        );
        let ei = p.youngs_modulus * p.width.powi(4) / 12.0;
        let eb = p_load * p.length.powi(3) / (3.0 * ei);
        errs.push((d - eb) / eb);
        // the exact discrete excess over the beam: 3/(2N) + 1/(2N²)
        let excess = 1.5 / nn + 0.5 / (nn * nn);
        assert!(((d - eb) / eb - excess).abs() < 1e-7, "N = {n}");
        let st = stability(&sys, 0.0, &eq.q, &eq.lambda, 1e-3).unwrap();
        assert_eq!((st.stable, st.unstable, st.neutral), (n, 0, 0));
    }
    // first order: the error quarters from N = 10 to 40 and again to 160
    assert!(
        errs[1] < errs[0] / 3.5 && errs[2] < errs[1] / 3.5,
        "{errs:?}"
    );
}

/// The discrete cantilever under a dead tip load −P ŷ, in absolute angles
/// θ_i from +x: `k(θ_i − θ_{i−1}) − k(θ_{i+1} − θ_i) + P l_s cos θ_i = 0`
/// (θ_0 = 0, no last term for i = N), Newton with a dense Jacobian.
fn hand_large_deflection(n: usize, k: f64, ls: f64, p: f64) -> Vec<f64> {
    let mut th = vec![0.0; n];
    // continuation in the load, 20 steps, Newton to 1e-14
    for step in 1..=20 {
        let pl = p * step as f64 / 20.0;
        for _ in 0..50 {
            let mut r = vec![0.0; n];
            let mut j = Mat::<f64>::zeros(n, n);
            for i in 0..n {
                let prev = if i == 0 { 0.0 } else { th[i - 1] };
                r[i] = k * (th[i] - prev) + pl * ls * th[i].cos();
                j[(i, i)] = k - pl * ls * th[i].sin();
                if i > 0 {
                    j[(i, i - 1)] = -k;
                }
                if i + 1 < n {
                    r[i] -= k * (th[i + 1] - th[i]);
                    j[(i, i)] += k;
                    j[(i, i + 1)] = -k;
                }
            }
            let rn = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let mut b = Mat::<f64>::zeros(n, 1);
            for i in 0..n {
                b[(i, 0)] = -r[i];
            }
            use faer::linalg::solvers::Solve;
            let x = j.partial_piv_lu().solve(&b);
            for i in 0..n {
                th[i] += x[(i, 0)];
            }
            if rn < 1e-12 * pl.max(1.0) {
                break;
            }
        }
    }
    th
}

#[test]
fn large_tip_load_matches_the_hand_solved_discrete_model() {
    let n = 12;
    let (sys0, _, p) = horizontal(n, [0.0, 0.0]);
    drop(sys0);
    let ei = p.youngs_modulus * p.width.powi(4) / 12.0;
    // linear estimate of the tip deflection 0.3 l
    let p_load = 0.9 * ei / p.length.powi(2);
    let (sys, q0, _) = horizontal(n, [0.0, -p_load]);
    let eq = static_equilibrium(&sys, &q0, StaticOptions::default()).unwrap();
    let th = hand_large_deflection(n, p.spring_stiffness(), p.segment_length(), p_load);
    let ls = p.segment_length();
    for (i, t) in th.iter().enumerate() {
        let phi = eq.q[3 * i + 2] + PI / 2.0;
        assert!((phi - t).abs() < 1e-10, "segment {i}: {phi} vs {t}");
    }
    let y_hand: f64 = th.iter().map(|t| ls * t.sin()).sum();
    let y = tip(&eq.q, ls)[1];
    println!(
        "large deflection: tip y {y} vs {y_hand}, {} load steps, {} iterations",
        eq.load_steps, eq.iterations
    );
    assert!(y_hand < -0.2, "a large deflection: {y_hand}");
    assert!((y - y_hand).abs() < 1e-10);
}

#[test]
fn fourbar_reactions_at_rest_balance_each_link() {
    let text = scenario::FOURBAR_TOML.replace("torque = 0.5", "torque = 0.0");
    let sc = scenario::parse(&text, "fourbar.toml", "fourbar", &[]).unwrap();
    let sys = &sc.system;
    let eq = static_equilibrium(sys, &sc.q0, StaticOptions::default()).unwrap();
    // one degree of freedom: the potential V(θ) of the crank angle θ by the
    // loop closure (C on the circles about B and D, above the ground line)
    let potential = |th: f64| -> f64 {
        let b = [0.2 * th.cos(), 0.2 * th.sin()];
        let d = [0.4, 0.0];
        let (dx, dy) = (d[0] - b[0], d[1] - b[1]);
        let dist = dx.hypot(dy);
        let a = (0.4 * 0.4 - 0.25 * 0.25 + dist * dist) / (2.0 * dist);
        let h = (0.4 * 0.4 - a * a).sqrt();
        let (ux, uy) = (dx / dist, dy / dist);
        let c1 = [b[0] + a * ux - h * uy, b[1] + a * uy + h * ux];
        let c2 = [b[0] + a * ux + h * uy, b[1] + a * uy - h * ux];
        let c = if c1[1] > c2[1] { c1 } else { c2 };
        9.81 * (0.2 * 0.5 * b[1] + 0.4 * 0.5 * (b[1] + c[1]) + 0.25 * 0.5 * c[1])
    };
    let th = eq.q[2];
    let hh = 1e-4;
    let dv = (potential(th + hh) - potential(th - hh)) / (2.0 * hh);
    let d2v = (potential(th + hh) - 2.0 * potential(th) + potential(th - hh)) / (hh * hh);
    assert!(dv.abs() < 1e-7, "dV/dθ = {dv} at the equilibrium θ = {th}");
    let st = stability(sys, 0.0, &eq.q, &eq.lambda, 1e-3).unwrap();
    let expect = if d2v > 0.0 { (1, 0, 0) } else { (0, 1, 0) };
    println!("four-bar equilibrium θ = {th}, d²V/dθ² = {d2v}, {st:?}");
    assert_eq!((st.stable, st.unstable, st.neutral), expect, "{st:?}");
    // pins in world coordinates from the poses and the file's local points
    let q = &eq.q;
    let world = |b: usize, p: [f64; 2]| {
        let (s, c) = q[3 * b + 2].sin_cos();
        [
            q[3 * b] + c * p[0] - s * p[1],
            q[3 * b + 1] + s * p[0] + c * p[1],
        ]
    };
    let c = |b: usize| [q[3 * b], q[3 * b + 1]];
    let ra = world(0, [-0.1, 0.0]);
    let rb = world(0, [0.1, 0.0]);
    let rc = world(1, [0.2, 0.0]);
    let rd = world(2, [-0.125, 0.0]);
    let masses = [0.2, 0.4, 0.25];
    let g = 9.81;
    let cross = |r: [f64; 2], f: [f64; 2]| r[0] * f[1] - r[1] * f[0];
    let sub = |a: [f64; 2], b: [f64; 2]| [a[0] - b[0], a[1] - b[1]];
    // unknowns: F_A (ground on crank), F_B (crank on coupler), F_C
    // (coupler on rocker), F_D (ground on rocker); Newton–Euler of each link
    let mut a = Mat::<f64>::zeros(9, 8);
    let mut rhs = Mat::<f64>::zeros(9, 1);
    // crank: F_A − F_B + m1 g = 0; (A − c1) × F_A − (B − c1) × F_B = 0
    let lin = |a: &mut Mat<f64>, row: usize, unk: usize, sign: f64| {
        a[(row, 2 * unk)] += sign;
        a[(row + 1, 2 * unk + 1)] += sign;
    };
    let mom = |a: &mut Mat<f64>, row: usize, unk: usize, r: [f64; 2], sign: f64| {
        // r × F = r_x F_y − r_y F_x
        a[(row, 2 * unk)] += -sign * r[1];
        a[(row, 2 * unk + 1)] += sign * r[0];
    };
    lin(&mut a, 0, 0, 1.0);
    lin(&mut a, 0, 1, -1.0);
    rhs[(1, 0)] = masses[0] * g;
    mom(&mut a, 2, 0, sub(ra, c(0)), 1.0);
    mom(&mut a, 2, 1, sub(rb, c(0)), -1.0);
    // coupler: F_B − F_C + m2 g = 0
    lin(&mut a, 3, 1, 1.0);
    lin(&mut a, 3, 2, -1.0);
    rhs[(4, 0)] = masses[1] * g;
    mom(&mut a, 5, 1, sub(rb, c(1)), 1.0);
    mom(&mut a, 5, 2, sub(rc, c(1)), -1.0);
    // rocker: F_C + F_D + m3 g = 0
    lin(&mut a, 6, 2, 1.0);
    lin(&mut a, 6, 3, 1.0);
    rhs[(7, 0)] = masses[2] * g;
    mom(&mut a, 8, 2, sub(rc, c(2)), 1.0);
    mom(&mut a, 8, 3, sub(rd, c(2)), 1.0);
    use faer::linalg::solvers::SolveLstsq;
    let f = a.qr().solve_lstsq(&rhs);
    let mut res = &a * &f;
    res -= &rhs;
    let worst = (0..9).fold(0.0f64, |m, i| m.max(res[(i, 0)].abs()));
    assert!(
        worst < 1e-10,
        "the balance is consistent at equilibrium: {worst}"
    );
    // the model's reactions: each joint's on its second body (D: the rocker)
    let map = sys.reaction_map();
    let mut jac = vec![0.0; sys.jacobian_pattern().len()];
    sys.jacobian_values(q, 0.0, &mut jac);
    let mut r = vec![0.0; 12];
    sys.joint_reactions(&map, &jac, &eq.lambda, &mut r);
    let expect = [
        (0, ra, c(0)), // A on the crank: F_A
        (1, rb, c(1)), // B on the coupler: F_B
        (2, rc, c(2)), // C on the rocker: F_C
        (3, rd, c(2)), // D on the rocker: F_D
    ];
    for (j, pin, centre) in expect {
        let fx = f[(2 * j, 0)];
        let fy = f[(2 * j + 1, 0)];
        let mz = cross(sub(pin, centre), [fx, fy]);
        for (got, want) in [(r[3 * j], fx), (r[3 * j + 1], fy), (r[3 * j + 2], mz)] {
            assert!((got - want).abs() < 1e-9, "joint {j}: {got} vs {want}");
        }
    }
}

fn pendulum_text(start_deg: f64) -> String {
    let (s, c) = start_deg.to_radians().sin_cos();
    format!(
        "gravity = [0.0, -9.81]\n[[body]]\nname = \"bob\"\nmass = 1.0\ninertia = 0.01\n\
         x = {}\ny = {}\nphi_deg = {start_deg}\n[[joint]]\ntype = \"revolute\"\nname = \"pivot\"\n\
         body_i = \"ground\"\npoint_i = [0.0, 0.0]\nbody_j = \"bob\"\npoint_j = [0.0, 0.5]\n\
         [time]\nend = 1.0\n",
        0.5 * s,
        -0.5 * c
    )
}

#[test]
fn pendulum_hangs_stable_and_stands_unstable() {
    let sc = scenario::parse(&pendulum_text(40.0), "p.toml", "p", &[]).unwrap();
    let eq = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap();
    assert!(
        eq.q[2].abs() < 1e-10,
        "hangs straight down: φ = {}",
        eq.q[2]
    );
    // reaction = weight
    assert!((eq.lambda.iter().map(|l| l * l).sum::<f64>().sqrt() - 9.81).abs() < 1e-9);
    let st = stability(&sc.system, 0.0, &eq.q, &eq.lambda, 1e-3).unwrap();
    assert_eq!(st.verdict(), "stable");
    // upside down: already an equilibrium, unstable
    let sc = scenario::parse(&pendulum_text(180.0), "p.toml", "p", &[]).unwrap();
    let eq = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap();
    assert!((eq.q[2].abs() - PI).abs() < 1e-9);
    let st = stability(&sc.system, 0.0, &eq.q, &eq.lambda, 1e-3).unwrap();
    assert_eq!((st.stable, st.unstable, st.neutral), (0, 1, 0));
}

#[test]
fn free_body_under_gravity_has_no_equilibrium() {
    let text = "gravity = [0.0, -9.81]\n[[body]]\nname = \"b\"\nmass = 1.0\ninertia = 0.1\n[time]\nend = 1.0\n";
    let sc = scenario::parse(text, "f.toml", "f", &[]).unwrap();
    let e = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, StaticError::NoEquilibrium { .. }), "{msg}");
    assert!(
        msg.contains("load factor reached") && msg.contains("‖g − Φ_qᵀλ‖∞"),
        "{msg}"
    );
}

#[test]
fn spring_pendulum_rests_at_the_static_stretch_with_a_neutral_rotation() {
    let sc = scenario::parse(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenarios/spring_pendulum.toml"
        ))
        .unwrap(),
        "spring_pendulum.toml",
        "spring_pendulum",
        &[],
    )
    .unwrap();
    let eq = static_equilibrium(&sc.system, &sc.q0, StaticOptions::default()).unwrap();
    // free length 0.5 + m g / k straight below the pivot
    assert!(eq.q[0].abs() < 1e-10);
    assert!((eq.q[1] + 0.5 + 9.81 / 60.0).abs() < 1e-10, "{}", eq.q[1]);
    let st = stability(&sc.system, 0.0, &eq.q, &eq.lambda, 1e-3).unwrap();
    assert_eq!((st.stable, st.unstable, st.neutral), (2, 0, 1));
}

/// A pendulum held by two identical pins (one redundant constraint pair):
/// the stability about the equilibrium of the one-pin pendulum (its λ on
/// the first pin, 0 on the second) is stable hanging and unstable standing
/// up — the same verdicts as with one pin.
#[test]
fn redundant_pins_do_not_stop_the_stability_report() {
    let twice = |start: f64| {
        pendulum_text(start).replace(
            "[time]",
            "[[joint]]\ntype = \"revolute\"\nname = \"pivot2\"\nbody_i = \"ground\"\n\
             point_i = [0.0, 0.0]\nbody_j = \"bob\"\npoint_j = [0.0, 0.5]\n[time]",
        )
    };
    let one = scenario::parse(&pendulum_text(40.0), "p.toml", "p", &[]).unwrap();
    let eq = static_equilibrium(&one.system, &one.q0, StaticOptions::default()).unwrap();
    let sc = scenario::parse(&twice(40.0), "p.toml", "p", &[]).unwrap();
    assert_eq!(sc.system.n_constraints(), 4);
    let lam = [eq.lambda[0], eq.lambda[1], 0.0, 0.0];
    let st = stability(&sc.system, 0.0, &eq.q, &lam, 1e-3).unwrap();
    assert_eq!((st.stable, st.unstable, st.neutral), (1, 0, 0));
    // the weight split between the pins: the same
    let half = [0.5 * lam[0], 0.5 * lam[1], 0.5 * lam[0], 0.5 * lam[1]];
    let st = stability(&sc.system, 0.0, &eq.q, &half, 1e-3).unwrap();
    assert_eq!((st.stable, st.unstable, st.neutral), (1, 0, 0));
    // standing up: at rest at φ = π (an equilibrium by symmetry), the pins
    // carry the same weight, so the same multipliers
    let up = [0.0, 0.5, PI];
    let st = stability(&sc.system, 0.0, &up, &lam, 1e-3).unwrap();
    assert_eq!((st.stable, st.unstable, st.neutral), (0, 1, 0));
}

/// A parallelogram with a redundant link (one rigid coupler pinned to the
/// tips of three cranks: 12 rows of rank 11) hangs at rest under
/// gravity: the same configuration as the chain of two separate couplers
/// (no redundancy), the cranks straight down (θ = −π/2, the minimum of
/// V = C sin θ), the ground pivots carrying the whole weight (Newton–Euler
/// of the mechanism), the redundant rows' λ zero as documented.
#[test]
fn redundant_parallelogram_hangs_like_its_non_redundant_twin() {
    use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
    let p = ParallelogramChain {
        loops: 2,
        theta0: -1.2,
        rate0: 0.0,
        redundant: true,
        ..Default::default()
    };
    let (r, g) = (p.crank_length, p.gravity);
    let weight = g * (3.0 * p.crank_mass + 2.0 * p.coupler_mass);
    let mut equilibria = Vec::new();
    for redundant in [true, false] {
        let p = ParallelogramChain {
            redundant,
            ..p.clone()
        };
        let sys = parallelogram_chain(&p).unwrap();
        let (q0, _) = sys.initial_state();
        let eq = static_equilibrium(&sys, &q0, StaticOptions::default())
            .unwrap_or_else(|e| panic!("redundant = {redundant}: {e}"));
        let dropped = usize::from(redundant);
        assert_eq!(eq.redundant.len(), dropped, "{:?}", eq.redundant);
        for &row in &eq.redundant {
            assert_eq!(eq.lambda[row], 0.0);
        }
        assert!(eq.constraint_residual < 1e-12, "{}", eq.constraint_residual);
        // cranks straight down: angle −π/2, centre at (i L, −r/2)
        for i in 0..3 {
            let ang = eq.q[3 * i + 2].rem_euclid(2.0 * PI);
            assert!((ang - 1.5 * PI).abs() < 1e-9, "crank {i}: φ = {ang}");
            assert!((eq.q[3 * i] - i as f64 * p.spacing).abs() < 1e-12);
            assert!((eq.q[3 * i + 1] + 0.5 * r).abs() < 1e-12);
        }
        // the couplers' centres at y = −r
        for b in 3..sys.bodies().len() {
            assert!((eq.q[3 * b + 1] + r).abs() < 1e-12, "body {b}");
        }
        // the ground pivots (joints 0 … 2) carry the weight, no side force
        let map = sys.reaction_map();
        let mut jac = vec![0.0; sys.jacobian_pattern().len()];
        sys.jacobian_values(&eq.q, 0.0, &mut jac);
        let mut react = vec![0.0; 3 * sys.constraints().len()];
        sys.joint_reactions(&map, &jac, &eq.lambda, &mut react);
        let (fx, fy) = (0..3).fold((0.0, 0.0), |(a, b), j| {
            (a + react[3 * j], b + react[3 * j + 1])
        });
        println!("redundant = {redundant}: pivots carry ({fx}, {fy}) N of {weight} N");
        assert!(fx.abs() < 1e-9 * weight, "{fx}");
        assert!((fy - weight).abs() < 1e-9 * weight, "{fy} vs {weight}");
        let st = stability(&sys, 0.0, &eq.q, &eq.lambda, 1e-3).unwrap();
        assert_eq!((st.stable, st.unstable, st.neutral), (1, 0, 0), "{st:?}");
        equilibria.push(eq.q[..9].to_vec());
    }
    for (a, b) in equilibria[0].iter().zip(&equilibria[1]) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
}
