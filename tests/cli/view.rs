//! `mbsolve view`: the self-contained page (no network, user text
//! escaped), and the page in a real browser: headless Chromium opens it at
//! `#t=…`, the time label and the error log are read from its DOM, and its
//! canvas is compared with `mbsolve animate`'s still PNG of the same output
//! time (two renderers of one drawing model: Rust/plotters and the page's
//! JavaScript). Skipped with a message when `chromium` is not installed,
//! except under `CI=true`, where its absence fails.

use crate::common::cli::{animate, mbsolve, png_rgb, stderr};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

#[test]
fn page_is_self_contained_and_escapes_user_text() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/fourbar.toml"),
    )
    .unwrap();
    let evil = r#"name = "</script><script>alert(1)</script>"
description = "<img src=x onerror=alert(2)> {{SCRIPT}}""#;
    // drop the scenario's own (top-level, first) name and description
    let (mut seen_name, mut seen_desc) = (false, false);
    let text = text
        .lines()
        .filter(|l| {
            let drop_name = !seen_name && l.starts_with("name =");
            let drop_desc = !seen_desc && l.starts_with("description =");
            seen_name |= drop_name;
            seen_desc |= drop_desc;
            !(drop_name || drop_desc)
        })
        .collect::<Vec<_>>()
        .join("\n");
    let scen = dir.path().join("fourbar.toml");
    std::fs::write(&scen, format!("{evil}\n{text}")).unwrap();
    let out = dir.path().join("out");
    let o = mbsolve(&[
        "run",
        scen.to_str().unwrap(),
        "--set",
        "time.end=0.2",
        "--out",
        out.to_str().unwrap(),
        "-q",
        "--view",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = std::fs::read_to_string(out.join("fourbar.view.html")).unwrap();
    assert!(!page.contains("<script>alert"), "script injection");
    assert!(!page.contains("<img"), "markup injection");
    assert!(page.contains("&lt;/script&gt;"), "the title escaped");
    // nothing fetched: no URLs, no src/href attributes
    for bad in ["http://", "https://", " src=\"", " href=\""] {
        assert!(!page.contains(bad), "{bad}");
    }
    // the inline script is the page's only script besides the data
    assert_eq!(page.matches("<script").count(), 2);

    let o = mbsolve(&["view", out.to_str().unwrap(), "--plot", "nope"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("--plot nope: no such column"),
        "{}",
        stderr(&o)
    );
    let o = mbsolve(&["view", dir.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("no <stem>.summary.json"),
        "{}",
        stderr(&o)
    );
}

/// The `chromium` binary, or None (skip) when absent outside CI.
fn chromium() -> Option<PathBuf> {
    for name in ["chromium", "chromium-browser"] {
        if let Ok(o) = Command::new("sh")
            .args(["-c", &format!("command -v {name}")])
            .output()
        {
            if o.status.success() {
                let p = String::from_utf8_lossy(&o.stdout).trim().to_string();
                if !p.is_empty() {
                    return Some(PathBuf::from(p));
                }
            }
        }
    }
    if std::env::var("CI").is_ok_and(|v| v == "true") {
        panic!("chromium is not installed: CI (.ci/run) installs Debian's chromium package");
    }
    eprintln!("SKIPPED: chromium is not installed (apt-get install chromium); the browser test did not run");
    None
}

/// Run headless Chromium on `url` with `extra` arguments.
fn headless(chromium: &Path, extra: &[&str], url: &str) -> Output {
    let profile = tempfile::tempdir().unwrap();
    Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--force-device-scale-factor=1",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(extra)
        .arg(url)
        .output()
        .expect("chromium runs")
}

/// The coloured ink (bodies, springs, dampers: channels differing by more
/// than 40; text and ground are grey) of the top-left `w × h` of an image,
/// as the fraction of inked pixels in each 8 × 8 block.
fn ink_blocks(img: &(usize, usize, Vec<u8>), w: usize, h: usize) -> Vec<f64> {
    let (iw, _, px) = img;
    let mut out = Vec::new();
    for by in 0..h / 8 {
        for bx in 0..w / 8 {
            let mut n = 0;
            for y in 8 * by..8 * by + 8 {
                for x in 8 * bx..8 * bx + 8 {
                    let p = &px[3 * (y * iw + x)..3 * (y * iw + x) + 3];
                    let (mx, mn) = (p.iter().max().unwrap(), p.iter().min().unwrap());
                    if mx - mn > 40 {
                        n += 1;
                    }
                }
            }
            out.push(n as f64 / 64.0);
        }
    }
    out
}

/// Mean absolute difference of two block maps over the blocks inked in
/// either, and the number of such blocks.
fn difference(a: &[f64], b: &[f64]) -> (f64, usize) {
    let (mut s, mut n) = (0.0, 0);
    for (x, y) in a.iter().zip(b) {
        if *x > 0.0 || *y > 0.0 {
            s += (x - y).abs();
            n += 1;
        }
    }
    (s / n.max(1) as f64, n)
}

#[test]
fn browser_draws_the_frame_animate_draws() {
    let Some(chromium) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let o = mbsolve(&[
        "run",
        "scenarios/quarter_car.toml",
        "--set",
        "time.end=2.5",
        "--out",
        out.to_str().unwrap(),
        "-q",
        "--view",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = out.join("quarter_car.view.html");
    let url = format!("file://{}#t=2", page.display());

    // the DOM: time label of the output time nearest 2 s, no errors
    let o = headless(&chromium, &["--dump-dom"], &url);
    let dom = String::from_utf8_lossy(&o.stdout);
    assert!(
        dom.contains("data-ready=\"1\""),
        "the script did not finish:\n{dom}"
    );
    assert!(
        dom.contains("<span id=\"time\">t = 2.000 s</span>"),
        "time label: {}",
        dom.split("id=\"time\"")
            .nth(1)
            .unwrap_or("")
            .chars()
            .take(60)
            .collect::<String>()
    );
    assert!(
        dom.contains("<pre id=\"errors\" data-count=\"0\"></pre>"),
        "errors: {}",
        dom.split("id=\"errors\"")
            .nth(1)
            .unwrap_or("")
            .chars()
            .take(400)
            .collect::<String>()
    );

    // the canvas (at the page's top left) against animate's still
    let shot = out.join("shot.png");
    let o = headless(
        &chromium,
        &[
            &format!("--screenshot={}", shot.display()),
            "--window-size=1200,800",
        ],
        &url,
    );
    assert!(shot.is_file(), "no screenshot: {}", stderr(&o));
    let browser = png_rgb(&shot);
    let still = |t: &str| {
        let p = out.join(format!("still_{t}.png"));
        let csv = out.join("quarter_car.csv");
        let o = animate(
            "scenarios/quarter_car.toml",
            csv.to_str().unwrap(),
            &p,
            &["--at", t],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        png_rgb(&p)
    };
    let same = still("2");
    let (w, h) = (same.0, same.1);
    assert!(
        browser.0 >= w && browser.1 >= h,
        "screenshot {}×{}",
        browser.0,
        browser.1
    );
    let b = ink_blocks(&browser, w, h);
    let (d_same, n) = difference(&b, &ink_blocks(&same, w, h));
    // half a road period later the chassis and the wheel stand elsewhere
    let (d_other, _) = difference(&b, &ink_blocks(&still("2.4"), w, h));
    eprintln!("ink difference: same time {d_same:.4} over {n} blocks, t = 2.4 s {d_other:.4}");
    assert!(n > 200, "too little ink: {n} blocks");
    assert!(d_same < 0.05, "browser vs animate at t = 2: {d_same:.4}");
    assert!(
        d_other > 2.0 * d_same && d_other > 0.05,
        "t = 2.4: {d_other:.4}"
    );
}
