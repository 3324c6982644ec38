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

    /// The index of the column named `name`: its name, or a positional
    /// name of earlier versions (`x1`, `phi3`; [`mbsolve::output::find_column`]).
    pub fn find(&self, name: &str) -> Option<usize> {
        let names: Vec<&str> = self.names.iter().map(String::as_str).collect();
        mbsolve::output::find_column(&names, name)
    }

    /// The column named `name` (or its positional name of earlier
    /// versions), or an error listing the available ones.
    pub fn column(&self, path: &Path, name: &str) -> Result<&[f64], String> {
        self.find(name)
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
    /// whole when it matches); a positional name of earlier versions (`x1`)
    /// is resolved to the column's name (`crank.x`).
    pub fn resolve_y(&self, path: &Path, ys: &[String]) -> Result<Vec<String>, String> {
        let mut out = Vec::new();
        for y in ys {
            if self.names.iter().any(|n| n == y) {
                out.push(y.clone());
            } else {
                for part in y.split(',').map(str::trim).filter(|p| !p.is_empty()) {
                    self.column(path, part)?;
                    let k = self.find(part).expect("checked by column");
                    out.push(self.names[k].clone());
                }
            }
        }
        if out.is_empty() {
            return Err("--y: name at least one column to plot".into());
        }
        Ok(out)
    }
}

/// The units of a table's columns, from the `<stem>.columns.json` beside
/// `<stem>.csv` (as `mbsolve run` and every figure write it: a list of
/// `{"name", "unit"}`); empty when there is no such file.
pub struct Units {
    /// (column name, unit) as listed.
    pub columns: Vec<(String, String)>,
}

impl Units {
    /// Read the `columns.json` beside `csv`, if there is one; a file that
    /// is not such a list is an error naming it.
    pub fn beside(csv: &Path) -> Result<Units, String> {
        let path = csv.with_extension("columns.json");
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Ok(Units {
                    columns: Vec::new(),
                })
            }
            Err(e) => return Err(format!("{}: {e}", path.display())),
        };
        #[derive(serde::Deserialize)]
        struct Col {
            name: String,
            #[serde(default)]
            unit: String,
        }
        let cols: Vec<Col> = serde_json::from_str(&text).map_err(|e| {
            format!(
                "{}: not a list of {{\"name\", \"unit\"}} columns: {e}",
                path.display()
            )
        })?;
        Ok(Units {
            columns: cols.into_iter().map(|c| (c.name, c.unit)).collect(),
        })
    }

    /// The unit of column `name` (`""` when unknown or dimensionless).
    pub fn unit(&self, name: &str) -> &str {
        self.columns
            .iter()
            .find(|c| c.0 == name)
            .map_or("", |c| c.1.as_str())
    }

    /// An axis label for column `name`: `name [unit]` (just `name` without
    /// a unit, or when the name already ends with that bracket).
    pub fn label(&self, name: &str) -> String {
        with_unit(name, self.unit(name))
    }

    /// An ordinate label for `names`: the names grouped by unit, each group
    /// followed by its unit (`crank.x, crank.y [m]; crank.phi [rad]`).
    pub fn y_label(&self, names: &[String]) -> String {
        let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
        for n in names {
            let u = self.unit(n);
            match groups.iter_mut().find(|g| g.0 == u) {
                Some(g) => g.1.push(n),
                None => groups.push((u, vec![n])),
            }
        }
        groups
            .iter()
            .map(|(u, ns)| with_unit(&ns.join(", "), u))
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// `name [unit]`, or `name` when the unit is empty or already there.
fn with_unit(name: &str, unit: &str) -> String {
    if unit.is_empty() || name.trim_end().ends_with(&format!("[{unit}]")) {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// What `mbsolve plot` was asked for (the command's arguments).
#[derive(clap::Args)]
pub struct PlotArgs {
    /// The CSV file (first row: column names).
    pub csv: PathBuf,
    /// Abscissa column.
    #[arg(long, default_value = "t")]
    pub x: String,
    /// Ordinate column(s): repeat the flag or separate names by commas.
    #[arg(long, value_name = "COLUMN[,COLUMN...]", required = true)]
    pub y: Vec<String>,
    /// Logarithmic ordinate (|y| plotted; zeros are gaps).
    #[arg(long)]
    pub log_y: bool,
    /// With --log-y: the smallest |y| drawn (smaller values are gaps,
    /// stated under the legend) [default: the smallest nonzero |y|].
    #[arg(long, value_name = "VALUE")]
    pub log_floor: Option<f64>,
    /// A horizontal reference line, e.g. a wall (repeatable).
    #[arg(long, value_name = "LABEL=VALUE")]
    pub hline: Vec<String>,
    /// Text under the legend.
    #[arg(long)]
    pub note: Option<String>,
    /// Output file, .svg or .png [default: the CSV's path with .svg].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Title [default: the CSV's file name].
    #[arg(long)]
    pub title: Option<String>,
    /// Ordinate label [default: the columns' names and units].
    #[arg(long)]
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
    if let Some(f) = a.log_floor {
        if !a.log_y {
            return Err("--log-floor: applies to a log axis only (add --log-y)".into());
        }
        if !(f > 0.0 && f.is_finite()) {
            return Err(format!("--log-floor {f}: must be a positive number"));
        }
    }
    let hlines = a
        .hline
        .iter()
        .map(|h| {
            let (label, v) = h
                .rsplit_once('=')
                .ok_or_else(|| format!("--hline '{h}': expected LABEL=VALUE"))?;
            let v: f64 = v
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| format!("--hline '{h}': '{v}' is not a finite number"))?;
            Ok((label.to_string(), v))
        })
        .collect::<Result<Vec<_>, String>>()?;
    let table = Table::read(&a.csv)?;
    let units = Units::beside(&a.csv)?;
    let x = table.column(&a.csv, &a.x)?.to_vec();
    let x_name = table
        .resolve_y(&a.csv, std::slice::from_ref(&a.x))?
        .remove(0);
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
    let y_label = a.y_label.clone().unwrap_or_else(|| units.y_label(&ys));
    let title = a.title.clone().unwrap_or_else(|| {
        a.csv
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    Figure {
        title,
        x_label: units.label(&x_name),
        y_label,
        series,
        log_y: a.log_y,
        log_floor: a.log_floor,
        hlines,
        note: a.note.clone().unwrap_or_default(),
    }
    .render(&out)
    .map_err(|e| e.to_string())?;
    Ok(out)
}
