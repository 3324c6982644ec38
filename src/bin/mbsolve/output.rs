//! Outputs: time series as CSV, run summaries as JSON (figures: `figure`).

use mbsolve::model::System;
use mbsolve::simulation::{Summary, Trajectory};
use std::path::Path;

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

/// Write `t,x1,y1,phi1,…,xN,yN,phiN,constraint_norm` (bodies 1-based), one
/// row per output time.
pub fn write_trajectory_csv(
    path: &Path,
    sys: &System,
    traj: &Trajectory,
) -> Result<(), OutputError> {
    let mut w = csv::Writer::from_path(path).map_err(|e| OutputError::new(path, e))?;
    let mut header = vec!["t".to_string()];
    header.extend((0..sys.n_coords()).map(System::coordinate_name));
    header.push("constraint_norm".into());
    w.write_record(&header)
        .map_err(|e| OutputError::new(path, e))?;
    let mut row = Vec::with_capacity(header.len());
    for (k, t) in traj.t.iter().enumerate() {
        row.clear();
        row.push(fmt(*t));
        row.extend(traj.q[k].iter().map(|v| fmt(*v)));
        row.push(fmt(traj.constraint_norm[k]));
        w.write_record(&row)
            .map_err(|e| OutputError::new(path, e))?;
    }
    w.flush().map_err(|e| OutputError::new(path, e))
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

/// Write the run summary as pretty JSON.
pub fn write_summary_json(path: &Path, summary: &Summary) -> Result<(), OutputError> {
    let text = serde_json::to_string_pretty(summary).map_err(|e| OutputError::new(path, e))?;
    std::fs::write(path, text + "\n").map_err(|e| OutputError::new(path, e))
}
