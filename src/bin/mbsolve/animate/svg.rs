//! The SVG of `mbsolve animate`: one document whose marks move by SMIL
//! animations, frame times as the schedule gives them.

use super::*;

/// The SVG `points` attribute of `p` through the pixel map `px`:
/// `"x,y x,y …"` with two decimals.
fn svg_points(p: &[[f64; 2]], px: &dyn Fn([f64; 2]) -> (f64, f64)) -> String {
    p.iter()
        .map(|q| {
            let (a, b) = px(*q);
            format!("{a:.2},{b:.2}")
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// One mark as SVG, through the pixel map `px` (world or body frame).
fn svg_mark(o: &mut String, m: &Mark, px: &dyn Fn([f64; 2]) -> (f64, f64), k: f64) {
    let pts = |p: &[[f64; 2]]| svg_points(p, px);
    match m {
        Mark::Fill { points, ink } => {
            let fill = if *ink == Ink::Body {
                r##"fill="#56B4E9" fill-opacity="0.5""##
            } else {
                r##"fill="#bbbbbb""##
            };
            let _ = writeln!(
                o,
                r#"<polygon points="{}" {fill} stroke="{}" stroke-width="{}"/>"#,
                pts(points),
                ink_hex(*ink),
                ink_width(*ink)
            );
        }
        Mark::Line { points, ink } => {
            let _ = writeln!(
                o,
                r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="{}"/>"#,
                pts(points),
                ink_hex(*ink),
                ink_width(*ink)
            );
        }
        Mark::Circle {
            centre,
            radius,
            ink,
            filled,
        } => {
            let (a, b) = px(*centre);
            let fill = if *filled {
                r##"fill="#56B4E9" fill-opacity="0.5""##
            } else {
                r#"fill="none""#
            };
            let _ = writeln!(
                o,
                r#"<circle cx="{a:.2}" cy="{b:.2}" r="{:.2}" {fill} stroke="{}" stroke-width="2"/>"#,
                k * radius,
                ink_hex(*ink)
            );
        }
        Mark::Pin { centre } => {
            let (a, b) = px(*centre);
            let _ = writeln!(
                o,
                r#"<circle cx="{a:.2}" cy="{b:.2}" r="3.5" fill="white" stroke="black" stroke-width="1.5"/>"#
            );
        }
    }
}

/// The force arrows of an animated SVG: per arrow a shaft and a head
/// polyline whose points are animated over `rows` (a zero force: all
/// points at its point of application), titled with its escaped name.
fn svg_arrows(
    o: &mut String,
    a: &SceneArrows,
    rows: &[usize],
    px: &dyn Fn([f64; 2]) -> (f64, f64),
    key_times: &str,
    dur: f64,
) {
    let Some(first) = a.rows.first() else { return };
    for (j, arrow) in first.iter().enumerate() {
        if !rows.iter().any(|&r| a.key.is_visible(a.rows[r][j].force)) {
            continue; // negligible in every frame: no zero-length lines
        }
        let ink = ink_hex(arrow.kind.ink());
        let name = crate::view::escape_html(&arrow.name);
        for part in 0..2 {
            let values: Vec<String> = rows
                .iter()
                .map(|&r| {
                    let x = &a.rows[r][j];
                    let d = [
                        x.force[0] * a.key.metres_per_newton,
                        x.force[1] * a.key.metres_per_newton,
                    ];
                    match arrows::arrow_marks(x.at, d, a.head, arrow.kind.ink()).get(part) {
                        Some(Mark::Line { points, .. }) => svg_points(points, px),
                        _ => svg_points(&vec![x.at; part + 2], px),
                    }
                })
                .collect();
            let _ = writeln!(
                o,
                r#"<polyline class="force" points="{}" fill="none" stroke="{ink}" stroke-width="2"><title>{name}</title><animate attributeName="points" values="{}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/></polyline>"#,
                values[0],
                values.join(";")
            );
        }
    }
}

/// The animated SVG: static ground; per body a group of its parts whose
/// translation and rotation are animated (SMIL `animateTransform`);
/// springs and dampers as paths whose points are animated; key times at
/// the rows chosen by [`schedule`] (at most 100 per second of playback).
pub(super) fn write_svg(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    use mbsolve::drawing::Part;
    let size = s.size;
    let (k, off) = pixel_map(s, size);
    let (rows, _) = schedule(&s.t, speed, SVG_MIN_DELAY, every, 1e-3);
    let (t0, t1) = (s.t[0], s.t[*rows.last().unwrap_or(&0)]);
    let dur = ((t1 - t0) / speed).max(1e-3);
    let key_times: String = rows
        .iter()
        .map(|&r| {
            if t1 > t0 {
                format!("{:.6}", (s.t[r] - t0) / (t1 - t0))
            } else {
                "0".into()
            }
        })
        .collect::<Vec<_>>()
        .join(";");
    let world_px = |p: [f64; 2]| (off[0] + k * p[0], off[1] - k * p[1]);
    let local_px = |p: [f64; 2]| (k * p[0], -k * p[1]);
    let nb = s.drawing.bodies.len();
    let identity = vec![0.0; 3 * nb];
    // Split the parts: ground, one body, two bodies.
    let mut ground = s.drawing.clone();
    ground.parts.clear();
    let mut per_body = vec![ground.clone(); nb];
    let mut moving = ground.clone();
    for p in &s.drawing.parts {
        let carrier = match p {
            Part::Polygon { body, .. }
            | Part::Bar { body, .. }
            | Part::Disc { body, .. }
            | Part::Contact { body, .. }
            | Part::Pin { body, .. }
            | Part::Guide { body, .. } => Some(*body),
            Part::Support { .. } | Part::Ground { .. } => Some(None),
            Part::Spring(_) | Part::Damper { .. } => None,
        };
        match carrier {
            Some(None) => ground.parts.push(p.clone()),
            Some(Some(i)) => per_body[i].parts.push(p.clone()),
            None => moving.parts.push(p.clone()),
        }
    }
    let mut o = String::new();
    let _ = writeln!(
        o,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}" viewBox="0 0 {} {}">"#,
        size.0, size.1, size.0, size.1
    );
    let (bar, label) = scale_bar(k, size.0 as f64);
    let y0 = size.1 as f64 - 12.0;
    let _ = writeln!(
        o,
        r#"<rect width="100%" height="100%" fill="white"/>
<text x="8" y="18" font-family="sans-serif" font-size="13">t = {t0:.3} … {t1:.3} s ({} frames, {speed}× real time)</text>
<path d="M10,{:.1} v4 h{:.2} v-4" fill="none" stroke="black" stroke-width="2"/>
<text x="{:.1}" y="{:.1}" font-family="sans-serif" font-size="13">{label}</text>"#,
        rows.len(),
        y0 - 4.0,
        bar * k,
        16.0 + bar * k,
        y0,
    );
    if !s.note.caption.is_empty() {
        let _ = writeln!(
            o,
            r#"<text x="8" y="36" font-family="sans-serif" font-size="13">{}</text>"#,
            crate::view::escape_html(&s.note.caption)
        );
    }
    for m in ground.marks(&identity) {
        svg_mark(&mut o, &m, &world_px, k);
    }
    if let Some(g) = &s.note.ghost {
        let _ = writeln!(o, r#"<g opacity="0.3">"#);
        for m in s.drawing.marks(g) {
            svg_mark(&mut o, &m, &world_px, k);
        }
        let _ = writeln!(o, "</g>");
    }
    for (i, d) in per_body.iter().enumerate() {
        let tr: Vec<String> = rows
            .iter()
            .map(|&r| {
                let q = &s.poses[r];
                let (a, b) = world_px([q[3 * i], q[3 * i + 1]]);
                format!("{a:.3},{b:.3}")
            })
            .collect();
        let rot: Vec<String> = rows
            .iter()
            .map(|&r| format!("{:.4}", -s.poses[r][3 * i + 2].to_degrees()))
            .collect();
        let _ = writeln!(
            o,
            r#"<g transform="translate({tr0})"><animateTransform attributeName="transform" type="translate" values="{tr}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/>
<g transform="rotate({rot0})"><animateTransform attributeName="transform" type="rotate" values="{rot}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/>"#,
            // the first frame as the static pose: what a renderer without
            // SMIL animation (and the print) shows
            tr0 = tr[0].replace(',', " "),
            rot0 = rot[0],
            tr = tr.join(";"),
            rot = rot.join(";"),
        );
        for m in d.marks(&identity) {
            svg_mark(&mut o, &m, &local_px, k);
        }
        let _ = writeln!(o, "</g></g>");
    }
    // Springs and dampers: one polyline per mark, its points animated.
    let frames: Vec<Vec<Mark>> = rows.iter().map(|&r| moving.marks(&s.poses[r])).collect();
    for (j, m) in frames[0].iter().enumerate() {
        let (Mark::Line { points, ink } | Mark::Fill { points, ink }) = m else {
            continue;
        };
        let pts = |p: &[[f64; 2]]| svg_points(p, &world_px);
        let values: Vec<String> = frames
            .iter()
            .map(|f| match &f[j] {
                Mark::Line { points, .. } | Mark::Fill { points, .. } => pts(points),
                _ => String::new(),
            })
            .collect();
        let _ = writeln!(
            o,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="2"><animate attributeName="points" values="{}" keyTimes="{key_times}" dur="{dur}s" repeatCount="indefinite"/></polyline>"#,
            pts(points),
            ink_hex(*ink),
            values.join(";")
        );
    }
    if let Some(a) = &s.arrows {
        svg_arrows(&mut o, a, &rows, &world_px, &key_times, dur);
        let (from, to, label) = key_geometry(a, k, size);
        let h = key_head(a, k);
        let _ = writeln!(
            o,
            r#"<g class="force-key"><path d="M{:.2},{:.2} L{:.2},{:.2} M{:.2},{:.2} L{:.2},{:.2} L{:.2},{:.2}" fill="none" stroke="black" stroke-width="2"/>
<text x="{:.2}" y="{:.2}" font-family="sans-serif" font-size="13" text-anchor="end">{}</text></g>"#,
            from[0],
            from[1],
            to[0],
            to[1],
            to[0] - h,
            to[1] - 0.5 * h,
            to[0],
            to[1],
            to[0] - h,
            to[1] + 0.5 * h,
            from[0] - 6.0,
            from[1] + 4.0,
            crate::view::escape_html(&label)
        );
    }
    let _ = writeln!(o, "</svg>");
    std::fs::write(path, o).map_err(|e| format!("{}: {e}", path.display()))
}
