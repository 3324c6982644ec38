//! Outputs: time series as CSV, run summaries as JSON (figures: `figure`).

use mbsolve::model::{ReactionMap, System};
use mbsolve::simulation::{OutputQuantities, Sample, Summary};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Output failure, naming the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct OutputError {
    /// File being written.
    pub path: String,
    /// What went wrong.
    pub message: String,
}

impl OutputError {
    /// The error `e` while writing `path`.
    pub fn new(path: &Path, e: impl std::fmt::Display) -> Self {
        OutputError {
            path: path.display().to_string(),
            message: e.to_string(),
        }
    }
}

/// The short name of joint `k` (the quoted name in its description, else
/// `joint<k+1>`).
fn joint_label(sys: &System, k: usize) -> String {
    let name = sys.constraints()[k].name();
    match (name.find('\''), name.rfind('\'')) {
        (Some(a), Some(b)) if b > a + 1 => name[a + 1..b].to_string(),
        _ => format!("joint{}", k + 1),
    }
}

/// Columns of the trajectory CSV with their units: `t`, `x1,y1,phi1,…`
/// (bodies 1-based), `constraint_norm`, then what `o` selects: velocities
/// `vx1,vy1,omega1,…`, accelerations `ax1,ay1,alpha1,…`, per joint
/// `J.fx,J.fy,J.mz` (reaction on its body, global frame, moment about the
/// centre of mass) and `J.fx_local,J.fy_local` (in that body's frame),
/// `kinetic_energy,potential_energy,total_energy` and the balance:
/// `work_nonconservative` (work of non-conservative and constraint forces
/// since t0), `energy_balance_error` (`T + V − E0 − W`).
pub fn csv_columns(sys: &System, o: &OutputQuantities) -> Vec<(String, &'static str)> {
    let nb = sys.bodies().len();
    let mut c = vec![("t".to_string(), "s")];
    for k in 0..sys.n_coords() {
        c.push((
            System::coordinate_name(k),
            if k % 3 == 2 { "rad" } else { "m" },
        ));
    }
    c.push(("constraint_norm".into(), "m"));
    let per_body =
        |c: &mut Vec<(String, &'static str)>, names: [&str; 3], units: [&'static str; 3]| {
            for i in 1..=nb {
                for (n, u) in names.iter().zip(units) {
                    c.push((format!("{n}{i}"), u));
                }
            }
        };
    if o.velocities {
        per_body(&mut c, ["vx", "vy", "omega"], ["m/s", "m/s", "rad/s"]);
    }
    if o.accelerations {
        per_body(&mut c, ["ax", "ay", "alpha"], ["m/s^2", "m/s^2", "rad/s^2"]);
    }
    if o.reactions {
        for k in 0..sys.constraints().len() {
            let j = joint_label(sys, k);
            for (n, u) in [
                ("fx", "N"),
                ("fy", "N"),
                ("mz", "N m"),
                ("fx_local", "N"),
                ("fy_local", "N"),
            ] {
                c.push((format!("{j}.{n}"), u));
            }
        }
    }
    if o.energy {
        for n in [
            "kinetic_energy",
            "potential_energy",
            "total_energy",
            "work_nonconservative",
            "energy_balance_error",
        ] {
            c.push((n.into(), "J"));
        }
    }
    c
}

/// Header line of the trajectory CSV ([`csv_columns`]).
pub fn csv_header(sys: &System, o: &OutputQuantities) -> String {
    let names: Vec<String> = csv_columns(sys, o).into_iter().map(|c| c.0).collect();
    names.join(",")
}

/// One trajectory CSV row (with its newline) into `buf`, in the order of
/// [`csv_columns`]; a missing value (a failed evaluation) is `NaN`.
pub fn csv_row(buf: &mut String, map: &ReactionMap, s: &Sample<'_>, o: &OutputQuantities) {
    use std::fmt::Write as _;
    buf.clear();
    let mut put = |v: f64| {
        if !buf.is_empty() {
            buf.push(',');
        }
        let _ = write!(buf, "{v:.12e}");
    };
    put(s.t);
    s.q.iter().for_each(|v| put(*v));
    put(s.constraint_norm);
    if o.velocities {
        s.qd.iter().for_each(|v| put(*v));
    }
    if o.accelerations {
        match s.qdd {
            Some(a) => a.iter().for_each(|v| put(*v)),
            None => (0..s.q.len()).for_each(|_| put(f64::NAN)),
        }
    }
    if o.reactions {
        let nj = s.reactions.map_or(0, |r| r.len() / 3);
        for k in 0..nj {
            let r = s
                .reactions
                .map_or([f64::NAN; 3], |r| [r[3 * k], r[3 * k + 1], r[3 * k + 2]]);
            // in the frame of the body the reaction acts on: rotate by −φ
            let phi = map.body(k).map_or(0.0, |b| s.q[3 * b + 2]);
            let (sn, cs) = phi.sin_cos();
            for v in [
                r[0],
                r[1],
                r[2],
                cs * r[0] + sn * r[1],
                -sn * r[0] + cs * r[1],
            ] {
                put(v);
            }
        }
    }
    if o.energy {
        let [k, p, w, e] = s.energy.unwrap_or([f64::NAN; 4]);
        for v in [k, p, k + p, w, e] {
            put(v);
        }
    }
    buf.push('\n');
}

/// The sidecar `<stem>.columns.json`: every CSV column with its unit.
pub fn columns_json(sys: &System, o: &OutputQuantities) -> String {
    let cols: Vec<serde_json::Value> = csv_columns(sys, o)
        .into_iter()
        .map(|(name, unit)| serde_json::json!({"name": name, "unit": unit}))
        .collect();
    serde_json::to_string_pretty(&cols).unwrap_or_default() + "\n"
}

/// Write named columns as CSV, one row per index of the longest column;
/// missing and NaN values are empty cells.
pub fn write_columns_csv(path: &Path, columns: &[(&str, &[f64])]) -> Result<(), OutputError> {
    let mut w = csv::Writer::from_path(path).map_err(|e| OutputError::new(path, e))?;
    w.write_record(columns.iter().map(|c| c.0))
        .map_err(|e| OutputError::new(path, e))?;
    let rows = columns.iter().map(|c| c.1.len()).max().unwrap_or(0);
    for k in 0..rows {
        w.write_record(columns.iter().map(|c| match c.1.get(k) {
            Some(v) if !v.is_nan() => fmt(*v),
            _ => String::new(),
        }))
        .map_err(|e| OutputError::new(path, e))?;
    }
    w.flush().map_err(|e| OutputError::new(path, e))
}

fn fmt(v: f64) -> String {
    format!("{v:.12e}")
}

/// Write the run summary as pretty JSON, atomically ([`write_atomic`]).
pub fn write_summary_json(path: &Path, summary: &Summary) -> Result<(), OutputError> {
    let text = serde_json::to_string_pretty(summary).map_err(|e| OutputError::new(path, e))?;
    write_atomic(path, &(text + "\n"))
}

/// Remove `path` if it exists — a symlink itself, never its target; a
/// directory in its place is an error.
pub fn remove_stale(path: &Path) -> Result<(), OutputError> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => Err(OutputError::new(
            path,
            "is a directory; remove it or choose another --out",
        )),
        Ok(_) => std::fs::remove_file(path).map_err(|e| OutputError::new(path, e)),
        Err(_) => Ok(()),
    }
}

/// Create `path` fresh: never through a symlink, never appending to an
/// old file (a stale one is removed first, then `create_new`).
pub fn create_fresh(path: &Path) -> Result<File, OutputError> {
    remove_stale(path)?;
    OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|e| OutputError::new(path, e))
}

/// Write `text` to `path` atomically: a fresh temporary file beside it,
/// synced, renamed over `path` (which replaces a symlink, not its target).
pub fn write_atomic(path: &Path, text: &str) -> Result<(), OutputError> {
    let tmp = sibling(path, ".tmp");
    let mut f = create_fresh(&tmp)?;
    f.write_all(text.as_bytes())
        .and_then(|_| f.sync_all())
        .map_err(|e| OutputError::new(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| OutputError::new(path, e))
}

/// `path` with `suffix` appended to its file name.
pub fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}
