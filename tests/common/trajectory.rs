//! Comparing two runs' trajectories on the same output grid.

use mbsolve::simulation::Trajectory;

/// Largest |a − b| over every output time and coordinate (positions q);
/// asserts that both runs have the same output times (to 1e-12 s).
pub fn max_diff(a: &Trajectory, b: &Trajectory) -> f64 {
    assert_eq!(a.t.len(), b.t.len(), "output grids differ in length");
    let mut e: f64 = 0.0;
    for k in 0..a.t.len() {
        assert!(
            (a.t[k] - b.t[k]).abs() < 1e-12,
            "output {k}: t {} vs {}",
            a.t[k],
            b.t[k]
        );
        for (x, y) in a.q[k].iter().zip(&b.q[k]) {
            e = e.max((x - y).abs());
        }
    }
    e
}
