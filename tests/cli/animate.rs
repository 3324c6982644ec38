//! `mbsolve animate`: the drawing of the model (shapes, springs, dampers),
//! honest time (frames chosen so that each lasts at least the format's
//! minimum, delays summing to the simulated span over the speed), the SVG's
//! structure, and bad input.

use crate::common::cli::{animate, mbsolve, png_rgb, run_csv as run, scenario, stderr, stdout};
use std::path::Path;
use std::process::Command;

/// The delays (in 10 ms) of every frame of a GIF, decoded by the `gif` crate.
fn gif_delays(path: &Path) -> Vec<u16> {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::Indexed);
    let mut d = opts
        .read_info(std::fs::File::open(path).unwrap())
        .expect("a GIF");
    let mut delays = Vec::new();
    while let Some(f) = d.read_next_frame().unwrap() {
        delays.push(f.delay);
    }
    delays
}

#[test]
fn gif_plays_at_the_speed_it_states() {
    let dir = tempfile::tempdir().unwrap();
    // 2 s at 1 ms: 2001 rows, far more than a GIF can show
    let csv = run(dir.path(), "scenarios/fourbar.toml", &["output.dt=0.001"]);
    let gif = dir.path().join("a.gif");
    for (speed, frames, total_cs) in [("1", 101, 200), ("0.5", 201, 400), ("4", 26, 50)] {
        let o = animate("scenarios/fourbar.toml", &csv, &gif, &["--speed", speed]);
        assert!(o.status.success(), "{}", stderr(&o));
        let delays = gif_delays(&gif);
        // frames every 20 ms of wall time (GIF's shortest honest delay)
        assert_eq!(delays.len(), frames, "speed {speed}");
        assert!(delays.iter().all(|&d| d >= 2), "{delays:?}");
        // the frames before the last span the simulated 2 s / speed
        let shown: u32 = delays[..delays.len() - 1].iter().map(|&d| d as u32).sum();
        assert_eq!(shown, total_cs, "speed {speed}: {delays:?}");
        let said = stdout(&o);
        assert!(
            said.contains(&format!("{frames} of 2001 output rows shown"))
                && said.contains("frames of ≥ 20 ms"),
            "{said}"
        );
    }
}

#[test]
fn gif_keeps_every_row_when_rows_are_slow_enough() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run(dir.path(), "scenarios/fourbar.toml", &["output.dt=0.05"]);
    let gif = dir.path().join("a.gif");
    let o = animate("scenarios/fourbar.toml", &csv, &gif, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d = gif_delays(&gif);
    assert_eq!(d.len(), 41, "2 s at 0.05 s: every row");
    assert!(d.iter().all(|&x| x == 5), "{d:?}");
    let o = animate("scenarios/fourbar.toml", &csv, &gif, &["--every", "10"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let d = gif_delays(&gif);
    assert_eq!(d, vec![50; 5], "rows 0, 10, 20, 30, 40, half a second each");
}

#[test]
fn svg_animates_bodies_and_springs() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run(dir.path(), "scenarios/fourbar.toml", &["output.dt=0.05"]);
    let svg = dir.path().join("a.svg");
    let o = animate("scenarios/fourbar.toml", &csv, &svg, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    // three bodies, each with an animated translation and rotation
    assert_eq!(text.matches("<animateTransform").count(), 6);
    assert_eq!(text.matches("<g transform=\"translate(").count(), 3);
    let key_times = text.split("keyTimes=\"").nth(1).unwrap();
    let key_times = &key_times[..key_times.find('"').unwrap()];
    assert_eq!(key_times.split(';').count(), 41);
    // four revolute joints, one pin each; two bars' outlines drawn per body
    assert_eq!(text.matches("r=\"3.5\"").count(), 4);
    assert_eq!(
        text.matches("<polygon").count(),
        3 + 2,
        "3 bars, 2 supports"
    );

    // the quarter car: two springs (zig-zags) and one damper (4 polylines),
    // their points animated
    let csv = run(dir.path(), "scenarios/quarter_car.toml", &["time.end=0.5"]);
    let o = animate("scenarios/quarter_car.toml", &csv, &svg, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_eq!(text.matches("stroke=\"#D55E00\"").count(), 2, "springs");
    assert_eq!(text.matches("stroke=\"#009E73\"").count(), 4, "damper");
    assert_eq!(text.matches("<animate attributeName=\"points\"").count(), 6);
}

#[test]
fn quarter_car_still_shows_springs_where_the_run_puts_the_bodies() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run(dir.path(), "scenarios/quarter_car.toml", &["time.end=1"]);
    let png_path = dir.path().join("q.png");
    let o = animate(
        "scenarios/quarter_car.toml",
        &csv,
        &png_path,
        &["--at", "1"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = png_rgb(&png_path);
    let rows_of = |c: [u8; 3]| -> Vec<usize> {
        (0..h)
            .filter(|&y| (0..w).any(|x| px[3 * (y * w + x)..3 * (y * w + x) + 3] == c))
            .collect()
    };
    let spring = rows_of([0xD5, 0x5E, 0x00]);
    let damper = rows_of([0x00, 0x9E, 0x73]);
    assert!(!spring.is_empty() && !damper.is_empty());
    // The suspension's damper spans the gap between the wheel's top and
    // the chassis' bottom: its pixel height over the spring's whole
    // extent (tyre and suspension) is the ratio of the run's lengths.
    let table = std::fs::read_to_string(&csv).unwrap();
    let last = table.lines().last().unwrap();
    let v: Vec<f64> = last.split(',').map(|x| x.parse().unwrap()).collect();
    let (y_road, y_wheel, y_chassis) = (v[2], v[5], v[8]);
    let susp = (y_chassis - 0.15) - (y_wheel + 0.3);
    let all = (y_chassis - 0.15) - (y_road + 0.025);
    let px_susp = (damper.last().unwrap() - damper[0]) as f64;
    let px_all = (spring.last().unwrap() - spring[0]) as f64;
    let ratio = px_susp / px_all;
    assert!(
        (ratio - susp / all).abs() < 0.03,
        "damper/spring extents {px_susp}/{px_all} = {ratio:.3}, lengths {susp:.4}/{all:.4} = {:.3}",
        susp / all
    );
}

#[test]
fn bad_shape_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/quarter_car.toml"),
    )
    .unwrap();
    for (bad, want) in [
        ("shape = { circle = -0.3 }", "circle radius -0.3"),
        ("shape = { hexagon = 1.0 }", "hexagon"),
        (
            "shape = { polygon = [[0.0, 0.0], [1.0, 0.0]] }",
            "at least 3",
        ),
    ] {
        let p = dir.path().join("q.toml");
        std::fs::write(&p, text.replacen("shape = { circle = 0.3 }", bad, 1)).unwrap();
        let o = mbsolve(&["check", p.to_str().unwrap()]);
        assert!(!o.status.success());
        let e = stderr(&o) + &stdout(&o);
        assert!(e.contains("body[1].shape") || e.contains("body[1]"), "{e}");
        assert!(e.contains(want), "{bad}: {e}");
    }
}

#[test]
fn animate_rejects_bad_arguments() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run(dir.path(), "scenarios/fourbar.toml", &["output.dt=0.1"]);
    let out = dir.path().join("a.avi");
    let o = animate("scenarios/fourbar.toml", &csv, &out, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown animation format 'avi'"),
        "{}",
        stderr(&o)
    );
    let o = mbsolve(&["animate", "scenarios/fourbar.toml", &csv, "--speed", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--speed 0"), "{}", stderr(&o));
}

/// A ground pivot's support points away from the body pinned to it: a
/// pendulum hanging from its pin gets the support above the pin (it used
/// to be drawn under the pin, over the body), a body standing on its pin
/// gets it below.
#[test]
fn ground_support_is_drawn_away_from_the_pinned_body() {
    use mbsolve::drawing::{Drawing, Ink, Mark};
    let text = |y: f64, pin: f64| {
        format!(
            "[[body]]\nname = \"bob\"\nmass = 1.0\ninertia = 0.01\nx = 0.0\ny = {y}\n\
             [[joint]]\ntype = \"revolute\"\nname = \"pivot\"\nbody_i = \"ground\"\n\
             point_i = [0.0, 0.0]\nbody_j = \"bob\"\npoint_j = [0.0, {pin}]\n\
             [time]\nend = 1.0\n"
        )
    };
    for (y, pin, above) in [(-0.5, 0.5, true), (0.5, -0.5, false)] {
        let sc = mbsolve::scenario::parse(&text(y, pin), "p.toml", "p", &[]).unwrap();
        let d = Drawing::new(&sc.system, &sc.q0, &[], &[]);
        let ground: Vec<[f64; 2]> = d
            .marks(&sc.q0)
            .into_iter()
            .filter_map(|m| match m {
                Mark::Fill {
                    points,
                    ink: Ink::Ground,
                } => Some(points),
                _ => None,
            })
            .flatten()
            .collect();
        assert_eq!(ground.len(), 3, "one support triangle");
        for p in ground {
            let ok = if above { p[1] >= -1e-12 } else { p[1] <= 1e-12 };
            assert!(
                ok && p[0].abs() < 0.1,
                "support point {p:?} (above: {above})"
            );
        }
    }
}

/// The delays (numerator, denominator) of every frame of an APNG, and the
/// frame count its animation control announces, decoded by the `png` crate.
fn apng_delays(path: &Path) -> (u32, Vec<(u16, u16)>) {
    let dec = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = dec.read_info().expect("a PNG");
    let announced = reader
        .info()
        .animation_control
        .expect("an animated PNG (acTL)")
        .num_frames;
    let mut buf = vec![0; reader.output_buffer_size()];
    let mut delays = Vec::new();
    while reader.next_frame(&mut buf).is_ok() {
        let fc = reader.info().frame_control.expect("a frame control (fcTL)");
        delays.push((fc.delay_num, fc.delay_den));
    }
    (announced, delays)
}

#[test]
fn apng_plays_at_the_speed_it_states() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run(dir.path(), "scenarios/fourbar.toml", &["output.dt=0.001"]);
    let apng = dir.path().join("a.apng");
    let o = animate("scenarios/fourbar.toml", &csv, &apng, &["--speed", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (announced, delays) = apng_delays(&apng);
    // 2 s at twice real time: a frame every 20 ms of wall time, 51 frames
    assert_eq!(announced as usize, delays.len());
    assert_eq!(delays.len(), 51);
    assert!(
        delays.iter().all(|&(n, d)| d == 1000 && n >= 20),
        "{delays:?}"
    );
    let shown: u32 = delays[..delays.len() - 1].iter().map(|d| d.0 as u32).sum();
    assert_eq!(shown, 1000, "the frames before the last span 2 s / 2");
    assert!(
        stdout(&o).contains("APNG: 51 of 2001 output rows shown"),
        "{}",
        stdout(&o)
    );
}

/// MP4 through ffmpeg where it is on the PATH; without it the command
/// fails with a message that names ffmpeg and the formats that need no
/// external tool (the test says which case it checked).
#[test]
fn video_needs_ffmpeg_or_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run(dir.path(), "scenarios/fourbar.toml", &["output.dt=0.01"]);
    let mp4 = dir.path().join("a.mp4");
    let o = mbsolve(&[
        "animate",
        "scenarios/fourbar.toml",
        &csv,
        "--out",
        mp4.to_str().unwrap(),
    ]);
    let has_ffmpeg = Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    if has_ffmpeg {
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(std::fs::metadata(&mp4).unwrap().len() > 0);
        assert!(stdout(&o).contains("video: "), "{}", stdout(&o));
    } else {
        println!(
            "skipped the MP4 encoding: ffmpeg is not on the PATH; checked the message instead"
        );
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(
            e.contains("ffmpeg") && e.contains(".gif") && e.contains(".apng"),
            "{e}"
        );
    }
}

/// A ball (2 kg, r = 0.2 m) resting on the floor through a Hertz contact
/// (k = 1e5 N/m^1.5) at its equilibrium penetration δ = (m g/k)^(2/3), and
/// a bob (1 kg) hanging at rest from a pin whose name needs escaping.
fn resting_toml() -> String {
    let delta = (2.0 * 9.81 / 1e5_f64).powf(2.0 / 3.0);
    format!(
        r#"name = "arrows"
gravity = [0.0, -9.81]
[[body]]
name = "ball"
mass = 2.0
inertia = 0.04
y = {y:e}
shape = {{ circle = 0.2 }}
[[body]]
name = "bob"
mass = 1.0
inertia = 0.01
x = 1.0
y = 0.7
[[joint]]
type = "revolute"
name = "p<i>n&\"1'"
body_i = "ground"
point_i = [1.0, 1.0]
body_j = "bob"
point_j = [0.0, 0.3]
[[force]]
type = "contact"
name = "floor"
body = "ball"
radius = 0.2
wall_point = [0.0, 0.0]
wall_normal_deg = 90.0
stiffness = 1e5
damping = 0.5
friction = 0.3
[time]
end = 0.1
[output]
dt = 0.05
quantities = ["velocities"]
"#,
        y = 0.2 - delta
    )
}

/// The first `points="…"` of an SVG element, as pixel pairs.
fn first_points(el: &str) -> Vec<(f64, f64)> {
    let p = el
        .split("points=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap();
    p.split(' ')
        .map(|xy| {
            let (x, y) = xy.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

#[test]
fn force_arrows_show_the_weights_against_their_key() {
    let dir = tempfile::tempdir().unwrap();
    let scen = dir.path().join("arrows.toml");
    std::fs::write(&scen, resting_toml()).unwrap();
    let scen = scen.to_str().unwrap();
    let csv = run(dir.path(), scen, &[]);
    let svg = dir.path().join("a.svg");
    let o = animate(scen, &csv, &svg, &["--forces", "contacts,reactions"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    // shaft and head per arrow: the contact first, then the reaction
    let arrows: Vec<&str> = text
        .lines()
        .filter(|l| l.contains(r#"class="force""#))
        .collect();
    assert_eq!(arrows.len(), 4, "{text}");
    // the key: 10 N (the round force below the largest, 19.62 N)
    let key = text
        .lines()
        .skip_while(|l| !l.contains("force-key"))
        .take(2)
        .collect::<String>();
    assert!(key.contains(">10 N</text>"), "{key}");
    let d = key.split("d=\"M").nth(1).unwrap();
    let nums: Vec<f64> = d
        .split(['L', ',', ' ', 'M', '"'])
        .filter_map(|s| s.trim().parse().ok())
        .take(4)
        .collect();
    let key_px = (nums[2] - nums[0]).hypot(nums[3] - nums[1]);
    // the floor pushes the ball up with m g = 19.62 N, the pin holds the
    // bob with 9.81 N: shafts upward, their lengths to the key's as the
    // forces to 10 N (pixels to two decimals)
    for (shaft, force) in [(arrows[0], 19.62), (arrows[2], 9.81)] {
        let p = first_points(shaft);
        let (dx, dy) = (p[1].0 - p[0].0, p[1].1 - p[0].1);
        assert!(dx.abs() < 0.02 && dy < 0.0, "{shaft}");
        let ratio = dy.abs() / key_px;
        assert!(
            (ratio - force / 10.0).abs() < 2e-3,
            "{ratio} vs {}",
            force / 10.0
        );
    }
    // names reach the SVG escaped
    assert!(
        arrows[2].contains("<title>p&lt;i&gt;n&amp;&quot;1&#39;</title>"),
        "{}",
        arrows[2]
    );
    assert!(
        arrows[0].contains("<title>force[0] &#39;floor&#39;"),
        "{}",
        arrows[0]
    );
    assert!(!text.contains("p<i>"));
    // a still PNG with the arrows
    let png = dir.path().join("a.png");
    let o = animate(scen, &csv, &png, &["--forces", "all", "--at", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    // the viewer carries the arrows, names as JSON text with `<` escaped
    let o = mbsolve(&["view", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = std::fs::read_to_string(dir.path().join("arrows.view.html")).unwrap();
    assert!(page.contains(r#""arrows":{"#), "no arrows in the page");
    assert!(
        page.contains(r#"p\u003ci>n&\"1'"#),
        "the pin's name as JSON"
    );
    assert!(!page.contains("p<i>"), "raw markup in the page");
    assert!(page.contains(r#"id="forces""#), "the toggle");
    // a bad kind is named
    let o = mbsolve(&["animate", scen, &csv, "--forces", "torques"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--forces: 'torques'"), "{}", stderr(&o));
}

/// The bob of [`resting_toml`] alone, hanging at rest from a pin named
/// plainly, with the run writing velocities and reactions.
fn hanging_toml() -> String {
    r#"name = "hanging"
gravity = [0.0, -9.81]
[[body]]
name = "bob"
mass = 1.0
inertia = 0.01
x = 1.0
y = 0.7
[[joint]]
type = "revolute"
name = "pin"
body_i = "ground"
point_i = [1.0, 1.0]
body_j = "bob"
point_j = [0.0, 0.3]
[time]
end = 0.1
[output]
dt = 0.05
quantities = ["velocities", "reactions"]
"#
    .into()
}

/// The first force arrow's shaft of an SVG (frame 0) against its key:
/// (dx, dy) in pixels and the key's length in pixels and label.
fn first_arrow_and_key(svg: &str) -> ((f64, f64), f64, String) {
    let shaft = svg
        .lines()
        .find(|l| l.contains(r#"class="force""#))
        .unwrap_or_else(|| panic!("no arrow in {svg}"));
    let p = first_points(shaft);
    let key = svg
        .lines()
        .skip_while(|l| !l.contains("force-key"))
        .take(2)
        .collect::<String>();
    let d = key.split("d=\"M").nth(1).unwrap();
    let nums: Vec<f64> = d
        .split(['L', ',', ' ', 'M', '"'])
        .filter_map(|s| s.trim().parse().ok())
        .take(4)
        .collect();
    let label = key
        .split("\">")
        .last()
        .unwrap()
        .split('<')
        .next()
        .unwrap()
        .to_string();
    (
        (p[1].0 - p[0].0, p[1].1 - p[0].1),
        (nums[2] - nums[0]).hypot(nums[3] - nums[1]),
        label,
    )
}

/// Reaction arrows are drawn from the run's `J.fx, J.fy` columns where it
/// wrote them: the hanging bob's pin column holds m g = 9.81 N (the
/// analytic reaction at rest), drawn against a 5 N key; the same table
/// with that column halved (as a run with other multipliers would have
/// written it) draws 4.905 N against a 2 N key — the columns, not a
/// recomputation from the positions, set the arrow. Without the columns
/// the arrow is computed from the state, and says so.
#[test]
fn reaction_arrows_come_from_the_runs_columns() {
    let dir = tempfile::tempdir().unwrap();
    let scen = dir.path().join("hanging.toml");
    std::fs::write(&scen, hanging_toml()).unwrap();
    let scen = scen.to_str().unwrap();
    let csv = run(dir.path(), scen, &[]);
    let mut r = csv::Reader::from_path(&csv).unwrap();
    let h = r.headers().unwrap().clone();
    let rows: Vec<Vec<String>> = r
        .records()
        .map(|x| x.unwrap().iter().map(String::from).collect())
        .collect();
    let fy = h.iter().position(|c| c == "pin.fy").expect("pin.fy column");
    for row in &rows {
        let v: f64 = row[fy].parse().unwrap();
        assert!((v - 9.81).abs() < 1e-9, "pin.fy = {v}");
    }
    let draw = |table: &str, name: &str| {
        let svg = dir.path().join(name);
        let o = animate(scen, table, &svg, &["--forces", "reactions"]);
        assert!(o.status.success(), "{}", stderr(&o));
        (
            first_arrow_and_key(&std::fs::read_to_string(&svg).unwrap()),
            stdout(&o),
        )
    };
    let (((dx, dy), key_px, label), said) = draw(&csv, "run.svg");
    assert!(
        said.contains("joint reactions from the run's columns"),
        "{said}"
    );
    assert_eq!(label, "5 N");
    assert!(dx.abs() < 0.02 && dy < 0.0);
    assert!(
        (dy.abs() / key_px - 9.81 / 5.0).abs() < 2e-3,
        "{dy} {key_px}"
    );
    // the same table, the pin's fy halved
    let halved = dir.path().join("halved.csv");
    let mut w = csv::Writer::from_path(&halved).unwrap();
    w.write_record(&h).unwrap();
    for row in &rows {
        let mut row = row.clone();
        row[fy] = format!("{:e}", 0.5 * row[fy].parse::<f64>().unwrap());
        w.write_record(&row).unwrap();
    }
    w.flush().unwrap();
    let (((dx, dy), key_px, label), _) = draw(halved.to_str().unwrap(), "halved.svg");
    assert_eq!(label, "2 N");
    assert!(dx.abs() < 0.02 && dy < 0.0);
    assert!(
        (dy.abs() / key_px - 4.905 / 2.0).abs() < 2e-3,
        "{dy} {key_px}"
    );
    // without reaction columns: computed (m g again), and said so
    let plain = dir.path().join("plain");
    std::fs::create_dir(&plain).unwrap();
    let csv = run(&plain, scen, &["output.quantities=[\"velocities\"]"]);
    let (((_, dy), key_px, label), said) = draw(&csv, "plain.svg");
    assert!(said.contains("computed from the state"), "{said}");
    assert_eq!(label, "5 N");
    assert!(
        (dy.abs() / key_px - 9.81 / 5.0).abs() < 2e-3,
        "{dy} {key_px}"
    );
}

/// `modes --animate --forces`: the mode's table is in a run's named
/// columns (`bob.x`, …, `bob.vx`, …) with the velocities the time
/// derivative of the positions (central differences to O(Δt²)), and its
/// animation carries the same force arrows as `animate --forces`: at the
/// first frame (the equilibrium, swinging at Ω) the pin holds the bob with
/// m g + m L Ω² (L = 0.3 m from pin to centre of mass), upward.
#[test]
fn mode_animations_draw_force_arrows_from_named_columns() {
    let dir = tempfile::tempdir().unwrap();
    let scen = dir.path().join("hanging.toml");
    std::fs::write(&scen, hanging_toml()).unwrap();
    let out = dir.path().join("m");
    let o = mbsolve(&[
        "modes",
        scen.to_str().unwrap(),
        "--count",
        "1",
        "--animate",
        "1",
        "--forces",
        "reactions",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut r = csv::Reader::from_path(out.join("hanging.mode1.csv")).unwrap();
    let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(
        h,
        [
            "t",
            "bob.x",
            "bob.y",
            "bob.phi",
            "bob.vx",
            "bob.vy",
            "bob.omega"
        ]
    );
    let rows: Vec<Vec<f64>> = r
        .records()
        .map(|x| x.unwrap().iter().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 49);
    let dt = rows[1][0] - rows[0][0];
    let omega_max = rows.iter().map(|r| r[6].abs()).fold(0.0, f64::max);
    // drawn visibly: the largest rotation 0.3 rad or a tenth of the model
    let phi_max = rows.iter().map(|r| r[3].abs()).fold(0.0, f64::max);
    assert!(phi_max > 0.05, "the mode swings by {phi_max} rad");
    for k in 1..rows.len() - 1 {
        for c in 1..4 {
            let fd = (rows[k + 1][c] - rows[k - 1][c]) / (2.0 * dt);
            // the central difference of a sine: v sin(ω Δt)/(ω Δt),
            // 1 − 2.9e-3 at 48 frames a period
            let scale = if c == 3 { omega_max } else { 0.3 * omega_max };
            assert!(
                (fd - rows[k][c + 3]).abs() < 3.5e-3 * scale,
                "row {k} col {}: {fd} vs {}",
                h[c],
                rows[k][c + 3]
            );
        }
    }
    let svg = std::fs::read_to_string(out.join("hanging.mode1.svg")).unwrap();
    assert!(svg.contains("<title>pin</title>"), "the pin's arrow");
    let ((dx, dy), key_px, label) = first_arrow_and_key(&svg);
    let key: f64 = label.trim_end_matches(" N").parse().unwrap();
    let big_omega = rows[0][6];
    let want = 1.0 * 9.81 + 1.0 * 0.3 * big_omega * big_omega;
    assert!(dx.abs() < 0.02 && dy < 0.0, "{dx} {dy}");
    assert!(
        (dy.abs() / key_px - want / key).abs() < 2e-3 * want / key,
        "{} vs {want} N",
        dy.abs() / key_px * key
    );
    assert!(
        std::fs::metadata(out.join("hanging.mode1.png"))
            .unwrap()
            .len()
            > 1000
    );
}

/// A joint named with a comma and double quotes: the run's CSV header
/// quotes its columns per RFC 4180, so an RFC 4180 reader (the `csv`
/// crate) reads every row at the header's width with the names whole;
/// `plot` and `animate --forces` find its columns by those names.
#[test]
fn names_with_commas_and_quotes_stay_one_column() {
    let dir = tempfile::tempdir().unwrap();
    let scen = dir.path().join("hanging.toml");
    let name = r#"pin, "main""#;
    let toml = hanging_toml().replace("name = \"pin\"", &format!("name = {}", toml_string(name)));
    std::fs::write(&scen, toml).unwrap();
    let scen = scen.to_str().unwrap();
    let csv = run(dir.path(), scen, &[]);
    let mut r = csv::Reader::from_path(&csv).unwrap();
    let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let fy = format!("{name}.fy");
    let k = h.iter().position(|c| *c == fy).expect("the column, whole");
    for rec in r.records() {
        let rec = rec.expect("rows as wide as the header");
        assert_eq!(rec.len(), h.len());
        assert!((rec[k].parse::<f64>().unwrap() - 9.81).abs() < 1e-9);
    }
    let o = mbsolve(&[
        "plot",
        &csv,
        "--y",
        &fy,
        "--out",
        dir.path().join("fy.svg").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let svg = dir.path().join("a.svg");
    let o = animate(scen, &csv, &svg, &["--forces", "reactions"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("joint reactions from the run's columns"),
        "{}",
        stdout(&o)
    );
}

/// `s` as a TOML basic string.
fn toml_string(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// The frames of the first force arrow's shaft in an animated SVG: per
/// frame, its two end points in pixels.
fn first_arrow_frames(svg: &str) -> Vec<Vec<(f64, f64)>> {
    let el = svg.split(r#"class="force""#).nth(1).expect("a force arrow");
    let values = el
        .split("values=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap();
    values
        .split(';')
        .map(|f| {
            f.split(' ')
                .map(|xy| {
                    let (x, y) = xy.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect()
}

/// A model with a controller state (the PID pendulum: the torque reads
/// the integral z, a coordinate after the bodies'): the pin's reaction
/// computed from the table's state, z from its column, draws the arrow
/// the run's own reaction columns draw, frame by frame (to the SVG's
/// 0.01 px), over a run in which z grows from 0 to its equilibrium; with
/// the z column removed, the states' initial values are taken and a note
/// says so. `--forces all` and the viewer run on it.
#[test]
fn force_arrows_read_the_controller_states() {
    let dir = tempfile::tempdir().unwrap();
    let scen = scenario("pid_pendulum.toml");
    let csv = run(
        dir.path(),
        &scen,
        &["output.quantities=[\"velocities\",\"reactions\"]"],
    );
    let mut r = csv::Reader::from_path(&csv).unwrap();
    let h = r.headers().unwrap().clone();
    let rows: Vec<csv::StringRecord> = r.records().map(Result::unwrap).collect();
    // the same table without some columns
    let without = |name: &str, drop: &dyn Fn(&str) -> bool| {
        let path = dir.path().join(name);
        let mut w = csv::Writer::from_path(&path).unwrap();
        let keep: Vec<usize> = (0..h.len()).filter(|&k| !drop(&h[k])).collect();
        w.write_record(keep.iter().map(|&k| &h[k])).unwrap();
        for row in &rows {
            w.write_record(keep.iter().map(|&k| &row[k])).unwrap();
        }
        w.flush().unwrap();
        path.to_str().unwrap().to_string()
    };
    let plain = without("plain.csv", &|c| c.starts_with("pin."));
    let no_z = without("no_z.csv", &|c| c.starts_with("pin.") || c == "z");
    let draw = |table: &str, name: &str| {
        let svg = dir.path().join(name);
        let o = animate(&scen, table, &svg, &["--forces", "reactions"]);
        assert!(o.status.success(), "{}", stderr(&o));
        (
            first_arrow_frames(&std::fs::read_to_string(&svg).unwrap()),
            stdout(&o),
        )
    };
    let (columns, said) = draw(&csv, "columns.svg");
    assert!(said.contains("from the run's columns"), "{said}");
    let (computed, said) = draw(&plain, "computed.svg");
    assert!(said.contains("computed from the state"), "{said}");
    assert!(!said.contains("controller state"), "{said}");
    assert_eq!(columns.len(), rows.len());
    let gap = |a: &[Vec<(f64, f64)>], b: &[Vec<(f64, f64)>]| {
        a.iter()
            .zip(b)
            .flat_map(|(f, g)| f.iter().zip(g))
            .map(|(p, q)| (p.0 - q.0).abs().max((p.1 - q.1).abs()))
            .fold(0.0, f64::max)
    };
    let d = gap(&columns, &computed);
    assert!(d <= 0.011, "computed arrow {d} px from the run's");
    // z at its initial value: the integral torque is missing from the
    // reaction, visibly
    let (initial, said) = draw(&no_z, "no_z.svg");
    assert!(said.contains("lacks a controller state's column"), "{said}");
    let d = gap(&columns, &initial);
    assert!(d > 1.0, "without z the arrow is only {d} px off");
    let png = dir.path().join("all.png");
    let o = animate(&scen, &csv, &png, &["--forces", "all", "--at", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = mbsolve(&["view", dir.path().to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
}
