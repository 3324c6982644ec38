//! Dense output of the implicit schemes on the constraint manifold: the
//! positions of an output row interpolated between two steps are
//! projected onto `Φ(q, t) = 0` ([`SecondOrderDae::project_output`]), so
//! the rows between steps satisfy the constraints as the step ends do.

use super::SecondOrderDae;
use crate::numeric::Time;

/// The warning of a row that could not be projected (given once per run).
const UNPROJECTED: &str = "an output row between steps could not be projected onto the constraints";

/// Project the positions of the interpolated row `out = [q; q̇]` at `t`
/// with `sys`; on failure the row stays as interpolated and `warnings`
/// gets one notice for the run.
pub(crate) fn settle_output(
    sys: &mut dyn SecondOrderDae,
    t: f64,
    out: &mut [f64],
    warnings: &mut Vec<String>,
) {
    let q = &mut out[..sys.n()];
    if let Err(e) = sys.project_output(t, q) {
        if !warnings.iter().any(|w| w.starts_with(UNPROJECTED)) {
            warnings.push(format!(
                "{UNPROJECTED} (first at t = {}: {e}); such rows are the method's \
                 interpolant, the step ends are unaffected",
                Time(t)
            ));
        }
    }
}
