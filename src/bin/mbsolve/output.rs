//! Outputs: time series as CSV, run summaries as JSON (figures: `figure`).

use mbsolve::output::Column;
use mbsolve::simulation::Summary;
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

/// Create the directory `dir` and its parents; the error names it.
pub fn create_dir(dir: &Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))
}

/// The sidecar `<stem>.columns.json`: every column with its unit, and a
/// body's coordinate columns (`crank.x`, …) with their positional name of
/// earlier versions as `"alias"` (`x1`, …; still accepted by `plot` and the
/// metrics).
pub fn columns_json(columns: &[Column]) -> String {
    let names: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
    let cols: Vec<serde_json::Value> = columns
        .iter()
        .zip(positional_aliases(&names))
        .map(|(c, alias)| match alias {
            Some(a) => serde_json::json!({"name": c.name, "unit": c.unit, "alias": a}),
            None => serde_json::json!({"name": c.name, "unit": c.unit}),
        })
        .collect();
    serde_json::to_string_pretty(&cols).unwrap_or_default() + "\n"
}

/// The positional name of earlier versions (`x1`, `omega2`, …) of each
/// column of a run's table that has one: the bodies are the `.x` columns
/// every third after `t` up to `constraint_norm`.
fn positional_aliases(names: &[&str]) -> Vec<Option<String>> {
    let mut out = vec![None; names.len()];
    let Some(end) = names.iter().position(|n| *n == "constraint_norm") else {
        return out;
    };
    if names.first() != Some(&"t") || end % 3 != 1 {
        return out;
    }
    use mbsolve::output::{ACCELERATION, POSITION, VELOCITY};
    // each name's first column, looked up once per body and quantity
    // (a linear search made this quadratic: 10⁴ segments, 10⁹ compares)
    let mut first = std::collections::HashMap::with_capacity(names.len());
    for (k, n) in names.iter().enumerate() {
        first.entry(*n).or_insert(k);
    }
    for i in 0..(end - 1) / 3 {
        let Some(body) = names[1 + 3 * i].strip_suffix(".x") else {
            continue;
        };
        for c in POSITION.iter().chain(&VELOCITY).chain(&ACCELERATION) {
            let full = format!("{body}.{c}");
            if let Some(&k) = first.get(full.as_str()) {
                out[k] = Some(format!("{c}{}", i + 1));
            }
        }
    }
    out
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

/// Write `text` to `path` atomically: a fresh temporary file beside it
/// (named with the process id),
/// synced, renamed over `path` (which replaces a symlink, not its target).
pub fn write_atomic(path: &Path, text: &str) -> Result<(), OutputError> {
    // unique per process: two runs into one directory never share it
    let tmp = sibling(path, &format!(".{}.tmp", std::process::id()));
    let mut f = create_fresh(&tmp)?;
    f.write_all(text.as_bytes())
        .and_then(|_| f.sync_all())
        .map_err(|e| OutputError::new(&tmp, e))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| OutputError::new(path, e)))
        .inspect_err(|_| {
            // a full disk or a file-size limit leaves no temporary file
            let _ = std::fs::remove_file(&tmp);
        })
}

/// `path` with `suffix` appended to its file name.
pub fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A write that cannot complete (here the rename: the target is a
    /// non-empty directory; on a full disk the write itself) is an error
    /// naming the file and leaves no temporary file beside it.
    #[test]
    fn a_failed_atomic_write_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("run.summary.json");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("inside"), "x").unwrap();
        let e = write_atomic(&target, "{}\n").unwrap_err().to_string();
        assert!(e.contains("run.summary.json"), "{e}");
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["run.summary.json"], "left behind: {names:?}");
        // and a good write leaves only its file
        let good = dir.path().join("good.json");
        write_atomic(&good, "{}\n").unwrap();
        assert_eq!(std::fs::read_to_string(&good).unwrap(), "{}\n");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }
}
