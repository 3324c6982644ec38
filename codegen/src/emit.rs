//! Emission of plain Rust from expression DAGs.
//!
//! A [`Block`] turns a set of outputs into straight-line Rust statements:
//! every node shared by more than one parent (or output) becomes one `let`
//! (common-subexpression elimination), single-use nodes are inlined, and a
//! `sin a` / `cos a` pair becomes one `let (s, c) = a.sin_cos();`. Inputs are
//! bound to Rust expressions (e.g. `q[3]`), and any node can be bound, which
//! is how precomputed values (the sines and cosines carried along a chain
//! loop) enter a kernel. The association of every operation is kept exactly
//! (parentheses follow the tree), so the emitted code computes the same bits
//! as [`Ctx::eval`].

use crate::expr::{Ctx, Id, Node};
use std::collections::{HashMap, HashSet};
use std::fmt::Write;

/// How an output is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Store {
    /// `dest = value;`
    Assign,
    /// `dest += value;` (a zero value emits nothing).
    AddAssign,
}

/// A Rust literal for `v` (shortest round-trip form).
pub fn literal(v: f64) -> String {
    if v.is_nan() {
        "f64::NAN".into()
    } else if v.is_infinite() {
        if v > 0.0 {
            "f64::INFINITY".into()
        } else {
            "f64::NEG_INFINITY".into()
        }
    } else {
        let s = format!("{v:?}");
        if s.contains(['.', 'e', 'E']) {
            s
        } else {
            format!("{s}.0")
        }
    }
}

/// Straight-line code for a set of outputs sharing one CSE scope.
#[derive(Debug)]
pub struct Block<'c> {
    ctx: &'c Ctx,
    indent: String,
    bound: HashMap<Id, String>,
    names: HashMap<Id, String>,
    uses: HashMap<Id, u32>,
    pair_of: HashMap<Id, Id>,
    prepared: bool,
    code: String,
    n_ops: usize,
}

const ATOM: u8 = 4;
const UNARY: u8 = 3;
const MUL: u8 = 2;
const ADD: u8 = 1;

impl<'c> Block<'c> {
    /// A block whose lines are indented by `indent` spaces.
    pub fn new(ctx: &'c Ctx, indent: usize) -> Self {
        Self {
            ctx,
            indent: " ".repeat(indent),
            bound: HashMap::new(),
            names: HashMap::new(),
            uses: HashMap::new(),
            pair_of: HashMap::new(),
            prepared: false,
            code: String::new(),
            n_ops: 0,
        }
    }

    /// Bind node `id` (a variable, or any precomputed node) to the Rust
    /// expression `expr`, which must be an atom (a name, `a[3]`, `(…)`).
    pub fn bind(&mut self, id: Id, expr: impl Into<String>) -> &mut Self {
        assert!(!self.prepared, "bind before prepare");
        self.bound.insert(id, expr.into());
        self
    }

    /// Is `id` bound?
    pub fn is_bound(&self, id: Id) -> bool {
        self.bound.contains_key(&id)
    }

    /// Count uses over all the outputs that will be stored (call once, with
    /// every output of the block, before [`Block::store`]).
    pub fn prepare(&mut self, outputs: &[Id]) {
        assert!(!self.prepared, "prepare called twice");
        self.prepared = true;
        let bound = &self.bound;
        let reach = self.ctx.reachable(outputs, |id| bound.contains_key(&id));
        for &o in outputs {
            *self.uses.entry(o).or_insert(0) += 1;
        }
        let mut sin_of = HashMap::new();
        let mut cos_of = HashMap::new();
        for &id in &reach {
            if self.bound.contains_key(&id) {
                continue;
            }
            let node = self.ctx.node(id);
            node.for_each_child(|c| *self.uses.entry(c).or_insert(0) += 1);
            if let Node::Powi(a, 2) = node {
                // rendered as `a * a`: a must be computed once
                *self.uses.entry(a).or_insert(0) += 1;
            }
            match node {
                Node::Sin(a) => {
                    sin_of.insert(a, id);
                }
                Node::Cos(a) => {
                    cos_of.insert(a, id);
                }
                _ => {}
            }
        }
        for (a, s) in sin_of {
            if let Some(&c) = cos_of.get(&a) {
                self.pair_of.insert(s, c);
                self.pair_of.insert(c, s);
            }
        }
    }

    fn needs_let(&self, id: Id) -> bool {
        if self.bound.contains_key(&id) {
            return false;
        }
        match self.ctx.node(id) {
            Node::Const(_) | Node::Var(_) => false,
            Node::Step(_) | Node::Select(..) => true,
            _ => self.pair_of.contains_key(&id) || self.uses.get(&id).copied().unwrap_or(0) > 1,
        }
    }

    /// Emit the `let`s that `id` needs and have not been emitted yet.
    fn ensure(&mut self, id: Id) {
        let bound = &self.bound;
        let names = &self.names;
        let order = self
            .ctx
            .reachable(&[id], |x| bound.contains_key(&x) || names.contains_key(&x));
        for x in order {
            if self.names.contains_key(&x) || !self.needs_let(x) {
                continue;
            }
            let node = self.ctx.node(x);
            if let Some(&other) = self.pair_of.get(&x) {
                let (s, c) = match node {
                    Node::Sin(_) => (x, other),
                    _ => (other, x),
                };
                let arg = match self.ctx.node(s) {
                    Node::Sin(a) => a,
                    _ => unreachable!(),
                };
                let (a, _) = self.inline(arg, ATOM);
                let (sn, cn) = (format!("s{}", s.0), format!("c{}", c.0));
                let _ = writeln!(
                    self.code,
                    "{}let ({sn}, {cn}) = {a}.sin_cos();",
                    self.indent
                );
                self.n_ops += 2;
                self.names.insert(s, sn);
                self.names.insert(c, cn);
                continue;
            }
            let e = self.render(node);
            let name = format!("t{}", x.0);
            let _ = writeln!(self.code, "{}let {name} = {e};", self.indent);
            self.n_ops += 1;
            self.names.insert(x, name);
        }
    }

    /// `(text, precedence)` of a node as a sub-expression.
    fn expr(&mut self, id: Id) -> (String, u8) {
        if let Some(b) = self.bound.get(&id) {
            return (b.clone(), ATOM);
        }
        if let Some(n) = self.names.get(&id) {
            return (n.clone(), ATOM);
        }
        match self.ctx.node(id) {
            Node::Const(b) => {
                let v = f64::from_bits(b);
                let p = if v.is_sign_negative() { UNARY } else { ATOM };
                (literal(v), p)
            }
            Node::Var(k) => panic!(
                "emit: variable '{}' is not bound to an input",
                self.ctx.var_info(k as usize).name
            ),
            n => {
                self.n_ops += 1;
                let p = prec(n);
                (self.render(n), p)
            }
        }
    }

    /// Sub-expression, parenthesised unless its precedence is at least `min`.
    fn inline(&mut self, id: Id, min: u8) -> (String, u8) {
        let (s, p) = self.expr(id);
        if p < min {
            (format!("({s})"), ATOM)
        } else {
            (s, p)
        }
    }

    fn render(&mut self, n: Node) -> String {
        use Node::*;
        match n {
            Add(a, b) => {
                let (x, _) = self.inline(a, ADD);
                let (y, _) = self.inline(b, MUL);
                format!("{x} + {y}")
            }
            Sub(a, b) => {
                let (x, _) = self.inline(a, ADD);
                let (y, _) = self.inline(b, MUL);
                format!("{x} - {y}")
            }
            Mul(a, b) => {
                let (x, _) = self.inline(a, MUL);
                let (y, _) = self.inline(b, UNARY);
                format!("{x} * {y}")
            }
            Div(a, b) => {
                let (x, _) = self.inline(a, MUL);
                let (y, _) = self.inline(b, UNARY);
                format!("{x} / {y}")
            }
            Neg(a) => {
                let (x, _) = self.inline(a, ATOM);
                format!("-{x}")
            }
            Powi(a, 2) => {
                let (x, _) = self.inline(a, UNARY);
                format!("{x} * {x}")
            }
            Powi(a, k) => {
                let (x, _) = self.inline(a, ATOM);
                format!("{x}.powi({k})")
            }
            Sqrt(a) => self.method(a, "sqrt()"),
            Sin(a) => self.method(a, "sin()"),
            Cos(a) => self.method(a, "cos()"),
            Abs(a) => self.method(a, "abs()"),
            Sign(a) => self.method(a, "signum()"),
            Tanh(a) => self.method(a, "tanh()"),
            Max0(a) => self.method(a, "max(0.0)"),
            Exp(a) => self.method(a, "exp()"),
            Ln(a) => self.method(a, "ln()"),
            Atan2(a, b) => {
                let (y, _) = self.inline(b, 0);
                self.method(a, &format!("atan2({y})"))
            }
            Pow(a, b) => {
                let (y, _) = self.inline(b, 0);
                self.method(a, &format!("powf({y})"))
            }
            Step(a) => {
                let (x, _) = self.inline(a, ADD);
                format!("if {x} > 0.0 {{ 1.0 }} else {{ 0.0 }}")
            }
            Select(a, b) => {
                let (x, _) = self.inline(a, ADD);
                let (y, _) = self.inline(b, 0);
                format!("if {x} > 0.0 {{ {y} }} else {{ 0.0 }}")
            }
            Const(_) | Var(_) => unreachable!(),
        }
    }

    fn method(&mut self, a: Id, m: &str) -> String {
        let (x, _) = self.inline(a, ATOM);
        format!("{x}.{m}")
    }

    /// Store output `id` into `dest` (after the `let`s it needs).
    pub fn store(&mut self, dest: &str, id: Id, how: Store) {
        assert!(self.prepared, "prepare before store");
        let zero = self.ctx.as_const(id) == Some(0.0);
        if how == Store::AddAssign && zero {
            return;
        }
        self.ensure(id);
        let (op, id) = match (how, self.ctx.node(id)) {
            (Store::AddAssign, Node::Neg(x)) if !self.names.contains_key(&id) => ("-=", x),
            (Store::AddAssign, _) => ("+=", id),
            (Store::Assign, _) => ("=", id),
        };
        let (e, _) = self.expr(id);
        let _ = writeln!(self.code, "{}{dest} {op} {e};", self.indent);
    }

    /// Bind the result of an output to a fresh name instead of storing it
    /// (e.g. a value the surrounding template needs).
    pub fn let_value(&mut self, name: &str, id: Id) {
        assert!(self.prepared, "prepare before let_value");
        self.ensure(id);
        let (e, _) = self.expr(id);
        let _ = writeln!(self.code, "{}let {name} = {e};", self.indent);
    }

    /// Append a raw line (indented).
    pub fn line(&mut self, s: &str) {
        let _ = writeln!(self.code, "{}{s}", self.indent);
    }

    /// Floating-point operations emitted so far (each `sin_cos` counts 2).
    pub fn n_ops(&self) -> usize {
        self.n_ops
    }

    /// The emitted statements.
    pub fn finish(self) -> String {
        self.code
    }

    /// Bound inputs that the block's outputs actually read.
    pub fn used_bindings(&self, outputs: &[Id]) -> HashSet<Id> {
        let bound = &self.bound;
        self.ctx
            .reachable(outputs, |id| bound.contains_key(&id))
            .into_iter()
            .filter(|id| bound.contains_key(id))
            .collect()
    }
}

fn prec(n: Node) -> u8 {
    use Node::*;
    match n {
        Add(..) | Sub(..) => ADD,
        Mul(..) | Div(..) => MUL,
        Powi(_, 2) => MUL,
        Neg(_) => UNARY,
        Step(_) | Select(..) => 0,
        _ => ATOM,
    }
}
