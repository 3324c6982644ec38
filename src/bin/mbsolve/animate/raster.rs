//! The raster formats of `mbsolve animate`: frames drawn with plotters,
//! a GIF with a fixed palette, an APNG, an MP4/WebM through `ffmpeg`, a
//! still PNG.

use super::*;

/// Draw output row `f` of the scene: marks, time stamp, scale bar (on a
/// white background unless `blank` says the canvas is white already).
fn draw_frame<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    s: &Scene,
    f: usize,
    blank: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let size = root.dim_in_pixel();
    let (k, off) = pixel_map(s, size);
    let px = |p: [f64; 2]| {
        (
            (off[0] + k * p[0]).round() as i32,
            (off[1] - k * p[1]).round() as i32,
        )
    };
    if !blank {
        root.fill(&WHITE)?;
    }
    if let Some(g) = &s.note.ghost {
        draw_marks(root, &s.drawing.marks(g), &px, k, true)?;
    }
    draw_marks(root, &s.drawing.marks(&s.poses[f]), &px, k, false)?;
    if let Some(a) = &s.arrows {
        draw_marks(root, &a.marks(f), &px, k, false)?;
    }
    let font = ("sans-serif", 14.0).into_font();
    root.draw(&Text::new(
        format!("t = {:.3} s", s.t[f]),
        (8, 8),
        font.clone(),
    ))?;
    if !s.note.caption.is_empty() {
        root.draw(&Text::new(s.note.caption.as_str(), (8, 28), font.clone()))?;
    }
    let (bar, label) = scale_bar(k, size.0 as f64);
    let (x0, y0) = (10, size.1 as i32 - 12);
    let x1 = x0 + (bar * k).round() as i32;
    root.draw(&PathElement::new(
        vec![(x0, y0 - 4), (x0, y0), (x1, y0), (x1, y0 - 4)],
        BLACK.stroke_width(2),
    ))?;
    root.draw(&Text::new(label, (x1 + 6, y0 - 12), font.clone()))?;
    if let Some(a) = &s.arrows {
        // the key, bottom right: an arrow of the key force and its value
        let (from, to, label) = key_geometry(a, k, size);
        let head = key_head(a, k);
        let p = |x: [f64; 2]| (x[0].round() as i32, x[1].round() as i32);
        root.draw(&PathElement::new(
            vec![p(from), p(to)],
            BLACK.stroke_width(2),
        ))?;
        root.draw(&PathElement::new(
            vec![
                p([to[0] - head, to[1] - 0.5 * head]),
                p(to),
                p([to[0] - head, to[1] + 0.5 * head]),
            ],
            BLACK.stroke_width(2),
        ))?;
        let w = 7 * label.chars().count() as i32;
        root.draw(&Text::new(label, (p(from).0 - w - 6, p(from).1 - 8), font))?;
    }
    Ok(())
}

/// Draw marks through the pixel map `px` (`k` pixels per metre); `faded`:
/// light grey outlines only (a reference pose under the motion).
fn draw_marks<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    marks: &[Mark],
    px: &dyn Fn([f64; 2]) -> (i32, i32),
    k: f64,
    faded: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let fill = RGBColor(0x56, 0xB4, 0xE9).mix(0.5);
    let ground_fill = RGBColor(0xbb, 0xbb, 0xbb);
    let faint = RGBColor(0xc8, 0xc8, 0xc8);
    let ink = |i: Ink| if faded { faint } else { ink_rgb(i) };
    for m in marks {
        match m {
            Mark::Fill { points, ink: i } => {
                let pts: Vec<(i32, i32)> = points.iter().map(|p| px(*p)).collect();
                if !faded {
                    let f = if *i == Ink::Body {
                        fill.filled()
                    } else {
                        ground_fill.filled()
                    };
                    root.draw(&Polygon::new(pts.clone(), f))?;
                }
                let mut closed = pts.clone();
                closed.push(pts[0]);
                root.draw(&PathElement::new(
                    closed,
                    ink(*i).stroke_width(ink_width(*i)),
                ))?;
            }
            Mark::Line { points, ink: i } => {
                let pts: Vec<(i32, i32)> = points.iter().map(|p| px(*p)).collect();
                root.draw(&PathElement::new(pts, ink(*i).stroke_width(ink_width(*i))))?;
            }
            Mark::Circle {
                centre,
                radius,
                ink: i,
                filled,
            } => {
                let r = ((k * radius).round() as i32).max(1);
                if *filled && !faded {
                    root.draw(&Circle::new(px(*centre), r, fill.filled()))?;
                }
                root.draw(&Circle::new(
                    px(*centre),
                    r,
                    ink(*i).stroke_width(ink_width(*i)),
                ))?;
            }
            Mark::Pin { centre } => {
                if !faded {
                    root.draw(&Circle::new(px(*centre), 4, WHITE.filled()))?;
                }
                root.draw(&Circle::new(
                    px(*centre),
                    4,
                    (if faded { faint } else { BLACK }).stroke_width(1),
                ))?;
            }
        }
    }
    Ok(())
}

/// One RGB frame of output row `f`.
fn render_rgb(s: &Scene, f: usize) -> Result<Vec<u8>, String> {
    let (w, h) = s.size;
    let mut buf = vec![255u8; 3 * w as usize * h as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw_frame(&root, s, f, true).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(buf)
}

/// The fixed GIF palette: the 6 × 6 × 6 colour cube and 40 greys.
fn palette() -> Vec<u8> {
    let mut p = Vec::with_capacity(768);
    for r in 0..6u8 {
        for g in 0..6u8 {
            for b in 0..6u8 {
                p.extend([r * 51, g * 51, b * 51]);
            }
        }
    }
    for i in 0..40u32 {
        let v = ((i + 1) * 255 / 41) as u8;
        p.extend([v, v, v]);
    }
    p
}

/// The palette index of an RGB pixel: a grey of the 40 (or the cube's
/// black/white) when the channels are within 8 of each other, else the
/// nearest cube colour.
fn quantize(c: &[u8]) -> u8 {
    let (r, g, b) = (c[0] as i32, c[1] as i32, c[2] as i32);
    let (mx, mn) = (r.max(g).max(b), r.min(g).min(b));
    let level = |v: i32| ((v + 25) / 51) as u8;
    if mx - mn <= 8 {
        let v = (r + g + b) / 3;
        if v >= 250 {
            return 215;
        }
        if v <= 3 {
            return 0;
        }
        let i = ((v * 41 + 127) / 255 - 1).clamp(0, 39);
        return 216 + i as u8;
    }
    level(r) * 36 + level(g) * 6 + level(b)
}

/// The start of an animated file: the font registered, the frames of
/// [`schedule`] at `(speed, every)` with `(min_delay, tick)`, and `path`
/// created (the error names it).
fn start(
    s: &Scene,
    path: &Path,
    (speed, every): (f64, usize),
    (min_delay, tick): (f64, f64),
) -> Result<(Vec<usize>, Vec<u32>, std::fs::File), String> {
    crate::figure::register_font();
    let (rows, delays) = schedule(&s.t, speed, min_delay, every, tick);
    let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((rows, delays, file))
}

/// The frames `rows` (delays `delays`) drawn in parallel, 64 at a time
/// (bounded memory), each image made into a frame by `frame`, and handed
/// to `write` in order with its delay.
fn frames_in_order<F: Send>(
    s: &Scene,
    rows: &[usize],
    delays: &[u32],
    frame: impl Fn(Vec<u8>, u32) -> Result<F, String> + Sync,
    mut write: impl FnMut(F, u32) -> Result<(), String>,
) -> Result<(), String> {
    for chunk in rows.iter().zip(delays).collect::<Vec<_>>().chunks(64) {
        let frames: Vec<F> = chunk
            .par_iter()
            .map(|(&r, &d)| frame(render_rgb(s, r)?, d))
            .collect::<Result<_, String>>()?;
        for (f, (_, &d)) in frames.into_iter().zip(chunk) {
            write(f, d)?;
        }
    }
    Ok(())
}

/// The GIF: frames chosen by [`schedule`], drawn and LZW-encoded in
/// parallel, written in order with a fixed global palette.
pub(super) fn write_gif(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    let (rows, delays, file) = start(s, path, (speed, every), (GIF_MIN_DELAY, GIF_TICK))?;
    let (w, h) = s.size;
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let pal = palette();
    let mut enc = gif::Encoder::new(std::io::BufWriter::new(file), w as u16, h as u16, &pal)
        .map_err(|e| err(&e))?;
    enc.set_repeat(gif::Repeat::Infinite).map_err(|e| err(&e))?;
    let frame = |rgb: Vec<u8>, d: u32| {
        let idx: Vec<u8> = rgb.chunks_exact(3).map(quantize).collect();
        let mut f = gif::Frame::from_indexed_pixels(w as u16, h as u16, &idx, None);
        f.delay = d.min(u16::MAX as u32) as u16;
        f.make_lzw_pre_encoded();
        Ok(f)
    };
    frames_in_order(s, &rows, &delays, frame, |f, _| {
        enc.write_lzw_pre_encoded_frame(&f).map_err(|e| err(&e))
    })?;
    drop(enc);
    report_schedule(s, &rows, &delays, GIF_TICK, speed, "GIF");
    Ok(())
}

/// Shortest APNG frame \[s\] (as the GIF's: browsers slow shorter ones
/// down) and its delay tick (the frame delay is ms/1000).
const APNG_MIN_DELAY: f64 = 0.02;
const APNG_TICK: f64 = 0.001;

/// The APNG: full-colour frames chosen by [`schedule`] at 1 ms delay
/// resolution, drawn in parallel (64 at a time), written in order.
pub(super) fn write_apng(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    let (rows, delays, file) = start(s, path, (speed, every), (APNG_MIN_DELAY, APNG_TICK))?;
    let (w, h) = s.size;
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_animated(rows.len() as u32, 0)
        .map_err(|e| err(&e))?;
    let mut writer = enc.write_header().map_err(|e| err(&e))?;
    frames_in_order(
        s,
        &rows,
        &delays,
        |rgb, _| Ok(rgb),
        |rgb, d| {
            // a delay beyond u16 ms (65 s) in whole seconds
            let (num, den) = if d <= u16::MAX as u32 {
                (d as u16, 1000)
            } else {
                (((d + 500) / 1000).min(u16::MAX as u32) as u16, 1)
            };
            writer.set_frame_delay(num, den).map_err(|e| err(&e))?;
            writer.write_image_data(&rgb).map_err(|e| err(&e))
        },
    )?;
    writer.finish().map_err(|e| err(&e))?;
    report_schedule(s, &rows, &delays, APNG_TICK, speed, "APNG");
    Ok(())
}

/// MP4 or WebM through `ffmpeg` on the PATH: constant frame rate (50 fps
/// at most), each frame the output row nearest its wall-clock time.
pub(super) fn write_video(s: &Scene, path: &Path, speed: f64, every: usize) -> Result<(), String> {
    use std::io::Write as _;
    crate::figure::register_font();
    let n = s.t.len();
    let span = s.t[n - 1] - s.t[0];
    let dt = if n > 1 { span / (n - 1) as f64 } else { 1.0 };
    // frame interval: a whole number of milliseconds ≥ 20 ms
    let d = ((every as f64 * dt / speed).max(VIDEO_MIN_DELAY) * 1000.0).round() / 1000.0;
    let frames = ((span / speed) / d).floor() as usize + 1;
    let fps = format!("{}/1000", (1e6 / (d * 1000.0)).round() as u64);
    let (w, h) = (s.size.0 & !1, s.size.1 & !1);
    let mut child = std::process::Command::new("ffmpeg")
        .args([
            "-loglevel",
            "error",
            "-y",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
        ])
        .args(["-s", &format!("{}x{}", s.size.0, s.size.1)])
        .args(["-framerate", &fps, "-i", "-"])
        .args(["-vf", &format!("crop={w}:{h}:0:0"), "-pix_fmt", "yuv420p"])
        .arg(path)
        .stdin(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| {
            format!(
                "{}: MP4/WebM need ffmpeg on the PATH ({e}); write a .gif or .apng instead",
                path.display()
            )
        })?;
    let mut stdin = child.stdin.take().ok_or("ffmpeg: no stdin")?;
    let mut r = 0;
    for i in 0..frames {
        let target = s.t[0] + i as f64 * d * speed;
        while r + 1 < n && (s.t[r + 1] - target).abs() <= (s.t[r] - target).abs() {
            r += 1;
        }
        let rgb = render_rgb(s, r)?;
        stdin
            .write_all(&rgb)
            .map_err(|e| format!("{}: ffmpeg: {e}", path.display()))?;
    }
    drop(stdin);
    let st = child.wait().map_err(|e| format!("ffmpeg: {e}"))?;
    if !st.success() {
        return Err(format!("{}: ffmpeg failed ({st})", path.display()));
    }
    println!(
        "video: {frames} frames of {:.0} ms; {span:.3} s of simulation at {speed}× real time play in {:.2} s",
        d * 1000.0,
        frames as f64 * d
    );
    Ok(())
}

/// A still PNG of the output time nearest to `at` (default: the last).
pub(super) fn write_png(s: &Scene, path: &Path, at: Option<f64>) -> Result<(), String> {
    crate::figure::register_font();
    let f = nearest_row(&s.t, at);
    let err = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let root = BitMapBackend::new(path, s.size).into_drawing_area();
    draw_frame(&root, s, f, false).map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_maps_pure_colours_exactly() {
        let p = palette();
        assert_eq!(p.len(), 768);
        for c in [[0u8, 0, 0], [255, 255, 255], [0, 102, 204], [136, 136, 136]] {
            let i = quantize(&c) as usize;
            let q = &p[3 * i..3 * i + 3];
            for k in 0..3 {
                assert!((q[k] as i32 - c[k] as i32).abs() <= 4, "{c:?} -> {q:?}");
            }
        }
    }
}
