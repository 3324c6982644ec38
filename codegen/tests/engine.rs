//! The symbolic engine: interning, simplification, differentiation, CSE.

mod common;
use common::{random_tree, rel, Rng};
use mbsolve_codegen::{Ctx, Node};

fn vars(c: &mut Ctx, n: usize) -> Vec<mbsolve_codegen::Id> {
    (0..n).map(|k| c.var(format!("x{k}"))).collect()
}

#[test]
fn interning_shares_structurally_equal_nodes() {
    let mut c = Ctx::new();
    let v = vars(&mut c, 2);
    let a = c.sin(v[0]);
    let b = c.sin(v[0]);
    assert_eq!(a, b);
    let s1 = c.add(v[0], v[1]);
    let s2 = c.add(v[1], v[0]);
    assert_eq!(s1, s2, "commutative operands are ordered canonically");
    let p1 = c.mul(s1, a);
    let p2 = c.mul(a, s2);
    assert_eq!(p1, p2);
    let n = c.len();
    let _ = c.mul(s2, b);
    assert_eq!(c.len(), n, "no new node for an existing expression");
}

#[test]
fn exact_simplifications() {
    let mut c = Ctx::new();
    let v = vars(&mut c, 2);
    let (x, y) = (v[0], v[1]);
    let z = c.zero();
    let one = c.one();
    assert_eq!(c.add(x, z), x);
    assert_eq!(c.mul(x, one), x);
    assert_eq!(c.mul(x, z), z);
    assert_eq!(c.sub(x, x), z);
    let nx = c.neg(x);
    assert_eq!(c.neg(nx), x);
    let two = c.constant(2.0);
    let three = c.constant(3.0);
    let five = c.add(two, three);
    assert_eq!(c.as_const(five), Some(5.0));
    let s = c.sin(x);
    let co = c.cos(x);
    let (s2, co2) = (c.sin(x), c.cos(x));
    assert_eq!((s, co), (s2, co2), "sin/cos of the same argument shared");
    // negations move outwards: (−x)·y = −(x·y), a + (−b) = a − b
    let ny = c.neg(y);
    let p = c.mul(nx, y);
    let xy = c.mul(x, y);
    assert_eq!(c.node(p), Node::Neg(xy));
    let d = c.add(x, ny);
    assert_eq!(c.node(d), Node::Sub(x, y));
    // sign(x)·x = |x|
    let sg = c.sign(x);
    let m = c.mul(sg, x);
    assert_eq!(c.node(m), Node::Abs(x));
    // sin(0) folds
    let s0 = c.sin(z);
    assert_eq!(c.as_const(s0), Some(0.0));
}

/// Random trees: the simplified DAG evaluates to the same bits as the raw
/// tree (up to the sign of zero), and sharing (CSE) changes nothing.
#[test]
fn simplification_and_cse_leave_values_unchanged() {
    let mut r = Rng(0x9E37_79B9_7F4A_7C15);
    let nv = 4;
    let mut checked = 0;
    for _ in 0..400 {
        let t = random_tree(&mut r, 6, nv, false);
        let mut c = Ctx::new();
        let v = vars(&mut c, nv);
        let e = t.build(&mut c, &v);
        for _ in 0..5 {
            let x: Vec<f64> = (0..nv).map(|_| r.uniform(-1.5, 1.5)).collect();
            if !t.all_finite(&x) {
                continue;
            }
            let want = t.eval(&x);
            let got = c.eval(&[e], &x)[0];
            let tree = c.eval_tree(e, &x);
            assert!(
                want == got || (want == 0.0 && got == 0.0),
                "simplified value differs: {want:e} vs {got:e} for {t:?}"
            );
            assert_eq!(got.to_bits(), tree.to_bits(), "CSE changed a value");
            checked += 1;
        }
    }
    assert!(checked > 1000, "only {checked} finite samples");
}

fn fd(c: &Ctx, e: mbsolve_codegen::Id, x: &[f64], k: usize, h: f64) -> f64 {
    let mut xp = x.to_vec();
    let mut xm = x.to_vec();
    xp[k] += h;
    xm[k] -= h;
    (c.eval(&[e], &xp)[0] - c.eval(&[e], &xm)[0]) / (2.0 * h)
}

/// Symbolic derivatives against central differences at random points
/// (points where the difference quotient is not converged are skipped).
#[test]
fn derivatives_match_finite_differences() {
    let mut r = Rng(0x1234_5678_9ABC_DEF1);
    let nv = 3;
    let (mut checked, mut skipped) = (0, 0);
    for _ in 0..300 {
        let t = random_tree(&mut r, 5, nv, true);
        let mut c = Ctx::new();
        let v = vars(&mut c, nv);
        let e = t.build(&mut c, &v);
        let d: Vec<_> = v.iter().map(|&x| c.diff(e, x)).collect();
        for _ in 0..3 {
            let x: Vec<f64> = (0..nv).map(|_| r.uniform(-1.2, 1.2)).collect();
            if !t.all_finite(&x) {
                continue;
            }
            let f = c.eval(&[e], &x)[0];
            for (k, &dk) in d.iter().enumerate() {
                let sym = c.eval(&[dk], &x)[0];
                let (a, b) = (fd(&c, e, &x, k, 1e-4), fd(&c, e, &x, k, 5e-5));
                let tol = 1e-6 * (1.0 + b.abs() + f.abs());
                if !(a - b).abs().is_finite() || (a - b).abs() > tol {
                    skipped += 1;
                    continue;
                }
                assert!(
                    (sym - b).abs() <= 4.0 * tol,
                    "d/dx{k}: symbolic {sym:e} vs fd {b:e} at {x:?} for {t:?}"
                );
                checked += 1;
            }
        }
    }
    assert!(
        checked > 1500 && skipped * 10 < checked,
        "checked {checked}, skipped {skipped}"
    );
}

/// Non-smooth primitives away from their kinks, and chained time inputs.
#[test]
fn nonsmooth_and_time_derivatives() {
    let mut c = Ctx::new();
    let v = vars(&mut c, 2);
    let (x, y) = (v[0], v[1]);
    let xy = c.mul(x, y);
    let a = c.abs(xy);
    let th = c.tanh(a);
    let m = c.max0(x);
    let sq = c.sqrt(m);
    let e1 = c.mul(th, sq); // tanh(|xy|) sqrt(max(x,0))
    let e2 = c.mul(a, xy); // |xy| xy
    for &(px, py) in &[(0.7, -0.4), (1.3, 0.9), (0.2, 2.0)] {
        for e in [e1, e2] {
            for (k, &var) in v.iter().enumerate() {
                let de = c.diff(e, var);
                let sym = c.eval(&[de], &[px, py])[0];
                let num = fd(&c, e, &[px, py], k, 1e-6);
                assert!(rel(sym, num) < 1e-7, "{sym} vs {num}");
            }
        }
    }
    // f(t) with f' and f'' as declared time derivatives
    let mut c = Ctx::new();
    let t = c.var("t");
    c.set_time(t);
    let f: Vec<_> = (0..3).map(|k| c.var(format!("f{k}"))).collect();
    c.set_time_derivative(f[0], f[1]);
    c.set_time_derivative(f[1], f[2]);
    let s = c.sin(f[0]);
    let e = c.mul(t, s); // t sin f(t)
    let de = c.diff(e, t); // sin f + t cos f f'
    let vals = [0.3, 0.8, -1.1, 0.4];
    let got = c.eval(&[de], &vals)[0];
    let want = 0.8f64.sin() + 0.3 * 0.8f64.cos() * -1.1;
    assert!(rel(got, want) < 1e-15);
}

#[test]
fn emitted_block_shares_nodes_and_pairs_sin_cos() {
    let mut c = Ctx::new();
    let v = vars(&mut c, 2);
    let s = c.sin(v[0]);
    let co = c.cos(v[0]);
    let a = c.mul(s, v[1]);
    let b = c.add(a, co);
    let e1 = c.mul(b, b);
    let e2 = c.sub(a, co);
    let mut blk = mbsolve_codegen::Block::new(&c, 0);
    blk.bind(v[0], "x[0]").bind(v[1], "x[1]");
    blk.prepare(&[e1, e2]);
    blk.store("out[0]", e1, mbsolve_codegen::Store::Assign);
    blk.store("out[1]", e2, mbsolve_codegen::Store::Assign);
    let code = blk.finish();
    assert_eq!(code.matches("sin_cos()").count(), 1, "{code}");
    assert!(
        !code.contains(".sin()") && !code.contains(".cos()"),
        "{code}"
    );
    // `a` is used twice → one let; `b` used twice (b·b) → one let
    assert_eq!(code.matches("let ").count(), 3, "{code}");
}
