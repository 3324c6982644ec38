//! Building a [`Drawing`] from a system: the parts of every body, joint,
//! force element and wall, sized from the initial pose.

use super::*;

impl Drawing {
    /// The drawing of `system` with body outlines `shapes` (by body index;
    /// `None` or missing: the default), rod channel walls at
    /// `channel_walls` (x \[m\]), sized from the pose `q0`.
    pub fn new(
        system: &System,
        q0: &[f64],
        shapes: &[Option<BodyShape>],
        channel_walls: &[f64],
    ) -> Drawing {
        let nb = system.bodies().len();
        let mut joints: Vec<Vec<P>> = vec![Vec::new(); nb];
        let mut sliders = vec![false; nb];
        let mut pins: Vec<(Option<usize>, P)> = Vec::new();
        let mut pts: Vec<P> = (0..nb).map(|i| world(q0, Some(i), [0.0; 2])).collect();
        let push = |v: &mut Vec<P>, p: P| {
            if !v.iter().any(|q| norm(sub(*q, p)) < 1e-12) {
                v.push(p)
            }
        };
        for c in system.constraints() {
            let g = c.geometry();
            for p in g.attachment_points() {
                pts.push(p.at(q0));
                if let BodyRef::Body(i) = p.body {
                    push(&mut joints[i], p.point);
                }
            }
            match g {
                JointGeometry::Revolute { i, j } => {
                    // one pin per joint, on the second body (or the first
                    // when the second is the ground)
                    pins.push(match j.body {
                        BodyRef::Body(b) => (Some(b), j.point),
                        BodyRef::Ground => (carrier(i.body), i.point),
                    });
                }
                JointGeometry::Translational(Slide {
                    j:
                        BodyPoint {
                            body: BodyRef::Body(j),
                            ..
                        },
                    ..
                }) => sliders[j] = true,
                _ => {}
            }
        }
        let mut geoms = Vec::new();
        for f in system.forces() {
            let g = f.geometry();
            match g {
                ForceGeometry::PointToPoint { i, j, .. } => {
                    pts.push(i.at(q0));
                    pts.push(j.at(q0));
                }
                ForceGeometry::Wall {
                    body,
                    point,
                    radius,
                    ..
                } => {
                    let c = world(q0, Some(body), point);
                    pts.push(add(c, [radius, radius]));
                    pts.push(sub(c, [radius, radius]));
                }
                ForceGeometry::Other => continue,
            }
            geoms.push(g);
        }
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for p in &pts {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let scale = if pts.is_empty() {
            1.0
        } else {
            let s = norm(sub(hi, lo));
            if s > 1e-9 {
                s
            } else {
                1.0
            }
        };
        let mut d = Drawing {
            bodies: system.bodies().iter().map(|b| b.name.clone()).collect(),
            parts: Vec::new(),
            scale,
            bounds: [0.0; 4],
            pending: channel_walls
                .iter()
                .map(|&x| Pending::ChannelWall(x))
                .collect(),
        };
        let slider_box = [0.12 * scale, 0.07 * scale];
        // Bodies.
        for i in 0..nb {
            let js = &joints[i];
            let body = Some(i);
            let shape = shapes.get(i).cloned().flatten();
            let bar = |a: P, b: P, width: f64| Part::Bar { body, a, b, width };
            let polygon_of = |js: &[P]| {
                let c = js.iter().fold([0.0, 0.0], |a, q| add(a, *q));
                let c = mul(c, 1.0 / js.len() as f64);
                let mut p = js.to_vec();
                p.sort_by(|a, b| {
                    (a[1] - c[1])
                        .atan2(a[0] - c[0])
                        .total_cmp(&(b[1] - c[1]).atan2(b[0] - c[0]))
                });
                p
            };
            match shape {
                Some(BodyShape::Box([w, h])) => d.parts.push(Part::Polygon {
                    body,
                    points: vec![
                        [-0.5 * w, -0.5 * h],
                        [0.5 * w, -0.5 * h],
                        [0.5 * w, 0.5 * h],
                        [-0.5 * w, 0.5 * h],
                    ],
                }),
                Some(BodyShape::Circle(r)) => d.parts.push(Part::Disc {
                    body,
                    centre: [0.0; 2],
                    radius: r,
                }),
                Some(BodyShape::Polygon(points)) => d.parts.push(Part::Polygon { body, points }),
                Some(BodyShape::Bar(w)) => match js.len() {
                    0 => d.parts.push(Part::Disc {
                        body,
                        centre: [0.0; 2],
                        radius: 0.5 * w,
                    }),
                    1 => d.parts.push(bar(js[0], mul(js[0], -1.0), w)),
                    2 => d.parts.push(bar(js[0], js[1], w)),
                    _ => {
                        let p = polygon_of(js);
                        for k in 0..p.len() {
                            d.parts.push(bar(p[k], p[(k + 1) % p.len()], w));
                        }
                    }
                },
                None => {
                    let w = 0.03 * scale;
                    let at_cm = js.iter().all(|p| norm(*p) < 1e-12);
                    if sliders[i] && at_cm {
                        d.parts.push(Part::Polygon {
                            body,
                            points: vec![
                                [-0.5 * slider_box[0], -0.5 * slider_box[1]],
                                [0.5 * slider_box[0], -0.5 * slider_box[1]],
                                [0.5 * slider_box[0], 0.5 * slider_box[1]],
                                [-0.5 * slider_box[0], 0.5 * slider_box[1]],
                            ],
                        })
                    } else {
                        match js.len() {
                            0 => d.parts.push(Part::Disc {
                                body,
                                centre: [0.0; 2],
                                radius: 0.04 * scale,
                            }),
                            1 if at_cm => d.parts.push(Part::Disc {
                                body,
                                centre: [0.0; 2],
                                radius: 0.04 * scale,
                            }),
                            1 => d.parts.push(bar(js[0], mul(js[0], -1.0), w)),
                            2 => d.parts.push(bar(js[0], js[1], w)),
                            _ => d.parts.push(Part::Polygon {
                                body,
                                points: polygon_of(js),
                            }),
                        }
                    }
                }
            }
        }
        // Joints' ground parts and guides.
        for c in system.constraints() {
            match c.geometry() {
                JointGeometry::Revolute {
                    i:
                        BodyPoint {
                            body: BodyRef::Ground,
                            point: p,
                        },
                    j: BodyPoint { body: other, .. },
                }
                | JointGeometry::Revolute {
                    j:
                        BodyPoint {
                            body: BodyRef::Ground,
                            point: p,
                        },
                    i: BodyPoint { body: other, .. },
                } => {
                    // the support points away from the pinned body's
                    // centre at the initial pose, along the nearer axis
                    // (a body hanging from the pin gets its support above)
                    let away =
                        carrier(other).map_or([0.0, -1.0], |b| sub(p, [q0[3 * b], q0[3 * b + 1]]));
                    let down = if away[0].abs() <= 1e-12 * scale && away[1].abs() <= 1e-12 * scale {
                        [0.0, -1.0]
                    } else if away[0].abs() > away[1].abs() {
                        [away[0].signum(), 0.0]
                    } else {
                        [0.0, away[1].signum()]
                    };
                    d.parts.insert(
                        0,
                        Part::Support {
                            at: p,
                            size: 0.05 * scale,
                            down,
                        },
                    )
                }
                JointGeometry::Translational(slide) => {
                    let axis = mul(slide.u_i, 1.0 / norm(slide.u_i).max(1e-300));
                    let gap = slider_box[1] * 1.3;
                    let (i, j) = (slide.i, slide.j);
                    match (i.body, j.body) {
                        (BodyRef::Ground, BodyRef::Body(b)) => d
                            .pending
                            .push(Pending::GroundGuide(i.point, axis, gap, b, j.point)),
                        (BodyRef::Body(_), _) => d.parts.push(Part::Guide {
                            body: carrier(i.body),
                            point: i.point,
                            axis,
                            from: -0.25 * scale,
                            to: 0.25 * scale,
                            gap,
                        }),
                        _ => {}
                    }
                }
                _ => {}
            }
        }
        // Force elements.
        for g in geoms {
            match g {
                ForceGeometry::PointToPoint {
                    i,
                    j,
                    free_length,
                    spring,
                    damper,
                } => {
                    let (a, b) = (i.point, j.point);
                    let (bi, bj) = (carrier(i.body), carrier(j.body));
                    let l0 = norm(sub(world(q0, bj, b), world(q0, bi, a)));
                    // a ground end: a short hatched anchor across the element
                    for (end, other, body) in [(a, world(q0, bj, b), bi), (b, world(q0, bi, a), bj)]
                    {
                        if body.is_none() {
                            let dir = sub(other, end);
                            let n = if norm(dir) > 0.0 {
                                mul(dir, 1.0 / norm(dir))
                            } else {
                                [0.0, -1.0]
                            };
                            let t = mul(perp(n), 0.04 * scale);
                            d.parts.insert(
                                0,
                                Part::Ground {
                                    a: sub(end, t),
                                    b: add(end, t),
                                    normal: n,
                                    hatch: 0.02 * scale,
                                },
                            );
                        }
                    }
                    let width = (0.05 * scale)
                        .min(0.3 * l0.max(free_length))
                        .max(1e-3 * scale);
                    let off = if spring && damper { 0.6 * width } else { 0.0 };
                    let span = Span {
                        body_i: bi,
                        a,
                        body_j: bj,
                        b,
                        width,
                        offset: off,
                    };
                    if spring || !damper {
                        d.parts.push(Part::Spring(span));
                    }
                    if damper {
                        d.parts.push(Part::Damper {
                            span: Span {
                                width: 0.8 * width,
                                offset: -off,
                                ..span
                            },
                            rest: if l0 > 0.0 {
                                l0
                            } else {
                                free_length.max(0.1 * scale)
                            },
                        });
                    }
                }
                ForceGeometry::Wall {
                    body,
                    point,
                    radius,
                    wall_point,
                    normal,
                } => {
                    d.parts.push(Part::Contact {
                        body: Some(body),
                        centre: point,
                        radius,
                    });
                    d.pending.push(Pending::Wall(wall_point, normal));
                }
                ForceGeometry::Other => {}
            }
        }
        for (body, at) in pins {
            d.parts.push(Part::Pin { body, at });
        }
        d.bounds = d.frame_bounds(q0);
        d
    }
}
