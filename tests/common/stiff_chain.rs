//! The cantilevered stiff chain of the peer comparisons
//! (`builders::stiff_chain`, `../shared/peers/README.md`): N segments
//! released at 5° from the vertical, the free end's x reported at 0.1 s.

use mbsolve::builders::{stiff_chain, stiff_chain_tip_x};
use mbsolve::simulation::{simulate, RunConfig, Summary, Trajectory};

/// Release angle of the peers' runs \[rad\] (5°).
pub fn theta0() -> f64 {
    5f64.to_radians()
}

/// The time of the peers' reported tip \[s\].
pub const T_END: f64 = 0.1;

/// Runs the `n`-segment chain from the peers' release under `cfg` (which
/// sets the method, steps and `t_end`); asserts the run completed and
/// returns the free end's x at the last output \[m\], the summary and the
/// trajectory.
pub fn tip_after(n: usize, cfg: &RunConfig) -> (f64, Summary, Trajectory) {
    let (sys, q0, qd0, info) = stiff_chain(n, theta0()).unwrap();
    let (traj, s) = simulate(&sys, &q0, &qd0, cfg, &mut []).unwrap();
    assert_eq!(
        s.status, "completed",
        "N = {n}, {}: {:?}",
        cfg.method, s.message
    );
    (stiff_chain_tip_x(&info, traj.q.last().unwrap()), s, traj)
}
