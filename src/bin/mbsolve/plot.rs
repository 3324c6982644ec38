//! `mbsolve plot`: a figure of chosen columns of any CSV that mbsolve wrote
//! (a run's trajectory, a study's table, the data beside a figure).

use crate::figure::{extension, Figure, Series};
use std::path::{Path, PathBuf};

/// A table read from CSV: column names and their values (empty or
/// unparsable cells are NaN, and are not plotted).
pub struct Table {
    /// Column names in file order.
    pub names: Vec<String>,
    /// Column values.
    pub columns: Vec<Vec<f64>>,
}

impl Table {
    /// Read `path` (first row = header).
    pub fn read(path: &Path) -> Result<Table, String> {
        let mut r = csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let names: Vec<String> = r
            .headers()
            .map_err(|e| format!("{}: {e}", path.display()))?
            .iter()
            .map(str::to_string)
            .collect();
        let mut columns = vec![Vec::new(); names.len()];
        for (k, rec) in r.records().enumerate() {
            let rec = rec.map_err(|e| format!("{}: row {}: {e}", path.display(), k + 2))?;
            for (c, col) in columns.iter_mut().enumerate() {
                col.push(
                    rec.get(c)
                        .and_then(|v| v.trim().parse::<f64>().ok())
                        .unwrap_or(f64::NAN),
                );
            }
        }
        Ok(Table { names, columns })
    }

    /// The column named `name`, or an error listing the available ones.
    pub fn column(&self, path: &Path, name: &str) -> Result<&[f64], String> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|k| self.columns[k].as_slice())
            .ok_or_else(|| {
                format!(
                    "{}: no column '{name}'; the columns are: {}",
                    path.display(),
                    self.names.join(", ")
                )
            })
    }

    /// Resolve `--y` arguments: each is a column name, or a comma-separated
    /// list of column names (a name that itself contains a comma is taken
    /// whole when it matches).
    pub fn resolve_y(&self, path: &Path, ys: &[String]) -> Result<Vec<String>, String> {
        let mut out = Vec::new();
        for y in ys {
            if self.names.iter().any(|n| n == y) {
                out.push(y.clone());
            } else {
                for part in y.split(',').map(str::trim).filter(|p| !p.is_empty()) {
                    self.column(path, part)?;
                    out.push(part.to_string());
                }
            }
        }
        if out.is_empty() {
            return Err("--y: name at least one column to plot".into());
        }
        Ok(out)
    }
}

/// What `mbsolve plot` was asked for.
pub struct PlotArgs {
    /// The CSV file.
    pub csv: PathBuf,
    /// Abscissa column.
    pub x: String,
    /// Ordinate columns (see [`Table::resolve_y`]).
    pub y: Vec<String>,
    /// Logarithmic ordinate.
    pub log_y: bool,
    /// Output file (.svg or .png); default: the CSV's path with `.svg`.
    pub out: Option<PathBuf>,
    /// Title; default: the CSV's file name.
    pub title: Option<String>,
    /// Ordinate label; default: the single column's name, else empty.
    pub y_label: Option<String>,
}

/// Draw the figure; returns the path written.
pub fn plot(a: &PlotArgs) -> Result<PathBuf, String> {
    let out = a.out.clone().unwrap_or_else(|| a.csv.with_extension("svg"));
    let ext = extension(&out);
    if ext != "svg" && ext != "png" {
        return Err(format!(
            "--out {}: unknown figure format '{ext}': use .svg or .png",
            out.display()
        ));
    }
    let table = Table::read(&a.csv)?;
    let x = table.column(&a.csv, &a.x)?.to_vec();
    let ys = table.resolve_y(&a.csv, &a.y)?;
    let series = ys
        .iter()
        .map(|name| {
            Ok(Series {
                label: name.clone(),
                x: x.clone(),
                y: table.column(&a.csv, name)?.to_vec(),
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    let y_label = a.y_label.clone().unwrap_or_else(|| {
        if ys.len() == 1 {
            ys[0].clone()
        } else {
            String::new()
        }
    });
    let title = a.title.clone().unwrap_or_else(|| {
        a.csv
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    Figure {
        title,
        x_label: a.x.clone(),
        y_label,
        series,
        log_y: a.log_y,
    }
    .render(&out)
    .map_err(|e| e.to_string())?;
    Ok(out)
}
