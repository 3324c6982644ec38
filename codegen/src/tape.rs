//! A flat instruction tape for fast, allocation-free run-time evaluation of a
//! set of expressions (for instance user force laws and their symbolic
//! partial derivatives, see [`mod@crate::parse`]).
//!
//! [`Tape::new`] walks the nodes reachable from the outputs once, in
//! ascending id order (a topological order, and after the hash-consing every
//! common subexpression is one node, so it is computed once), and assigns
//! each a slot; constants are stored in their slots at compile time.
//! [`Tape::eval`] copies the variables into their slots and runs the
//! instructions in order — no hashing, no allocation — computing exactly
//! what [`Ctx::eval`] computes, bit for bit (same operations in the same
//! order).

use crate::expr::{eval_op, Ctx, Id, Node};

/// A compiled set of expressions; see the module documentation.
#[derive(Clone, Debug)]
pub struct Tape {
    /// Instructions: destination slot and the operation, whose children are
    /// slot numbers (stored as [`Id`]s).
    ops: Vec<(u32, Node)>,
    /// `(variable number, slot)` for every variable the outputs use.
    vars: Vec<(u32, u32)>,
    /// Slot of each output.
    outputs: Vec<u32>,
    /// Values of all slots (constants preset).
    slots: Vec<f64>,
    /// Number of variables of the context (the length `eval` expects).
    n_vars: usize,
}

impl Tape {
    /// Compile `outputs` of `ctx`.
    pub fn new(ctx: &Ctx, outputs: &[Id]) -> Self {
        let order = ctx.reachable(outputs, |_| false);
        let mut slot_of = vec![u32::MAX; ctx.len()];
        for (s, id) in order.iter().enumerate() {
            slot_of[id.index()] = s as u32;
        }
        let remap = |x: Id| Id(slot_of[x.index()]);
        let mut slots = vec![0.0; order.len()];
        let (mut ops, mut vars) = (Vec::new(), Vec::new());
        for (s, &id) in order.iter().enumerate() {
            use Node::*;
            let n = match ctx.node(id) {
                Const(b) => {
                    slots[s] = f64::from_bits(b);
                    continue;
                }
                Var(k) => {
                    vars.push((k, s as u32));
                    continue;
                }
                Add(a, b) => Add(remap(a), remap(b)),
                Sub(a, b) => Sub(remap(a), remap(b)),
                Mul(a, b) => Mul(remap(a), remap(b)),
                Div(a, b) => Div(remap(a), remap(b)),
                Select(a, b) => Select(remap(a), remap(b)),
                Neg(a) => Neg(remap(a)),
                Powi(a, k) => Powi(remap(a), k),
                Sqrt(a) => Sqrt(remap(a)),
                Sin(a) => Sin(remap(a)),
                Cos(a) => Cos(remap(a)),
                Abs(a) => Abs(remap(a)),
                Sign(a) => Sign(remap(a)),
                Tanh(a) => Tanh(remap(a)),
                Max0(a) => Max0(remap(a)),
                Step(a) => Step(remap(a)),
                Exp(a) => Exp(remap(a)),
                Ln(a) => Ln(remap(a)),
                Atan2(a, b) => Atan2(remap(a), remap(b)),
                Pow(a, b) => Pow(remap(a), remap(b)),
            };
            ops.push((s as u32, n));
        }
        Tape {
            ops,
            vars,
            outputs: outputs.iter().map(|o| slot_of[o.index()]).collect(),
            slots,
            n_vars: ctx.n_vars(),
        }
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.outputs.len()
    }

    /// Number of instructions (operations after common-subexpression
    /// elimination; equals [`Ctx::op_count`] of the outputs).
    pub fn n_ops(&self) -> usize {
        self.ops.len()
    }

    /// Evaluate with variable `k` set to `vars[k]`, writing output `i` to
    /// `out[i]`. Allocation-free.
    ///
    /// # Panics
    /// If `vars` is shorter than the context's variable count or `out`
    /// shorter than [`Tape::n_outputs`] (caller sizes, fixed at set-up).
    pub fn eval(&mut self, vars: &[f64], out: &mut [f64]) {
        assert!(vars.len() >= self.n_vars && out.len() >= self.outputs.len());
        for &(k, s) in &self.vars {
            self.slots[s as usize] = vars[k as usize];
        }
        for &(s, n) in &self.ops {
            let slots = &self.slots;
            let v = eval_op(n, |x| slots[x.index()]);
            self.slots[s as usize] = v;
        }
        for (o, &s) in out.iter_mut().zip(&self.outputs) {
            *o = self.slots[s as usize];
        }
    }
}
