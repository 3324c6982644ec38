//! Emitted code compiles (with `#![deny(warnings)]`) and computes what the
//! interpreter computes: random expression sets, an unrolled custom topology
//! with every joint and force kind, and chain loops — written with a `main`
//! into a temporary directory, compiled with `rustc -O`, run, compared.
//! This is also the embedding path of a downstream crate (a custom topology
//! through `emit_unrolled` / `emit_chain`).

mod common;
use common::{random_tree, Rng};
use mbsolve_codegen::{
    emit_chain, emit_unrolled, Block, ChainElement, Ctx, ForceKind, Id, JointKind, PlanarModel,
    Side, Store, Topology,
};
use std::fmt::Write;
use std::process::Command;

fn custom() -> Topology {
    common::mixed_topology("custom").force(
        "wall",
        ForceKind::WallContact,
        Side::Body(0),
        Side::Ground,
    )
}

/// Chain equivalent, unrolled for the interpreter: 4 bodies, revolutes and
/// torsional springs between neighbours, drag on every body.
fn chain4() -> Topology {
    let mut t = Topology::new("chain4", 4);
    for k in 0..3 {
        t = t.revolute("link", Side::Body(k), Side::Body(k + 1));
    }
    for k in 0..3 {
        t = t.force(
            "spring",
            ForceKind::TorsionalSpringDamper,
            Side::Body(k),
            Side::Body(k + 1),
        );
    }
    for k in 0..4 {
        t = t.force("drag", ForceKind::Drag, Side::Body(k), Side::Ground);
    }
    t
}

fn arr(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

struct Program {
    code: String,
    main: String,
    expected: Vec<(String, f64)>,
}

impl Program {
    fn call(&mut self, label: &str, setup: &str, call: &str, out: &str, want: &[f64]) {
        let _ = writeln!(
            self.main,
            "    {{\n        {setup}\n        {call};\n        pr(&{out});\n    }}"
        );
        for (k, &w) in want.iter().enumerate() {
            self.expected.push((format!("{label}[{k}]"), w));
        }
    }
}

fn values(m: &PlanarModel, v: &[f64], ids: &[Id]) -> Vec<f64> {
    m.ctx.eval(ids, v)
}

#[test]
fn emitted_code_compiles_and_matches_the_interpreter() {
    let mut r = Rng(2024);
    let mut prog = Program {
        code: String::new(),
        main: String::new(),
        expected: Vec::new(),
    };

    // 1. Random expression sets through one Block (shared CSE scope).
    let mut c = Ctx::new();
    let nv = 4;
    let vars: Vec<Id> = (0..nv).map(|k| c.var(format!("x{k}"))).collect();
    let x: Vec<f64> = (0..nv).map(|_| r.uniform(-1.2, 1.2)).collect();
    let mut outs = Vec::new();
    // the functions random trees do not draw (real powers, exp, log, atan2,
    // smooth steps and tables), with a derivative each
    for text in [
        "exp(x0*x1) + log(2 + x2^2)",
        "atan2(x0, x1 - 2) * pow(1 + x3^2, 1.5 + 0.1*x2)",
        "smoothstep(x0, -1, 1) + table(x1, [-2, 0, 2], [1, -1, 3])",
    ] {
        let e = mbsolve_codegen::parse(&mut c, text, |n, _| {
            let k: usize = n.strip_prefix('x')?.parse().ok()?;
            vars.get(k).copied()
        })
        .unwrap();
        outs.push(e);
        outs.push(c.diff(e, vars[0]));
    }
    while outs.len() < 46 {
        let t = random_tree(&mut r, 6, nv, false);
        if t.all_finite(&x) {
            let e = t.build(&mut c, &vars);
            outs.push(e);
            // and a derivative of it
            let d = c.diff(e, vars[outs.len() % nv]);
            if c.eval(&[d], &x)[0].is_finite() {
                outs.push(d);
            }
        }
    }
    let mut b = Block::new(&c, 4);
    for (k, &v) in vars.iter().enumerate() {
        b.bind(v, format!("x[{k}]"));
    }
    b.prepare(&outs);
    for (k, &e) in outs.iter().enumerate() {
        b.store(&format!("out[{k}]"), e, Store::Assign);
    }
    let _ = writeln!(
        prog.code,
        "/// Random expressions.\npub fn exprs(x: &[f64; {nv}], out: &mut [f64; {}]) {{\n{}}}\n",
        outs.len(),
        b.finish()
    );
    let want = c.eval(&outs, &x);
    prog.call(
        "exprs",
        &format!("let mut o = [0.0; {}];", outs.len()),
        &format!("g::exprs(&{}, &mut o)", arr(&x)),
        "o",
        &want,
    );

    // 2. The unrolled custom topology.
    let topo = custom();
    let (code, _) = emit_unrolled(&topo, "custom");
    prog.code.push_str(&code);
    let m = PlanarModel::new(&topo);
    let mut v: Vec<f64> = (0..m.ctx.n_vars()).map(|_| r.uniform(-1.0, 1.0)).collect();
    let get = |v: &Vec<f64>, ids: &[Id]| -> Vec<f64> {
        ids.iter()
            .map(|&i| v[m.ctx.var_number(i).unwrap()])
            .collect()
    };
    // unit sliding axes
    for j in &m.joints {
        if j.params.len() == 7 {
            let ix = m.ctx.var_number(m.p[j.params.start + 2]).unwrap();
            let iy = m.ctx.var_number(m.p[j.params.start + 3]).unwrap();
            let n = (v[ix] * v[ix] + v[iy] * v[iy]).sqrt();
            v[ix] /= n;
            v[iy] /= n;
        }
    }
    let (q, qd, p, tf, lam, fp) = (
        get(&v, &m.q),
        get(&v, &m.qd),
        get(&v, &m.p),
        get(&v, &m.tf),
        get(&v, &m.lambda),
        get(&v, &m.fp),
    );
    let (nr, nj, nh, nc) = (m.n_rows(), m.jac().len(), m.hess().len(), m.n_coords());
    let inputs = format!(
        "let q = {}; let qd = {}; let p = {}; let tf = {}; let lam = {}; let fp = {};",
        arr(&q),
        arr(&qd),
        arr(&p),
        arr(&tf),
        arr(&lam),
        arr(&fp)
    );
    let s = |extra: &str| format!("{inputs} {extra}");
    prog.call(
        "phi",
        &s(&format!("let mut o = [0.0; {nr}];")),
        "g::custom_phi(&q, &p, &tf, &mut o)",
        "o",
        &values(&m, &v, &m.phi()),
    );
    prog.call(
        "jac",
        &s(&format!("let mut o = [0.0; {nj}];")),
        "g::custom_jacobian(&q, &p, &tf, &mut o)",
        "o",
        &values(&m, &v, &m.jac()),
    );
    prog.call(
        "phi_t",
        &s(&format!("let mut o = [0.0; {nr}];")),
        "g::custom_phi_t(&q, &p, &tf, &mut o)",
        "o",
        &values(&m, &v, &m.phi_t()),
    );
    prog.call(
        "gamma",
        &s(&format!("let mut o = [0.0; {nr}];")),
        "g::custom_gamma(&q, &qd, &p, &tf, &mut o)",
        "o",
        &values(&m, &v, &m.gamma()),
    );
    prog.call(
        "hess",
        &s(&format!("let mut o = [0.0; {nh}];")),
        "g::custom_hessian(&q, &p, &tf, &lam, &mut o)",
        "o",
        &values(&m, &v, &m.hess()),
    );
    let fused = [
        values(&m, &v, &m.phi()),
        values(&m, &v, &m.jac()),
        values(&m, &v, &m.gamma()),
    ]
    .concat();
    prog.call(
        "eval",
        &s(&format!("let (mut a, mut b, mut c) = ([0.0; {nr}], [0.0; {nj}], [0.0; {nr}]);")),
        "g::custom_eval(&q, &qd, &p, &tf, &mut a, &mut b, &mut c); let o: Vec<f64> = a.iter().chain(&b).chain(&c).copied().collect()",
        "o",
        &fused,
    );
    let mut g = vec![0.0; nc];
    for f in &m.forces {
        for (c, gv) in f.coords.iter().zip(values(&m, &v, &f.g)) {
            g[*c] += gv;
        }
    }
    prog.call(
        "forces",
        &s(&format!("let mut o = [0.0; {nc}];")),
        "g::custom_forces(&q, &qd, &fp, &mut o)",
        "o",
        &g,
    );
    let dq: Vec<Id> = m.forces.iter().flat_map(|f| f.dq.clone()).collect();
    let dqd: Vec<Id> = m.forces.iter().flat_map(|f| f.dqd.clone()).collect();
    let nfj = dq.len();
    prog.call(
        "force_jac",
        &s(&format!("let (mut a, mut b) = ([0.0; {nfj}], [0.0; {nfj}]);")),
        "g::custom_force_jacobians(&q, &qd, &fp, &mut a, &mut b); let o: Vec<f64> = a.iter().chain(&b).copied().collect()",
        "o",
        &[values(&m, &v, &dq), values(&m, &v, &dqd)].concat(),
    );

    // 3. Chain loops (revolute joints, torsional springs, drag) vs the
    //    interpreted unrolled 4-body chain; also a translational chain.
    for (prefix, el) in [
        ("rc", ChainElement::Joint(JointKind::Revolute)),
        (
            "tc",
            ChainElement::PairForce(ForceKind::TorsionalSpringDamper),
        ),
        ("dc", ChainElement::BodyForce(ForceKind::Drag)),
        ("pc", ChainElement::Joint(JointKind::Translational)),
    ] {
        prog.code.push_str(&emit_chain(prefix, el).0);
    }
    let m = PlanarModel::new(&chain4());
    let v: Vec<f64> = (0..m.ctx.n_vars()).map(|_| r.uniform(-1.0, 1.0)).collect();
    let get = |ids: &[Id]| -> Vec<f64> {
        ids.iter()
            .map(|&i| v[m.ctx.var_number(i).unwrap()])
            .collect()
    };
    let (q, qd, p, lam, fp) = (get(&m.q), get(&m.qd), get(&m.p), get(&m.lambda), get(&m.fp));
    let (nr, nj, nh, nc) = (m.n_rows(), m.jac().len(), m.hess().len(), m.n_coords());
    let (fps, fpd) = fp.split_at(9);
    let inputs = format!(
        "let q = {}; let qd = {}; let p = {}; let lam = {}; let fps = {}; let fpd = {};",
        arr(&q),
        arr(&qd),
        arr(&p),
        arr(&lam),
        arr(fps),
        arr(fpd)
    );
    let s = |extra: &str| format!("{inputs} {extra}");
    prog.call(
        "chain_phi",
        &s(&format!("let mut o = [0.0; {nr}];")),
        "g::rc_phi(&q, &p, &mut o)",
        "o",
        &values(&m, &v, &m.phi()),
    );
    prog.call(
        "chain_jac",
        &s(&format!("let mut o = [0.0; {nj}];")),
        "g::rc_jacobian(&q, &p, &mut o)",
        "o",
        &values(&m, &v, &m.jac()),
    );
    prog.call(
        "chain_phi_t",
        &s(&format!("let mut o = [1.0; {nr}];")),
        "g::rc_phi_t(&q, &p, &mut o)",
        "o",
        &values(&m, &v, &m.phi_t()),
    );
    prog.call(
        "chain_gamma",
        &s(&format!("let mut o = [0.0; {nr}];")),
        "g::rc_gamma(&q, &qd, &p, &mut o)",
        "o",
        &values(&m, &v, &m.gamma()),
    );
    prog.call(
        "chain_hess",
        &s(&format!("let mut o = [0.0; {nh}];")),
        "g::rc_hessian(&q, &p, &lam, &mut o)",
        "o",
        &values(&m, &v, &m.hess()),
    );
    prog.call(
        "chain_eval",
        &s(&format!("let (mut a, mut b, mut c) = ([0.0; {nr}], [0.0; {nj}], [0.0; {nr}]);")),
        "g::rc_eval(&q, &qd, &p, &mut a, &mut b, &mut c); let o: Vec<f64> = a.iter().chain(&b).chain(&c).copied().collect()",
        "o",
        &[values(&m, &v, &m.phi()), values(&m, &v, &m.jac()), values(&m, &v, &m.gamma())].concat(),
    );
    let mut g = vec![0.0; nc];
    for f in &m.forces {
        for (c, gv) in f.coords.iter().zip(values(&m, &v, &f.g)) {
            g[*c] += gv;
        }
    }
    prog.call(
        "chain_forces",
        &s(&format!("let mut o = [0.0; {nc}];")),
        "g::tc_forces(&q, &qd, &fps, &mut o); g::dc_forces(&q, &qd, &fpd, &mut o)",
        "o",
        &g,
    );
    let (fs, fd) = m.forces.split_at(3);
    let blocks = |fs: &[mbsolve_codegen::topology::ForceModel]| -> Vec<f64> {
        let dq: Vec<Id> = fs.iter().flat_map(|f| f.dq.clone()).collect();
        let dqd: Vec<Id> = fs.iter().flat_map(|f| f.dqd.clone()).collect();
        [values(&m, &v, &dq), values(&m, &v, &dqd)].concat()
    };
    prog.call(
        "chain_spring_jac",
        &s("let (mut a, mut b) = ([0.0; 12], [0.0; 12]);"),
        "g::tc_force_jacobians(&q, &qd, &fps, &mut a, &mut b); let o: Vec<f64> = a.iter().chain(&b).copied().collect()",
        "o",
        &blocks(fs),
    );
    prog.call(
        "chain_drag_jac",
        &s("let (mut a, mut b) = ([0.0; 36], [0.0; 36]);"),
        "g::dc_force_jacobians(&q, &qd, &fpd, &mut a, &mut b); let o: Vec<f64> = a.iter().chain(&b).copied().collect()",
        "o",
        &blocks(fd),
    );

    // Write, compile, run.
    let dir = std::env::temp_dir().join(format!("mbsolve-codegen-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("gen.rs"), &prog.code).unwrap();
    // The generated items as a library that denies every warning (and
    // missing docs), then a program using it.
    std::fs::write(
        dir.join("lib.rs"),
        "//! Generated kernels.\n#![deny(warnings, missing_docs)]\ninclude!(\"gen.rs\");\n",
    )
    .unwrap();
    let main = format!(
        "#![deny(warnings)]\n#![allow(unused_variables)]\nuse generated as g;\n\nfn pr(v: &[f64]) {{\n    for x in v {{\n        println!(\"{{:016x}}\", x.to_bits());\n    }}\n}}\n\nfn main() {{\n{}}}\n",
        prog.main
    );
    std::fs::write(dir.join("main.rs"), main).unwrap();
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    for args in [
        &[
            "-O",
            "--edition",
            "2021",
            "--crate-type",
            "lib",
            "--crate-name",
            "generated",
            "lib.rs",
        ][..],
        &[
            "-O",
            "--edition",
            "2021",
            "main.rs",
            "-o",
            "prog",
            "--extern",
            "generated=libgenerated.rlib",
            "-L",
            ".",
        ][..],
    ] {
        let out = Command::new(&rustc)
            .args(args)
            .current_dir(&dir)
            .output()
            .expect("run rustc");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "rustc {args:?} failed:\n{stderr}");
        assert!(!stderr.contains("warning"), "{stderr}");
    }
    let run = Command::new(dir.join("prog"))
        .output()
        .expect("run program");
    assert!(run.status.success());
    let got: Vec<f64> = String::from_utf8_lossy(&run.stdout)
        .lines()
        .map(|l| f64::from_bits(u64::from_str_radix(l, 16).unwrap()))
        .collect();
    assert_eq!(got.len(), prog.expected.len());
    let mut bitwise = 0;
    for ((label, want), got) in prog.expected.iter().zip(&got) {
        let tol = 1e-14 * want.abs().max(1.0);
        assert!(
            (want - got).abs() <= tol,
            "{label}: compiled {got:e} vs interpreter {want:e}"
        );
        if want.to_bits() == got.to_bits() || (*want == 0.0 && *got == 0.0) {
            bitwise += 1;
        }
    }
    eprintln!("{} values compared, {bitwise} bit-identical", got.len());
    let _ = std::fs::remove_dir_all(&dir);
}
