//! A parser from text to the hash-consed DAG of [`crate::expr`], for force
//! laws written by users (see `docs/expressions.md`).
//!
//! Grammar (whitespace is ignored between tokens):
//!
//! ```text
//! expr    := term   (('+' | '-') term)*          left-associative
//! term    := unary  (('*' | '/') unary)*         left-associative
//! unary   := '-' unary | '+' unary | power
//! power   := atom ('^' unary)?                   right-associative: 2^3^2 = 2^9
//! atom    := number | name | name '(' arg (',' arg)* ')' | '(' expr ')'
//! arg     := expr | '[' expr (',' expr)* ']'     a list: constants only
//! number  := digits ['.' digits] [('e' | 'E') ['+' | '-'] digits]
//! name    := (letter | '_') (letter | digit | '_' | '.' | '[' digits ']')*
//! ```
//!
//! As in mathematics, `-x^2 = -(x^2)`. `a^b` is [`Ctx::pow`]: an integer
//! constant exponent of magnitude ≤ 64 is an integer power and `0.5` a
//! square root (defined for every base), any other exponent a real power
//! (`powf`: NaN for a negative base).
//!
//! Functions: `sin cos tan sqrt abs tanh sign exp log` (one argument;
//! `log` is the natural logarithm), `min max atan2 pow` (two),
//! `clamp(x, lo, hi)`, `smoothstep(x, x0, x1)` and `table(x, [x…], [y…])`
//! (three). `tan x` is built as `sin x / cos x`, `min(a, b)` as
//! `a − max(a − b, 0)` and `max(a, b)` as `a + max(b − a, 0)`,
//! `clamp(x, lo, hi)` as `max(min(x, hi), lo)`, so they
//! differentiate through the engine's rules: the non-smooth functions get
//! their piecewise derivatives — `d|a| = sign(a)·da` (so `0` at `a = 0`
//! only where `sign` is taken as Rust's `signum`, i.e. `±1` at `±0`),
//! `d max(a, b)` takes the derivative of `b` where `b > a` and of `a`
//! otherwise, `d min(a, b)` that of `b` where `a > b` and of `a` otherwise;
//! `sign` has derivative 0. `smoothstep(x, x0, x1)` is the cubic
//! `3u² − 2u³` of `u = clamp((x − x0)/(x1 − x0), 0, 1)`: 0 at `x0`, 1 at
//! `x1`, continuous first derivative. `table(x, [x₀, …], [y₀, …])`
//! interpolates linearly between the points (at least two, strictly
//! increasing abscissae) and is constant beyond the ends; its derivative
//! is the slope of the segment (the left one at a node). `atan2(y, x)` is
//! the angle of the point `(x, y)` in `(−π, π]`.
//!
//! Outside their domains `log` (of a negative number: NaN; of 0: −∞), `pow`
//! (negative base, non-integer exponent: NaN) and `sqrt` give IEEE values;
//! callers check their results (mbsolve stops a run at the first
//! non-finite force with the time and the component).
//!
//! Bounded depth: brackets, signs, exponents and function calls nest at
//! most [`MAX_NESTING`] deep in the text, and the parsed expression is at
//! most [`MAX_DEPTH`] operations deep (a longer error, never a stack
//! overflow in the parser or in the recursive differentiation after it). A
//! sum or product of more than [`BALANCE_FROM`] terms is combined as a
//! balanced tree (depth log₂ of the number of terms) instead of left to
//! right, so long flat sums stay shallow; shorter ones keep the left-to-right
//! order of rounding.
//!
//! Names are resolved by a caller-supplied resolver, which returns the node
//! for the name (a variable or any expression, e.g. a relative angle built
//! from coordinates) or `None` for an unknown name.

use crate::expr::{Ctx, Id};
use std::fmt;

/// Why a text is not an expression; `pos` is the byte offset in the text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// Byte offset of the offending token.
    pub pos: usize,
    /// What is wrong.
    pub kind: ParseErrorKind,
}

/// The kinds of [`ParseError`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ParseErrorKind {
    /// A character that starts no token.
    UnexpectedChar(char),
    /// A token where another was expected (`expected`, `found`).
    Unexpected {
        /// What the grammar allows here.
        expected: &'static str,
        /// What was found.
        found: String,
    },
    /// A malformed number literal.
    BadNumber(String),
    /// A name the resolver does not know.
    UnknownName(String),
    /// A function that does not exist.
    UnknownFunction(String),
    /// A function called with the wrong number of arguments.
    Arity {
        /// The function.
        name: String,
        /// Arguments it takes.
        expected: usize,
        /// Arguments given.
        found: usize,
    },
    /// A function argument outside what the function accepts (e.g. a
    /// table whose abscissae do not increase); the message names the
    /// function.
    BadArgument(String),
    /// Brackets, signs, exponents or calls nested deeper than
    /// [`MAX_NESTING`].
    TooNested,
    /// The parsed expression is `depth` operations deep, more than
    /// [`MAX_DEPTH`].
    TooDeep {
        /// Depth reached.
        depth: usize,
    },
}

/// Largest nesting of brackets, signs, exponents and function calls in the
/// text: 200 (the recursive descent then stays far below any thread's stack).
pub const MAX_NESTING: usize = 200;

/// Largest depth (operations on the longest path to a leaf) of a parsed
/// expression, the resolver's expressions included: 1000, so that the
/// recursive passes over it (differentiation, substitution) stay within a
/// 2 MiB thread stack.
pub const MAX_DEPTH: usize = 1000;

/// Sums and products of more terms than this are combined as a balanced
/// tree: 16.
pub const BALANCE_FROM: usize = 16;

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use ParseErrorKind::*;
        match &self.kind {
            UnexpectedChar(c) => write!(f, "unexpected character '{c}'"),
            Unexpected { expected, found } => write!(f, "expected {expected}, found {found}"),
            BadNumber(s) => write!(f, "malformed number '{s}'"),
            UnknownName(s) => write!(f, "unknown name '{s}'"),
            UnknownFunction(s) => write!(f, "unknown function '{s}'"),
            Arity {
                name,
                expected,
                found,
            } => write!(
                f,
                "function '{name}' takes {expected} argument(s), got {found}"
            ),
            BadArgument(m) => write!(f, "{m}"),
            TooNested => write!(
                f,
                "brackets, signs, exponents and calls nest deeper than the limit of {MAX_NESTING}"
            ),
            TooDeep { depth } => write!(
                f,
                "the expression is {depth} operations deep; the limit is {MAX_DEPTH}"
            ),
        }?;
        write!(f, " at {}", self.pos)
    }
}

impl std::error::Error for ParseError {}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Op(char),
    End,
}

impl Tok {
    fn describe(&self) -> String {
        match self {
            Tok::Num(v) => format!("number {v}"),
            Tok::Name(s) => format!("'{s}'"),
            Tok::Op(c) => format!("'{c}'"),
            Tok::End => "end of input".into(),
        }
    }
}

/// The length of a leading `[digits]` of `b` (an index inside a name), or
/// `None`.
fn index_len(b: &[u8]) -> Option<usize> {
    let digits = b
        .get(1..)?
        .iter()
        .take_while(|c| c.is_ascii_digit())
        .count();
    (b[0] == b'[' && digits > 0 && b.get(1 + digits) == Some(&b']')).then_some(digits + 2)
}

fn tokenize(s: &str) -> Result<Vec<(Tok, usize)>, ParseError> {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || (c == b'.' && b.get(i + 1).is_some_and(u8::is_ascii_digit))
        {
            let start = i;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                let mut j = i + 1;
                if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                    j += 1;
                }
                if j < b.len() && b[j].is_ascii_digit() {
                    i = j;
                    while i < b.len() && b[i].is_ascii_digit() {
                        i += 1;
                    }
                } else {
                    return Err(ParseError {
                        pos: start,
                        kind: ParseErrorKind::BadNumber(s[start..j.min(b.len())].into()),
                    });
                }
            }
            let text = &s[start..i];
            let v: f64 = text.parse().map_err(|_| ParseError {
                pos: start,
                kind: ParseErrorKind::BadNumber(text.into()),
            })?;
            out.push((Tok::Num(v), start));
        } else if c.is_ascii_alphabetic() || c == b'_' {
            let start = i;
            while i < b.len() {
                if b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] == b'.' {
                    i += 1;
                } else if let Some(n) = index_len(&b[i..]) {
                    // `[k]` inside a name: a numbered body (`arm.link[2].phi`)
                    i += n;
                } else {
                    break;
                }
            }
            out.push((Tok::Name(s[start..i].into()), start));
        } else if b"+-*/^(),[]".contains(&c) {
            out.push((Tok::Op(c as char), i));
            i += 1;
        } else {
            let ch = s[i..].chars().next().unwrap_or('?');
            return Err(ParseError {
                pos: i,
                kind: ParseErrorKind::UnexpectedChar(ch),
            });
        }
    }
    out.push((Tok::End, s.len()));
    Ok(out)
}

struct Parser<'a, R> {
    toks: Vec<(Tok, usize)>,
    at: usize,
    ctx: &'a mut Ctx,
    resolve: R,
    /// Current nesting of `unary` (every bracket, sign, exponent and call
    /// argument passes through it).
    nesting: usize,
}

/// One operand of a flat sum or product: `inverse` marks a subtracted term
/// or a divisor.
#[derive(Clone, Copy)]
struct Operand {
    inverse: bool,
    id: Id,
}

impl<R: FnMut(&str, &mut Ctx) -> Option<Id>> Parser<'_, R> {
    fn peek(&self) -> &Tok {
        &self.toks[self.at].0
    }
    fn pos(&self) -> usize {
        self.toks[self.at].1
    }
    fn unexpected(&self, expected: &'static str) -> ParseError {
        ParseError {
            pos: self.pos(),
            kind: ParseErrorKind::Unexpected {
                expected,
                found: self.peek().describe(),
            },
        }
    }
    fn eat(&mut self, c: char) -> bool {
        if *self.peek() == Tok::Op(c) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn expr(&mut self) -> Result<Id, ParseError> {
        let mut ops = vec![Operand {
            inverse: false,
            id: self.term()?,
        }];
        loop {
            let inverse = if self.eat('+') {
                false
            } else if self.eat('-') {
                true
            } else {
                return Ok(self.combine(ops, false));
            };
            let id = self.term()?;
            ops.push(Operand { inverse, id });
        }
    }

    fn term(&mut self) -> Result<Id, ParseError> {
        let mut ops = vec![Operand {
            inverse: false,
            id: self.unary()?,
        }];
        loop {
            let inverse = if self.eat('*') {
                false
            } else if self.eat('/') {
                true
            } else {
                return Ok(self.combine(ops, true));
            };
            let id = self.unary()?;
            ops.push(Operand { inverse, id });
        }
    }

    /// `a ± b` (sum) or `a · b`, `a / b` (product).
    fn pair(&mut self, product: bool, a: Id, b: Id, inverse: bool) -> Id {
        match (product, inverse) {
            (false, false) => self.ctx.add(a, b),
            (false, true) => self.ctx.sub(a, b),
            (true, false) => self.ctx.mul(a, b),
            (true, true) => self.ctx.div(a, b),
        }
    }

    /// The operands of a flat sum (or product) combined: left to right up to
    /// [`BALANCE_FROM`] operands, else pairwise as a balanced tree.
    fn combine(&mut self, mut ops: Vec<Operand>, product: bool) -> Id {
        if ops.len() <= BALANCE_FROM {
            let mut acc = ops[0].id;
            for o in &ops[1..] {
                acc = self.pair(product, acc, o.id, o.inverse);
            }
            return acc;
        }
        while ops.len() > 1 {
            let mut next = Vec::with_capacity(ops.len().div_ceil(2));
            for two in ops.chunks(2) {
                next.push(match *two {
                    [x, y] => match (x.inverse, y.inverse) {
                        (false, inv) => Operand {
                            inverse: false,
                            id: self.pair(product, x.id, y.id, inv),
                        },
                        (true, false) => Operand {
                            inverse: false,
                            id: self.pair(product, y.id, x.id, true),
                        },
                        (true, true) => Operand {
                            inverse: true,
                            id: self.pair(product, x.id, y.id, false),
                        },
                    },
                    [x] => x,
                    _ => unreachable!("chunks of two"),
                });
            }
            ops = next;
        }
        let last = ops[0];
        if !last.inverse {
            last.id
        } else if product {
            let one = self.ctx.one();
            self.ctx.div(one, last.id)
        } else {
            self.ctx.neg(last.id)
        }
    }

    fn unary(&mut self) -> Result<Id, ParseError> {
        if self.nesting >= MAX_NESTING {
            return Err(ParseError {
                pos: self.pos(),
                kind: ParseErrorKind::TooNested,
            });
        }
        self.nesting += 1;
        let r = self.unary_inner();
        self.nesting -= 1;
        r
    }

    fn unary_inner(&mut self) -> Result<Id, ParseError> {
        if self.eat('-') {
            let a = self.unary()?;
            Ok(self.ctx.neg(a))
        } else if self.eat('+') {
            self.unary()
        } else {
            self.power()
        }
    }

    fn power(&mut self) -> Result<Id, ParseError> {
        let base = self.atom()?;
        if !self.eat('^') {
            return Ok(base);
        }
        let e = self.unary()?;
        Ok(self.ctx.pow(base, e))
    }

    fn atom(&mut self) -> Result<Id, ParseError> {
        let pos = self.pos();
        match self.peek().clone() {
            Tok::Num(v) => {
                self.at += 1;
                Ok(self.ctx.constant(v))
            }
            Tok::Op('(') => {
                self.at += 1;
                let e = self.expr()?;
                if !self.eat(')') {
                    return Err(self.unexpected("')'"));
                }
                Ok(e)
            }
            Tok::Name(name) => {
                self.at += 1;
                if self.eat('(') {
                    let mut args = vec![self.argument()?];
                    while self.eat(',') {
                        args.push(self.argument()?);
                    }
                    if !self.eat(')') {
                        return Err(self.unexpected("',' or ')'"));
                    }
                    self.call(&name, &args, pos)
                } else {
                    (self.resolve)(&name, self.ctx).ok_or(ParseError {
                        pos,
                        kind: ParseErrorKind::UnknownName(name),
                    })
                }
            }
            _ => Err(self.unexpected("a number, a name or '('")),
        }
    }

    /// One argument of a call: an expression or a bracketed list of
    /// constant expressions (the nodes of `table`).
    fn argument(&mut self) -> Result<Arg, ParseError> {
        let pos = self.pos();
        if !self.eat('[') {
            return Ok(Arg::Expr(self.expr()?, pos));
        }
        let mut items = Vec::new();
        loop {
            let at = self.pos();
            let e = self.expr()?;
            let v = self.ctx.as_const(e).ok_or(ParseError {
                pos: at,
                kind: ParseErrorKind::BadArgument("the entries of a list must be constants".into()),
            })?;
            items.push(v);
            if self.eat(']') {
                return Ok(Arg::List(items, pos));
            }
            if !self.eat(',') {
                return Err(self.unexpected("',' or ']'"));
            }
        }
    }

    fn call(&mut self, name: &str, args: &[Arg], pos: usize) -> Result<Id, ParseError> {
        let arity = match name {
            "sin" | "cos" | "tan" | "sqrt" | "abs" | "tanh" | "sign" | "exp" | "log" => 1,
            "min" | "max" | "atan2" | "pow" => 2,
            "smoothstep" | "clamp" | "table" => 3,
            _ => {
                return Err(ParseError {
                    pos,
                    kind: ParseErrorKind::UnknownFunction(name.into()),
                })
            }
        };
        if args.len() != arity {
            return Err(ParseError {
                pos,
                kind: ParseErrorKind::Arity {
                    name: name.into(),
                    expected: arity,
                    found: args.len(),
                },
            });
        }
        let bad = |pos: usize, msg: String| ParseError {
            pos,
            kind: ParseErrorKind::BadArgument(format!("{name}: {msg}")),
        };
        if name == "table" {
            let x = match args[0] {
                Arg::Expr(x, _) => x,
                Arg::List(_, p) => {
                    return Err(bad(
                        p,
                        "the first argument is the abscissa, an expression".into(),
                    ))
                }
            };
            let (xs, ys) = match (&args[1], &args[2]) {
                (Arg::List(xs, px), Arg::List(ys, py)) => {
                    ((xs.as_slice(), *px), (ys.as_slice(), *py))
                }
                (Arg::Expr(_, p), _) | (_, Arg::Expr(_, p)) => {
                    return Err(bad(
                        *p,
                        "the abscissae and values are lists [a, b, …]".into(),
                    ))
                }
            };
            return table(self.ctx, x, xs, ys).map_err(|(p, m)| bad(p, m));
        }
        let mut ids = Vec::with_capacity(args.len());
        for a in args {
            match *a {
                Arg::Expr(id, _) => ids.push(id),
                Arg::List(_, p) => {
                    return Err(bad(p, "a list is an argument of table only".into()))
                }
            }
        }
        let c = &mut *self.ctx;
        let a = ids[0];
        Ok(match name {
            "sin" => c.sin(a),
            "cos" => c.cos(a),
            "tan" => {
                let (s, co) = (c.sin(a), c.cos(a));
                c.div(s, co)
            }
            "sqrt" => c.sqrt(a),
            "abs" => c.abs(a),
            "tanh" => c.tanh(a),
            "sign" => c.sign(a),
            "exp" => c.exp(a),
            "log" => c.ln(a),
            "atan2" => c.atan2(a, ids[1]),
            "pow" => c.pow(a, ids[1]),
            "min" => min(c, a, ids[1]),
            "max" => max(c, a, ids[1]),
            "clamp" => {
                let m = min(c, a, ids[2]);
                max(c, m, ids[1])
            }
            _ => {
                // smoothstep(x, x0, x1): u = clamp((x − x0)/(x1 − x0), 0, 1),
                // u²(3 − 2u)
                let (x0, x1) = (ids[1], ids[2]);
                if c.as_const(x0).is_some() && c.as_const(x0) == c.as_const(x1) {
                    let p = match args[2] {
                        Arg::Expr(_, p) | Arg::List(_, p) => p,
                    };
                    return Err(bad(p, "the edges x0 and x1 must differ".into()));
                }
                let num = c.sub(a, x0);
                let den = c.sub(x1, x0);
                let u = c.div(num, den);
                let one = c.one();
                let over = c.sub(u, one);
                let over = c.max0(over);
                let u = c.sub(u, over);
                let u = c.max0(u);
                let (two, three) = (c.constant(2.0), c.constant(3.0));
                let tu = c.mul(two, u);
                let f = c.sub(three, tu);
                let u2 = c.powi(u, 2);
                c.mul(u2, f)
            }
        })
    }
}

/// One argument of a call: an expression or a list of constants, with the
/// byte offset where it starts.
enum Arg {
    Expr(Id, usize),
    List(Vec<f64>, usize),
}

/// `min(a, b)` as `a − max(a − b, 0)`.
fn min(c: &mut Ctx, a: Id, b: Id) -> Id {
    let d = c.sub(a, b);
    let m = c.max0(d);
    c.sub(a, m)
}

/// `max(a, b)` as `a + max(b − a, 0)`.
fn max(c: &mut Ctx, a: Id, b: Id) -> Id {
    let d = c.sub(b, a);
    let m = c.max0(d);
    c.add(a, m)
}

/// Piecewise-linear interpolation of the points `(xs[i], ys[i])` at `x`,
/// constant beyond the ends: `y₀ + Σᵢ sᵢ (max(x − xᵢ, 0) − max(x − xᵢ₊₁, 0))`
/// with the segment slopes `sᵢ`, summed as a balanced tree. Its derivative
/// through the engine is the slope of the segment (the left one at a node).
/// Errors: `(byte offset, message)`.
fn table(
    c: &mut Ctx,
    x: Id,
    (xs, px): (&[f64], usize),
    (ys, py): (&[f64], usize),
) -> Result<Id, (usize, String)> {
    if xs.len() < 2 {
        return Err((
            px,
            format!("a table needs at least 2 points, got {}", xs.len()),
        ));
    }
    if ys.len() != xs.len() {
        return Err((
            py,
            format!("{} values for {} abscissae", ys.len(), xs.len()),
        ));
    }
    if let Some(v) = xs.iter().chain(ys).find(|v| !v.is_finite()) {
        return Err((px, format!("the entry {v} is not finite")));
    }
    if let Some(w) = xs.windows(2).find(|w| w[0] >= w[1]) {
        return Err((
            px,
            format!(
                "the abscissae must increase strictly ({} is followed by {})",
                w[0], w[1]
            ),
        ));
    }
    let ramps: Vec<Id> = xs
        .iter()
        .map(|&xi| {
            let k = c.constant(xi);
            let d = c.sub(x, k);
            c.max0(d)
        })
        .collect();
    let mut terms = vec![c.constant(ys[0])];
    for i in 0..xs.len() - 1 {
        let s = c.constant((ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i]));
        let seg = c.sub(ramps[i], ramps[i + 1]);
        terms.push(c.mul(s, seg));
    }
    while terms.len() > 1 {
        terms = terms
            .chunks(2)
            .map(|p| {
                if p.len() == 2 {
                    c.add(p[0], p[1])
                } else {
                    p[0]
                }
            })
            .collect();
    }
    Ok(terms[0])
}

/// Parse `text` into `ctx`; names are resolved by `resolve(name, ctx)`.
///
/// ```
/// use mbsolve_codegen::{parse, Ctx};
/// let mut ctx = Ctx::new();
/// let x = ctx.var("x");
/// let e = parse(&mut ctx, "-x^2 + 3*sin(x)", |n, _| (n == "x").then_some(x)).unwrap();
/// let v = ctx.eval(&[e], &[2.0])[0];
/// assert!((v - (-4.0 + 3.0 * 2f64.sin())).abs() < 1e-15);
/// ```
pub fn parse(
    ctx: &mut Ctx,
    text: &str,
    resolve: impl FnMut(&str, &mut Ctx) -> Option<Id>,
) -> Result<Id, ParseError> {
    let toks = tokenize(text)?;
    let mut p = Parser {
        toks,
        at: 0,
        ctx,
        resolve,
        nesting: 0,
    };
    let e = p.expr()?;
    if *p.peek() != Tok::End {
        return Err(p.unexpected("an operator or end of input"));
    }
    let depth = depth(p.ctx, e);
    if depth > MAX_DEPTH {
        return Err(ParseError {
            pos: 0,
            kind: ParseErrorKind::TooDeep { depth },
        });
    }
    Ok(e)
}

/// Operations on the longest path from `e` to a leaf, without recursion
/// (children are interned before their parents, so ascending ids are a
/// topological order).
fn depth(ctx: &Ctx, e: Id) -> usize {
    let order = ctx.reachable(&[e], |_| false);
    let mut depth = std::collections::HashMap::with_capacity(order.len());
    for &id in &order {
        let mut d = 0;
        ctx.node(id).for_each_child(|c| d = d.max(depth[&c] + 1));
        depth.insert(id, d);
    }
    depth[&e]
}
