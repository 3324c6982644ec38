//! Bounded work before a run starts: the time span must
//! be resolvable in floating point, and the number of output times, of
//! bodies and the estimated memory have limits, each checked before
//! anything scales with them is allocated. Each is an error naming the key
//! and the limit; docs/limits.md lists them.

use super::{error, RawScenario, ScenarioError};
use crate::integrate::eps;
use crate::simulation::RunConfig;

/// Most output times of one run (10⁸; the largest documented run has 10⁴,
/// the long-run tests of `tests/cli/stream.rs` 5·10⁷). Rows are streamed,
/// but the output times themselves are one vector (8 B each: 800 MB here).
pub const MAX_OUTPUT_TIMES: f64 = 1e8;

/// Most bodies of one scenario, `[[body]]` tables plus rod segments (10⁶;
/// the largest documented rod has N = 10⁴ segments).
pub const MAX_BODIES: usize = 1_000_000;

/// Shortest time span, in units of the spacing of doubles at the span's
/// largest |t| (`eps(t)`): a shorter span makes the integrators' steps
/// (a tenth of the span at most, and not below `16·eps(t)`) round to
/// `t + h == t`.
pub const MIN_SPAN_ULPS: f64 = 1e4;

/// Smallest step or output spacing, in units of `eps(t)`: MATLAB's smallest
/// step `hmin = 16·eps(t)`, below which `t + h` does not advance reliably.
pub const MIN_STEP_ULPS: f64 = 16.0;

/// Memory of the model, its evaluation buffers and the linear solver per
/// body \[bytes\]: 8 kB, above the falling rod's peak resident memory per
/// segment (the measurements are in docs/limits.md).
pub const MODEL_BYTES_PER_BODY: f64 = 8e3;

/// Memory the estimate may not exceed when the machine's is unknown \[bytes\].
pub const FALLBACK_MEMORY: f64 = 16.0 * 1024.0 * 1024.0 * 1024.0;

/// The time span `[t0, t_end]`: finite, forward and at least
/// [`MIN_SPAN_ULPS`] spacings of doubles long; errors at `time.end`.
pub(super) fn time_span(t0: f64, t_end: f64, file: &str) -> Result<(), ScenarioError> {
    if !(t0.is_finite() && t_end.is_finite() && t_end > t0 && (t_end - t0).is_finite()) {
        return Err(error(
            file,
            "time.end",
            format!(
                "{} is invalid: must be finite and > time.start = {}, with a finite span",
                num(t_end),
                num(t0)
            ),
        ));
    }
    let ulp = eps(t0.abs().max(t_end.abs()));
    if t_end - t0 < MIN_SPAN_ULPS * ulp {
        return Err(error(
            file,
            "time.end",
            format!(
                "{} is invalid: the span time.end − time.start = {} s is shorter than \
                 {} times the spacing of doubles there ({} s): the steps would not advance \
                 t (t + h == t) (docs/limits.md)",
                num(t_end),
                num(t_end - t0),
                num(MIN_SPAN_ULPS),
                num(ulp)
            ),
        ));
    }
    Ok(())
}

/// A step-like value `h` at `key`: at least [`MIN_STEP_ULPS`]·eps(t) over
/// the span, so that `t + h` advances t.
fn resolvable(key: &str, h: f64, run: &RunConfig, file: &str) -> Result<(), ScenarioError> {
    let floor = MIN_STEP_ULPS * eps(run.t0.abs().max(run.t_end.abs()));
    if h < floor {
        return Err(error(
            file,
            key,
            format!(
                "{} is invalid: below {MIN_STEP_ULPS}·eps(t) = {} s for t up to time.end = {}, \
                 so t + h would not advance t (docs/limits.md)",
                num(h),
                num(floor),
                num(run.t_end)
            ),
        ));
    }
    Ok(())
}

/// The number of output times of `run` (as [`RunConfig::output_times`]
/// makes them), computed without allocating.
pub fn output_count(run: &RunConfig) -> f64 {
    run.output_intervals() + 1.0
}

/// Estimated peak memory of a run \[bytes\] with `bodies` bodies and
/// `outputs` output times: the model ([`MODEL_BYTES_PER_BODY`]) and the
/// output times (8 B each). Output rows are streamed
/// ([`crate::simulation::simulate_into`]); a caller that keeps them in
/// memory ([`crate::simulation::Trajectory`]) adds 8 (2n + m) B per output
/// time (64 B per rod segment), which is not counted here.
pub fn memory_estimate(bodies: usize, outputs: f64) -> f64 {
    MODEL_BYTES_PER_BODY * bodies as f64 + 8.0 * outputs
}

/// The memory a run may use \[bytes\]: the smallest of the machine's
/// physical memory (`MemTotal` of /proc/meminfo, else
/// [`FALLBACK_MEMORY`]), the cgroup's limit (v2 `memory.max`, v1
/// `memory.limit_in_bytes`) and the address-space limit (`ulimit -v`,
/// "Max address space" of /proc/self/limits) less the address space the
/// process already holds (`VmSize`).
pub fn memory_limit() -> f64 {
    memory_limits()
        .into_iter()
        .map(|(_, v)| v)
        .fold(f64::INFINITY, f64::min)
}

/// The limits behind [`memory_limit`], named for messages.
pub fn memory_limits() -> Vec<(&'static str, f64)> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let field = |text: &str, key: &str| -> Option<f64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let mut out = vec![(
        "the machine's memory",
        read("/proc/meminfo")
            .and_then(|s| field(&s, "MemTotal:"))
            .map_or(FALLBACK_MEMORY, |kb| kb * 1024.0),
    )];
    for p in [
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    ] {
        if let Some(v) = read(p).and_then(|s| s.trim().parse::<f64>().ok()) {
            out.push(("the cgroup's memory limit", v));
        }
    }
    if let Some(limit) = read("/proc/self/limits").and_then(|s| field(&s, "Max address space")) {
        let held = read("/proc/self/status")
            .and_then(|s| field(&s, "VmSize:"))
            .map_or(0.0, |kb| kb * 1024.0);
        out.push((
            "the address-space limit (ulimit -v) less what is held",
            (limit - held).max(0.0),
        ));
    }
    out
}

/// `x` for messages: plain in [1e-4, 1e6), else in exponent form (`1e308`,
/// not 309 digits).
fn num(x: f64) -> String {
    if x == 0.0 || (1e-4..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn gb(bytes: f64) -> String {
    format!("{:.3} GB", bytes / 1e9)
}

/// Steps, output times, bodies and memory of `raw` with `run`, before the
/// model is built or anything is allocated.
pub(super) fn check(raw: &RawScenario, run: &RunConfig, file: &str) -> Result<(), ScenarioError> {
    for (key, h) in [
        ("integrator.step", run.ode.fixed_step),
        ("integrator.max_step", run.ode.max_step),
    ] {
        if let Some(h) = h {
            resolvable(key, h, run, file)?;
        }
    }
    let outputs = output_count(run);
    if outputs > MAX_OUTPUT_TIMES {
        let count = if outputs.is_finite() {
            format!("{outputs:.4e}")
        } else {
            "over 1e308".into()
        };
        return Err(error(
            file,
            "output.dt",
            format!(
                "{} over time.end − time.start = {} s gives {count} output times; the limit \
                 is {} (docs/limits.md): raise output.dt or shorten the span",
                num(run.output_dt),
                num(run.t_end - run.t0),
                num(MAX_OUTPUT_TIMES)
            ),
        ));
    }
    resolvable("output.dt", run.output_dt, run, file)?;
    // The bodies of the rods (a rod without `segments` has problem B's ten)
    // and chains, each with its key; a count < 1 is the model's error.
    let mut parts: Vec<(String, i64)> = raw
        .rod
        .as_ref()
        .map(|r| r.each())
        .unwrap_or_default()
        .into_iter()
        .map(|(key, r)| (format!("{key}.segments"), r.segments.unwrap_or(10)))
        .collect();
    parts.extend(
        raw.chain
            .iter()
            .enumerate()
            .map(|(k, c)| (format!("chain[{k}].links"), c.links)),
    );
    let mut segments = 0usize;
    let mut largest: Option<(String, usize)> = None;
    for (key, n) in parts {
        if n > MAX_BODIES as i64 {
            return Err(error(
                file,
                key,
                format!("{n} is invalid: the limit is {MAX_BODIES} bodies (docs/limits.md)"),
            ));
        }
        let n = usize::try_from(n).unwrap_or(0);
        segments += n;
        if largest.as_ref().is_none_or(|l| n > l.1) {
            largest = Some((key, n));
        }
    }
    let bodies = raw.body.len() + segments;
    if bodies > MAX_BODIES {
        return Err(error(
            file,
            "body",
            format!(
                "{bodies} bodies (with the rods' segments and chains' links): the limit is \
                 {MAX_BODIES} (docs/limits.md)"
            ),
        ));
    }
    let largest = largest.filter(|l| l.1 > 0);
    memory(
        bodies,
        largest.as_ref().map(|(k, n)| (k.as_str(), *n)),
        outputs,
        memory_limit(),
        file,
    )
}

/// The memory estimate of `bodies` bodies and `outputs` output times
/// against `limit`; an error at the key of the largest component (`rod.segments`,
/// `chain[0].links`, with its count) when there is one, else at `body`.
fn memory(
    bodies: usize,
    component: Option<(&str, usize)>,
    outputs: f64,
    limit: f64,
    file: &str,
) -> Result<(), ScenarioError> {
    let need = memory_estimate(bodies, outputs);
    if need > limit {
        let (key, what) = match component {
            Some((key, n)) => (key, format!("{n} ({bodies} bodies)")),
            None => ("body", format!("{bodies} bodies")),
        };
        return Err(error(
            file,
            key,
            format!(
                "{what}: the run would need an estimated {} ({} kB per body), more than the {} \
                 available: the smallest of the machine's memory, the cgroup's limit and \
                 ulimit -v (docs/limits.md)",
                gb(need),
                MODEL_BYTES_PER_BODY / 1e3,
                gb(limit)
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_beyond_the_limit_names_the_rod_or_the_bodies() {
        // 10⁴ segments need 80 MB (8 kB each): accepted with 1 GB, refused with 10 MB.
        let rod = Some(("rod.segments", 10_000));
        assert!(memory(10_000, rod, 1e4, 1e9, "f").is_ok());
        let e = memory(10_000, rod, 1e4, 1e7, "f").unwrap_err();
        assert_eq!(e.key, "rod.segments");
        assert!(e.message.contains("0.080 GB"), "{e}");
        assert!(e.message.contains("0.010 GB"), "{e}");
        let e = memory(10_000, None, 1e4, 1e7, "f").unwrap_err();
        assert_eq!(e.key, "body");
        // The output times count: 10⁷ of them are 80 MB.
        assert!(memory(1, None, 1e7, 5e7, "f").is_err());
    }

    #[test]
    fn output_count_matches_the_output_times() {
        for (t0, t_end, dt) in [(0.0, 2.0, 0.002), (0.0, 1.0, 0.3), (1.0, 1.5, 1.0)] {
            let run = RunConfig {
                t0,
                t_end,
                output_dt: dt,
                ..RunConfig::default()
            };
            assert_eq!(output_count(&run), run.output_times().len() as f64);
        }
    }
}
