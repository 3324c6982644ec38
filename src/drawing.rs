//! A drawing of a planar multibody system: the model as [`Part`]s attached
//! to bodies or to the ground, resolved at one pose into world-space
//! [`Mark`]s (filled outlines, lines, circles, pins). One drawing model
//! serves every renderer: `mbsolve animate` draws the marks with plotters
//! or as SVG, `mbsolve view` serialises the [`Drawing`] to JSON and its
//! script resolves the same parts into the same marks on a canvas
//! (`assets/viewer.js`, a line-for-line port of [`Drawing::marks`]).
//!
//! What is drawn: bodies as their declared [`BodyShape`] or by default as
//! a bar between their two joint points, the polygon of three or more, a
//! box for a slider, a disc otherwise; revolute joints as pins; ground
//! pivots as hatched supports; translational joints as guides; point
//! spring-dampers as zig-zags (their length follows the motion) beside a
//! dashpot; half-plane contacts as their circle and the hatched wall; a
//! rod channel's walls. Sizes not given by the model (bar widths, spring
//! widths) are fractions of the model's size at its initial state.
//! Force arrows (contacts, reactions) with their key: [`arrows`].

pub mod arrows;
mod build;

use crate::model::{BodyPoint, BodyRef, ForceGeometry, JointGeometry, Slide, System};
use serde::{Deserialize, Serialize};

/// A point or vector in the plane \[m\].
pub type P = [f64; 2];

/// The declared outline of a body, in its own frame (`[[body]] shape`):
/// `{ box = [w, h] }`, `{ circle = r }`, `{ polygon = [[x, y], ...] }` or
/// `{ bar = w }`. Default (no `shape`): see the module documentation.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum BodyShape {
    /// A rectangle of width (body x) and height (body y) centred on the
    /// centre of mass \[m\].
    Box([f64; 2]),
    /// A disc of this radius about the centre of mass \[m\].
    Circle(f64),
    /// A closed outline through these body-frame points (≥ 3) \[m\].
    Polygon(Vec<[f64; 2]>),
    /// Bars of this width \[m\] between the body's joint points.
    Bar(f64),
}

impl BodyShape {
    /// Sizes finite and > 0, a polygon of at least three points.
    pub fn check(&self) -> Result<(), String> {
        let pos = |v: f64, what: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} {v} is invalid: must be finite and > 0"))
            }
        };
        match self {
            BodyShape::Box([w, h]) => pos(*w, "box width").and(pos(*h, "box height")),
            BodyShape::Circle(r) => pos(*r, "circle radius"),
            BodyShape::Bar(w) => pos(*w, "bar width"),
            BodyShape::Polygon(p) => {
                if p.len() < 3 {
                    Err(format!(
                        "a polygon needs at least 3 points, got {}",
                        p.len()
                    ))
                } else if p.iter().flatten().any(|v| !v.is_finite()) {
                    Err("a polygon point is not finite".into())
                } else {
                    Ok(())
                }
            }
        }
    }
}

/// One element of the drawing, attached to a body (`Some(index)`, points
/// in its frame) or to the ground (`None`, global points). Serialised with
/// a `kind` tag for the viewer.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Part {
    /// A filled closed outline.
    Polygon {
        /// Carrier.
        body: Option<usize>,
        /// Outline points.
        points: Vec<P>,
    },
    /// A filled bar of `width` from `a` to `b` (ends extended by width/2).
    Bar {
        /// Carrier.
        body: Option<usize>,
        /// One end.
        a: P,
        /// Other end.
        b: P,
        /// Width \[m\].
        width: f64,
    },
    /// A filled disc.
    Disc {
        /// Carrier.
        body: Option<usize>,
        /// Centre.
        centre: P,
        /// Radius \[m\].
        radius: f64,
    },
    /// A contact circle (outline) of a half-plane contact.
    Contact {
        /// Carrier.
        body: Option<usize>,
        /// Centre.
        centre: P,
        /// Radius \[m\] (0: a point, drawn as a small cross).
        radius: f64,
    },
    /// A revolute joint's pin (a ring of fixed pixel size).
    Pin {
        /// Carrier.
        body: Option<usize>,
        /// Pin point.
        at: P,
    },
    /// A ground pivot: a triangle from the point towards `down` on a
    /// hatched base.
    Support {
        /// Pivot point, global.
        at: P,
        /// Triangle height \[m\].
        size: f64,
        /// Unit direction from the pivot into the support (`[0, −1]`: the
        /// support under the pivot; chosen away from the pinned body).
        down: P,
    },
    /// A fixed line with hatching on the side opposite `normal` (walls,
    /// the ground under a guide).
    Ground {
        /// One end, global.
        a: P,
        /// Other end, global.
        b: P,
        /// Unit normal into the free side.
        normal: P,
        /// Hatch spacing and length \[m\].
        hatch: f64,
    },
    /// A slider guide: two lines parallel to `axis` at ±gap/2 through
    /// `point`, from `from` to `to` along the axis.
    Guide {
        /// Carrier of the axis.
        body: Option<usize>,
        /// Point of the axis.
        point: P,
        /// Unit axis.
        axis: P,
        /// Start along the axis from `point` \[m\].
        from: f64,
        /// End along the axis from `point` \[m\].
        to: f64,
        /// Distance of the two lines \[m\].
        gap: f64,
    },
    /// A spring between two body points: a zig-zag.
    Spring(Span),
    /// A dashpot between two body points: a cylinder on the first, a
    /// piston on the second.
    Damper {
        /// Where it is drawn (`width`: the cylinder's).
        #[serde(flatten)]
        span: Span,
        /// Length at which the piston sits mid-cylinder \[m\].
        rest: f64,
    },
}

/// The line of a spring or dashpot between two body points, its width and
/// its sideways offset (beside the other of the same element).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Span {
    /// First body.
    pub body_i: Option<usize>,
    /// Point on it.
    pub a: P,
    /// Second body.
    pub body_j: Option<usize>,
    /// Point on it.
    pub b: P,
    /// Width \[m\].
    pub width: f64,
    /// Sideways offset \[m\].
    pub offset: f64,
}

impl Span {
    /// The two end points, global, at `q`.
    fn ends(&self, q: &[f64]) -> (P, P) {
        (world(q, self.body_i, self.a), world(q, self.body_j, self.b))
    }
}

/// How a mark is inked; each renderer maps these to the same colours
/// (Okabe–Ito: bodies blue, springs vermilion, dampers green, contacts
/// purple, reactions orange, ground grey).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Ink {
    /// Body fill and outline.
    Body,
    /// Ground lines and supports.
    Ground,
    /// Hatching.
    Hatch,
    /// Springs.
    Spring,
    /// Dampers.
    Damper,
    /// Contact circles and contact force arrows.
    Contact,
    /// Joint reaction arrows.
    Reaction,
}

/// A resolved, world-space mark.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Mark {
    /// A filled, outlined closed polygon.
    Fill {
        /// Points, world.
        points: Vec<P>,
        /// Ink.
        ink: Ink,
    },
    /// A polyline.
    Line {
        /// Points, world.
        points: Vec<P>,
        /// Ink.
        ink: Ink,
    },
    /// A circle (outline only unless `filled`).
    Circle {
        /// Centre, world.
        centre: P,
        /// Radius \[m\].
        radius: f64,
        /// Ink.
        ink: Ink,
        /// Filled.
        filled: bool,
    },
    /// A pin: a ring of fixed pixel size.
    Pin {
        /// Centre, world.
        centre: P,
    },
}

/// The drawing of a system: its parts, its bodies' names and the world
/// box its motion covers (after [`Drawing::fit`]).
#[derive(Debug, Clone, Serialize)]
pub struct Drawing {
    /// Body names, by index.
    pub bodies: Vec<String>,
    /// The parts, drawn in order (ground first, then bodies, then
    /// elements, then pins).
    pub parts: Vec<Part>,
    /// Size of the model at its initial state \[m\] (the diagonal of the
    /// box of its bodies' and joints' points).
    pub scale: f64,
    /// World box `[x_min, y_min, x_max, y_max]` of every mark over the
    /// motion \[m\].
    pub bounds: [f64; 4],
    #[serde(skip)]
    pending: Vec<Pending>,
}

/// Ground parts whose extent depends on the motion.
#[derive(Debug, Clone)]
enum Pending {
    /// A rod channel's wall at x.
    ChannelWall(f64),
    /// A half-plane wall (point, normal).
    Wall(P, P),
    /// A guide on the ground: point, axis, gap and the sliding body point.
    GroundGuide(P, P, f64, usize, P),
}

fn add(a: P, b: P) -> P {
    [a[0] + b[0], a[1] + b[1]]
}
fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1]]
}
fn mul(a: P, k: f64) -> P {
    [a[0] * k, a[1] * k]
}
fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
fn norm(a: P) -> f64 {
    a[0].hypot(a[1])
}
/// The left normal of a.
fn perp(a: P) -> P {
    [-a[1], a[0]]
}

/// `r + R(φ) s` for body `b` of the pose `q` (3 coordinates per body);
/// `s` itself for the ground.
pub fn world(q: &[f64], body: Option<usize>, s: P) -> P {
    body.map_or(BodyRef::Ground, BodyRef::Body).point_at(q, s)
}

fn carrier(b: BodyRef) -> Option<usize> {
    match b {
        BodyRef::Ground => None,
        BodyRef::Body(i) => Some(i),
    }
}

/// The zig-zag of a spring from `a` to `b` (world), `width` wide, shifted
/// sideways by `offset`: straight ends of 10 % and 15 %, six turns.
pub fn zigzag(a: P, b: P, width: f64, offset: f64) -> Vec<P> {
    let d = sub(b, a);
    let len = norm(d).max(1e-300);
    let e = mul(d, 1.0 / len);
    let n = perp(e);
    let at = |u: f64, side: f64| add(add(a, mul(e, u * len)), mul(n, offset + side));
    let mut p = vec![a, at(0.1, -offset), at(0.1, 0.0), at(0.25, 0.0)];
    let turns = 12;
    for k in 1..turns {
        let u = 0.25 + 0.5 * k as f64 / turns as f64;
        let side = if k % 2 == 1 { 0.5 } else { -0.5 } * width;
        p.push(at(u, side));
    }
    p.extend([at(0.75, 0.0), at(0.9, 0.0), at(0.9, -offset), b]);
    p
}

/// The dashpot from `a` (cylinder) to `b` (piston), world, as four
/// polylines: the lead and one cylinder wall, the other wall, the piston
/// plate, the piston rod. The piston sits mid-cylinder at length `rest`
/// and moves with the length.
pub fn dashpot(a: P, b: P, width: f64, offset: f64, rest: f64) -> [Vec<P>; 4] {
    let d = sub(b, a);
    let len = norm(d).max(1e-300);
    let e = mul(d, 1.0 / len);
    let n = perp(e);
    let at = |u: f64, side: f64| add(add(a, mul(e, u)), mul(n, offset + side));
    let base = 0.15 * len.min(rest);
    let lead = 0.5 * base;
    let cyl = 0.5 * rest;
    let h = 0.5 * width;
    let s = (base + 0.5 * cyl + (len - rest)).clamp(base + 0.05 * cyl, base + cyl);
    let end = (len - lead).max(s);
    [
        vec![
            a,
            at(lead, -offset),
            at(lead, 0.0),
            at(base, 0.0),
            at(base, -h),
            at(base + cyl, -h),
        ],
        vec![at(base, 0.0), at(base, h), at(base + cyl, h)],
        vec![at(s, 0.8 * h), at(s, -0.8 * h)],
        vec![at(s, 0.0), at(end, 0.0), at(end, -offset), b],
    ]
}

impl Drawing {
    /// The box of the marks at pose `q` (pins and hatching excluded).
    fn frame_bounds(&self, q: &[f64]) -> [f64; 4] {
        let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        let mut grow = |p: P| {
            b[0] = b[0].min(p[0]);
            b[1] = b[1].min(p[1]);
            b[2] = b[2].max(p[0]);
            b[3] = b[3].max(p[1]);
        };
        for m in self.marks(q) {
            match m {
                Mark::Fill { points, .. } | Mark::Line { points, .. } => {
                    points.into_iter().for_each(&mut grow)
                }
                Mark::Circle { centre, radius, .. } => {
                    grow(add(centre, [radius, radius]));
                    grow(sub(centre, [radius, radius]));
                }
                Mark::Pin { centre } => grow(centre),
            }
        }
        b
    }

    /// Fit the drawing to a motion (poses of all bodies, 3 coordinates per
    /// body each): the bounds cover every pose (at most 400 sampled), and
    /// the ground parts that span the motion (walls, ground guides) are
    /// sized to it. Call once, before drawing.
    pub fn fit<'a>(&mut self, poses: impl ExactSizeIterator<Item = &'a [f64]> + Clone) {
        let n = poses.len();
        let stride = n.div_ceil(400).max(1);
        let mut b = self.bounds;
        let mut slide: Vec<(f64, f64)> = vec![(f64::MAX, f64::MIN); self.pending.len()];
        for (k, q) in poses.enumerate() {
            for (s, p) in slide.iter_mut().zip(&self.pending) {
                if let Pending::GroundGuide(pt, axis, _, j, sj) = p {
                    let u = dot(sub(world(q, Some(*j), *sj), *pt), *axis);
                    *s = (s.0.min(u), s.1.max(u));
                }
            }
            if k % stride == 0 || k + 1 == n {
                let f = self.frame_bounds(q);
                b = [
                    b[0].min(f[0]),
                    b[1].min(f[1]),
                    b[2].max(f[2]),
                    b[3].max(f[3]),
                ];
            }
        }
        let m = 0.05 * self.scale;
        let hatch = 0.025 * self.scale;
        for (p, s) in std::mem::take(&mut self.pending).into_iter().zip(slide) {
            match p {
                Pending::ChannelWall(x) => {
                    let normal = if x <= 0.5 * (b[0] + b[2]) {
                        [1.0, 0.0]
                    } else {
                        [-1.0, 0.0]
                    };
                    self.parts.insert(
                        0,
                        Part::Ground {
                            a: [x, b[1] - m],
                            b: [x, b[3] + m],
                            normal,
                            hatch,
                        },
                    );
                    b[0] = b[0].min(x - hatch);
                    b[2] = b[2].max(x + hatch);
                }
                Pending::Wall(pt, nrm) => {
                    let nrm = mul(nrm, 1.0 / norm(nrm).max(1e-300));
                    let t = perp(nrm);
                    // the wall's stretch beside the motion's box
                    let corners = [[b[0], b[1]], [b[2], b[1]], [b[0], b[3]], [b[2], b[3]]];
                    let us = corners.map(|c| dot(sub(c, pt), t));
                    let (u0, u1) = (
                        us.iter().cloned().fold(f64::MAX, f64::min) - m,
                        us.iter().cloned().fold(f64::MIN, f64::max) + m,
                    );
                    let (a, e) = (add(pt, mul(t, u0)), add(pt, mul(t, u1)));
                    self.parts.insert(
                        0,
                        Part::Ground {
                            a,
                            b: e,
                            normal: nrm,
                            hatch,
                        },
                    );
                    for q in [a, e, sub(a, mul(nrm, hatch)), sub(e, mul(nrm, hatch))] {
                        b = [
                            b[0].min(q[0]),
                            b[1].min(q[1]),
                            b[2].max(q[0]),
                            b[3].max(q[1]),
                        ];
                    }
                }
                Pending::GroundGuide(point, axis, gap, ..) => {
                    let half = 0.5 * 0.12 * self.scale + m;
                    let (from, to) = if s.0 <= s.1 {
                        (s.0 - half, s.1 + half)
                    } else {
                        (-half, half)
                    };
                    self.parts.insert(
                        0,
                        Part::Guide {
                            body: None,
                            point,
                            axis,
                            from,
                            to,
                            gap,
                        },
                    );
                    let n = perp(axis);
                    for u in [from, to] {
                        for side in [-0.5, 0.5] {
                            let q = add(add(point, mul(axis, u)), mul(n, side * gap));
                            b = [
                                b[0].min(q[0]),
                                b[1].min(q[1]),
                                b[2].max(q[0]),
                                b[3].max(q[1]),
                            ];
                        }
                    }
                }
            }
        }
        self.bounds = b;
    }

    /// The marks of the drawing at pose `q` (3 coordinates per body), in
    /// drawing order.
    pub fn marks(&self, q: &[f64]) -> Vec<Mark> {
        let mut out = Vec::with_capacity(self.parts.len() + 4);
        for part in &self.parts {
            match part {
                Part::Polygon { body, points } => out.push(Mark::Fill {
                    points: points.iter().map(|p| world(q, *body, *p)).collect(),
                    ink: Ink::Body,
                }),
                Part::Bar { body, a, b, width } => {
                    let (a, b) = (world(q, *body, *a), world(q, *body, *b));
                    let d = sub(b, a);
                    let l = norm(d);
                    let e = if l > 0.0 { mul(d, 1.0 / l) } else { [1.0, 0.0] };
                    let (e, n) = (mul(e, 0.5 * width), mul(perp(e), 0.5 * width));
                    out.push(Mark::Fill {
                        points: vec![
                            sub(sub(a, e), n),
                            sub(add(b, e), n),
                            add(add(b, e), n),
                            add(sub(a, e), n),
                        ],
                        ink: Ink::Body,
                    });
                }
                Part::Disc {
                    body,
                    centre,
                    radius,
                } => {
                    let c = world(q, *body, *centre);
                    out.push(Mark::Circle {
                        centre: c,
                        radius: *radius,
                        ink: Ink::Body,
                        filled: true,
                    });
                    // a spoke, so that rotation shows
                    out.push(Mark::Line {
                        points: vec![c, world(q, *body, add(*centre, [*radius, 0.0]))],
                        ink: Ink::Body,
                    });
                }
                Part::Contact {
                    body,
                    centre,
                    radius,
                } => {
                    let c = world(q, *body, *centre);
                    if *radius > 0.0 {
                        out.push(Mark::Circle {
                            centre: c,
                            radius: *radius,
                            ink: Ink::Contact,
                            filled: false,
                        });
                    } else {
                        let h = 0.015 * self.scale;
                        out.push(Mark::Line {
                            points: vec![sub(c, [h, h]), add(c, [h, h])],
                            ink: Ink::Contact,
                        });
                        out.push(Mark::Line {
                            points: vec![add(c, [-h, h]), add(c, [h, -h])],
                            ink: Ink::Contact,
                        });
                    }
                }
                Part::Pin { body, at } => out.push(Mark::Pin {
                    centre: world(q, *body, *at),
                }),
                Part::Support { at, size, down } => {
                    let (h, w) = (*size, 0.6 * size);
                    let base = add(*at, mul(*down, h));
                    let side = perp(*down);
                    out.push(Mark::Fill {
                        points: vec![*at, add(base, mul(side, -w)), add(base, mul(side, w))],
                        ink: Ink::Ground,
                    });
                    hatched(
                        &mut out,
                        add(base, mul(side, -1.6 * w)),
                        add(base, mul(side, 1.6 * w)),
                        mul(*down, -1.0),
                        0.4 * h,
                    );
                }
                Part::Ground {
                    a,
                    b,
                    normal,
                    hatch,
                } => hatched(&mut out, *a, *b, *normal, *hatch),
                Part::Guide {
                    body,
                    point,
                    axis,
                    from,
                    to,
                    gap,
                } => {
                    let n = perp(*axis);
                    for side in [-0.5, 0.5] {
                        let p0 = add(add(*point, mul(*axis, *from)), mul(n, side * gap));
                        let p1 = add(add(*point, mul(*axis, *to)), mul(n, side * gap));
                        let (w0, w1) = (world(q, *body, p0), world(q, *body, p1));
                        if body.is_none() {
                            // hatched away from the slot
                            let nw = mul(n, if side < 0.0 { 1.0 } else { -1.0 });
                            hatched(&mut out, w0, w1, nw, 0.02 * self.scale);
                        } else {
                            out.push(Mark::Line {
                                points: vec![w0, w1],
                                ink: Ink::Ground,
                            });
                        }
                    }
                }
                Part::Spring(s) => {
                    let (a, b) = s.ends(q);
                    out.push(Mark::Line {
                        points: zigzag(a, b, s.width, s.offset),
                        ink: Ink::Spring,
                    })
                }
                Part::Damper { span, rest } => {
                    let (a, b) = span.ends(q);
                    for points in dashpot(a, b, span.width, span.offset, *rest) {
                        out.push(Mark::Line {
                            points,
                            ink: Ink::Damper,
                        });
                    }
                }
            }
        }
        out
    }
}

/// A line from `a` to `b` with hatch strokes of length `h` every `h` on
/// the side opposite `normal`.
fn hatched(out: &mut Vec<Mark>, a: P, b: P, normal: P, h: f64) {
    out.push(Mark::Line {
        points: vec![a, b],
        ink: Ink::Ground,
    });
    let d = sub(b, a);
    let l = norm(d);
    if h.is_nan() || h <= 0.0 || l <= 0.0 {
        return;
    }
    let e = mul(d, 1.0 / l);
    let k = ((l / h).floor() as usize).min(2000);
    for i in 0..=k {
        let p = add(a, mul(e, i as f64 * h));
        out.push(Mark::Line {
            points: vec![p, add(p, add(mul(normal, -h), mul(e, -0.6 * h)))],
            ink: Ink::Hatch,
        });
    }
}

/// A round length for a scale bar at most `max` long: 1, 2 or 5 × 10ᵏ \[m\].
pub fn scale_bar(max: f64) -> f64 {
    if !(max.is_finite() && max > 0.0) {
        return 1.0;
    }
    let e = 10f64.powf(max.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * e)
        .find(|&v| v <= max)
        .unwrap_or(e)
}

/// The world → pixel map of a canvas of `size` px showing `bounds`: equal
/// scales, y up, the box filling 88 % of the tighter side, centred.
/// Returns (px per m, pixel position of the world origin).
pub fn view(bounds: [f64; 4], size: (f64, f64)) -> (f64, P) {
    let (w, h) = size;
    let span = [
        (bounds[2] - bounds[0]).max(1e-9),
        (bounds[3] - bounds[1]).max(1e-9),
    ];
    let k = 0.88 * (w / span[0]).min(h / span[1]);
    (
        k,
        [
            0.5 * w - k * 0.5 * (bounds[0] + bounds[2]),
            0.5 * h + k * 0.5 * (bounds[1] + bounds[3]),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zigzag_spans_its_ends_at_any_length() {
        for l in [0.1, 1.0, 3.0] {
            let z = zigzag([1.0, 2.0], [1.0 + l, 2.0], 0.2, 0.0);
            assert_eq!(z[0], [1.0, 2.0]);
            assert_eq!(*z.last().unwrap(), [1.0 + l, 2.0]);
            let wmax = z.iter().map(|p| (p[1] - 2.0).abs()).fold(0.0, f64::max);
            assert!((wmax - 0.1).abs() < 1e-12, "half width {wmax}");
            // monotone along the axis: the zig-zag follows the length
            assert!(z.windows(2).all(|w| w[1][0] >= w[0][0] - 1e-12));
        }
    }

    #[test]
    fn scale_bar_is_round_and_fits() {
        assert_eq!(scale_bar(0.37), 0.2);
        assert_eq!(scale_bar(1.0), 1.0);
        assert_eq!(scale_bar(7.0), 5.0);
        assert_eq!(scale_bar(0.012), 0.01);
    }

    #[test]
    fn shape_check_names_the_bad_value() {
        assert!(BodyShape::Box([0.1, 0.2]).check().is_ok());
        let e = BodyShape::Circle(-1.0).check().unwrap_err();
        assert!(e.contains("-1"), "{e}");
        assert!(BodyShape::Polygon(vec![[0.0, 0.0]; 2]).check().is_err());
    }
}
