//! `mbsolve plot` and `mbsolve animate`: files with the requested content,
//! clear errors for bad requests.

use crate::common::cli::{animate, mbsolve, run_csv, stderr};
use std::path::Path;

/// Run the four-bar with output every `dt` into `dir`; returns the CSV path.
fn fourbar_run(dir: &Path, dt: &str) -> String {
    run_csv(dir, "scenarios/fourbar.toml", &[&format!("output.dt={dt}")])
}

/// Width and height from a PNG's IHDR chunk.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// Number of images (frames) in a GIF, by walking its block structure.
fn gif_frames(b: &[u8]) -> usize {
    assert!(
        b.starts_with(b"GIF89a") || b.starts_with(b"GIF87a"),
        "not a GIF"
    );
    let mut i = 13;
    if b[10] & 0x80 != 0 {
        i += 3 << ((b[10] & 7) + 1);
    }
    let skip_sub_blocks = |mut i: usize| {
        while b[i] != 0 {
            i += b[i] as usize + 1;
        }
        i + 1
    };
    let mut frames = 0;
    loop {
        match b[i] {
            0x21 => i = skip_sub_blocks(i + 2),
            0x2C => {
                frames += 1;
                let flags = b[i + 9];
                i += 10;
                if flags & 0x80 != 0 {
                    i += 3 << ((flags & 7) + 1);
                }
                i = skip_sub_blocks(i + 1);
            }
            0x3B => return frames,
            x => panic!("bad GIF block 0x{x:02x} at {i}"),
        }
    }
}

#[test]
fn plot_writes_svg_and_png_with_the_requested_series() {
    let dir = tempfile::tempdir().unwrap();
    let csv = fourbar_run(dir.path(), "0.02");
    let svg = dir.path().join("p.svg");
    let o = mbsolve(&[
        "plot",
        &csv,
        "--x",
        "t",
        "--y",
        "crank.x,crank.y",
        "--y",
        // a positional name of earlier versions: the third body's angle
        "phi3",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    // physical size for print, and one legend entry per requested column
    assert!(
        text.starts_with(r#"<svg width="17.01cm" height="10.00cm""#),
        "{}",
        &text[..120]
    );
    for name in ["crank.x", "crank.y", "rocker.phi"] {
        assert!(
            text.contains(&format!("\n{name}\n")),
            "legend entry {name} missing"
        );
    }
    assert!(
        !text.contains("\ncoupler.x\n"),
        "a column that was not asked for is drawn"
    );
    // 3 curves (solid, dashed, dotted; lengths in the SVG's tenths of a
    // px), each one path in its colour
    // beside its legend sample, with their units from fourbar.columns.json
    for (colour, dash) in [("#0072B2", ""), ("#D55E00", "60 35"), ("#009E73", "16 26")] {
        let curves = text
            .split("<path d=\"M")
            .map(|p| &p[..p.find("/>").unwrap()])
            .filter(|p| {
                // not a marker (filled triangles)
                p.contains(&format!("stroke=\"{colour}\""))
                    && !p.contains(&format!("fill=\"{colour}\""))
            })
            .count();
        assert_eq!(curves, 2, "curve and legend sample in {colour}");
        if !dash.is_empty() {
            assert!(
                text.contains(&format!("stroke-dasharray=\"{dash}\"")),
                "{colour}: no dash pattern {dash}"
            );
        }
    }
    assert!(
        text.contains("\ncrank.x, crank.y [m]; rocker.phi [rad]\n"),
        "ordinate label"
    );
    assert!(text.contains("\nt [s]\n"), "abscissa label");

    // a log axis: ticks are the decades 10ⁿ of the norm's range
    let log = dir.path().join("log.svg");
    let o = mbsolve(&[
        "plot",
        &csv,
        "--y",
        "constraint_norm",
        "--log-y",
        "--out",
        log.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&log).unwrap();
    let norms: Vec<f64> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .filter(|v: &f64| *v > 0.0)
        .collect();
    let top = norms.iter().cloned().fold(0.0, f64::max).log10().ceil() as i32;
    let sup = |n: i32| -> String {
        let d = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
        let e: String = n
            .unsigned_abs()
            .to_string()
            .chars()
            .map(|c| d[c as usize - 48])
            .collect();
        format!("10{}{e}", if n < 0 { "⁻" } else { "" })
    };
    assert!(
        text.contains(&format!("\n{}\n", sup(top))),
        "no tick {}",
        sup(top)
    );
    assert!(
        !text.contains(&format!("\n{}\n", sup(top + 1))),
        "axis beyond the data"
    );

    let png = dir.path().join("p.png");
    let o = mbsolve(&[
        "plot",
        &csv,
        "--y",
        "constraint_norm",
        "--log-y",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h) = png_size(&std::fs::read(&png).unwrap());
    assert_eq!((w, h), (1929, 1134), "17 cm × 10 cm at 3 × 96 dpi");
}

#[test]
fn plot_errors_name_the_missing_column_and_list_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let csv = fourbar_run(dir.path(), "0.1");
    let o = mbsolve(&["plot", &csv, "--y", "crank.x,nonsense"]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("no column 'nonsense'"), "{e}");
    assert!(
        e.contains("the columns are: t, crank.x, crank.y, crank.phi, coupler.x"),
        "{e}"
    );
    let o = mbsolve(&["plot", &csv, "--y", "x1", "--out", "fig.pdf"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown figure format 'pdf'"),
        "{}",
        stderr(&o)
    );
    let o = mbsolve(&["plot", "no/such.csv", "--y", "x1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no/such.csv"), "{}", stderr(&o));
}

#[test]
fn animate_writes_one_frame_per_output_time() {
    let dir = tempfile::tempdir().unwrap();
    let csv = fourbar_run(dir.path(), "0.05");
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count() - 1;
    assert_eq!(rows, 41, "2 s at 0.05 s");

    let svg = dir.path().join("a.svg");
    let o = animate("scenarios/fourbar.toml", &csv, &svg, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    // three bodies, each with an animated translation and rotation
    assert_eq!(text.matches("<animateTransform").count(), 6);
    // without SMIL the bodies stand at their first-frame pose
    assert_eq!(text.matches("<g transform=\"translate(").count(), 3);
    assert_eq!(text.matches("<g transform=\"rotate(").count(), 3);
    let key_times = text.split("keyTimes=\"").nth(1).unwrap();
    let key_times = &key_times[..key_times.find('"').unwrap()];
    assert_eq!(key_times.split(';').count(), rows);
    // four revolute joints, one pin each (tests/cli/animate.rs: the rest)
    assert_eq!(text.matches("r=\"3.5\"").count(), 4);

    let gif = dir.path().join("a.gif");
    let o = animate("scenarios/fourbar.toml", &csv, &gif, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(gif_frames(&std::fs::read(&gif).unwrap()), rows);

    let o = animate("scenarios/fourbar.toml", &csv, &gif, &["--every", "10"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        gif_frames(&std::fs::read(&gif).unwrap()),
        5,
        "rows 0, 10, 20, 30, 40"
    );
}

#[test]
fn animate_rejects_a_csv_of_another_model() {
    let dir = tempfile::tempdir().unwrap();
    let csv = fourbar_run(dir.path(), "0.1");
    let o = mbsolve(&[
        "animate",
        "scenarios/falling_rod.toml",
        &csv,
        "--out",
        dir.path().join("a.svg").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    // the rod's first body is not the four-bar's crank (no reading its
    // positional x1 through the four-bar's names)
    assert!(
        stderr(&o).contains("no column 'rod.segment[1].x'"),
        "{}",
        stderr(&o)
    );
}

/// A controller state's unit (`[[state]] unit`) reaches `columns.json` and
/// the plot's ordinate label beside the bodies' units.
#[test]
fn state_units_reach_columns_json_and_the_plot() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = mbsolve(&[
        "run",
        "scenarios/pid_arm.toml",
        "--set",
        "time.end=0.2",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cols: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("pid_arm.columns.json")).unwrap(),
    )
    .unwrap();
    let unit = |n: &str| {
        cols.as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == n)
            .unwrap_or_else(|| panic!("no column {n}"))["unit"]
            .clone()
    };
    assert_eq!((unit("e1"), unit("e3")), ("rad s".into(), "rad s".into()));
    let svg = dir.path().join("e.svg");
    let csv = dir.path().join("pid_arm.csv");
    let o = mbsolve(&[
        "plot",
        csv.to_str().unwrap(),
        "--y",
        "e1,e2,link1.phi",
        "--out",
        svg.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(
        text.contains("\ne1, e2 [rad s]; link1.phi [rad]\n"),
        "ordinate label"
    );
}
