//! The expression parser: precedence, associativity, functions, error
//! positions, and derivatives of parsed expressions against finite differences.

use mbsolve_codegen::{parse, Ctx, Id, ParseErrorKind};

/// Context with variables x, y, z (values given at evaluation).
fn ctx3() -> (Ctx, [Id; 3]) {
    let mut c = Ctx::new();
    let v = [c.var("x"), c.var("y"), c.var("z")];
    (c, v)
}

fn eval(text: &str, vals: [f64; 3]) -> f64 {
    let (mut c, v) = ctx3();
    let e = parse(&mut c, text, |n, _| match n {
        "x" => Some(v[0]),
        "y" => Some(v[1]),
        "z" => Some(v[2]),
        _ => None,
    })
    .unwrap_or_else(|e| panic!("{text}: {e}"));
    c.eval(&[e], &vals)[0]
}

fn err(text: &str) -> (usize, ParseErrorKind, String) {
    let (mut c, v) = ctx3();
    let e = parse(&mut c, text, |n, _| (n == "x").then_some(v[0])).unwrap_err();
    (e.pos, e.kind.clone(), e.to_string())
}

#[test]
fn precedence_and_associativity() {
    let xyz = [2.0, 3.0, 5.0];
    let cases: &[(&str, f64)] = &[
        ("1 + 2 * 3", 7.0),
        ("(1 + 2) * 3", 9.0),
        ("10 - 4 - 3", 3.0),
        ("64 / 4 / 2", 8.0),
        ("2 ^ 3 ^ 2", 512.0),
        ("-2 ^ 2", -4.0),
        ("(-2) ^ 2", 4.0),
        ("2 ^ -1", 0.5),
        ("x * y ^ 2", 18.0),
        ("-x * -y", 6.0),
        ("x - -y", 5.0),
        ("+x", 2.0),
        ("1e-3 * 1000", 1.0),
        ("2.5E+2", 250.0),
        (".5 + 1.", 1.5),
        ("z / x * y", 7.5),
        ("x ^ (1 + 1)", 4.0),
        ("4 ^ 0.5", 2.0),
        ("z ^ 0.5", 5f64.sqrt()),
        ("z ^ 1.5", 5f64.powf(1.5)),
        ("x ^ y", 8.0),
        ("2 ^ 0.25", 2f64.powf(0.25)),
    ];
    for &(t, want) in cases {
        let got = eval(t, xyz);
        assert!(
            (got - want).abs() <= 1e-15 * want.abs(),
            "{t}: {got} ≠ {want}"
        );
    }
}

#[test]
fn functions() {
    let (x, y) = (0.7f64, -1.3f64);
    let cases: &[(&str, f64)] = &[
        ("sin(x)", x.sin()),
        ("cos(x)", x.cos()),
        ("tan(x)", x.tan()),
        ("sqrt(x)", x.sqrt()),
        ("abs(y)", y.abs()),
        ("tanh(y)", y.tanh()),
        ("sign(y)", -1.0),
        ("min(x, y)", y),
        ("min(y, x)", y),
        ("max(x, y)", x),
        ("max(y, x)", x),
        ("max(x, x)", x),
        (
            "2*sin(x)^2 + cos(x*y)",
            2.0 * x.sin().powi(2) + (x * y).cos(),
        ),
        ("exp(y)", y.exp()),
        ("log(x)", x.ln()),
        ("atan2(y, x)", y.atan2(x)),
        ("atan2(x, y)", x.atan2(y)),
        ("pow(x, 2.5)", x.powf(2.5)),
        ("pow(y, 3)", y * y * y),
        ("pow(y, -2)", 1.0 / (y * y)),
        ("clamp(x, 0, 0.5)", 0.5),
        ("clamp(y, -1, 1)", -1.0),
        ("clamp(x, 0, 1)", x),
        ("smoothstep(x, 0, 1)", x * x * (3.0 - 2.0 * x)),
        ("smoothstep(x, 1, 0)", 1.0 - x * x * (3.0 - 2.0 * x)),
        ("smoothstep(y, 0, 1)", 0.0),
        ("smoothstep(x, -2, 0.5)", 1.0),
        // piecewise linear: x = 0.7 in the segment [0.5, 1] from 2 to 4
        ("table(x, [0, 0.5, 1], [1, 2, 4])", 2.0 + 0.2 / 0.5 * 2.0),
        ("table(y, [0, 0.5, 1], [1, 2, 4])", 1.0),
        ("table(x + 1, [0, 0.5, 1], [1, 2, 4])", 4.0),
        ("table(x, [-1, 1], [3, -3])", -3.0 * x),
    ];
    for &(t, want) in cases {
        let got = eval(t, [x, y, 0.0]);
        assert!(
            (got - want).abs() <= 2e-16 * want.abs().max(1.0),
            "{t}: {got} ≠ {want}"
        );
    }
}

#[test]
fn errors_carry_position_and_message() {
    let (pos, kind, msg) = err("1 + sinh(x)");
    assert_eq!(pos, 4);
    assert_eq!(kind, ParseErrorKind::UnknownFunction("sinh".into()));
    assert_eq!(msg, "unknown function 'sinh' at 4");

    let (pos, kind, _) = err("x + q");
    assert_eq!((pos, kind), (4, ParseErrorKind::UnknownName("q".into())));

    let (pos, kind, _) = err("(x + 1");
    assert_eq!(pos, 6);
    assert!(
        matches!(kind, ParseErrorKind::Unexpected { .. }),
        "{kind:?}"
    );

    let (pos, kind, _) = err("x $ 2");
    assert_eq!((pos, kind), (2, ParseErrorKind::UnexpectedChar('$')));

    let (pos, kind, _) = err("x * * 2");
    assert_eq!(pos, 4);
    assert!(matches!(kind, ParseErrorKind::Unexpected { .. }));

    let (pos, kind, msg) = err("table(x, [0, 1, 1], [0, 1, 2])");
    assert_eq!(pos, 9);
    assert!(matches!(kind, ParseErrorKind::BadArgument(_)), "{msg}");
    assert_eq!(
        msg,
        "table: the abscissae must increase strictly (1 is followed by 1) at 9"
    );
    let (pos, _, msg) = err("table(x, [0, 1], [0, 1, 2])");
    assert_eq!(pos, 17);
    assert!(msg.contains("3 values for 2 abscissae"), "{msg}");
    let (_, _, msg) = err("table(x, [0], [0])");
    assert!(msg.contains("at least 2 points"), "{msg}");
    let (pos, _, msg) = err("table(x, [0, x], [0, 1])");
    assert_eq!(pos, 13);
    assert!(msg.contains("constants"), "{msg}");
    let (_, _, msg) = err("table(x, 1, [0, 1])");
    assert!(msg.contains("lists"), "{msg}");
    let (_, _, msg) = err("sin([1, 2])");
    assert!(msg.contains("argument of table only"), "{msg}");
    let (_, _, msg) = err("smoothstep(x, 1, 1)");
    assert!(msg.contains("must differ"), "{msg}");
    let (_, _, msg) = err("table(x, [0, 1e999], [0, 1])");
    assert!(msg.contains("not finite"), "{msg}");
    let (pos, kind, _) = err("table(x, [0, 1, [0, 1])");
    assert_eq!(pos, 16);
    assert!(matches!(kind, ParseErrorKind::Unexpected { .. }));

    let (pos, kind, _) = err("max(x)");
    assert_eq!(pos, 0);
    assert!(matches!(
        kind,
        ParseErrorKind::Arity {
            expected: 2,
            found: 1,
            ..
        }
    ));

    let (pos, kind, _) = err("2 x");
    assert_eq!(pos, 2);
    assert!(matches!(kind, ParseErrorKind::Unexpected { .. }));

    let (pos, kind, _) = err("1e+");
    assert_eq!(pos, 0);
    assert!(matches!(kind, ParseErrorKind::BadNumber(_)));

    let (pos, _, _) = err("");
    assert_eq!(pos, 0);
}

#[test]
fn resolver_may_return_expressions() {
    // A name bound to a whole expression (as the scenario layer binds
    // relative angles and distances).
    let mut c = Ctx::new();
    let (a, b) = (c.var("a"), c.var("b"));
    let e = parse(&mut c, "2 * rel", |n, c| (n == "rel").then(|| c.sub(a, b))).unwrap();
    assert_eq!(c.eval(&[e], &[5.0, 1.5])[0], 7.0);
}

/// Symbolic derivatives of parsed expressions agree with central differences,
/// away from the kinks of abs, min and max (and on each side of them).
#[test]
fn names_may_hold_an_index_of_digits() {
    // a numbered body of a chain or rod: `arm.link[2].phi`
    let mut seen = Vec::new();
    let mut c = Ctx::new();
    let x = c.var("x");
    let e = parse(&mut c, "arm.link[2].phi + 2*rod.segment[10].y", |n, _| {
        seen.push(n.to_string());
        Some(x)
    })
    .unwrap();
    assert_eq!(seen, ["arm.link[2].phi", "rod.segment[10].y"]);
    assert_eq!(c.eval(&[e], &[1.5])[0], 4.5);
    // a bracket that is not `[digits]` is still an error at its position
    // (`[` is a token of its own since table lists, `table(x, [..], [..])`)
    for (text, pos) in [("a[] + 1", 1), ("a[x]", 1), ("a[2", 1)] {
        let mut c = Ctx::new();
        let e = parse(&mut c, text, |_, c| Some(c.zero())).unwrap_err();
        assert_eq!(e.pos, pos, "{text}");
        let found_bracket = match &e.kind {
            ParseErrorKind::UnexpectedChar(ch) => *ch == '[',
            ParseErrorKind::Unexpected { found, .. } => found == "'['",
            _ => false,
        };
        assert!(found_bracket, "{text}: {:?}", e.kind);
    }
}

#[test]
fn derivatives_match_finite_differences() {
    let texts = [
        "x*y^3 - z/x + sin(x*z)",
        "sqrt(x^2 + y^2) * tanh(z)",
        "tan(x) + cos(y)^-2",
        "abs(x - y) * z",
        "min(x, y*z) + max(x^2, z)",
        "-x^2 / (1 + y^2)",
        "exp(x*y) + log(z^2 + x)",
        "atan2(y, x) * atan2(z, y - 2)",
        "pow(x^2 + 1, y) + pow(z^2, 0.75) + (x^2 + 2)^1.5",
        "smoothstep(x*y, -0.5, 0.9) + clamp(z, -0.5, 0.5)",
        "table(x + y, [-2, 0.1, 0.5, 1.2, 3], [0, 1, -1, 2, 2]) * z",
    ];
    let points = [[0.3, 0.8, 1.7], [1.1, -0.4, 0.6], [0.45, 1.3, -0.9]];
    for t in texts {
        let (mut c, v) = ctx3();
        let e = parse(&mut c, t, |n, _| {
            ["x", "y", "z"].iter().position(|&m| m == n).map(|k| v[k])
        })
        .unwrap();
        let d: Vec<Id> = v.iter().map(|&vk| c.diff(e, vk)).collect();
        for p in points {
            let sym = c.eval(&d, &p);
            for k in 0..3 {
                let h = 1e-6;
                let (mut pp, mut pm) = (p, p);
                pp[k] += h;
                pm[k] -= h;
                let fd = (c.eval(&[e], &pp)[0] - c.eval(&[e], &pm)[0]) / (2.0 * h);
                assert!(
                    (sym[k] - fd).abs() <= 1e-7 * (1.0 + fd.abs()),
                    "{t} d/d{k} at {p:?}: {} vs fd {fd}",
                    sym[k]
                );
            }
        }
    }
}

/// The piecewise derivatives of the non-smooth functions, exactly.
#[test]
fn nonsmooth_derivatives_are_piecewise() {
    let (mut c, v) = ctx3();
    let r = |n: &str, _: &mut Ctx| ["x", "y", "z"].iter().position(|&m| m == n).map(|k| v[k]);
    let mx = parse(&mut c, "max(x, y)", r).unwrap();
    let mn = parse(&mut c, "min(x, y)", r).unwrap();
    let ab = parse(&mut c, "abs(x)", r).unwrap();
    let d = [
        c.diff(mx, v[0]),
        c.diff(mx, v[1]),
        c.diff(mn, v[0]),
        c.diff(mn, v[1]),
        c.diff(ab, v[0]),
    ];
    assert_eq!(c.eval(&d, &[2.0, 1.0, 0.0]), vec![1.0, 0.0, 0.0, 1.0, 1.0]);
    assert_eq!(
        c.eval(&d, &[-1.0, 1.0, 0.0]),
        vec![0.0, 1.0, 1.0, 0.0, -1.0]
    );
    // At the tie the first argument's derivative is taken.
    assert_eq!(c.eval(&d, &[1.0, 1.0, 0.0])[..4], [1.0, 0.0, 1.0, 0.0]);
}

/// Deep inputs are errors naming the limit, never a stack overflow: run on
/// a thread with a 2 MiB stack (rayon's and many callers' default).
#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let deep = format!("{}x{}", "(".repeat(50_000), ")".repeat(50_000));
            let (_, kind, msg) = err(&deep);
            assert_eq!(kind, ParseErrorKind::TooNested, "{msg}");
            assert!(msg.contains("200"), "{msg}");
            let signs = format!("{}x", "-".repeat(50_000));
            assert_eq!(err(&signs).1, ParseErrorKind::TooNested);
            let calls = format!("{}x{}", "sin(".repeat(50_000), ")".repeat(50_000));
            assert_eq!(err(&calls).1, ParseErrorKind::TooNested);
            // Within the nesting limit, a DAG deeper than MAX_DEPTH: each
            // level `sin((next) + x^2 + ... + x^15)` adds 15 operations on
            // the longest path (sums up to 16 terms fold left to right).
            let level = |n: usize| {
                let tail: String = (2..16).map(|k| format!("+x^{k}")).collect();
                format!("{}x{}", "sin(".repeat(n), format!("{tail})").repeat(n))
            };
            assert!(parse_ok(&level(40)));
            let (pos, kind, msg) = err(&level(100));
            assert!(
                matches!(kind, ParseErrorKind::TooDeep { depth } if depth > 1000),
                "{msg}"
            );
            assert_eq!(pos, 0);
            assert!(msg.contains("limit is 1000"), "{msg}");
        })
        .unwrap()
        .join()
        .unwrap();
}

fn parse_ok(text: &str) -> bool {
    let (mut c, v) = ctx3();
    parse(&mut c, text, |n, _| (n == "x").then_some(v[0])).is_ok()
}

/// A flat sum or product of 200 000 terms parses to a shallow expression
/// (balanced), evaluates to the exact value and differentiates on a 2 MiB
/// stack.
#[test]
fn long_flat_sums_and_products_are_shallow_and_exact() {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let n = 200_000;
            let sum = vec!["x"; n].join("+");
            assert_eq!(eval(&sum, [0.5, 0.0, 0.0]), 0.5 * n as f64);
            // Alternating signs: x - y + x - y ... (n even) = n/2 (x - y).
            let alt: String = (0..n)
                .map(|k| if k % 2 == 0 { "+x" } else { "-y" })
                .collect::<String>()[1..]
                .to_string();
            assert_eq!(eval(&alt, [3.0, 1.0, 0.0]), n as f64);
            // Products and quotients: x*y/x*y/... with powers of two exact.
            let prod: String = (0..n)
                .map(|k| if k % 2 == 0 { "*x" } else { "/y" })
                .collect::<String>()[1..]
                .to_string();
            assert_eq!(eval(&prod, [2.0, 2.0, 0.0]), 1.0);
            let sums: String = (0..n)
                .map(|k| format!("{}sin({k}*x)", if k % 3 == 1 { "-" } else { "+" }))
                .collect::<String>()[1..]
                .to_string();
            let (mut c, v) = ctx3();
            let e = parse(&mut c, &sums, |m, _| (m == "x").then_some(v[0])).unwrap();
            let d = c.diff(e, v[0]);
            let x: f64 = 1e-3;
            let want: f64 = (0..n)
                .map(|k| {
                    let s = if k % 3 == 1 { -1.0 } else { 1.0 };
                    s * k as f64 * (k as f64 * x).cos()
                })
                .sum();
            let got = c.eval(&[d], &[x, 0.0, 0.0])[0];
            assert!((got - want).abs() <= 1e-9 * want.abs(), "{got} vs {want}");
        })
        .unwrap()
        .join()
        .unwrap();
}

/// Short sums keep the left-to-right order of rounding: (1e16 + 1) + 1 =
/// 1e16 in floating point, not 1e16 + 2.
#[test]
fn short_sums_round_left_to_right() {
    assert_eq!(eval("x + 1 + 1", [1e16, 0.0, 0.0]), 1e16);
}

/// The new functions against their closed forms over a grid, and the table
/// through every node and beyond both ends.
#[test]
fn new_functions_match_closed_forms() {
    let xs = [0.0, 0.3, 1.0, 2.5, 4.0];
    let ys = [1.0, -2.0, 0.5, 0.5, 3.0];
    let text = "table(x, [0, 0.3, 1, 2.5, 4], [1, -2, 0.5, 0.5, 3])";
    let closed = |x: f64| {
        if x <= xs[0] {
            return ys[0];
        }
        for i in 0..4 {
            if x <= xs[i + 1] {
                return ys[i] + (ys[i + 1] - ys[i]) * (x - xs[i]) / (xs[i + 1] - xs[i]);
            }
        }
        ys[4]
    };
    for k in -10..=50 {
        let x = k as f64 * 0.1;
        let got = eval(text, [x, 0.0, 0.0]);
        assert!(
            (got - closed(x)).abs() <= 1e-14,
            "table at {x}: {got} vs {}",
            closed(x)
        );
    }
    for (&x, &y) in xs.iter().zip(&ys) {
        let got = eval(text, [x, 0.0, 0.0]);
        assert!(
            (got - y).abs() <= 4.0 * f64::EPSILON * 3.0,
            "node {x}: {got} vs {y}"
        );
    }
    for k in 0..=20 {
        let x = -1.0 + 0.15 * k as f64;
        let u = ((x - 0.2) / 1.5f64).clamp(0.0, 1.0);
        let want = u * u * (3.0 - 2.0 * u);
        let got = eval("smoothstep(x, 0.2, 1.7)", [x, 0.0, 0.0]);
        assert!((got - want).abs() <= 1e-15, "smoothstep at {x}");
        let got = eval("exp(-x) * log(2 + x) + atan2(x, -1)", [x, 0.0, 0.0]);
        let want = (-x).exp() * (2.0 + x).ln() + x.atan2(-1.0);
        assert!(
            (got - want).abs() <= 1e-15 * want.abs().max(1.0),
            "exp/log at {x}"
        );
    }
    // Outside the domains: IEEE values, documented (never a parse error).
    assert!(eval("log(x)", [-1.0, 0.0, 0.0]).is_nan());
    assert_eq!(eval("log(x)", [0.0, 0.0, 0.0]), f64::NEG_INFINITY);
    assert!(eval("x ^ 1.5", [-1.0, 0.0, 0.0]).is_nan());
    // integer and 0.5 exponents are exact for negative bases
    assert_eq!(eval("x ^ 3", [-2.0, 0.0, 0.0]), -8.0);
    assert_eq!(eval("pow(x, 2)", [-2.0, 0.0, 0.0]), 4.0);
}

/// smoothstep has a continuous first derivative: 0 at both edges, 1.5/(x1 −
/// x0) in the middle; the table's derivative is the segment slope.
#[test]
fn smooth_step_and_table_derivatives() {
    let (mut c, v) = ctx3();
    let r = |n: &str, _: &mut Ctx| (n == "x").then_some(v[0]);
    let s = parse(&mut c, "smoothstep(x, 1, 3)", r).unwrap();
    let tb = parse(&mut c, "table(x, [0, 1, 3], [0, 2, 1])", r).unwrap();
    let d = [c.diff(s, v[0]), c.diff(tb, v[0])];
    let at = |c: &Ctx, x: f64| c.eval(&d, &[x, 0.0, 0.0]);
    assert_eq!(at(&c, 1.0)[0], 0.0);
    assert_eq!(at(&c, 3.0)[0], 0.0);
    assert_eq!(at(&c, 2.0)[0], 0.75);
    assert_eq!(at(&c, 0.5)[1], 2.0);
    assert_eq!(at(&c, 2.0)[1], -0.5);
    assert_eq!(at(&c, 1.0)[1], 2.0);
    assert_eq!(at(&c, 4.0)[1], 0.0);
    assert_eq!(at(&c, -1.0)[1], 0.0);
}
