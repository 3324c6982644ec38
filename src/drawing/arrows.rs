//! Force arrows: contact forces and joint reactions at a state, as arrows
//! from their points of application, scaled with a key (one round force
//! and its arrow length). Shared by `mbsolve animate`, the mode
//! animations and the viewer, which draw the same [`Mark`]s.
//!
//! - **Contacts**: every half-plane contact ([`ForceGeometry::Wall`]) as
//!   the translational part of its generalized force, from the contact
//!   point `c − r n` of its circle (centre `c`, radius `r`, wall normal
//!   `n`); every rod corner in contact ([`WallContact::corner_states`]) as
//!   its normal force and friction, from the corner.
//! - **Reactions**: each joint's reaction on its [`ReactionMap::body`]
//!   ([`System::joint_reactions`], `−Φ_qᵀλ` on that body) with λ from the
//!   saddle-point system, eq. (5) without Baumgarte terms, at `(t, q, q̇)`;
//!   from the joint's point on that body (a revolute pin, a slider's
//!   point), or the body's centre of mass for drives and other joints. The
//!   reaction moment is not drawn.
//!
//! Arrows come in a fixed order and number for a system (one per joint
//! with a body, per half-plane contact, per rod corner), with a zero force
//! where nothing acts, so that an animation can follow each arrow.

use super::{add, mul, norm, perp, sub, world, Ink, Mark, P};
use crate::forces::{Wall, WallContact};
use crate::formulation::{Index1, Index1Options};
use crate::model::{BodyRef, ForceGeometry, ReactionMap, System};
use serde::Serialize;

/// What an arrow shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ArrowKind {
    /// A contact force on a body.
    Contact,
    /// A joint reaction on a body.
    Reaction,
}

impl ArrowKind {
    /// The ink its marks use ([`Ink::Contact`], [`Ink::Reaction`]).
    pub fn ink(self) -> Ink {
        match self {
            ArrowKind::Contact => Ink::Contact,
            ArrowKind::Reaction => Ink::Reaction,
        }
    }
}

/// One force arrow, world frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Arrow {
    /// Contact or reaction.
    pub kind: ArrowKind,
    /// The element or joint (as messages name it).
    pub name: String,
    /// Point of application \[m\].
    pub at: P,
    /// The force on the body \[N\].
    pub force: P,
}

/// Which arrows to draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ArrowSet {
    /// Contact forces.
    pub contacts: bool,
    /// Joint reactions.
    pub reactions: bool,
}

impl ArrowSet {
    /// Parse a comma-separated list of `contact`/`contacts`,
    /// `reaction`/`reactions` and `all`; the error names the bad word.
    pub fn parse(list: &str) -> Result<Self, String> {
        let mut s = ArrowSet::default();
        for w in list.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            match w {
                "contact" | "contacts" => s.contacts = true,
                "reaction" | "reactions" => s.reactions = true,
                "all" => {
                    s.contacts = true;
                    s.reactions = true;
                }
                _ => {
                    return Err(format!(
                        "'{w}' is not a kind of force arrow (contacts, reactions, all)"
                    ))
                }
            }
        }
        Ok(s)
    }
}

/// Computes the arrows of one system at any state.
pub struct ForceArrows<'a> {
    sys: &'a System,
    set: ArrowSet,
    rod_contacts: Vec<WallContact>,
    index1: Option<Index1<'a>>,
    map: ReactionMap,
    jac: Vec<f64>,
    qdd: Vec<f64>,
    reactions: Vec<f64>,
    corners: Vec<crate::forces::CornerState>,
}

impl<'a> ForceArrows<'a> {
    /// Arrows of `set` for `sys`; `rod_contacts` are the rods' wall
    /// contacts (their corners get arrows).
    pub fn new(
        sys: &'a System,
        set: ArrowSet,
        rod_contacts: &[WallContact],
    ) -> Result<Self, String> {
        let index1 = if set.reactions && sys.n_constraints() > 0 {
            // the default options: no Baumgarte terms
            Some(Index1::new(sys, Index1Options::default()).map_err(|e| e.to_string())?)
        } else {
            None
        };
        Ok(Self {
            sys,
            set,
            rod_contacts: rod_contacts.to_vec(),
            index1,
            map: sys.reaction_map(),
            jac: vec![0.0; sys.jacobian_pattern().len()],
            qdd: vec![0.0; sys.n_coords()],
            reactions: vec![0.0; 3 * sys.constraints().len()],
            corners: Vec::new(),
        })
    }

    /// The arrows at `(t, q, q̇)`, in the fixed order (module docs).
    pub fn at(&mut self, t: f64, q: &[f64], qd: &[f64]) -> Result<Vec<Arrow>, String> {
        self.at_with_reactions(t, q, qd, None)
    }

    /// [`ForceArrows::at`], with the joint reactions given where a run
    /// wrote them: `reactions` holds `(fx, fy, mz)` per constraint on its
    /// [`ReactionMap::body`], global frame, as
    /// [`System::joint_reactions`] lays them out (the run's `J.fx`, `J.fy`,
    /// `J.mz` columns, from its own multipliers — with its Baumgarte terms,
    /// if any). `None`, or a slice of another length: computed from the
    /// state (module docs).
    pub fn at_with_reactions(
        &mut self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        reactions: Option<&[f64]>,
    ) -> Result<Vec<Arrow>, String> {
        let sys = self.sys;
        let n = sys.n_coords();
        if q.len() != n || qd.len() != n {
            return Err(format!(
                "force arrows: (q, q̇) have {} and {} entries, the system {n} \
                 (3 per body, then its controller states)",
                q.len(),
                qd.len()
            ));
        }
        let given = reactions.filter(|r| r.len() == self.reactions.len());
        let mut out = Vec::new();
        if self.set.contacts {
            let mut g = vec![0.0; sys.n_coords()];
            for (i, e) in sys.forces().iter().enumerate() {
                if let ForceGeometry::Wall {
                    body,
                    point,
                    radius,
                    normal,
                    ..
                } = e.geometry()
                {
                    g.fill(0.0);
                    e.add_forces(t, q, qd, &mut g);
                    let n = mul(normal, 1.0 / norm(normal).max(1e-300));
                    out.push(Arrow {
                        kind: ArrowKind::Contact,
                        name: sys.force_label(i),
                        at: sub(world(q, Some(body), point), mul(n, radius)),
                        force: [g[3 * body], g[3 * body + 1]],
                    });
                }
            }
            for c in &self.rod_contacts {
                self.corners.clear();
                c.corner_states(q, qd, &mut self.corners);
                for corner in 0..4 {
                    let at = world(q, Some(c.body), c.corner_offset(corner));
                    let state = self.corners.iter().find(|s| s.corner == corner);
                    let force = state.map_or([0.0, 0.0], |s| {
                        let side = if s.wall == Wall::Left { 1.0 } else { -1.0 };
                        [side * s.normal_force, s.friction_force]
                    });
                    out.push(Arrow {
                        kind: ArrowKind::Contact,
                        name: format!("segment {} corner {corner}", c.segment),
                        at: state.map_or(at, |s| s.position),
                        force,
                    });
                }
            }
        }
        if self.set.reactions {
            if let Some(r) = given {
                self.reactions.copy_from_slice(r);
            } else if let Some(f) = self.index1.as_mut() {
                f.accelerations(t, q, qd, &mut self.qdd)
                    .map_err(|e| e.to_string())?;
                sys.jacobian_values(q, t, &mut self.jac);
                sys.joint_reactions(&self.map, &self.jac, f.lambda(), &mut self.reactions);
            }
            for (k, c) in sys.constraints().iter().enumerate() {
                let Some(b) = self.map.body(k) else { continue };
                // the joint's point on that body (the second side first)
                let point = c
                    .geometry()
                    .attachment_points()
                    .into_iter()
                    .rev()
                    .find_map(|p| (p.body == BodyRef::Body(b)).then_some(p.point));
                out.push(Arrow {
                    kind: ArrowKind::Reaction,
                    name: crate::model::joint_short_name(c.as_ref()).unwrap_or_else(|| c.name()),
                    at: world(q, Some(b), point.unwrap_or([0.0, 0.0])),
                    force: [self.reactions[3 * k], self.reactions[3 * k + 1]],
                });
            }
        }
        Ok(out)
    }
}

/// The arrows' scale and key: `metres_per_newton` maps a force to an arrow
/// length; the key is an arrow of `key_force` newtons (1, 2 or 5 × 10ᵏ).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ArrowKey {
    /// Arrow length per force \[m/N\].
    pub metres_per_newton: f64,
    /// The key's force \[N\].
    pub key_force: f64,
}

impl ArrowKey {
    /// The scale that draws the largest force `max_force` \[N\] at
    /// `length` \[m\] (a quarter of the model's size is a good choice),
    /// with the largest round key force not above `max_force`. `None` when
    /// no force is finite and positive.
    pub fn new(max_force: f64, length: f64) -> Option<Self> {
        (max_force.is_finite() && max_force > 0.0 && length > 0.0).then(|| Self {
            metres_per_newton: length / max_force,
            key_force: super::scale_bar(max_force),
        })
    }

    /// The key's arrow length \[m\].
    pub fn key_length(&self) -> f64 {
        self.key_force * self.metres_per_newton
    }

    /// Whether `force` \[N\] draws an arrow: at least [`VISIBLE`] of the
    /// key's length. Shorter ones (a drive's reaction of 1e-20 N beside
    /// forces of newtons) would be zero-length lines.
    pub fn is_visible(&self, force: P) -> bool {
        norm(force) * self.metres_per_newton >= VISIBLE * self.key_length()
    }

    /// The key's label in newtons: `100 N`, `0.5 N`; in exponent form
    /// outside 0.01 … 1e6 N (`2e-3 N`).
    pub fn label(&self) -> String {
        let f = self.key_force;
        if (1e-2..1e6).contains(&f) {
            format!("{} N", (f * 1e6).round() / 1e6)
        } else {
            format!("{f:e} N")
        }
    }
}

/// The marks of an arrow from `from` along `d` (world, metres): a shaft
/// and a two-stroke head of length `head` (at most 40 % of the arrow).
/// Nothing for a zero vector.
pub fn arrow_marks(from: P, d: P, head: f64, ink: Ink) -> Vec<Mark> {
    let l = norm(d);
    if !(l > 0.0 && l.is_finite()) {
        return Vec::new();
    }
    let e = mul(d, 1.0 / l);
    let tip = add(from, d);
    let h = head.min(0.4 * l);
    let back = sub(tip, mul(e, h));
    let side = mul(perp(e), 0.5 * h);
    vec![
        Mark::Line {
            points: vec![from, tip],
            ink,
        },
        Mark::Line {
            points: vec![add(back, side), tip, sub(back, side)],
            ink,
        },
    ]
}

/// The shortest arrow drawn, as a fraction of the key's length: below a
/// tenth of a pixel where the key is 100 px long.
pub const VISIBLE: f64 = 1e-3;

/// The marks of `arrows` at scale `key` (head length `head` \[m\]);
/// nothing for a force that is not [`ArrowKey::is_visible`].
pub fn marks(arrows: &[Arrow], key: &ArrowKey, head: f64) -> Vec<Mark> {
    arrows
        .iter()
        .filter(|a| key.is_visible(a.force))
        .flat_map(|a| {
            arrow_marks(
                a.at,
                mul(a.force, key.metres_per_newton),
                head,
                a.kind.ink(),
            )
        })
        .collect()
}

/// The largest force of `arrows` \[N\] (0 for none).
pub fn max_force(arrows: &[Arrow]) -> f64 {
    arrows
        .iter()
        .map(|a| norm(a.force))
        .filter(|f| f.is_finite())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constraints::Revolute;
    use crate::forces::{ContactLaw, HalfPlaneContact};
    use crate::model::{Body, SystemBuilder};

    const G: f64 = 9.81;

    /// A ball (m = 2 kg, r = 0.2 m) on the floor y = 0 through a Hertz
    /// contact (k = 1e5 N/m^1.5) at its equilibrium penetration
    /// δ = (m g / k)^(2/3), and a bob (1 kg) hanging from the ground pin
    /// (1, 1) at its local (0, 0.3), both at rest.
    fn resting() -> (System, Vec<f64>) {
        let (m, r, k) = (2.0, 0.2, 1e5);
        let delta = (m * G / k).powf(2.0 / 3.0);
        let mut b = SystemBuilder::new();
        b.add_body(Body::new("ball", m, 0.04, [0.0, r - delta, 0.0]));
        b.add_body(Body::new("bob", 1.0, 0.01, [1.0, 0.7, 0.0]));
        b.add_force(HalfPlaneContact::new(
            0,
            [0.0, 0.0],
            r,
            [0.0, 0.0],
            [0.0, 1.0],
            ContactLaw {
                stiffness: k,
                damping: 0.5,
                friction: 0.3,
                slip_velocity: 1e-3,
            },
        ));
        b.add_constraint(Revolute::new(
            "pin",
            BodyRef::Ground,
            [1.0, 1.0],
            BodyRef::Body(1),
            [0.0, 0.3],
        ));
        b.gravity([0.0, -G]);
        let sys = b.build().unwrap();
        let (q, _) = sys.initial_state();
        (sys, q)
    }

    #[test]
    fn a_state_of_another_length_is_an_error() {
        let (sys, q) = resting();
        let set = ArrowSet::parse("all").unwrap();
        let mut fa = ForceArrows::new(&sys, set, &[]).unwrap();
        let e = fa.at(0.0, &q[..3], &q[..3]).unwrap_err();
        assert!(e.contains("have 3 and 3 entries, the system 6"), "{e}");
    }

    #[test]
    fn resting_ball_and_hanging_bob_carry_their_weights() {
        let (sys, q) = resting();
        let qd = vec![0.0; q.len()];
        let set = ArrowSet::parse("contacts, reactions").unwrap();
        let mut fa = ForceArrows::new(&sys, set, &[]).unwrap();
        let arrows = fa.at(0.0, &q, &qd).unwrap();
        assert_eq!(arrows.len(), 2, "{arrows:?}");
        // the floor pushes the ball up with m g at its lowest point
        let c = &arrows[0];
        assert_eq!(c.kind, ArrowKind::Contact);
        assert!((c.force[1] - 2.0 * G).abs() < 1e-9 * 2.0 * G, "{c:?}");
        assert!(c.force[0].abs() < 1e-12, "{c:?}");
        assert!(c.at[0].abs() < 1e-15 && (c.at[1] - (q[1] - 0.2)).abs() < 1e-15);
        // the pin holds the bob with its weight, at the pin
        let p = &arrows[1];
        assert_eq!((p.kind, p.name.as_str()), (ArrowKind::Reaction, "pin"));
        assert!(
            (p.force[1] - G).abs() < 1e-12 * G && p.force[0].abs() < 1e-12,
            "{p:?}"
        );
        assert!((p.at[0] - 1.0).abs() < 1e-15 && (p.at[1] - 1.0).abs() < 1e-15);
        // drawn: the shaft runs from the point along the force, its length
        // the force times the scale; the key is the round 10 N below the
        // largest force, the largest arrow a given length
        let key = ArrowKey::new(max_force(&arrows), 0.5).unwrap();
        assert_eq!(key.key_force, 10.0);
        assert_eq!(key.label(), "10 N");
        // (the largest force is the contact's m g to 1e-9)
        assert!((key.key_length() - 0.5 * 10.0 / (2.0 * G)).abs() < 1e-9);
        let m = marks(&arrows, &key, 0.05);
        assert_eq!(m.len(), 4);
        let Mark::Line { points, ink } = &m[0] else {
            panic!("{m:?}")
        };
        assert_eq!(*ink, Ink::Contact);
        let d = sub(points[1], points[0]);
        assert_eq!(points[0], c.at);
        assert!(d[0].abs() < 1e-12 && (d[1] - 0.5).abs() < 1e-12, "{d:?}");
        let Mark::Line { points, ink } = &m[2] else {
            panic!("{m:?}")
        };
        assert_eq!(*ink, Ink::Reaction);
        let d = sub(points[1], points[0]);
        assert!((d[1] - 0.5 * G / (2.0 * G)).abs() < 1e-9, "{d:?}");
        // the head: two strokes ending at the tip, 0.05 back
        let Mark::Line { points, .. } = &m[1] else {
            panic!("{m:?}")
        };
        assert_eq!(points[1], add(c.at, [0.0, 0.5]));
        assert!((points[0][1] - (c.at[1] + 0.45)).abs() < 1e-12);
        // a zero force draws nothing; bad kinds are named
        assert!(arrow_marks([0.0, 0.0], [0.0, 0.0], 0.1, Ink::Contact).is_empty());
        let e = ArrowSet::parse("contacts,torques").unwrap_err();
        assert!(e.contains("'torques'"), "{e}");
        assert!(ArrowKey::new(0.0, 1.0).is_none());
    }

    #[test]
    fn negligible_forces_draw_no_arrow() {
        // key 10 N drawn at 0.5 m: 1e-2 N is the shortest arrow drawn
        let key = ArrowKey::new(10.0, 0.5).unwrap();
        assert_eq!(key.key_force, 10.0);
        let arrow = |f: f64| Arrow {
            name: "J".into(),
            kind: ArrowKind::Reaction,
            at: [0.0, 0.0],
            force: [0.0, f],
        };
        assert_eq!(marks(&[arrow(1e-20)], &key, 0.05).len(), 0);
        assert_eq!(marks(&[arrow(0.9e-2)], &key, 0.05).len(), 0);
        assert_eq!(marks(&[arrow(1.1e-2)], &key, 0.05).len(), 2);
        assert_eq!(marks(&[arrow(-5.0), arrow(1e-20)], &key, 0.05).len(), 2);
    }
}
