//! Outputs: time series as CSV, run summaries as JSON, figures as SVG.
//!
//! Figures use plotters' SVG backend with its built-in font metrics, so no
//! system library (fontconfig, freetype) is needed to draw them.

use mbsolve::model::System;
use mbsolve::simulation::{Summary, Trajectory};
use plotters::prelude::*;
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

fn oerr(path: &Path, e: impl std::fmt::Display) -> OutputError {
    OutputError {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Write `t,x1,y1,phi1,…,xN,yN,phiN,constraint_norm` (bodies 1-based), one
/// row per output time.
pub fn write_trajectory_csv(
    path: &Path,
    sys: &System,
    traj: &Trajectory,
) -> Result<(), OutputError> {
    let mut w = csv::Writer::from_path(path).map_err(|e| oerr(path, e))?;
    let mut header = vec!["t".to_string()];
    header.extend((0..sys.n_coords()).map(System::coordinate_name));
    header.push("constraint_norm".into());
    w.write_record(&header).map_err(|e| oerr(path, e))?;
    let mut row = Vec::with_capacity(header.len());
    for (k, t) in traj.t.iter().enumerate() {
        row.clear();
        row.push(fmt(*t));
        row.extend(traj.q[k].iter().map(|v| fmt(*v)));
        row.push(fmt(traj.constraint_norm[k]));
        w.write_record(&row).map_err(|e| oerr(path, e))?;
    }
    w.flush().map_err(|e| oerr(path, e))
}

/// Write named columns of equal length as CSV.
pub fn write_columns_csv(path: &Path, columns: &[(&str, &[f64])]) -> Result<(), OutputError> {
    let mut w = csv::Writer::from_path(path).map_err(|e| oerr(path, e))?;
    w.write_record(columns.iter().map(|c| c.0))
        .map_err(|e| oerr(path, e))?;
    let rows = columns.iter().map(|c| c.1.len()).min().unwrap_or(0);
    for k in 0..rows {
        w.write_record(columns.iter().map(|c| fmt(c.1[k])))
            .map_err(|e| oerr(path, e))?;
    }
    w.flush().map_err(|e| oerr(path, e))
}

fn fmt(v: f64) -> String {
    format!("{v:.12e}")
}

/// Write the run summary as pretty JSON.
pub fn write_summary_json(path: &Path, summary: &Summary) -> Result<(), OutputError> {
    let text = serde_json::to_string_pretty(summary).map_err(|e| oerr(path, e))?;
    std::fs::write(path, text + "\n").map_err(|e| oerr(path, e))
}

/// One curve of a figure.
pub struct Series<'a> {
    /// Legend label.
    pub label: String,
    /// Abscissae.
    pub x: &'a [f64],
    /// Ordinates.
    pub y: &'a [f64],
}

/// A line plot written as SVG. With `log_y`, ordinates are plotted as
/// log10(|y|) (zeros clipped at 1e-16).
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series<'_>],
    log_y: bool,
) -> Result<(), OutputError> {
    let tr = |v: f64| {
        if log_y {
            v.abs().max(1e-16).log10()
        } else {
            v
        }
    };
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for s in series {
        for (&x, &y) in s.x.iter().zip(s.y) {
            let y = tr(y);
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if y1 - y0 < 1e-300 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let root = SVGBackend::new(path, (900, 560)).into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error + '_>> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))?;
        let ylab = if log_y {
            format!("log10 |{y_label}|")
        } else {
            y_label.to_string()
        };
        chart.configure_mesh().x_desc(x_label).y_desc(ylab).draw()?;
        for (i, s) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> =
                s.x.iter()
                    .zip(s.y)
                    .map(|(&x, &y)| (x, tr(y)))
                    .filter(|p| p.1.is_finite())
                    .collect();
            chart
                .draw_series(LineSeries::new(pts, color.stroke_width(2)))?
                .label(s.label.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| oerr(path, e))
}
