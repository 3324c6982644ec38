//! Figures as vector graphics: curves in floating point (no grid snapping),
//! log axes that leave gaps at zeros and below a stated floor instead of
//! joining across them, units from `columns.json`, and the figure set of
//! `mbsolve reproduce` with its data beside every figure.

use crate::common::cli::{mbsolve, stderr};
use std::path::Path;

/// Write a CSV of `t` and the named columns.
fn write_csv(path: &Path, t: &[f64], cols: &[(&str, Vec<f64>)]) {
    let mut s = String::from("t");
    for (n, _) in cols {
        s += &format!(",{n}");
    }
    s.push('\n');
    for (k, tk) in t.iter().enumerate() {
        s += &format!("{tk:e}");
        for (_, v) in cols {
            s += &format!(",{:e}", v[k]);
        }
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

/// The `d` attribute of every `<path>` drawn with `stroke` (a curve's
/// colour), in file order.
fn paths_with_stroke(svg: &str, stroke: &str) -> Vec<String> {
    svg.split("<path d=\"")
        .skip(1)
        .filter(|p| {
            let end = p.find("/>").unwrap();
            p[..end].contains(&format!("stroke=\"{stroke}\""))
        })
        .map(|p| p[..p.find('"').unwrap()].to_string())
        .collect()
}

/// The subpaths of path data `M x y L x y ... M ...` as point lists.
fn subpaths(d: &str) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut rest = d;
    while !rest.is_empty() {
        let cmd = rest.chars().next().unwrap();
        rest = &rest[1..];
        let end = rest.find(['M', 'L', 'H', 'Z']).unwrap_or(rest.len());
        let nums: Vec<f64> = rest[..end]
            .split([' ', ','])
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().unwrap())
            .collect();
        rest = &rest[end..];
        match cmd {
            'M' => out.push(vec![(nums[0], nums[1])]),
            'L' => out.last_mut().unwrap().push((nums[0], nums[1])),
            c => panic!("unexpected path command {c} in a curve"),
        }
    }
    out
}

/// Least-squares fit `v ≈ a + b u`; returns the largest residual.
fn affine_residual(u: &[f64], v: &[f64]) -> f64 {
    let n = u.len() as f64;
    let (mu, mv) = (u.iter().sum::<f64>() / n, v.iter().sum::<f64>() / n);
    let suv: f64 = u.iter().zip(v).map(|(a, b)| (a - mu) * (b - mv)).sum();
    let suu: f64 = u.iter().map(|a| (a - mu) * (a - mu)).sum();
    let b = suv / suu;
    u.iter()
        .zip(v)
        .map(|(a, c)| (mv + b * (a - mu) - c).abs())
        .fold(0.0, f64::max)
}

/// The first curve colour of the figures (Okabe–Ito blue).
const BLUE: &str = "#0072B2";

#[test]
fn svg_curve_follows_the_data_without_grid_snapping() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("smooth.csv");
    let t: Vec<f64> = (0..=1000).map(|k| k as f64 * 1e-3).collect();
    let y: Vec<f64> = t.iter().map(|t| (3.0 * t).sin()).collect();
    write_csv(&csv, &t, &[("y", y.clone())]);
    let svg = dir.path().join("smooth.svg");
    let o = mbsolve(&[
        "plot",
        csv.to_str().unwrap(),
        "--y",
        "y",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    let paths = paths_with_stroke(&text, BLUE);
    // the curve and its legend sample
    assert_eq!(paths.len(), 2, "{paths:?}");
    let pieces = subpaths(&paths[0]);
    assert_eq!(pieces.len(), 1, "one unbroken curve");
    let pts = &pieces[0];
    assert_eq!(pts.len(), t.len(), "every sample is a vertex");
    let non_integer = pts
        .iter()
        .filter(|p| p.0.fract() != 0.0 || p.1.fract() != 0.0)
        .count();
    assert!(
        non_integer > pts.len() / 2,
        "coordinates snapped to a grid: {non_integer} of {} are not integers",
        pts.len()
    );
    // The vertices are an affine image of the data to the two decimals
    // written (0.005 user units); a grid of whole pixels of the 643 px
    // wide figure (10 user units each) would leave residuals up to 5.
    let (px, py): (Vec<f64>, Vec<f64>) = pts.iter().copied().unzip();
    let rx = affine_residual(&t, &px);
    let ry = affine_residual(&y, &py);
    assert!(rx < 0.01 && ry < 0.01, "residuals x {rx}, y {ry}");
    // the scale: y = -1..1 spans more than half the figure height (3780)
    let span =
        py.iter().cloned().fold(f64::MIN, f64::max) - py.iter().cloned().fold(f64::MAX, f64::min);
    assert!(span > 1500.0, "span {span}");
}

#[test]
fn log_axis_breaks_the_curve_at_zeros_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("impacts.csv");
    let t: Vec<f64> = (0..100).map(|k| k as f64 * 0.01).collect();
    // a decaying force until row 40, zero after it but for three isolated
    // impacts at rows 50, 60, 70 and a two-sample contact at rows 80-81
    let y: Vec<f64> = (0..100)
        .map(|k| match k {
            0..=39 => (-(k as f64) * 0.1).exp(),
            50 | 60 | 70 => 1e-2,
            80 | 81 => 3e-2,
            _ => 0.0,
        })
        .collect();
    write_csv(&csv, &t, &[("force", y)]);
    let svg = dir.path().join("impacts.svg");
    let o = mbsolve(&[
        "plot",
        csv.to_str().unwrap(),
        "--y",
        "force",
        "--log-y",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    let paths = paths_with_stroke(&text, BLUE);
    let pieces = subpaths(&paths[0]);
    // two separate polylines (rows 0-39 and 80-81), never joined
    assert_eq!(
        pieces.iter().map(Vec::len).collect::<Vec<_>>(),
        vec![40, 2],
        "{pieces:?}"
    );
    // the isolated impacts are dots of the curve's colour
    let dots = text.matches(&format!("fill=\"{BLUE}\"/>")).count();
    assert_eq!(dots, 3, "one dot per isolated impact");
    // the pieces lie where their samples are: the second starts 40 steps
    // of t after the first one ends
    let dx = (pieces[0][39].0 - pieces[0][0].0) / 39.0;
    let gap = (pieces[1][0].0 - pieces[0][39].0) / dx;
    assert!((gap - 41.0).abs() < 1e-3, "gap of {gap} steps");
    assert!(
        text.contains("gaps: where y = 0"),
        "the gaps are not stated"
    );

    // a floor: values below it are gaps, the axis starts at its decade
    let o = mbsolve(&[
        "plot",
        csv.to_str().unwrap(),
        "--y",
        "force",
        "--log-y",
        "--log-floor",
        "1e-1",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    let pieces = subpaths(&paths_with_stroke(&text, BLUE)[0]);
    // exp(-0.1 k) >= 0.1 for k <= 23
    assert_eq!(pieces.iter().map(Vec::len).collect::<Vec<_>>(), vec![24]);
    assert!(text.contains("gaps: where |y| &lt; 10⁻¹") || text.contains("gaps: where |y| < 10⁻¹"));
    assert!(text.contains("\n10⁻¹\n"), "the axis starts at the floor");
    assert!(!text.contains("\n10⁻²\n"), "the axis goes below the floor");

    let o = mbsolve(&[
        "plot",
        csv.to_str().unwrap(),
        "--y",
        "force",
        "--log-floor",
        "1e-1",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--log-floor"), "{}", stderr(&o));
    for bad in ["wall", "wall=abc", "wall=inf"] {
        let o = mbsolve(&[
            "plot",
            csv.to_str().unwrap(),
            "--y",
            "force",
            "--hline",
            bad,
        ]);
        assert_eq!(o.status.code(), Some(2), "--hline {bad}");
        assert!(
            stderr(&o).contains(&format!("--hline '{bad}'")),
            "{}",
            stderr(&o)
        );
    }
}

#[test]
fn plot_labels_axes_with_the_units_of_columns_json() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("run.csv");
    let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.02).collect();
    let m: Vec<f64> = t.iter().map(|t| 2.0 * t).collect();
    let a: Vec<f64> = t.iter().map(|t| t * t).collect();
    write_csv(&csv, &t, &[("J.mz", m), ("tip.x", a.clone()), ("tip.y", a)]);
    std::fs::write(
        dir.path().join("run.columns.json"),
        r#"[{"name": "t", "unit": "s"}, {"name": "J.mz", "unit": "N m"},
            {"name": "tip.x", "unit": "m"}, {"name": "tip.y", "unit": "m"}]"#,
    )
    .unwrap();
    let svg = dir.path().join("a.svg");
    let run = |ys: &[&str]| {
        let mut args = vec![
            "plot",
            csv.to_str().unwrap(),
            "--out",
            svg.to_str().unwrap(),
        ];
        for y in ys {
            args.extend(["--y", y]);
        }
        let o = mbsolve(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read_to_string(&svg).unwrap()
    };
    let text = run(&["J.mz"]);
    assert!(text.contains("\nJ.mz [N m]\n"), "no unit on the ordinate");
    assert!(text.contains("\nt [s]\n"), "no unit on the abscissa");
    let text = run(&["tip.x,tip.y", "J.mz"]);
    assert!(
        text.contains("\ntip.x, tip.y [m]; J.mz [N m]\n"),
        "columns grouped by unit"
    );

    // a columns.json that is not a list of columns is named
    std::fs::write(dir.path().join("run.columns.json"), "{\"t\": 1}").unwrap();
    let o = mbsolve(&["plot", csv.to_str().unwrap(), "--y", "J.mz"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("run.columns.json"), "{}", stderr(&o));
}

/// The column `name` of a CSV.
fn csv_column(path: &Path, name: &str) -> Vec<f64> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let k = r
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("{}: no column {name}", path.display()));
    r.records()
        .map(|rec| rec.unwrap()[k].parse().unwrap_or(f64::NAN))
        .collect()
}

#[test]
fn reproduce_writes_every_figure_with_its_data_and_the_velocity_norm() {
    let dir = tempfile::tempdir().unwrap();
    let o = mbsolve(&["reproduce", "--out", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (fb, rod) = (dir.path().join("fourbar"), dir.path().join("falling_rod"));
    for stem in [
        fb.join("fig2_fourbar_correct_velocity_norm"),
        fb.join("fig3_fourbar_incorrect_velocity_norm"),
    ] {
        assert!(stem.with_extension("svg").exists(), "{}", stem.display());
    }
    // every figure: its CSV, its units and its redraw command beside it,
    // curves in floating point
    let mut figures = 0;
    for d in [&fb, &rod] {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|e| e == "svg") {
                figures += 1;
                for ext in ["csv", "columns.json", "redraw.txt"] {
                    assert!(p.with_extension(ext).exists(), "{}: no {ext}", p.display());
                }
                let text = std::fs::read_to_string(&p).unwrap();
                let d = &paths_with_stroke(&text, BLUE)[0];
                assert!(
                    subpaths(d).concat().iter().any(|q| q.1.fract() != 0.0),
                    "{}: curve on a grid",
                    p.display()
                );
            }
        }
    }
    assert_eq!(figures, 9, "fig. 2 and 3: Φ_Bx, ‖Φ‖₂, ‖dΦ/dt‖₂; fig. 5-7");

    // the velocity figure plots each run's ‖Φ̇‖₂, not ‖Φ‖₂
    let fig = fb.join("fig3_fourbar_incorrect_velocity_norm.csv");
    let run = fb.join("incorrect_a10.000_b10.000.csv");
    let shown = csv_column(&fig, "α = β = 10");
    let vel = csv_column(&run, "velocity_constraint_norm");
    let pos = csv_column(&run, "constraint_norm");
    assert_eq!(shown, vel);
    assert_ne!(shown, pos);
    let units =
        std::fs::read_to_string(fb.join("fig3_fourbar_incorrect_velocity_norm.columns.json"))
            .unwrap();
    assert!(units.contains("\"unit\": \"m/s\""), "{units}");

    // fig. 2's log axis starts at the first computed value's decade, not at
    // the initial state's rounding (‖Φ‖₂(0) ≈ 3e-15 m), and says so
    let text = std::fs::read_to_string(fb.join("fig2_fourbar_correct_norm.svg")).unwrap();
    let norm = csv_column(&fb.join("fig2_fourbar_correct_norm.csv"), "α = β = 0");
    assert!(
        norm[0] < 1e-13 && norm[1] > 1e-10,
        "{} {}",
        norm[0],
        norm[1]
    );
    let lowest = (1..=20)
        .filter(|n: &usize| {
            let sup: String = n
                .to_string()
                .chars()
                .map(|c| ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'][c as usize - 48])
                .collect();
            text.contains(&format!("\n10⁻{sup}\n"))
        })
        .max()
        .unwrap();
    let first_computed = norm[1..].iter().cloned().fold(f64::MAX, f64::min);
    assert_eq!(lowest, (-first_computed.log10().floor()) as usize);
    assert!(
        text.contains("gaps: where |y|"),
        "the left-out start is not stated"
    );

    // fig. 5 in mm with the channel walls at ±25 mm
    let x1 = csv_column(&rod.join("fig5_rod_x.csv"), "segment 1");
    let peak = x1.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    assert!(peak > 5.0 && peak < 15.0, "segment 1 peaks at {peak} mm");
    let units = std::fs::read_to_string(rod.join("fig5_rod_x.columns.json")).unwrap();
    assert!(units.contains("\"unit\": \"mm\""), "{units}");
    let text = std::fs::read_to_string(rod.join("fig5_rod_x.svg")).unwrap();
    assert!(text.contains("walls, x = ±25 mm"), "no walls in the legend");
    let redraw = std::fs::read_to_string(rod.join("fig5_rod_x.redraw.txt")).unwrap();
    assert!(
        redraw.contains("=-2.5e1'") && redraw.contains("=2.5e1'"),
        "{redraw}"
    );

    // the chain's first three mode shapes beside the Euler–Bernoulli
    // cantilever's, with its data
    let cm = dir.path().join("chain_modes");
    for ext in ["svg", "csv", "columns.json", "redraw.txt"] {
        assert!(cm.join(format!("chain_modes.{ext}")).exists(), "{ext}");
    }
    let joints = cm.join("chain_modes_joints.csv");
    let s = csv_column(&joints, "s [m]");
    // the beam's shapes from 1 + cos β cosh β = 0, solved here by bisection
    let root = |mut a: f64, mut b: f64| {
        let f = |x: f64| 1.0 + x.cos() * x.cosh();
        for _ in 0..200 {
            let c = 0.5 * (a + b);
            if f(a) * f(c) <= 0.0 {
                b = c;
            } else {
                a = c;
            }
        }
        0.5 * (a + b)
    };
    let betas = [root(1.0, 3.0), root(4.0, 6.0), root(7.0, 9.0)];
    let header = std::fs::read_to_string(cm.join("chain_modes.csv")).unwrap();
    let header = header.lines().next().unwrap().to_string();
    let (ei, rho_a) = (2.1e11 * 0.03f64.powi(4) / 12.0, 7850.0 * 0.03 * 0.03);
    for (k, &b) in betas.iter().enumerate() {
        let w = |x: f64| {
            let sg = (b.cosh() + b.cos()) / (b.sinh() + b.sin());
            (b * x).cosh() - (b * x).cos() - sg * ((b * x).sinh() - (b * x).sin())
        };
        let beam = csv_column(&joints, &format!("Euler–Bernoulli mode {}", k + 1));
        for (x, v) in s.iter().zip(&beam) {
            assert!((v - w(*x) / w(1.0)).abs() < 1e-9, "beam mode {}", k + 1);
        }
        let hz = b * b * (ei / rho_a).sqrt() / (2.0 * std::f64::consts::PI);
        assert!(
            header.contains(&format!("Euler–Bernoulli, mode {} ({hz:.2} Hz)", k + 1)),
            "{header}"
        );
        // the chain's shape: pinned at the pivot, 1 at the free end, k − 1
        // nodes as the beam's, within 0.08 of it at N = 20 (first order)
        let chain = csv_column(&joints, &format!("chain mode {}", k + 1));
        assert!(chain[0].abs() < 1e-12 && (chain[chain.len() - 1] - 1.0).abs() < 1e-12);
        let signs: Vec<f64> = chain
            .iter()
            .filter(|v| v.abs() > 1e-9)
            .map(|v| v.signum())
            .collect();
        let nodes = signs.windows(2).filter(|p| p[0] != p[1]).count();
        assert_eq!(nodes, k, "chain mode {}", k + 1);
        let diff = chain
            .iter()
            .zip(&beam)
            .fold(0.0f64, |a, (c, e)| a.max((c - e).abs()));
        assert!(diff < 0.08, "chain mode {}: {diff}", k + 1);
    }
}
