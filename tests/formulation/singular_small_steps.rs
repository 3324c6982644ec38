//! A smaller step must not be less robust: generalized-α (index 3) on the
//! 40-loop parallelogram chain (IFToMM benchmark A02,
//! `scenarios/parallelogram_chain.toml`, the same system as the builder)
//! through its first two singular positions (θ = π at t ≈ 0.21 s, θ = 2π
//! at t ≈ 0.39 s) at fixed steps from 1e-3 down to 5e-5, checked against
//! the independent one-degree-of-freedom reference of the builder (RK4 on
//! `I θ̈ = −C cos θ`): the run completes, every crank tip stays on the
//! parallelogram branch and the energy of the conservative chain is kept
//! to the method's numerical dissipation.
//! Near a singular position the Newton corrections are the rounding of Φ
//! amplified by the inverse of Φ_q's smallest singular value and stop
//! contracting; the smaller the step, the closer its grid comes to the
//! singular position (src/integrate/genalpha/mod.rs, "Noise near a
//! singular position").

use mbsolve::builders::{parallelogram_chain, ParallelogramChain};
use mbsolve::integrate::Method;
use mbsolve::simulation::{simulate, RunConfig};

#[test]
fn genalpha_passes_the_a02_chain_singular_positions_at_every_step_size() {
    let p = ParallelogramChain {
        loops: 40,
        ..Default::default()
    };
    let sys = parallelogram_chain(&p).unwrap();
    let (q0, v0) = p.state(p.theta0, p.rate0);
    let t_end = 0.45;
    for h in [1e-3, 1e-4, 5e-5] {
        // the scenario file's integrator settings
        let mut cfg = RunConfig {
            method: Method::GenAlpha,
            t_end,
            output_dt: 0.005,
            ..Default::default()
        };
        cfg.ode.fixed_step = Some(h);
        cfg.implicit.rho_inf = 0.9;
        cfg.implicit.newton_tol = 1e-8;
        cfg.implicit.max_newton = 50;
        let (traj, s) = simulate(&sys, &q0, &v0, &cfg, &mut []).unwrap();
        // every crank's tip against the reference angle
        let reference = p.reference(&traj.t, 1e-5);
        let (mut worst, mut de) = (0.0_f64, 0.0_f64);
        let e0 = p.reduced_energy(p.theta0, p.rate0);
        let (r, l) = (p.crank_length, p.spacing);
        for ((q, qd), (th, _)) in traj.q.iter().zip(&traj.qd).zip(&reference) {
            for i in 0..=p.loops {
                // crank i: body i, centre at (i L + r/2 cos φ, r/2 sin φ)
                let (x, y, phi) = (q[3 * i], q[3 * i + 1], q[3 * i + 2]);
                let tip = [x + 0.5 * r * phi.cos(), y + 0.5 * r * phi.sin()];
                let want = [i as f64 * l + r * th.cos(), r * th.sin()];
                worst = worst.max((tip[0] - want[0]).hypot(tip[1] - want[1]));
            }
            de = de.max((sys.mechanical_energy(q, qd) - e0).abs() / e0.abs());
        }
        let th_end = reference.last().unwrap().0;
        eprintln!(
            "A02 chain, genalpha h = {h:e}: {} ({:?}) at t = {}, {} steps, Newton failures {:?}, \
             θ(t_end) = {th_end:.3} rad, worst crank tip {worst:.3e} m, energy {de:.3e} relative",
            s.status,
            s.message,
            s.t_reached,
            s.steps,
            s.extra.get("newton_failures"),
        );
        assert!(th_end > std::f64::consts::TAU, "the span passes θ = 2π");
        assert_eq!(s.status, "completed", "h = {h:e}: {:?}", s.message);
        assert_eq!(traj.t.last().copied(), Some(t_end));
        assert!(worst < 1e-3, "h = {h:e}: off the branch by {worst:e} m");
        // ρ∞ = 0.9 dissipates a little: 1.2e-4 of E0 at h = 1e-3
        assert!(de < 1e-3, "h = {h:e}: energy error {de:e} relative");
    }
}
