//! Expressions as a hash-consed DAG with exact simplification, symbolic
//! differentiation and an interpreter.
//!
//! Every node lives in a [`Ctx`]; structurally equal nodes are interned to
//! one [`Id`] (so common subexpressions are shared by construction). Children
//! always have smaller ids than their parents, so ascending id order is a
//! topological order.
//!
//! The constructors ([`Ctx::add`], [`Ctx::mul`], …) simplify on the fly, but
//! only with rewrites that are exact in IEEE arithmetic for finite operands
//! (`x + 0`, `x · 1`, `x − x`, pushing negations outwards, folding constant
//! operations, `sign(x) · x = |x|`, …) plus `x · 0 = 0`. Commutative operands
//! are ordered canonically; association is never changed, so a simplified
//! expression evaluates to the same bits as the expression it came from
//! (up to the sign of a zero).

use std::collections::HashMap;

/// Handle of a node in a [`Ctx`].
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Debug)]
pub struct Id(pub(crate) u32);

impl Id {
    /// Position in the context (ascending = topological order).
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// One node of the DAG.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Node {
    /// A constant (bits of an `f64`; `-0.0` is stored as `0.0`).
    Const(u64),
    /// Variable number `k` (see [`Ctx::var`]).
    Var(u32),
    /// `a + b`.
    Add(Id, Id),
    /// `a − b`.
    Sub(Id, Id),
    /// `a · b`.
    Mul(Id, Id),
    /// `a / b`.
    Div(Id, Id),
    /// `−a`.
    Neg(Id),
    /// `a^n` (integer power; `n = 2` is evaluated as `a · a`).
    Powi(Id, i32),
    /// `√a`.
    Sqrt(Id),
    /// `sin a`.
    Sin(Id),
    /// `cos a`.
    Cos(Id),
    /// `|a|`.
    Abs(Id),
    /// `signum(a)` (Rust's: ±1, also at ±0).
    Sign(Id),
    /// `tanh a`.
    Tanh(Id),
    /// `max(a, 0)`.
    Max0(Id),
    /// Heaviside step: 1 for `a > 0`, else 0 (derivative of `max(a, 0)`).
    Step(Id),
    /// `b` where `a > 0`, else 0 — a guard: the other branch is never used,
    /// even when it is not finite there (e.g. `√δ` terms for `δ ≤ 0`).
    Select(Id, Id),
    /// `eᵃ`.
    Exp(Id),
    /// Natural logarithm `ln a` (NaN for `a < 0`, −∞ at 0: IEEE `ln`).
    Ln(Id),
    /// `atan2(a, b)`: the angle of the point `(b, a)` in `(−π, π]` (IEEE `atan2`).
    Atan2(Id, Id),
    /// `aᵇ` with a real exponent (IEEE `powf`: NaN for `a < 0` and a
    /// non-integer `b`).
    Pow(Id, Id),
}

impl Node {
    /// Children of the node.
    pub fn children(&self) -> ([Option<Id>; 2], usize) {
        use Node::*;
        match *self {
            Const(_) | Var(_) => ([None, None], 0),
            Add(a, b)
            | Sub(a, b)
            | Mul(a, b)
            | Div(a, b)
            | Select(a, b)
            | Atan2(a, b)
            | Pow(a, b) => ([Some(a), Some(b)], 2),
            Neg(a)
            | Powi(a, _)
            | Sqrt(a)
            | Sin(a)
            | Cos(a)
            | Abs(a)
            | Sign(a)
            | Tanh(a)
            | Max0(a)
            | Step(a)
            | Exp(a)
            | Ln(a) => ([Some(a), None], 1),
        }
    }
    /// Iterator over the children.
    pub fn for_each_child(&self, mut f: impl FnMut(Id)) {
        let (c, n) = self.children();
        for x in c.iter().take(n).flatten() {
            f(*x);
        }
    }
}

/// Description of a variable.
#[derive(Clone, Debug)]
pub struct VarInfo {
    /// Name (for messages and generated comments).
    pub name: String,
    /// Its partial derivative with respect to the time variable, for
    /// explicitly time-dependent inputs such as `f(t)` → `f'(t)`.
    pub dt: Option<Id>,
}

/// The expression context: the interned nodes and the variables.
#[derive(Clone, Debug, Default)]
pub struct Ctx {
    nodes: Vec<Node>,
    index: HashMap<Node, Id>,
    vars: Vec<VarInfo>,
    var_ids: Vec<Id>,
    time: Option<Id>,
}

fn bits(v: f64) -> u64 {
    if v == 0.0 {
        0.0f64.to_bits()
    } else {
        v.to_bits()
    }
}

impl Ctx {
    /// An empty context.
    pub fn new() -> Self {
        Self::default()
    }

    fn intern(&mut self, n: Node) -> Id {
        if let Some(&id) = self.index.get(&n) {
            return id;
        }
        let id = Id(u32::try_from(self.nodes.len()).expect("too many nodes"));
        self.nodes.push(n);
        self.index.insert(n, id);
        id
    }

    /// Number of interned nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }
    /// No nodes yet?
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
    /// The node behind an id.
    pub fn node(&self, id: Id) -> Node {
        self.nodes[id.index()]
    }
    /// Value of a constant node.
    pub fn as_const(&self, id: Id) -> Option<f64> {
        match self.node(id) {
            Node::Const(b) => Some(f64::from_bits(b)),
            _ => None,
        }
    }
    fn is_const(&self, id: Id, v: f64) -> bool {
        self.as_const(id) == Some(v)
    }
    fn neg_inner(&self, id: Id) -> Option<Id> {
        match self.node(id) {
            Node::Neg(x) => Some(x),
            _ => None,
        }
    }

    /// A constant.
    pub fn constant(&mut self, v: f64) -> Id {
        self.intern(Node::Const(bits(v)))
    }
    /// 0.
    pub fn zero(&mut self) -> Id {
        self.constant(0.0)
    }
    /// 1.
    pub fn one(&mut self) -> Id {
        self.constant(1.0)
    }

    /// A new variable.
    pub fn var(&mut self, name: impl Into<String>) -> Id {
        let k = u32::try_from(self.vars.len()).expect("too many variables");
        self.vars.push(VarInfo {
            name: name.into(),
            dt: None,
        });
        let id = self.intern(Node::Var(k));
        self.var_ids.push(id);
        id
    }
    /// Declare `v` the time variable (for `∂/∂t` of time-dependent inputs).
    pub fn set_time(&mut self, v: Id) {
        assert!(
            matches!(self.node(v), Node::Var(_)),
            "time must be a variable"
        );
        self.time = Some(v);
    }
    /// The time variable, if declared.
    pub fn time(&self) -> Option<Id> {
        self.time
    }
    /// Declare `∂v/∂t = d` for an explicitly time-dependent input `v`.
    pub fn set_time_derivative(&mut self, v: Id, d: Id) {
        match self.node(v) {
            Node::Var(k) => self.vars[k as usize].dt = Some(d),
            _ => panic!("set_time_derivative: not a variable"),
        }
    }
    /// Number of variables.
    pub fn n_vars(&self) -> usize {
        self.vars.len()
    }
    /// Variable number of a `Var` node.
    pub fn var_number(&self, id: Id) -> Option<usize> {
        match self.node(id) {
            Node::Var(k) => Some(k as usize),
            _ => None,
        }
    }
    /// Information on variable number `k`.
    pub fn var_info(&self, k: usize) -> &VarInfo {
        &self.vars[k]
    }
    /// Node of variable number `k`.
    pub fn var_id(&self, k: usize) -> Id {
        self.var_ids[k]
    }

    /// `a + b`.
    pub fn add(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x + y);
        }
        if self.is_const(a, 0.0) {
            return b;
        }
        if self.is_const(b, 0.0) {
            return a;
        }
        match (self.neg_inner(a), self.neg_inner(b)) {
            (Some(x), Some(y)) => {
                let s = self.add(x, y);
                return self.neg(s);
            }
            (None, Some(y)) => return self.sub(a, y),
            (Some(x), None) => return self.sub(b, x),
            (None, None) => {}
        }
        if a == b {
            let two = self.constant(2.0);
            return self.mul(two, a);
        }
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        self.intern(Node::Add(a, b))
    }

    /// `a − b`.
    pub fn sub(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x - y);
        }
        if self.is_const(b, 0.0) {
            return a;
        }
        if self.is_const(a, 0.0) {
            return self.neg(b);
        }
        if a == b {
            return self.zero();
        }
        if let Some(y) = self.neg_inner(b) {
            return self.add(a, y);
        }
        if let Some(x) = self.neg_inner(a) {
            let s = self.add(x, b);
            return self.neg(s);
        }
        self.intern(Node::Sub(a, b))
    }

    /// `a · b`.
    pub fn mul(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x * y);
        }
        if self.is_const(a, 0.0) || self.is_const(b, 0.0) {
            return self.zero();
        }
        if self.is_const(a, 1.0) {
            return b;
        }
        if self.is_const(b, 1.0) {
            return a;
        }
        if self.is_const(a, -1.0) {
            return self.neg(b);
        }
        if self.is_const(b, -1.0) {
            return self.neg(a);
        }
        if let Some(x) = self.neg_inner(a) {
            let p = self.mul(x, b);
            return self.neg(p);
        }
        if let Some(y) = self.neg_inner(b) {
            let p = self.mul(a, y);
            return self.neg(p);
        }
        // sign(x) · x = |x| (exact)
        if self.node(a) == Node::Sign(b) || self.node(b) == Node::Sign(a) {
            let x = if self.node(a) == Node::Sign(b) { b } else { a };
            return self.abs(x);
        }
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        self.intern(Node::Mul(a, b))
    }

    /// `a / b`.
    pub fn div(&mut self, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(x / y);
        }
        if self.is_const(b, 1.0) {
            return a;
        }
        if self.is_const(b, -1.0) {
            return self.neg(a);
        }
        if self.is_const(a, 0.0) {
            return self.zero();
        }
        if let Some(x) = self.neg_inner(a) {
            let p = self.div(x, b);
            return self.neg(p);
        }
        if let Some(y) = self.neg_inner(b) {
            let p = self.div(a, y);
            return self.neg(p);
        }
        self.intern(Node::Div(a, b))
    }

    /// `−a`.
    pub fn neg(&mut self, a: Id) -> Id {
        match self.node(a) {
            Node::Const(b) => self.constant(-f64::from_bits(b)),
            Node::Neg(x) => x,
            Node::Sub(x, y) => self.sub(y, x),
            _ => self.intern(Node::Neg(a)),
        }
    }

    /// `a^n`.
    pub fn powi(&mut self, a: Id, n: i32) -> Id {
        if n == 0 {
            return self.one();
        }
        if n == 1 {
            return a;
        }
        if let Some(x) = self.as_const(a) {
            return self.constant(eval_powi(x, n));
        }
        if let Some(x) = self.neg_inner(a) {
            let p = self.powi(x, n);
            return if n % 2 == 0 { p } else { self.neg(p) };
        }
        self.intern(Node::Powi(a, n))
    }

    /// `√a`.
    pub fn sqrt(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.sqrt());
        }
        self.intern(Node::Sqrt(a))
    }
    /// `sin a`.
    pub fn sin(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.sin());
        }
        self.intern(Node::Sin(a))
    }
    /// `cos a`.
    pub fn cos(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.cos());
        }
        self.intern(Node::Cos(a))
    }
    /// `|a|`.
    pub fn abs(&mut self, a: Id) -> Id {
        match self.node(a) {
            Node::Const(b) => self.constant(f64::from_bits(b).abs()),
            Node::Neg(x) => self.abs(x),
            Node::Abs(_) => a,
            _ => self.intern(Node::Abs(a)),
        }
    }
    /// `signum(a)`.
    pub fn sign(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.signum());
        }
        self.intern(Node::Sign(a))
    }
    /// `tanh a`.
    pub fn tanh(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.tanh());
        }
        self.intern(Node::Tanh(a))
    }
    /// `max(a, 0)`.
    pub fn max0(&mut self, a: Id) -> Id {
        match self.node(a) {
            Node::Const(b) => self.constant(f64::from_bits(b).max(0.0)),
            Node::Abs(_) | Node::Max0(_) => a,
            _ => self.intern(Node::Max0(a)),
        }
    }
    /// Heaviside step `[a > 0]`.
    pub fn step(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(if x > 0.0 { 1.0 } else { 0.0 });
        }
        self.intern(Node::Step(a))
    }

    /// `b` where `a > 0`, else 0.
    pub fn select(&mut self, a: Id, b: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return if x > 0.0 { b } else { self.zero() };
        }
        if self.is_const(b, 0.0) {
            return b;
        }
        self.intern(Node::Select(a, b))
    }

    /// `eᵃ`.
    pub fn exp(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.exp());
        }
        self.intern(Node::Exp(a))
    }
    /// Natural logarithm `ln a`.
    pub fn ln(&mut self, a: Id) -> Id {
        if let Some(x) = self.as_const(a) {
            return self.constant(x.ln());
        }
        self.intern(Node::Ln(a))
    }
    /// `atan2(a, b)`: the angle of the point `(b, a)`.
    pub fn atan2(&mut self, a: Id, b: Id) -> Id {
        if let (Some(y), Some(x)) = (self.as_const(a), self.as_const(b)) {
            return self.constant(y.atan2(x));
        }
        self.intern(Node::Atan2(a, b))
    }
    /// `aᵇ` with a real exponent. A constant exponent that is an integer of
    /// magnitude at most 64 gives [`Ctx::powi`], `0.5` gives [`Ctx::sqrt`]
    /// (both exact for every base, negative ones included); any other
    /// exponent the `powf` node (NaN for a negative base).
    pub fn pow(&mut self, a: Id, b: Id) -> Id {
        if let Some(e) = self.as_const(b) {
            if e == 0.5 {
                return self.sqrt(a);
            }
            if e.fract() == 0.0 && e.abs() <= 64.0 {
                return self.powi(a, e as i32);
            }
            if let Some(x) = self.as_const(a) {
                return self.constant(x.powf(e));
            }
        }
        self.intern(Node::Pow(a, b))
    }

    /// Sum of `terms` (left to right).
    pub fn sum(&mut self, terms: &[Id]) -> Id {
        let mut acc = self.zero();
        for &t in terms {
            acc = self.add(acc, t);
        }
        acc
    }

    /// Partial derivative `∂e/∂v` of `e` with respect to the variable `v`.
    /// When `v` is the time variable, time-dependent inputs contribute their
    /// declared derivatives ([`Ctx::set_time_derivative`]).
    pub fn diff(&mut self, e: Id, v: Id) -> Id {
        let mut memo = HashMap::new();
        self.diff_memo(e, v, &mut memo)
    }

    /// Partial derivatives of several expressions with one shared memo.
    pub fn diff_many(&mut self, es: &[Id], v: Id) -> Vec<Id> {
        let mut memo = HashMap::new();
        es.iter()
            .map(|&e| self.diff_memo(e, v, &mut memo))
            .collect()
    }

    fn diff_memo(&mut self, e: Id, v: Id, memo: &mut HashMap<Id, Id>) -> Id {
        if let Some(&d) = memo.get(&e) {
            return d;
        }
        use Node::*;
        let d = match self.node(e) {
            Const(_) => self.zero(),
            Var(k) => {
                if e == v {
                    self.one()
                } else if Some(v) == self.time {
                    match self.vars[k as usize].dt {
                        Some(d) => d,
                        None => self.zero(),
                    }
                } else {
                    self.zero()
                }
            }
            Add(a, b) => {
                let (da, db) = (self.diff_memo(a, v, memo), self.diff_memo(b, v, memo));
                self.add(da, db)
            }
            Sub(a, b) => {
                let (da, db) = (self.diff_memo(a, v, memo), self.diff_memo(b, v, memo));
                self.sub(da, db)
            }
            Mul(a, b) => {
                let (da, db) = (self.diff_memo(a, v, memo), self.diff_memo(b, v, memo));
                let l = self.mul(da, b);
                let r = self.mul(a, db);
                self.add(l, r)
            }
            Div(a, b) => {
                let (da, db) = (self.diff_memo(a, v, memo), self.diff_memo(b, v, memo));
                let l = self.div(da, b);
                let adb = self.mul(a, db);
                let bb = self.mul(b, b);
                let r = self.div(adb, bb);
                self.sub(l, r)
            }
            Neg(a) => {
                let da = self.diff_memo(a, v, memo);
                self.neg(da)
            }
            Powi(a, n) => {
                let da = self.diff_memo(a, v, memo);
                let c = self.constant(n as f64);
                let p = self.powi(a, n - 1);
                let cp = self.mul(c, p);
                self.mul(cp, da)
            }
            Sqrt(a) => {
                let da = self.diff_memo(a, v, memo);
                let two = self.constant(2.0);
                let s = self.sqrt(a);
                let den = self.mul(two, s);
                self.div(da, den)
            }
            Sin(a) => {
                let da = self.diff_memo(a, v, memo);
                let c = self.cos(a);
                self.mul(c, da)
            }
            Cos(a) => {
                let da = self.diff_memo(a, v, memo);
                let s = self.sin(a);
                let p = self.mul(s, da);
                self.neg(p)
            }
            Abs(a) => {
                let da = self.diff_memo(a, v, memo);
                let s = self.sign(a);
                self.mul(s, da)
            }
            Tanh(a) => {
                let da = self.diff_memo(a, v, memo);
                let th = self.tanh(a);
                let th2 = self.powi(th, 2);
                let one = self.one();
                let f = self.sub(one, th2);
                self.mul(f, da)
            }
            Max0(a) => {
                let da = self.diff_memo(a, v, memo);
                let s = self.step(a);
                self.mul(s, da)
            }
            Select(a, b) => {
                let db = self.diff_memo(b, v, memo);
                self.select(a, db)
            }
            Exp(a) => {
                let da = self.diff_memo(a, v, memo);
                let ea = self.exp(a);
                self.mul(ea, da)
            }
            Ln(a) => {
                let da = self.diff_memo(a, v, memo);
                self.div(da, a)
            }
            Atan2(a, b) => {
                // d atan2(a, b) = (b da − a db) / (a² + b²)
                let (da, db) = (self.diff_memo(a, v, memo), self.diff_memo(b, v, memo));
                let (l, r) = (self.mul(b, da), self.mul(a, db));
                let num = self.sub(l, r);
                let (a2, b2) = (self.powi(a, 2), self.powi(b, 2));
                let den = self.add(a2, b2);
                self.div(num, den)
            }
            Pow(a, b) => {
                // d aᵇ = b a^(b−1) da + aᵇ ln(a) db
                let (da, db) = (self.diff_memo(a, v, memo), self.diff_memo(b, v, memo));
                let one = self.one();
                let bm1 = self.sub(b, one);
                let p = self.pow(a, bm1);
                let bp = self.mul(b, p);
                let l = self.mul(bp, da);
                let r = if self.is_const(db, 0.0) {
                    db
                } else {
                    let la = self.ln(a);
                    let pl = self.mul(e, la);
                    self.mul(pl, db)
                };
                self.add(l, r)
            }
            Sign(_) | Step(_) => self.zero(),
        };
        memo.insert(e, d);
        d
    }

    /// Substitute nodes (`map`: old → new) throughout `e`, re-simplifying.
    pub fn substitute(&mut self, e: Id, map: &HashMap<Id, Id>) -> Id {
        let mut memo = map.clone();
        self.subst_memo(e, &mut memo)
    }

    fn subst_memo(&mut self, e: Id, memo: &mut HashMap<Id, Id>) -> Id {
        if let Some(&d) = memo.get(&e) {
            return d;
        }
        use Node::*;
        let r = match self.node(e) {
            Const(_) | Var(_) => e,
            Add(a, b)
            | Sub(a, b)
            | Mul(a, b)
            | Div(a, b)
            | Select(a, b)
            | Atan2(a, b)
            | Pow(a, b) => {
                let (x, y) = (self.subst_memo(a, memo), self.subst_memo(b, memo));
                match self.node(e) {
                    Add(..) => self.add(x, y),
                    Sub(..) => self.sub(x, y),
                    Mul(..) => self.mul(x, y),
                    Div(..) => self.div(x, y),
                    Atan2(..) => self.atan2(x, y),
                    Pow(..) => self.pow(x, y),
                    _ => self.select(x, y),
                }
            }
            Neg(a) => {
                let x = self.subst_memo(a, memo);
                self.neg(x)
            }
            Powi(a, n) => {
                let x = self.subst_memo(a, memo);
                self.powi(x, n)
            }
            Sqrt(a) | Sin(a) | Cos(a) | Abs(a) | Sign(a) | Tanh(a) | Max0(a) | Step(a) | Exp(a)
            | Ln(a) => {
                let x = self.subst_memo(a, memo);
                match self.node(e) {
                    Exp(_) => self.exp(x),
                    Ln(_) => self.ln(x),
                    Sqrt(_) => self.sqrt(x),
                    Sin(_) => self.sin(x),
                    Cos(_) => self.cos(x),
                    Abs(_) => self.abs(x),
                    Sign(_) => self.sign(x),
                    Tanh(_) => self.tanh(x),
                    Max0(_) => self.max0(x),
                    _ => self.step(x),
                }
            }
        };
        memo.insert(e, r);
        r
    }

    /// Nodes reachable from `roots` (sorted ascending = topological order),
    /// not descending below nodes for which `stop` returns true.
    pub fn reachable(&self, roots: &[Id], stop: impl Fn(Id) -> bool) -> Vec<Id> {
        let mut seen = vec![false; self.nodes.len()];
        let mut stack: Vec<Id> = roots.to_vec();
        let mut out = Vec::new();
        while let Some(id) = stack.pop() {
            if seen[id.index()] {
                continue;
            }
            seen[id.index()] = true;
            out.push(id);
            if !stop(id) {
                self.node(id).for_each_child(|c| stack.push(c));
            }
        }
        out.sort_unstable();
        out
    }

    /// Number of distinct operation nodes (not constants or variables)
    /// reachable from `roots`: the work after common-subexpression elimination.
    pub fn op_count(&self, roots: &[Id]) -> usize {
        self.reachable(roots, |_| false)
            .into_iter()
            .filter(|&id| !matches!(self.node(id), Node::Const(_) | Node::Var(_)))
            .count()
    }

    /// Evaluate `outputs` with variable `k` set to `vars[k]` (the interpreter).
    pub fn eval(&self, outputs: &[Id], vars: &[f64]) -> Vec<f64> {
        let order = self.reachable(outputs, |_| false);
        let mut val: HashMap<Id, f64> = HashMap::with_capacity(order.len());
        for &id in &order {
            let g = |x: Id| val[&x];
            let v = match self.node(id) {
                Node::Const(b) => f64::from_bits(b),
                Node::Var(k) => *vars.get(k as usize).unwrap_or_else(|| {
                    panic!("no value for variable {}", self.vars[k as usize].name)
                }),
                n => eval_op(n, g),
            };
            val.insert(id, v);
        }
        outputs.iter().map(|o| val[o]).collect()
    }

    /// Evaluate without sharing: every tree path recomputed (the semantics
    /// of the expression *tree*; used to check that CSE changes nothing).
    pub fn eval_tree(&self, e: Id, vars: &[f64]) -> f64 {
        match self.node(e) {
            Node::Const(b) => f64::from_bits(b),
            Node::Var(k) => vars[k as usize],
            n => eval_op(n, |x| self.eval_tree(x, vars)),
        }
    }
}

/// `x^n` exactly as the emitted code computes it.
pub fn eval_powi(x: f64, n: i32) -> f64 {
    if n == 2 {
        x * x
    } else {
        x.powi(n)
    }
}

pub(crate) fn eval_op(n: Node, mut g: impl FnMut(Id) -> f64) -> f64 {
    use Node::*;
    match n {
        Const(_) | Var(_) => unreachable!(),
        Add(a, b) => g(a) + g(b),
        Sub(a, b) => g(a) - g(b),
        Mul(a, b) => g(a) * g(b),
        Div(a, b) => g(a) / g(b),
        Neg(a) => -g(a),
        Powi(a, k) => eval_powi(g(a), k),
        Sqrt(a) => g(a).sqrt(),
        Sin(a) => g(a).sin(),
        Cos(a) => g(a).cos(),
        Abs(a) => g(a).abs(),
        Sign(a) => g(a).signum(),
        Tanh(a) => g(a).tanh(),
        Max0(a) => g(a).max(0.0),
        Step(a) => {
            if g(a) > 0.0 {
                1.0
            } else {
                0.0
            }
        }
        Select(a, b) => {
            let (c, v) = (g(a), g(b));
            if c > 0.0 {
                v
            } else {
                0.0
            }
        }
        Exp(a) => g(a).exp(),
        Ln(a) => g(a).ln(),
        Atan2(a, b) => g(a).atan2(g(b)),
        Pow(a, b) => g(a).powf(g(b)),
    }
}
