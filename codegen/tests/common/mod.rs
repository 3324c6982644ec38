//! Shared helpers: a small deterministic RNG, random expression trees and
//! a mixed test topology.
#![allow(dead_code)]

use mbsolve_codegen::{Ctx, ForceKind, Id, JointKind, Side, Topology};

/// xorshift64*.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [a, b).
    pub fn uniform(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// A plain expression tree, evaluated directly in f64 (the reference).
#[derive(Clone, Debug)]
pub enum Tree {
    C(f64),
    V(usize),
    Add(Box<Tree>, Box<Tree>),
    Sub(Box<Tree>, Box<Tree>),
    Mul(Box<Tree>, Box<Tree>),
    Div(Box<Tree>, Box<Tree>),
    Neg(Box<Tree>),
    Powi(Box<Tree>, i32),
    Sqrt(Box<Tree>),
    Sin(Box<Tree>),
    Cos(Box<Tree>),
    Abs(Box<Tree>),
    Tanh(Box<Tree>),
    Max0(Box<Tree>),
}

impl Tree {
    pub fn eval(&self, x: &[f64]) -> f64 {
        use Tree::*;
        match self {
            C(c) => *c,
            V(k) => x[*k],
            Add(a, b) => a.eval(x) + b.eval(x),
            Sub(a, b) => a.eval(x) - b.eval(x),
            Mul(a, b) => a.eval(x) * b.eval(x),
            Div(a, b) => a.eval(x) / b.eval(x),
            Neg(a) => -a.eval(x),
            Powi(a, n) => {
                let v = a.eval(x);
                if *n == 2 {
                    v * v
                } else {
                    v.powi(*n)
                }
            }
            Sqrt(a) => a.eval(x).sqrt(),
            Sin(a) => a.eval(x).sin(),
            Cos(a) => a.eval(x).cos(),
            Abs(a) => a.eval(x).abs(),
            Tanh(a) => a.eval(x).tanh(),
            Max0(a) => a.eval(x).max(0.0),
        }
    }
    /// Does every intermediate value stay finite?
    pub fn all_finite(&self, x: &[f64]) -> bool {
        use Tree::*;
        let kids_ok = match self {
            C(_) | V(_) => true,
            Add(a, b) | Sub(a, b) | Mul(a, b) | Div(a, b) => a.all_finite(x) && b.all_finite(x),
            Neg(a) | Powi(a, _) | Sqrt(a) | Sin(a) | Cos(a) | Abs(a) | Tanh(a) | Max0(a) => {
                a.all_finite(x)
            }
        };
        kids_ok && self.eval(x).is_finite()
    }
    pub fn build(&self, c: &mut Ctx, vars: &[Id]) -> Id {
        use Tree::*;
        match self {
            C(v) => c.constant(*v),
            V(k) => vars[*k],
            Add(a, b) => {
                let (a, b) = (a.build(c, vars), b.build(c, vars));
                c.add(a, b)
            }
            Sub(a, b) => {
                let (a, b) = (a.build(c, vars), b.build(c, vars));
                c.sub(a, b)
            }
            Mul(a, b) => {
                let (a, b) = (a.build(c, vars), b.build(c, vars));
                c.mul(a, b)
            }
            Div(a, b) => {
                let (a, b) = (a.build(c, vars), b.build(c, vars));
                c.div(a, b)
            }
            Neg(a) => {
                let a = a.build(c, vars);
                c.neg(a)
            }
            Powi(a, n) => {
                let a = a.build(c, vars);
                c.powi(a, *n)
            }
            Sqrt(a) => {
                let a = a.build(c, vars);
                c.sqrt(a)
            }
            Sin(a) => {
                let a = a.build(c, vars);
                c.sin(a)
            }
            Cos(a) => {
                let a = a.build(c, vars);
                c.cos(a)
            }
            Abs(a) => {
                let a = a.build(c, vars);
                c.abs(a)
            }
            Tanh(a) => {
                let a = a.build(c, vars);
                c.tanh(a)
            }
            Max0(a) => {
                let a = a.build(c, vars);
                c.max0(a)
            }
        }
    }
}

/// A random smooth-ish tree of depth ≤ `depth` over `nv` variables, with
/// the patterns the simplifier rewrites (x+0, x·1, x·0, x−x, −−x, constants)
/// sprinkled in. Division and sqrt get safe (positive) operands.
pub fn random_tree(r: &mut Rng, depth: usize, nv: usize, smooth: bool) -> Tree {
    use Tree::*;
    if depth == 0 || r.below(5) == 0 {
        return match r.below(4) {
            0 => C([0.0, 1.0, -1.0, 2.0, 0.5, -3.25][r.below(6)]),
            _ => V(r.below(nv)),
        };
    }
    let sub = |r: &mut Rng| Box::new(random_tree(r, depth - 1, nv, smooth));
    match r.below(18) {
        0 | 1 => Add(sub(r), sub(r)),
        2 | 3 => Sub(sub(r), sub(r)),
        4 | 5 => Mul(sub(r), sub(r)),
        6 => {
            // a / (1.5 + b²)
            let b = sub(r);
            Div(
                sub(r),
                Box::new(Add(Box::new(C(1.5)), Box::new(Powi(b, 2)))),
            )
        }
        7 => Neg(sub(r)),
        8 => Powi(sub(r), [2, 3, -1, 4][r.below(4)]),
        9 => {
            let b = sub(r);
            Sqrt(Box::new(Add(Box::new(C(0.5)), Box::new(Powi(b, 2)))))
        }
        10 | 11 => Sin(sub(r)),
        12 | 13 => Cos(sub(r)),
        14 => Tanh(sub(r)),
        15 => {
            // the exact-simplification patterns
            let a = sub(r);
            match r.below(6) {
                0 => Add(a, Box::new(C(0.0))),
                1 => Mul(Box::new(C(1.0)), a),
                2 => Add(Box::new(Mul(a.clone(), Box::new(C(0.0)))), sub(r)),
                3 => Add(Box::new(Sub(a.clone(), a)), sub(r)),
                4 => Neg(Box::new(Neg(a))),
                _ => Mul(Box::new(Add(Box::new(C(2.0)), Box::new(C(0.5)))), a),
            }
        }
        16 if !smooth => Abs(sub(r)),
        17 if !smooth => Max0(sub(r)),
        _ => Mul(sub(r), sub(r)),
    }
}

/// Relative difference with an absolute floor.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1.0)
}

/// Three bodies with every joint kind (ground and body–body revolutes,
/// translational to a body and to the ground, an angle drive) and spring,
/// drag forces; the tests add what they need on top.
pub fn mixed_topology(name: &str) -> Topology {
    Topology::new(name, 3)
        .revolute("A", Side::Ground, Side::Body(0))
        .revolute("B", Side::Body(0), Side::Body(1))
        .joint("S", JointKind::Translational, Side::Body(1), Side::Body(2))
        .joint("P", JointKind::Translational, Side::Ground, Side::Body(2))
        .joint("D", JointKind::DriveAngle, Side::Body(0), Side::Body(2))
        .force(
            "k01",
            ForceKind::TorsionalSpringDamper,
            Side::Body(0),
            Side::Body(1),
        )
        .force(
            "k2",
            ForceKind::TorsionalSpringDamper,
            Side::Ground,
            Side::Body(2),
        )
        .force("drag", ForceKind::Drag, Side::Body(1), Side::Ground)
}
