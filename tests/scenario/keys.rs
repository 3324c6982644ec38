//! Scenario keys that would be silently ignored are errors naming the key:
//! options of another method, a β that the stabilization rule overrides.

use mbsolve::scenario::{self, FALLING_ROD_TOML, FOURBAR_TOML};

fn fourbar(o: &[&str]) -> Result<scenario::Scenario, scenario::ScenarioError> {
    let o: Vec<String> = o.iter().map(|s| s.to_string()).collect();
    scenario::parse(FOURBAR_TOML, "fourbar.toml", "fourbar", &o)
}

/// The error of `o` on the four-bar: its key and message.
fn rejected(o: &[&str]) -> (String, String) {
    match fourbar(o) {
        Ok(_) => panic!("{o:?} was accepted"),
        Err(e) => (e.key, e.message),
    }
}

#[test]
fn options_of_another_method_are_errors_naming_the_key() {
    let cases: &[(&[&str], &str, &str)] = &[
        (
            &["integrator.min_step=1e-9"],
            "integrator.min_step",
            "implicit methods",
        ),
        (
            &["integrator.rho_inf=0.5"],
            "integrator.rho_inf",
            "not to ode23",
        ),
        (&["integrator.lu=true"], "integrator.lu", "implicit methods"),
        (
            &["integrator.step=1e-3"],
            "integrator.step",
            "ode23 chooses its own steps",
        ),
        (
            &["integrator.method=\"ode45\"", "integrator.newton_tol=1e-8"],
            "integrator.newton_tol",
            "not to ode45",
        ),
        (
            &[
                "integrator.method=\"rk4\"",
                "integrator.step=1e-3",
                "integrator.rtol=1e-6",
            ],
            "integrator.rtol",
            "rk4 takes fixed steps",
        ),
        (
            &[
                "integrator.method=\"genalpha\"",
                "integrator.step=1e-3",
                "integrator.rtol=1e-6",
            ],
            "integrator.rtol",
            "adaptive = true only",
        ),
        (
            &[
                "integrator.method=\"genalpha\"",
                "integrator.step=1e-3",
                "integrator.initial_step=1e-4",
            ],
            "integrator.initial_step",
            "adaptive = true only",
        ),
        (
            &[
                "integrator.method=\"genalpha\"",
                "integrator.step=1e-3",
                "stabilization.alpha=5",
            ],
            "stabilization.alpha",
            "index-1 methods",
        ),
        (
            &[
                "integrator.method=\"hht\"",
                "integrator.step=1e-3",
                "formulation=\"eliminated\"",
            ],
            "formulation",
            "index-3 form",
        ),
    ];
    for (o, key, why) in cases {
        let (k, m) = rejected(o);
        assert_eq!(&k, key, "{o:?}: {m}");
        assert!(m.contains(why), "{o:?}: {m}");
    }
}

#[test]
fn a_beta_the_rule_would_replace_is_an_error() {
    let (k, m) = rejected(&[
        "stabilization.alpha=5",
        "stabilization.beta=3",
        "stabilization.rule=\"equal\"",
    ]);
    assert_eq!(k, "stabilization.beta");
    assert!(m.contains("derives β from α"), "{m}");
    // without beta the rule sets it
    let sc = fourbar(&[
        "stabilization.alpha=5",
        "stabilization.rule=\"sqrt_2alpha\"",
    ])
    .unwrap();
    assert_eq!(sc.run.formulation.baumgarte.beta, 10f64.sqrt());
    // an explicit pair stays as given
    let sc = fourbar(&["stabilization.alpha=5", "stabilization.beta=3"]).unwrap();
    assert_eq!(
        (
            sc.run.formulation.baumgarte.alpha,
            sc.run.formulation.baumgarte.beta
        ),
        (5.0, 3.0)
    );
}

/// Options that apply are accepted, and each value reaches the run: the
/// parsed run settings hold it, and a short run (the four-bar over 0.1 s)
/// shows its effect — `max_step` caps the steps (at least 100 in 0.1 s
/// at 1e-3, where ode45 at rtol 1e-6 takes 11 without it), rk4's and
/// generalized-α's `step` give exactly 100 steps, `project = true`
/// projects (the summary's `projections` > 0, 0 without), the adaptive
/// generalized-α's `initial_step` is its first step and `max_step` its
/// largest (the summary's `max_step_taken` ≤ 0.01), and `rod.segments`
/// the number of bodies.
#[test]
fn options_that_apply_are_accepted() {
    use mbsolve::simulation::simulate;
    let run = |o: &[&str]| {
        let mut o = o.to_vec();
        o.extend(["time.end=0.1", "output.dt=0.1"]);
        let sc = fourbar(&o).unwrap_or_else(|e| panic!("{o:?}: {e}"));
        let (_, s) = simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
        assert_eq!(s.status, "completed", "{o:?}: {:?}", s.message);
        (sc, s)
    };
    let extra = |s: &mbsolve::simulation::Summary, k: &str| {
        s.extra
            .get(k)
            .and_then(|v| v.as_f64())
            .unwrap_or_else(|| panic!("no {k} in the summary"))
    };

    let (sc, s) = run(&[
        "integrator.method=\"ode45\"",
        "integrator.rtol=1e-6",
        "integrator.max_step=1e-3",
    ]);
    assert_eq!(sc.run.ode.rtol, 1e-6);
    assert_eq!(sc.run.ode.max_step, Some(1e-3));
    assert_eq!(s.rtol, 1e-6);
    let (_, free) = run(&["integrator.method=\"ode45\"", "integrator.rtol=1e-6"]);
    assert!(
        s.steps >= 100 && free.steps < s.steps,
        "max_step 1e-3: {} steps, without: {}",
        s.steps,
        free.steps
    );

    let (sc, s) = run(&["integrator.method=\"rk4\"", "integrator.step=1e-3"]);
    assert_eq!(sc.run.ode.fixed_step, Some(1e-3));
    assert_eq!(s.steps, 100);

    let (sc, s) = run(&[
        "integrator.method=\"genalpha\"",
        "integrator.step=1e-3",
        "integrator.project=true",
    ]);
    assert!(sc.run.implicit.project);
    assert_eq!(s.steps, 100);
    assert!(
        extra(&s, "projections") > 0.0,
        "project = true did not project"
    );
    let (_, s) = run(&["integrator.method=\"genalpha\"", "integrator.step=1e-3"]);
    assert_eq!(extra(&s, "projections"), 0.0);

    let (sc, s) = run(&[
        "integrator.method=\"genalpha\"",
        "integrator.adaptive=true",
        "integrator.initial_step=1e-3",
        "integrator.rtol=1e-5",
        "integrator.max_step=0.01",
    ]);
    assert!(sc.run.implicit.adaptive);
    assert_eq!(sc.run.ode.initial_step, Some(1e-3));
    assert_eq!(sc.run.ode.rtol, 1e-5);
    assert_eq!(sc.run.ode.max_step, Some(0.01));
    assert_eq!(s.extra["adaptive"], true);
    assert!(
        extra(&s, "max_step_taken") <= 0.01 && extra(&s, "min_step_taken") <= 1e-3,
        "steps {} … {}",
        extra(&s, "min_step_taken"),
        extra(&s, "max_step_taken")
    );

    // the README's long-chain command
    let o: Vec<String> = [
        "rod.segments=50",
        "integrator.method=\"genalpha\"",
        "integrator.step=1e-4",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let sc = scenario::parse(FALLING_ROD_TOML, "falling_rod.toml", "falling_rod", &o).unwrap();
    assert_eq!(sc.system.bodies().len(), 50);
    assert_eq!(sc.run.ode.fixed_step, Some(1e-4));
}

/// The library refuses implicit-only options under an explicit method
/// (they used to be ignored silently).
#[test]
fn simulate_rejects_implicit_options_for_explicit_methods() {
    use mbsolve::integrate::{ImplicitOptions, Method};
    let sc = fourbar(&[]).unwrap();
    let mut cfg = sc.run.clone();
    cfg.method = Method::Ode45;
    cfg.implicit = ImplicitOptions {
        min_step: Some(1e-6),
        ..Default::default()
    };
    let e = mbsolve::simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &cfg, &mut [])
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("min_step") && e.contains("ode45"), "{e}");
}

/// `integrator.threads` reaches the run ([`mbsolve::parallel::Threads`]) and
/// its summary; a bad value is an error naming the key and the value.
#[test]
fn threads_key_reaches_the_run_and_its_summary() {
    use mbsolve::parallel::Threads;
    for (v, t) in [
        ("\"auto\"", Threads::Auto),
        ("1", Threads::One),
        ("2", Threads::Two),
    ] {
        let sc = fourbar(&[&format!("integrator.threads={v}")]).unwrap();
        assert_eq!(sc.run.threads, t, "{v}");
    }
    assert_eq!(fourbar(&[]).unwrap().run.threads, Threads::Auto);
    for (bad, shown) in [("3", "'3'"), ("0", "'0'"), ("\"many\"", "'many'")] {
        let (key, message) = rejected(&[&format!("integrator.threads={bad}")]);
        assert_eq!(key, "integrator.threads");
        assert!(message.contains(shown), "{message}");
    }
    // the summary says what the run did: one thread, nothing split
    let sc = fourbar(&["integrator.threads=1", "time.end=0.05"]).unwrap();
    let (_, s) =
        mbsolve::simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut []).unwrap();
    assert_eq!(s.extra["threads_setting"], "1");
    assert_eq!(s.extra["threads"], 1);
    assert_eq!(s.extra["split"], false);
    assert_eq!(s.extra["halves_split"], 0);
}

/// `MBSOLVE_THREADS` sets the threads of a run whose scenario leaves them
/// `auto` (the summary says so), an explicit key wins, and a bad value is
/// an error naming the variable and the value.
#[test]
fn threads_environment_variable_reaches_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let run = |env: &str, set: &[&str]| {
        let mut args = vec![
            "run",
            "scenarios/fourbar.toml",
            "--out",
            out,
            "--set",
            "time.end=0.05",
        ];
        for s in set {
            args.extend(["--set", s]);
        }
        std::process::Command::new(env!("CARGO_BIN_EXE_mbsolve"))
            .args(&args)
            .env("MBSOLVE_THREADS", env)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("binary runs")
    };
    let summary = || -> serde_json::Value {
        serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("fourbar.summary.json")).unwrap(),
        )
        .unwrap()
    };
    for (env, set, expect, decision) in [
        ("1", &[][..], "1", "one"),
        ("2", &[][..], "2", "two"),
        ("2", &["integrator.threads=1"][..], "1", "one"),
        ("auto", &[][..], "auto", "small"),
    ] {
        let o = run(env, set);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = summary();
        assert_eq!(
            s["threads_setting"], expect,
            "MBSOLVE_THREADS={env} {set:?}"
        );
        // the rule's decision and reason, in the summary and on the console
        assert_eq!(s["threads_rule"]["decision"], decision, "{env} {set:?}");
        let reason = s["threads_reason"].as_str().unwrap();
        let out = String::from_utf8_lossy(&o.stdout);
        let split = if s["split"] == true {
            "split"
        } else {
            "not split"
        };
        let line = format!("threads: {} used, solves {split}; {reason}", s["threads"]);
        assert!(out.contains(&line), "{out}");
        if expect == "1" {
            assert_eq!(s["threads"], 1);
            assert_eq!(s["halves_split"], 0);
        }
    }
    let o = run("many", &[]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("MBSOLVE_THREADS") && e.contains("'many'"), "{e}");
}

/// Every `[integrator]` key against every method, with and without
/// `adaptive = true`: the method table's row decides whether the loader
/// accepts the key, and a refusal names the key and the method.
#[test]
fn the_method_table_decides_which_integrator_keys_apply() {
    use mbsolve::integrate::{Stepping, METHODS};
    let values = [
        ("rtol", "1e-6"),
        ("atol", "1e-8"),
        ("step", "1e-3"),
        ("max_step", "0.01"),
        ("initial_step", "1e-4"),
        ("rho_inf", "0.9"),
        ("adaptive", "false"),
        ("newton_tol", "1e-7"),
        ("max_newton", "10"),
        ("project", "true"),
        ("reuse", "true"),
        ("filter_error", "true"),
        ("check_constraints", "true"),
        ("min_step", "1e-9"),
        ("lu", "true"),
        ("extrapolate", "true"),
        ("flight_step", "2e-3"),
        ("max_order", "3"),
        ("ndf", "true"),
    ];
    let mut refused_per_row = vec![0; METHODS.len()];
    for (r, row) in METHODS.iter().enumerate() {
        let modes: &[bool] = match row.stepping {
            Stepping::FixedOrAdaptive => &[false, true],
            _ => &[false],
        };
        for &adaptive in modes {
            for (key, value) in values {
                if key == "adaptive" && adaptive {
                    continue;
                }
                let mut o = vec![format!("integrator.method=\"{}\"", row.name)];
                if adaptive {
                    o.push("integrator.adaptive=true".into());
                } else if row.stepping != Stepping::Adaptive && key != "step" {
                    o.push("integrator.step=1e-3".into());
                }
                o.push(format!("integrator.{key}={value}"));
                let r#ref: Vec<&str> = o.iter().map(String::as_str).collect();
                let result = fourbar(&r#ref);
                if row.takes(key, adaptive) {
                    if let Err(e) = &result {
                        assert_ne!(e.key, format!("integrator.{key}"), "{o:?}: {e}");
                    }
                } else {
                    refused_per_row[r] += 1;
                    let e = result
                        .map(|_| ())
                        .expect_err(&format!("{o:?} was accepted"));
                    assert_eq!(e.key, format!("integrator.{key}"), "{o:?}: {e}");
                    assert!(e.message.contains(row.name), "{o:?}: {e}");
                }
            }
        }
    }
    // every family refuses something (the loop above is not vacuous)
    assert!(
        refused_per_row.iter().all(|&n| n > 0),
        "{refused_per_row:?}"
    );
}

/// The "applies to … only" messages name the methods the table gives the
/// key, one family at a time.
#[test]
fn applicability_messages_name_the_methods_of_the_table() {
    for (o, key, why) in [
        // generalized-α keys on an explicit Runge–Kutta method
        (
            &["integrator.rho_inf=0.5"][..],
            "integrator.rho_inf",
            "applies to the implicit methods genalpha, hht and newmark only, not to ode23",
        ),
        // keys of the generalized-α family and Radau IIA on the Adams method
        (
            &["integrator.method=\"ode113\"", "integrator.min_step=1e-9"],
            "integrator.min_step",
            "applies to the implicit methods genalpha, hht, newmark, radau5, radau9, radau59 and radau13 only, not to ode113",
        ),
        // a BDF key on the generalized-α family
        (
            &[
                "integrator.method=\"genalpha\"",
                "integrator.step=1e-3",
                "integrator.max_order=3",
            ],
            "integrator.max_order",
            "applies to bdf only, not to genalpha",
        ),
        // a generalized-α key on Radau IIA
        (
            &[
                "integrator.method=\"radau5\"",
                "integrator.step=1e-3",
                "integrator.lu=true",
            ],
            "integrator.lu",
            "applies to the implicit methods genalpha, hht and newmark only, not to radau5",
        ),
        // a Newton key on BDF
        (
            &["integrator.method=\"bdf\"", "integrator.newton_tol=1e-7"],
            "integrator.newton_tol",
            "applies to the implicit methods genalpha, hht, newmark, radau5, radau9, radau59 and radau13 only, not to bdf",
        ),
        // Baumgarte on an index-3 method: the index-1 methods from the table
        (
            &[
                "integrator.method=\"radau5\"",
                "integrator.step=1e-3",
                "stabilization.alpha=5",
            ],
            "stabilization.alpha",
            "applies to the index-1 methods (ode23, ode45, rk4 and ode113); radau5",
        ),
    ] {
        let (k, m) = rejected(o);
        assert_eq!(k, key, "{o:?}: {m}");
        assert!(m.contains(why), "{o:?}: {m}");
    }
}

/// `integrator.flight_step` must be an integer multiple (2 or more) of
/// `integrator.step`: anything else is an error naming the key and the
/// value, from the scenario or from the library's options.
#[test]
fn a_flight_step_off_the_grid_is_an_error_naming_key_and_value() {
    for bad in ["2.5e-3", "1e-3", "-2e-3", "5e-4"] {
        let o = [
            "integrator.method=\"radau5\"".to_string(),
            "integrator.step=1e-3".into(),
            format!("integrator.flight_step={bad}"),
        ];
        let o: Vec<&str> = o.iter().map(String::as_str).collect();
        let e = match fourbar(&o) {
            Err(e) => e.to_string(),
            Ok(sc) => mbsolve::simulation::simulate(&sc.system, &sc.q0, &sc.qd0, &sc.run, &mut [])
                .map(|_| ())
                .expect_err(bad)
                .to_string(),
        };
        let shown = bad.parse::<f64>().unwrap().to_string();
        assert!(
            e.contains("flight_step") && e.contains(&shown) && e.contains("multiple"),
            "{bad}: {e}"
        );
    }
}
