//! Rust source for topologies: fully unrolled functions for small fixed
//! topologies, and per-joint kernels plus loops for chains whose length is
//! known only at run time.
//!
//! The emitted code uses only `f64` arithmetic, fixed-size array references
//! and slices: no allocation, no trait objects, each body angle's sine and
//! cosine computed once per function (once per body along a chain loop).

use crate::emit::{Block, Store};
use crate::expr::Id;
use crate::topology::{ForceKind, JointKind, PlanarModel, Side, Topology};
use std::fmt::Write;

/// What an argument of a generated function is.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ArgKind {
    Input,
    Output,
}

/// One generated function.
struct FnSpec<'a> {
    doc: String,
    attr: &'a str,
    name: String,
    args: Vec<(String, String, ArgKind)>,
    binds: Vec<(Id, String)>,
    outs: Vec<(String, Id, Store)>,
}

/// Name of the argument an expression like `q[3]` or `trig[0]` reads.
fn arg_of(expr: &str) -> &str {
    expr.split(['[', '.', ' ']).next().unwrap_or(expr)
}

fn emit_fn(m: &PlanarModel, spec: &FnSpec, code: &mut String) -> usize {
    let mut b = Block::new(&m.ctx, 4);
    for (id, e) in &spec.binds {
        b.bind(*id, e.clone());
    }
    let ids: Vec<Id> = spec.outs.iter().map(|o| o.1).collect();
    b.prepare(&ids);
    let used = b.used_bindings(&ids);
    let mut used_args: Vec<&str> = spec
        .binds
        .iter()
        .filter(|(id, _)| used.contains(id))
        .map(|(_, e)| arg_of(e))
        .collect();
    for (dest, id, how) in &spec.outs {
        if *how == Store::Assign || m.ctx.as_const(*id) != Some(0.0) {
            used_args.push(arg_of(dest));
        }
    }
    for (dest, id, how) in &spec.outs {
        b.store(dest, *id, *how);
    }
    let ops = b.n_ops();
    let body = b.finish();
    for line in spec.doc.lines() {
        let _ = writeln!(code, "/// {line}");
    }
    if !spec.attr.is_empty() {
        let _ = writeln!(code, "{}", spec.attr);
    }
    let args: Vec<String> = spec
        .args
        .iter()
        .map(|(n, t, _)| format!("{n}: {t}"))
        .collect();
    let _ = writeln!(code, "pub fn {}({}) {{", spec.name, args.join(", "));
    let unused: Vec<&str> = spec
        .args
        .iter()
        .filter(|(n, _, _)| !used_args.contains(&n.as_str()))
        .map(|(n, _, _)| n.as_str())
        .collect();
    match unused.len() {
        0 => {}
        1 => {
            let _ = writeln!(code, "    let _ = {};", unused[0]);
        }
        _ => {
            let _ = writeln!(code, "    let _ = ({});", unused.join(", "));
        }
    }
    code.push_str(&body);
    code.push_str("}\n\n");
    ops
}

fn arr(n: usize) -> String {
    format!("&[f64; {n}]")
}
fn arr_mut(n: usize) -> String {
    format!("&mut [f64; {n}]")
}

/// Size figures of generated code.
#[derive(Clone, Debug, Default)]
pub struct Stats {
    /// Functions emitted.
    pub functions: usize,
    /// Floating-point operations in their bodies (after CSE).
    pub ops: usize,
}

/// Bindings of the model's inputs to conventional argument names:
/// `q`, `qd`, `p` (joint parameters), `tf` (time inputs), `lambda`, `fp`.
fn input_binds(
    m: &PlanarModel,
    with_qd: bool,
    with_lambda: bool,
    with_fp: bool,
) -> Vec<(Id, String)> {
    let mut v = Vec::new();
    for (k, &id) in m.q.iter().enumerate() {
        v.push((id, format!("q[{k}]")));
    }
    if with_qd {
        for (k, &id) in m.qd.iter().enumerate() {
            v.push((id, format!("qd[{k}]")));
        }
    }
    for (k, &id) in m.p.iter().enumerate() {
        v.push((id, format!("p[{k}]")));
    }
    for (k, &id) in m.tf.iter().enumerate() {
        v.push((id, format!("tf[{k}]")));
    }
    if with_lambda {
        for (k, &id) in m.lambda.iter().enumerate() {
            v.push((id, format!("lambda[{k}]")));
        }
    }
    if with_fp {
        for (k, &id) in m.fp.iter().enumerate() {
            v.push((id, format!("fp[{k}]")));
        }
    }
    v
}

fn outs(dest: &str, ids: &[Id], how: Store) -> Vec<(String, Id, Store)> {
    ids.iter()
        .enumerate()
        .map(|(k, &id)| (format!("{dest}[{k}]"), id, how))
        .collect()
}

fn pattern_const(code: &mut String, doc: &str, name: &str, pat: &[(usize, usize)]) {
    let _ = writeln!(code, "/// {doc}");
    let items: Vec<String> = pat.iter().map(|(r, c)| format!("({r}, {c})")).collect();
    let _ = writeln!(
        code,
        "pub const {name}: [(usize, usize); {}] = [{}];",
        pat.len(),
        items.join(", ")
    );
}

/// Fully unrolled functions for a small fixed topology (e.g. the four-bar),
/// all prefixed `prefix_`:
///
/// * constants `PREFIX_N_COORDS`, `_N_ROWS`, `_N_JAC`, `_N_HESS`,
///   `_N_PARAMS`, `_N_TIME_INPUTS`, `_N_FORCE_PARAMS`, `_N_FORCE_JAC`,
///   `_JAC_PATTERN`, `_HESS_PATTERN`, `_JOINTS` (kind, body i, body j; −1 =
///   ground), `_FORCE_COORDS`;
/// * `prefix_phi(q, p, tf, out)`, `prefix_jacobian(q, p, tf, vals)`,
///   `prefix_phi_t(q, p, tf, out)`, `prefix_gamma(q, qd, p, tf, out)`,
///   `prefix_hessian(q, p, tf, lambda, vals)` (adds (Φ_qᵀλ)_q),
///   `prefix_eval(q, qd, p, tf, phi, vals, gamma)` (Φ, Φ_q, γ fused);
/// * with force elements: `prefix_forces(q, qd, fp, g)` (adds g) and
///   `prefix_force_jacobians(q, qd, fp, dq, dqd)` (adds `k×k` row-major
///   blocks over each element's footprint, element after element).
///
/// `q`, `qd` are the topology's coordinates, `p` the joint parameters
/// (joint after joint, see [`JointKind::param_names`]), `tf` the time inputs
/// `f, f', f''` of each angle drive, `fp` the force parameters.
pub fn emit_unrolled(topo: &Topology, prefix: &str) -> (String, Stats) {
    let m = PlanarModel::new(topo);
    let up = prefix.to_uppercase();
    let (nc, nr) = (m.n_coords(), m.n_rows());
    let jp = m.jac_pattern();
    let hp = m.hess_pattern();
    let (np, nt, nfp) = (m.p.len(), m.tf.len(), m.fp.len());
    let nfj: usize = m.forces.iter().map(|f| f.coords.len().pow(2)).sum();
    let mut code = String::new();
    let mut st = Stats::default();
    let _ = writeln!(
        code,
        "// ---- topology '{}': {} bodies, {} joints, {} force elements (unrolled) ----\n",
        topo.name,
        topo.n_bodies,
        topo.joints.len(),
        topo.forces.len()
    );
    for (name, v, doc) in [
        ("N_COORDS", nc, "Coordinates (3 per body)."),
        ("N_ROWS", nr, "Constraint rows."),
        ("N_JAC", jp.len(), "Φ_q non-zeros."),
        ("N_HESS", hp.len(), "(Φ_qᵀλ)_q non-zeros."),
        ("N_PARAMS", np, "Joint parameters."),
        (
            "N_TIME_INPUTS",
            nt,
            "Time inputs (f, f', f'' per angle drive).",
        ),
        ("N_FORCE_PARAMS", nfp, "Force-element parameters."),
        ("N_FORCE_JAC", nfj, "Entries of the force Jacobian blocks."),
    ] {
        let _ = writeln!(code, "/// {doc}\npub const {up}_{name}: usize = {v};");
    }
    pattern_const(
        &mut code,
        "Φ_q pattern (row, coordinate), value order.",
        &format!("{up}_JAC_PATTERN"),
        &jp,
    );
    pattern_const(
        &mut code,
        "(Φ_qᵀλ)_q pattern (row ≥ col), value order.",
        &format!("{up}_HESS_PATTERN"),
        &hp,
    );
    let joints: Vec<String> = topo
        .joints
        .iter()
        .map(|j| format!("(\"{}\", {}, {})", j.kind.label(), j.i.code(), j.j.code()))
        .collect();
    let _ = writeln!(
        code,
        "/// Joints: (kind, body i, body j), −1 = ground.\npub const {up}_JOINTS: [(&str, i64, i64); {}] = [{}];",
        joints.len(),
        joints.join(", ")
    );
    let fc: Vec<usize> = m.forces.iter().flat_map(|f| f.coords.clone()).collect();
    let _ = writeln!(
        code,
        "/// Footprints of the force elements, concatenated.\npub const {up}_FORCE_COORDS: [usize; {}] = {:?};\n",
        fc.len(),
        fc
    );

    let q = ("q".to_string(), arr(nc), ArgKind::Input);
    let qd = ("qd".to_string(), arr(nc), ArgKind::Input);
    let p = ("p".to_string(), arr(np), ArgKind::Input);
    let tf = ("tf".to_string(), arr(nt), ArgKind::Input);
    let lam = ("lambda".to_string(), arr(nr), ArgKind::Input);
    let fpa = ("fp".to_string(), arr(nfp), ArgKind::Input);
    let o = |n: &str, len: usize| (n.to_string(), arr_mut(len), ArgKind::Output);
    let tn = &topo.name;
    let specs = vec![
        FnSpec {
            doc: format!("Φ(q) of '{tn}'."),
            attr: "",
            name: format!("{prefix}_phi"),
            args: vec![q.clone(), p.clone(), tf.clone(), o("out", nr)],
            binds: input_binds(&m, false, false, false),
            outs: outs("out", &m.phi(), Store::Assign),
        },
        FnSpec {
            doc: format!("Φ_q values of '{tn}' in the order of `{up}_JAC_PATTERN`."),
            attr: "",
            name: format!("{prefix}_jacobian"),
            args: vec![q.clone(), p.clone(), tf.clone(), o("vals", jp.len())],
            binds: input_binds(&m, false, false, false),
            outs: outs("vals", &m.jac(), Store::Assign),
        },
        FnSpec {
            doc: format!("Φ_t of '{tn}'."),
            attr: "",
            name: format!("{prefix}_phi_t"),
            args: vec![q.clone(), p.clone(), tf.clone(), o("out", nr)],
            binds: input_binds(&m, false, false, false),
            outs: outs("out", &m.phi_t(), Store::Assign),
        },
        FnSpec {
            doc: format!("γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt of '{tn}'."),
            attr: "",
            name: format!("{prefix}_gamma"),
            args: vec![q.clone(), qd.clone(), p.clone(), tf.clone(), o("out", nr)],
            binds: input_binds(&m, true, false, false),
            outs: outs("out", &m.gamma(), Store::Assign),
        },
        FnSpec {
            doc: format!("Adds (Φ_qᵀλ)_q of '{tn}' in the order of `{up}_HESS_PATTERN`."),
            attr: "",
            name: format!("{prefix}_hessian"),
            args: vec![q.clone(), p.clone(), tf.clone(), lam, o("vals", hp.len())],
            binds: input_binds(&m, false, true, false),
            outs: outs("vals", &m.hess(), Store::AddAssign),
        },
        FnSpec {
            doc: format!("Φ, Φ_q values and γ of '{tn}' in one pass (shared sines, cosines, subexpressions)."),
            attr: "",
            name: format!("{prefix}_eval"),
            args: vec![
                q.clone(),
                qd.clone(),
                p.clone(),
                tf.clone(),
                o("phi", nr),
                o("vals", jp.len()),
                o("gamma", nr),
            ],
            binds: input_binds(&m, true, false, false),
            outs: [
                outs("phi", &m.phi(), Store::Assign),
                outs("vals", &m.jac(), Store::Assign),
                outs("gamma", &m.gamma(), Store::Assign),
            ]
            .concat(),
        },
    ];
    let mut specs = specs;
    if !m.forces.is_empty() {
        let g: Vec<(String, Id, Store)> = m
            .forces
            .iter()
            .flat_map(|f| {
                f.coords
                    .iter()
                    .zip(&f.g)
                    .map(|(c, &id)| (format!("g[{c}]"), id, Store::AddAssign))
            })
            .collect();
        specs.push(FnSpec {
            doc: format!("Adds the generalized forces of the force elements of '{tn}' to `g`."),
            attr: "",
            name: format!("{prefix}_forces"),
            args: vec![q.clone(), qd.clone(), fpa.clone(), o("g", nc)],
            binds: input_binds(&m, true, false, true),
            outs: g,
        });
        let dq: Vec<Id> = m.forces.iter().flat_map(|f| f.dq.clone()).collect();
        let dqd: Vec<Id> = m.forces.iter().flat_map(|f| f.dqd.clone()).collect();
        specs.push(FnSpec {
            doc: format!(
                "Adds ∂g/∂q and ∂g/∂q̇ of the force elements of '{tn}': per element a k×k\nrow-major block over its footprint (`{up}_FORCE_COORDS`)."
            ),
            attr: "",
            name: format!("{prefix}_force_jacobians"),
            args: vec![q, qd, fpa, o("dq", nfj), o("dqd", nfj)],
            binds: input_binds(&m, true, false, true),
            outs: [outs("dq", &dq, Store::AddAssign), outs("dqd", &dqd, Store::AddAssign)].concat(),
        });
    }
    for s in &specs {
        st.ops += emit_fn(&m, s, &mut code);
        st.functions += 1;
    }
    (code, st)
}

/// What repeats along a chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChainElement {
    /// A joint of this kind between body k (side i) and body k+1 (side j),
    /// one per link `k = 0 … n−2`.
    Joint(JointKind),
    /// A two-body force element between body k (i) and body k+1 (j).
    PairForce(ForceKind),
    /// A one-body force element on every body.
    BodyForce(ForceKind),
}

/// Per-joint kernels (`#[inline(always)]`) and the loops over a chain.
///
/// For `ChainElement::Joint(kind)` with prefix `c`, joint `k` links body `k`
/// (side i) to body `k + 1` (side j) and owns rows `n_eq·k …`, Φ_q values
/// `n_jac·k …` (the runtime's per-joint pattern order, `C_JOINT_JAC_PATTERN`,
/// columns relative to `3k`) and parameters `n_par·k …`:
/// `c_phi(q, p, out)`, `c_jacobian(q, p, vals)`, `c_phi_t(q, p, out)`,
/// `c_gamma(q, qd, p, out)`, `c_hessian(q, p, lambda, vals)` (adds),
/// `c_eval(q, qd, p, phi, vals, gamma)` (fused), `c_phi_tmul(q, p, lambda,
/// phi, g)` (Φ and Φ_qᵀλ added to `g`, fused: the index-3 residual's
/// constraint part). The number of joints is
/// `p.len() / n_par`. Each body's sine and cosine are computed once per
/// loop and carried to the next joint.
///
/// For force elements: `c_forces(q, qd, fp, g)` (adds) and
/// `c_force_jacobians(q, qd, fp, dq, dqd)` (adds `k×k` blocks element after
/// element); the number of elements is `fp.len() / n_par`.
pub fn emit_chain(prefix: &str, element: ChainElement) -> (String, Stats) {
    match element {
        ChainElement::Joint(kind) => emit_joint_chain(prefix, kind),
        ChainElement::PairForce(kind) => emit_force_chain(prefix, kind, true),
        ChainElement::BodyForce(kind) => emit_force_chain(prefix, kind, false),
    }
}

fn emit_joint_chain(prefix: &str, kind: JointKind) -> (String, Stats) {
    assert_eq!(
        kind.n_time_inputs(),
        0,
        "chains of time-dependent joints are not supported"
    );
    let topo = Topology::new(format!("{prefix} link"), 2).joint(
        "link",
        kind,
        Side::Body(0),
        Side::Body(1),
    );
    let mut m = PlanarModel::new(&topo);
    let up = prefix.to_uppercase();
    let (ne, np) = (kind.n_eq(), kind.n_params());
    let j = m.joints[0].clone();
    let nj = j.jac.len();
    let nh = j.hess.len();
    let mut code = String::new();
    let mut st = Stats::default();
    let _ = writeln!(
        code,
        "// ---- chain '{prefix}': {} joint between body k and body k+1 ----\n",
        kind.label()
    );
    for (name, v, doc) in [
        ("N_EQ", ne, "Rows per joint."),
        ("N_JAC", nj, "Φ_q values per joint."),
        ("N_HESS", nh, "(Φ_qᵀλ)_q values per joint."),
        ("N_PARAMS", np, "Parameters per joint."),
    ] {
        let _ = writeln!(code, "/// {doc}\npub const {up}_{name}: usize = {v};");
    }
    pattern_const(
        &mut code,
        "Per-joint Φ_q pattern (local row, column relative to 3k), value order.",
        &format!("{up}_JOINT_JAC_PATTERN"),
        &j.jac_pattern,
    );
    pattern_const(
        &mut code,
        "Per-joint (Φ_qᵀλ)_q pattern (columns relative to 3k), value order.",
        &format!("{up}_JOINT_HESS_PATTERN"),
        &j.hess_pattern,
    );
    code.push('\n');

    // Kernel bindings: q, qd windows of 6, sines and cosines from `trig`.
    let (phi0, phi1) = (m.q[2], m.q[5]);
    let trig_nodes = [
        m.ctx.sin(phi0),
        m.ctx.cos(phi0),
        m.ctx.sin(phi1),
        m.ctx.cos(phi1),
    ];
    let mut binds = input_binds(&m, true, true, false);
    for (k, &id) in trig_nodes.iter().enumerate() {
        binds.push((id, format!("trig[{k}]")));
    }
    let q = ("q".to_string(), arr(6), ArgKind::Input);
    let qd = ("qd".to_string(), arr(6), ArgKind::Input);
    let trig = ("trig".to_string(), arr(4), ArgKind::Input);
    let p = ("p".to_string(), arr(np), ArgKind::Input);
    let lam = ("lambda".to_string(), arr(ne), ArgKind::Input);
    let o = |n: &str, len: usize| (n.to_string(), arr_mut(len), ArgKind::Output);
    let kdoc = "Kernel of one link (`trig` = [sin φ_k, cos φ_k, sin φ_k+1, cos φ_k+1]):";
    let kernels =
        vec![
        (
            "phi",
            "Φ",
            vec![q.clone(), trig.clone(), p.clone(), o("out", ne)],
            outs("out", &j.phi, Store::Assign),
        ),
        (
            "jacobian",
            "Φ_q values",
            vec![q.clone(), trig.clone(), p.clone(), o("vals", nj)],
            outs("vals", &j.jac, Store::Assign),
        ),
        (
            "phi_t",
            "Φ_t",
            vec![q.clone(), trig.clone(), p.clone(), o("out", ne)],
            outs("out", &j.phi_t, Store::Assign),
        ),
        (
            "gamma",
            "γ",
            vec![q.clone(), qd.clone(), trig.clone(), p.clone(), o("out", ne)],
            outs("out", &j.gamma, Store::Assign),
        ),
        (
            "hessian",
            "adds (Φ_qᵀλ)_q",
            vec![q.clone(), trig.clone(), p.clone(), lam.clone(), o("vals", nh)],
            outs("vals", &j.hess, Store::AddAssign),
        ),
        (
            "phi_tmul",
            "Φ, and adds Φ_qᵀλ to the window `g` of the two bodies (eq. (5)'s constraint forces)",
            vec![q.clone(), trig.clone(), p.clone(), lam.clone(), o("phi", ne), o("g", 6)],
            [
                outs("phi", &j.phi, Store::Assign),
                j.tmul_cols
                    .iter()
                    .zip(&j.tmul)
                    .map(|(c, &id)| (format!("g[{c}]"), id, Store::AddAssign))
                    .collect(),
            ]
            .concat(),
        ),
        (
            "eval",
            "Φ, Φ_q values, γ",
            vec![q, qd, trig, p, o("phi", ne), o("vals", nj), o("gamma", ne)],
            [
                outs("phi", &j.phi, Store::Assign),
                outs("vals", &j.jac, Store::Assign),
                outs("gamma", &j.gamma, Store::Assign),
            ]
            .concat(),
        ),
    ];
    let mut uses_trig = std::collections::HashMap::new();
    for (what, doc, args, o) in kernels {
        // Does this kernel read the sines/cosines?
        let mut b = Block::new(&m.ctx, 0);
        for (id, e) in &binds {
            b.bind(*id, e.clone());
        }
        let ids: Vec<Id> = o.iter().map(|x| x.1).collect();
        b.prepare(&ids);
        let used = b.used_bindings(&ids);
        uses_trig.insert(what, trig_nodes.iter().any(|t| used.contains(t)));
        let spec = FnSpec {
            doc: format!("{kdoc} {doc}."),
            attr: "#[inline(always)]",
            name: format!("{prefix}_joint_{what}"),
            args,
            binds: binds.clone(),
            outs: o,
        };
        st.ops += emit_fn(&m, &spec, &mut code);
        st.functions += 1;
    }

    // The loops.
    let loops: [(&str, &str, &str, &str, &str); 7] = [
        ("phi", "Φ of the chain into `out` (n_eq per joint).", "q: &[f64], p: &[f64], out: &mut [f64]", "out", ""),
        ("jacobian", "Φ_q values of the chain into `vals`, joint after joint in the per-joint pattern order.", "q: &[f64], p: &[f64], vals: &mut [f64]", "vals", ""),
        ("phi_t", "Φ_t of the chain into `out`.", "q: &[f64], p: &[f64], out: &mut [f64]", "out", ""),
        ("gamma", "γ of the chain into `out`.", "q: &[f64], qd: &[f64], p: &[f64], out: &mut [f64]", "out", "qd"),
        ("hessian", "Adds (Φ_qᵀλ)_q of the chain to `vals` (λ: this chain's multipliers).", "q: &[f64], p: &[f64], lambda: &[f64], vals: &mut [f64]", "vals", "lambda"),
        ("eval", "Φ, Φ_q values and γ of the chain in one pass.", "q: &[f64], qd: &[f64], p: &[f64], phi: &mut [f64], vals: &mut [f64], gamma: &mut [f64]", "", "qd"),
        ("phi_tmul", "Φ of the chain into `phi` and Φ_qᵀλ added to `g` (3 per body, n + 1 bodies) in one pass: the constraint part of the index-3 residual without the Φ_q values.", "q: &[f64], p: &[f64], lambda: &[f64], phi: &mut [f64], g: &mut [f64]", "", "lambda"),
    ];
    // Each loop twice: computing the sines and cosines as it goes, and
    // (`_sc`, for kernels that read them) taking them precomputed from
    // `sc = [sin φ_0, cos φ_0, sin φ_1, cos φ_1, …]`.
    for (what, doc, sig, outn, extra) in loops {
        for with_sc in [false, true] {
            let trig_used = uses_trig[what];
            if with_sc && !trig_used {
                continue;
            }
            let (suffix, sig) = if with_sc {
                (
                    "_sc",
                    sig.replacen("q: &[f64], ", "q: &[f64], sc: &[f64], ", 1),
                )
            } else {
                ("", sig.to_string())
            };
            let _ = writeln!(code, "/// {doc}\n/// The number of joints is `p.len() / {np}`; joint k links body k to body k+1.");
            if with_sc {
                let _ = writeln!(code, "/// Sines and cosines precomputed: `sc[2b] = sin φ_b`, `sc[2b + 1] = cos φ_b`.");
            }
            let _ = writeln!(code, "pub fn {prefix}_{what}{suffix}({sig}) {{");
            let _ = writeln!(code, "    let n = p.len() / {np};");
            let _ = writeln!(
                code,
                "    assert!(p.len() == {np} * n && (n == 0 || q.len() >= 3 * n + 3));"
            );
            if with_sc {
                let _ = writeln!(code, "    assert!(n == 0 || sc.len() >= 2 * n + 2);");
            }
            let (out_sizes, out_names): (Vec<usize>, Vec<&str>) = match what {
                "phi" | "phi_t" | "gamma" => (vec![ne], vec![outn]),
                "jacobian" => (vec![nj], vec![outn]),
                "hessian" => (vec![nh], vec![outn]),
                "phi_tmul" => (vec![ne], vec!["phi"]),
                _ => (vec![ne, nj, ne], vec!["phi", "vals", "gamma"]),
            };
            for (sz, nm) in out_sizes.iter().zip(&out_names) {
                let _ = writeln!(code, "    assert!({nm}.len() >= {sz} * n);");
            }
            if what == "phi_tmul" {
                let _ = writeln!(code, "    assert!(g.len() >= 3 * n + 3);");
            }
            if extra == "qd" {
                let _ = writeln!(code, "    assert!(n == 0 || qd.len() >= 3 * n + 3);");
            }
            if extra == "lambda" {
                let _ = writeln!(code, "    assert!(lambda.len() >= {ne} * n);");
            }
            let _ = writeln!(code, "    if n == 0 {{\n        return;\n    }}");
            if trig_used && !with_sc {
                let _ = writeln!(code, "    let (mut s0, mut c0) = q[2].sin_cos();");
            }
            let _ = writeln!(code, "    for k in 0..n {{");
            let _ = writeln!(
                code,
                "        let qk: &[f64; 6] = q[3 * k..3 * k + 6].try_into().unwrap();"
            );
            if extra == "qd" {
                let _ = writeln!(
                    code,
                    "        let qdk: &[f64; 6] = qd[3 * k..3 * k + 6].try_into().unwrap();"
                );
            }
            if extra == "lambda" {
                let _ = writeln!(code, "        let lk: &[f64; {ne}] = lambda[{ne} * k..{ne} * k + {ne}].try_into().unwrap();");
            }
            let _ = writeln!(
                code,
                "        let pk: &[f64; {np}] = p[{np} * k..{np} * k + {np}].try_into().unwrap();"
            );
            for (sz, nm) in out_sizes.iter().zip(&out_names) {
                let _ = writeln!(
                    code,
                    "        let {nm}k: &mut [f64; {sz}] = (&mut {nm}[{sz} * k..{sz} * k + {sz}]).try_into().unwrap();"
                );
            }
            if what == "phi_tmul" {
                let _ = writeln!(
                    code,
                    "        let gk: &mut [f64; 6] = (&mut g[3 * k..3 * k + 6]).try_into().unwrap();"
                );
            }
            let trig_arg = if with_sc {
                let _ = writeln!(
                    code,
                    "        let sck: &[f64; 4] = sc[2 * k..2 * k + 4].try_into().unwrap();"
                );
                "sck"
            } else if trig_used {
                let _ = writeln!(code, "        let (s1, c1) = qk[5].sin_cos();");
                "&[s0, c0, s1, c1]"
            } else {
                "&[0.0; 4]"
            };
            let call_args = match what {
                "phi" | "phi_t" | "jacobian" => format!("qk, {trig_arg}, pk, {outn}k"),
                "gamma" => format!("qk, qdk, {trig_arg}, pk, {outn}k"),
                "hessian" => format!("qk, {trig_arg}, pk, lk, {outn}k"),
                "phi_tmul" => format!("qk, {trig_arg}, pk, lk, phik, gk"),
                _ => format!("qk, qdk, {trig_arg}, pk, phik, valsk, gammak"),
            };
            let _ = writeln!(code, "        {prefix}_joint_{what}({call_args});");
            if trig_used && !with_sc {
                let _ = writeln!(code, "        s0 = s1;\n        c0 = c1;");
            }
            let _ = writeln!(code, "    }}\n}}\n");
            st.functions += 1;
        }
    }
    (code, st)
}

fn emit_force_chain(prefix: &str, kind: ForceKind, pair: bool) -> (String, Stats) {
    let nb = if pair { 2 } else { 1 };
    let j = if pair { Side::Body(1) } else { Side::Ground };
    let topo =
        Topology::new(format!("{prefix} element"), nb).force("element", kind, Side::Body(0), j);
    let m = PlanarModel::new(&topo);
    let f = m.forces[0].clone();
    let w = 3 * nb;
    let kk = f.coords.len() * f.coords.len();
    let np = kind.n_params();
    let up = prefix.to_uppercase();
    let mut code = String::new();
    let mut st = Stats::default();
    let what = if pair {
        "between body k and body k+1"
    } else {
        "on every body"
    };
    let _ = writeln!(
        code,
        "// ---- force chain '{prefix}': {kind:?} {what} ----\n"
    );
    let _ = writeln!(
        code,
        "/// Footprint of one element (columns relative to 3k).\npub const {up}_COORDS: [usize; {}] = {:?};",
        f.coords.len(),
        f.coords
    );
    let _ = writeln!(
        code,
        "/// Parameters per element.\npub const {up}_N_PARAMS: usize = {np};\n"
    );
    let binds = input_binds(&m, true, false, true);
    let q = ("q".to_string(), arr(w), ArgKind::Input);
    let qd = ("qd".to_string(), arr(w), ArgKind::Input);
    let fp = ("fp".to_string(), arr(np), ArgKind::Input);
    let o = |n: &str, len: usize| (n.to_string(), arr_mut(len), ArgKind::Output);
    let g: Vec<(String, Id, Store)> = f
        .coords
        .iter()
        .zip(&f.g)
        .map(|(c, &id)| (format!("g[{c}]"), id, Store::AddAssign))
        .collect();
    for spec in [
        FnSpec {
            doc: format!("Kernel of one element: adds its generalized forces to the window `g` (3 per body, {nb} bodies)."),
            attr: "#[inline(always)]",
            name: format!("{prefix}_element_forces"),
            args: vec![q.clone(), qd.clone(), fp.clone(), o("g", w)],
            binds: binds.clone(),
            outs: g,
        },
        FnSpec {
            doc: format!("Kernel of one element: adds ∂g/∂q, ∂g/∂q̇ ({0}×{0} row-major over `{up}_COORDS`).", f.coords.len()),
            attr: "#[inline(always)]",
            name: format!("{prefix}_element_jacobians"),
            args: vec![q, qd, fp, o("dq", kk), o("dqd", kk)],
            binds,
            outs: [outs("dq", &f.dq, Store::AddAssign), outs("dqd", &f.dqd, Store::AddAssign)].concat(),
        },
    ] {
        st.ops += emit_fn(&m, &spec, &mut code);
        st.functions += 1;
    }
    let count = if pair {
        "n + 1 bodies for n elements"
    } else {
        "one element per body"
    };
    let _ = writeln!(
        code,
        "/// Adds the forces of all elements ({what}; {count}; `n = fp.len() / {np}`) to `g`.\npub fn {prefix}_forces(q: &[f64], qd: &[f64], fp: &[f64], g: &mut [f64]) {{"
    );
    let span = if pair { "3 * n + 3" } else { "3 * n" };
    let _ = writeln!(code, "    let n = fp.len() / {np};");
    let _ = writeln!(code, "    assert!(fp.len() == {np} * n && (n == 0 || (q.len() >= {span} && qd.len() >= {span} && g.len() >= {span})));");
    let _ = writeln!(code, "    for k in 0..n {{");
    let _ = writeln!(
        code,
        "        let qk: &[f64; {w}] = q[3 * k..3 * k + {w}].try_into().unwrap();"
    );
    let _ = writeln!(
        code,
        "        let qdk: &[f64; {w}] = qd[3 * k..3 * k + {w}].try_into().unwrap();"
    );
    let _ = writeln!(
        code,
        "        let pk: &[f64; {np}] = fp[{np} * k..{np} * k + {np}].try_into().unwrap();"
    );
    let _ = writeln!(
        code,
        "        let gk: &mut [f64; {w}] = (&mut g[3 * k..3 * k + {w}]).try_into().unwrap();"
    );
    let _ = writeln!(
        code,
        "        {prefix}_element_forces(qk, qdk, pk, gk);\n    }}\n}}\n"
    );
    let _ = writeln!(
        code,
        "/// Adds ∂g/∂q, ∂g/∂q̇ of all elements: block k at `{kk} * k` ({0}×{0} row-major over `{up}_COORDS` + 3k).\npub fn {prefix}_force_jacobians(q: &[f64], qd: &[f64], fp: &[f64], dq: &mut [f64], dqd: &mut [f64]) {{",
        f.coords.len()
    );
    let _ = writeln!(code, "    let n = fp.len() / {np};");
    let _ = writeln!(code, "    assert!(fp.len() == {np} * n && (n == 0 || (q.len() >= {span} && qd.len() >= {span})));");
    let _ = writeln!(
        code,
        "    assert!(dq.len() >= {kk} * n && dqd.len() >= {kk} * n);"
    );
    let _ = writeln!(code, "    for k in 0..n {{");
    let _ = writeln!(
        code,
        "        let qk: &[f64; {w}] = q[3 * k..3 * k + {w}].try_into().unwrap();"
    );
    let _ = writeln!(
        code,
        "        let qdk: &[f64; {w}] = qd[3 * k..3 * k + {w}].try_into().unwrap();"
    );
    let _ = writeln!(
        code,
        "        let pk: &[f64; {np}] = fp[{np} * k..{np} * k + {np}].try_into().unwrap();"
    );
    let _ = writeln!(code, "        let dqk: &mut [f64; {kk}] = (&mut dq[{kk} * k..{kk} * k + {kk}]).try_into().unwrap();");
    let _ = writeln!(code, "        let dqdk: &mut [f64; {kk}] = (&mut dqd[{kk} * k..{kk} * k + {kk}]).try_into().unwrap();");
    let _ = writeln!(
        code,
        "        {prefix}_element_jacobians(qk, qdk, pk, dqk, dqdk);\n    }}\n}}\n"
    );
    st.functions += 2;
    (code, st)
}
