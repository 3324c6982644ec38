//! Outputs: time series as CSV, run summaries as JSON (figures: `figure`).

use mbsolve::model::{
    drives, evaluate_sensors, joint_short_name, Drive, ReactionMap, Sensor, System,
};
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
    joint_short_name(sys.constraints()[k].as_ref()).unwrap_or_else(|| format!("joint{}", k + 1))
}

/// The columns of a run's trajectory CSV and how to fill a row: what
/// [`OutputQuantities`] selects and the scenario's sensors.
pub struct Layout<'s> {
    sys: &'s System,
    o: OutputQuantities,
    /// The body each joint's reaction acts on (the local-frame columns).
    reactions: ReactionMap,
    drives: Vec<Drive>,
    sensors: &'s [Sensor],
    /// The sensor values of one row.
    values: Vec<f64>,
}

impl<'s> Layout<'s> {
    /// The layout of `sys`'s CSV with the quantities `o` and `sensors`.
    pub fn new(sys: &'s System, o: OutputQuantities, sensors: &'s [Sensor]) -> Self {
        Self {
            sys,
            o,
            reactions: sys.reaction_map(),
            drives: if o.drives { drives(sys) } else { Vec::new() },
            sensors,
            values: Vec::new(),
        }
    }

    /// Columns with their units: `t`, `x1,y1,phi1,…` (bodies 1-based),
    /// `constraint_norm`, then what the quantities select: velocities
    /// `vx1,vy1,omega1,…`, accelerations `ax1,ay1,alpha1,…`, per joint
    /// `J.fx,J.fy,J.mz` (reaction on its body, global frame, moment about
    /// the centre of mass) and `J.fx_local,J.fy_local` (in that body's
    /// frame), per drive `J.drive` (its generalized force −λ),
    /// `kinetic_energy,potential_energy,potential_gravity,potential_elastic,
    /// total_energy` and the balance: `work_nonconservative` (= `work_forces`
    /// + `work_drives`, since t0), `energy_balance_error` (`T + V − E0 −
    /// W`); then per sensor `S.QUANTITY`.
    pub fn columns(&self) -> Vec<(String, &'static str)> {
        let (sys, o) = (self.sys, &self.o);
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
        for d in &self.drives {
            c.push((format!("{}.drive", joint_label(sys, d.joint)), d.unit));
        }
        if o.energy {
            for n in ENERGY_COLUMNS {
                c.push((n.into(), "J"));
            }
        }
        for s in self.sensors {
            for (q, u) in s.quantities(sys) {
                c.push((format!("{}.{q}", s.name), u));
            }
        }
        c
    }

    /// Header line ([`Layout::columns`]).
    pub fn header(&self) -> String {
        let names: Vec<String> = self.columns().into_iter().map(|c| c.0).collect();
        names.join(",")
    }

    /// The sidecar `<stem>.columns.json`: every CSV column with its unit.
    pub fn columns_json(&self) -> String {
        let cols: Vec<serde_json::Value> = self
            .columns()
            .into_iter()
            .map(|(name, unit)| serde_json::json!({"name": name, "unit": unit}))
            .collect();
        serde_json::to_string_pretty(&cols).unwrap_or_default() + "\n"
    }

    /// One row (with its newline) into `buf`, in the order of
    /// [`Layout::columns`]; a missing value (a failed evaluation) is `NaN`.
    pub fn row(&mut self, buf: &mut String, s: &Sample<'_>) {
        use std::fmt::Write as _;
        let o = self.o;
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
                let phi = self.reactions.body(k).map_or(0.0, |b| s.q[3 * b + 2]);
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
        for d in &self.drives {
            put(s.lambda.map_or(f64::NAN, |l| d.force(l)));
        }
        if o.energy {
            let e = s.energy.map_or([f64::NAN; 9], |e| {
                let v = e.gravity + e.elastic;
                let w = e.work_forces + e.work_drives;
                [
                    e.kinetic,
                    v,
                    e.gravity,
                    e.elastic,
                    e.kinetic + v,
                    w,
                    e.work_forces,
                    e.work_drives,
                    e.balance_error,
                ]
            });
            e.into_iter().for_each(&mut put);
        }
        evaluate_sensors(self.sensors, self.sys, s.t, s.q, s.qd, &mut self.values);
        self.values.iter().for_each(|v| put(*v));
        buf.push('\n');
    }
}

/// The energy columns, in the order of [`Layout::row`].
const ENERGY_COLUMNS: [&str; 9] = [
    "kinetic_energy",
    "potential_energy",
    "potential_gravity",
    "potential_elastic",
    "total_energy",
    "work_nonconservative",
    "work_forces",
    "work_drives",
    "energy_balance_error",
];

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
