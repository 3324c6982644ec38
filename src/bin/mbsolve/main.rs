//! `mbsolve`: command-line front end of the mbsolve library.

use clap::{Parser, Subcommand};

/// `println!` that ignores a closed stdout (`mbsolve run … | head -1`): the
/// run goes on, writes its files and exits with its own status instead of
/// panicking on the broken pipe.
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

mod animate;
mod check;
mod figure;
mod gate;
mod inverse;
mod linearize;
mod modes;
mod output;
mod plot;
mod reproduce;
mod statics;
mod stream;
mod study;
mod sweep;
mod view;

use mbsolve::events::{ContactMonitor, ElementContacts};
use mbsolve::simulation::Monitor;
use mbsolve::{scenario, simulation};
use sha2::Digest as _;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "mbsolve",
    version,
    about = "Dynamics of constrained planar multibody systems"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scenario file; writes DIR/<stem>.csv and DIR/<stem>.summary.json.
    Run {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Override a scenario key, e.g. --set stabilization.alpha=10 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Remove a key of the file, e.g. --unset integrator.rtol (repeatable; before the --set).
        #[arg(long = "unset", value_name = "KEY")]
        unset: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Progress on stderr: a live line on a terminal (auto), a plain
        /// line every 10 s for logs (plain), or none (off).
        #[arg(long, value_enum, default_value = "auto")]
        progress: stream::ProgressMode,
        /// No progress and no report on stdout (warnings and errors still
        /// go to stderr).
        #[arg(long, short)]
        quiet: bool,
        /// Also write the interactive viewer DIR/<stem>.view.html.
        #[arg(long)]
        view: bool,
    },
    /// Recover a killed run's Arrow table: the complete record batches of
    /// DIR/<stem>.arrow.part (rows up to the run's last flush, at least
    /// every minute) written as the finished file DIR/<stem>.arrow.
    Recover {
        /// The `.arrow.part` file a killed run left.
        part: PathBuf,
        /// The file to write (default: the part's name without `.part`).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Run a scenario over the Cartesian product of parameter values, in
    /// parallel; writes DIR/<stem>_sweep.csv (one row per run) and a
    /// summary JSON per run.
    Sweep {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// A swept key (or [parameters] name) and its values, e.g. --param stabilization.alpha=0,1,5,10,
        /// --param k=[1e3, 2e3] or --param k=linspace(1e3, 4e3, 7) (repeatable).
        #[arg(long = "param", value_name = "KEY=V1,V2,...", required = true)]
        param: Vec<String>,
        /// Fixed overrides applied to every run.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Remove a key of the file, e.g. --unset integrator.rtol (repeatable; before the --set and --param).
        #[arg(long = "unset", value_name = "KEY")]
        unset: Vec<String>,
        /// A result column: a column or expression reduced over each run,
        /// e.g. --metric 'rms(ay2, 1, 5)', --metric 'peak=max(phi1)',
        /// --metric 'crossing(y2, 0.1, up)'; reductions final, min, max,
        /// mean, rms, crossing (repeatable; after the file's [[metric]]s).
        #[arg(long = "metric", value_name = "[NAME=]REDUCE(QUANTITY[, T0, T1])")]
        metric: Vec<String>,
        /// `runs`: keep each run's table as DIR/<stem>_sweep<k>.csv (k: the
        /// run's index in the product) with its columns.json.
        #[arg(long, value_enum)]
        keep: Option<sweep::Keep>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Run only shard I of N (1 ≤ I ≤ N): the runs k of the product
        /// with k mod N = I − 1; writes DIR/<stem>_sweep.shard-I-of-N.csv.
        #[arg(long, value_name = "I/N", conflicts_with = "merge")]
        shard: Option<String>,
        /// Join the shard tables in DIR (same --param and --set) into
        /// DIR/<stem>_sweep.csv, checking that every run is there once.
        #[arg(long)]
        merge: bool,
    },
    /// Validate a scenario without running it and print the system's size:
    /// bodies, coordinates, constraint equations, degrees of freedom and
    /// redundant equations (from the rank of Φ_q at the initial state),
    /// joints and force elements by kind, evaluation and method. Exit 0
    /// when valid, 1 with the error otherwise.
    Check {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Override a scenario key (repeatable), as for `run`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Remove a key of the file, e.g. --unset integrator.rtol (repeatable; before the --set).
        #[arg(long = "unset", value_name = "KEY")]
        unset: Vec<String>,
    },
    /// Kinematics and inverse dynamics of a mechanism without freedom once
    /// its drives are counted: positions, velocities and accelerations from
    /// the constraints alone at the output times, the drive forces/torques
    /// and joint reactions; writes DIR/<stem>.inverse.csv (run's column
    /// names) and DIR/<stem>.inverse.summary.json.
    Inverse {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Override a scenario key (repeatable), as for `run`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Linearise a scenario about a state: the state-space model
    /// ẋ = A x + B u, y = C x + D u in independent coordinates; writes
    /// DIR/<stem>.linear.json and the matrices as CSV.
    Linearize(linearize::LinearizeArgs),
    /// CI performance gate: machine-independent ratios measured in one run.
    BenchGate {
        /// Also write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Plot columns of a CSV written by mbsolve (a run, a study, the data
    /// beside a figure) as SVG or PNG.
    Plot(plot::PlotArgs),
    /// Animate a run: the mechanism's motion from the scenario's geometry and
    /// the run's CSV, as an animated SVG (SMIL), a GIF, an APNG or (with
    /// ffmpeg on the PATH) an MP4/WebM.
    Animate {
        /// Scenario file of the run.
        scenario: PathBuf,
        /// The run's trajectory CSV (written by `mbsolve run`).
        csv: PathBuf,
        /// The overrides the run used (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output file: .svg (animated), .gif, .apng, .mp4, .webm, or .png
        /// (one still) [default: the CSV's path with .svg].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Playback speed: simulated seconds per second.
        #[arg(long, default_value_t = 1.0)]
        speed: f64,
        /// GIF: draw every k-th output time.
        #[arg(long, default_value_t = 1)]
        every: usize,
        /// PNG still: the output time nearest to T [default: the last].
        #[arg(long, value_name = "T")]
        at: Option<f64>,
        /// Force arrows with a key: `contacts`, `reactions` or both
        /// (comma-separated; `all`) [default: none].
        #[arg(long, value_name = "KINDS")]
        forces: Option<String>,
    },
    /// Write an interactive viewer of a run: one self-contained HTML file
    /// (no network) with the mechanism (play, time slider, speed, zoom,
    /// pan) and plots of chosen columns; `FILE.html#t=T` opens at time T.
    View {
        /// The run's output directory (of `mbsolve run`).
        dir: PathBuf,
        /// The run's file stem when DIR holds several runs.
        #[arg(long)]
        stem: Option<String>,
        /// The scenario [default: the one the run's summary records].
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Column(s) plotted at first (repeat or separate by commas).
        #[arg(long, value_name = "COLUMN[,COLUMN...]", value_delimiter = ',')]
        plot: Vec<String>,
        /// Output file [default: DIR/<stem>.view.html].
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Studies beyond the paper's figures: `constraints` runs every
    /// constraint-enforcement method on the four-bar (correct and incorrect
    /// start), the falling rod, a parallelogram chain through its singular
    /// positions and a redundant one; writes a table and figures under
    /// DIR/constraints (docs/constraint_methods.md).
    Study {
        /// Which study: `constraints`.
        #[arg(value_parser = ["constraints"])]
        which: String,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Static equilibrium from the initial state (load stepping, Newton):
    /// configuration, reactions, λ, stability; writes DIR/<stem>.static.json
    /// and DIR/<stem>.equilibrium.json (a state `run` starts from with
    /// --set initial.state=FILE).
    Static {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Override a scenario key (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Directions with |ω| / 2π below this count as neutral [Hz].
        #[arg(long, default_value_t = statics::NEUTRAL_HZ)]
        neutral_hz: f64,
    },
    /// Natural frequencies, damping ratios and mode shapes about the static
    /// equilibrium or the initial state; writes DIR/<stem>.modes.json, a
    /// figure of the first shapes and an animation of each mode.
    Modes {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Override a scenario key (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Number of modes (the lowest).
        #[arg(long, default_value_t = 6)]
        count: usize,
        /// Linearise about `static` (the equilibrium), `initial` (the
        /// initial state) or `t=T` (the state a run reaches at T s).
        #[arg(long, default_value = "static")]
        at: modes::At,
        /// Animate the first this many modes (SVG, GIF and a PNG of the
        /// largest deflection each).
        #[arg(long, default_value_t = 6)]
        animate: usize,
        /// Force arrows on the mode animations, as for `animate --forces`:
        /// `contacts`, `reactions` or both (comma-separated; `all`)
        /// [default: none].
        #[arg(long, value_name = "KINDS")]
        forces: Option<String>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Reproduce the paper's studies (figures, CSVs, tables) under DIR.
    Reproduce {
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    stream::ignore_file_size_signal();
    // The whole command runs on a thread of one rayon pool (`RAYON_NUM_THREADS`
    // threads, or one per core): the concurrent halves of the chain solve and
    // of the assembly (N ≥ 2000) then join inside the pool, instead of each
    // join being handed from this thread to the global pool and waited for
    // (stiff chain N = 10 000, generalized-α, 0.01 s: 1 thread 9.7 → 5.9 s,
    // 2 threads 6.9 → 3.8 s wall, bit-identical results).
    let pool = match rayon::ThreadPoolBuilder::new()
        .stack_size(MAIN_STACK)
        .build()
    {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: cannot start the thread pool: {e}");
            return ExitCode::from(2);
        }
    };
    pool.install(|| command(cli))
}

/// Stack of the pool threads the commands run on: the main thread's usual
/// 8 MiB (rayon's default is 2 MiB).
const MAIN_STACK: usize = 8 << 20;

/// Runs one command; errors are printed and give exit status 2.
fn command(cli: Cli) -> ExitCode {
    let result = match cli.command {
        Command::Run {
            scenario,
            set,
            unset,
            out,
            progress,
            quiet,
            view,
        } => run(&scenario, &set, &unset, &out, progress, quiet).and_then(|code| {
            if view && code == ExitCode::SUCCESS {
                let stem = scenario
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned());
                let p = view::view(&view::ViewArgs {
                    dir: out.clone(),
                    stem,
                    scenario: None,
                    columns: Vec::new(),
                    out: None,
                })?;
                if !quiet {
                    say!("wrote {}", p.display());
                }
            }
            Ok(code)
        }),
        Command::View {
            dir,
            stem,
            scenario,
            plot,
            out,
        } => view::view(&view::ViewArgs {
            dir,
            stem,
            scenario,
            columns: plot,
            out,
        })
        .map(|p| {
            say!("wrote {}", p.display());
            ExitCode::SUCCESS
        }),
        Command::Reproduce { out } => reproduce_all(&out),
        Command::Static {
            scenario,
            set,
            out,
            neutral_hz,
        } => statics::command(&scenario, &set, &out, neutral_hz),
        Command::Modes {
            scenario,
            set,
            count,
            at,
            animate,
            forces,
            out,
        } => forces_arg(forces.as_deref()).and_then(|forces| {
            modes::command(&modes::ModesArgs {
                scenario: &scenario,
                set: &set,
                count,
                at,
                out: &out,
                animate,
                forces,
            })
        }),
        Command::Study { which: _, out } => study_constraints(&out),
        Command::Check {
            scenario,
            set,
            unset,
        } => Ok(check::command(&scenario, &set, &unset)),
        Command::Animate {
            scenario,
            csv,
            set,
            out,
            speed,
            every,
            at,
            forces,
        } => forces_arg(forces.as_deref())
            .and_then(|forces| {
                animate::animate(&animate::AnimateArgs {
                    at,
                    forces,
                    out: out.unwrap_or_else(|| csv.with_extension("svg")),
                    scenario,
                    set,
                    csv,
                    speed,
                    every,
                })
            })
            .map(|p| {
                say!("wrote {}", p.display());
                ExitCode::SUCCESS
            }),
        Command::Plot(args) => plot::plot(&args).map(|p| {
            say!("wrote {}", p.display());
            ExitCode::SUCCESS
        }),
        Command::Inverse { scenario, set, out } => inverse::command(&scenario, &set, &out),
        Command::Recover { part, out } => stream::recover(&part, out.as_deref()),
        Command::Linearize(args) => linearize::command(&args),
        Command::BenchGate { json } => bench_gate(json.as_deref()),
        Command::Sweep {
            scenario,
            param,
            set,
            unset,
            metric,
            keep,
            out,
            shard,
            merge,
        } => sweep::command(&sweep::SweepArgs {
            scenario,
            params: param,
            set,
            unset,
            metrics: metric,
            keep_runs: keep == Some(sweep::Keep::Runs),
            out,
            shard,
            merge,
        }),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// The force arrows of `--forces` (none when absent).
fn forces_arg(forces: Option<&str>) -> Result<mbsolve::drawing::arrows::ArrowSet, String> {
    mbsolve::drawing::arrows::ArrowSet::parse(forces.unwrap_or(""))
        .map_err(|e| format!("--forces: {e}"))
}

/// `mbsolve run`: load, check the output files, run streaming the rows,
/// write the summary whatever the end (completed, failed, interrupted).
fn run(
    path: &std::path::Path,
    set: &[String],
    unset: &[String],
    out: &std::path::Path,
    progress: stream::ProgressMode,
    quiet: bool,
) -> Result<ExitCode, String> {
    macro_rules! report {
        ($($t:tt)*) => {{ if !quiet { say!($($t)*); } }};
    }
    let sc =
        scenario::load_with(path, &scenario::overrides(unset, set)).map_err(|e| e.to_string())?;
    for n in &sc.notes {
        eprintln!("note: {n}");
    }
    if let Some(a) = &sc.assembly {
        report!(
            "assembled initial state: ‖Φ‖ = {:.2e}, ‖Φ_q q̇ + Φ_t‖ = {:.2e} ({} Newton iterations)",
            a.position_residual,
            a.velocity_residual,
            a.iterations
        );
    }
    let assembly = check::assembly_moves(&sc);
    if let Some((text, _)) = &assembly {
        report!("assembly moved the bodies {text}");
    }
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| sc.name.clone());
    if sc.name != stem {
        report!(
            "note: the output files are named after the scenario file ({stem}.*); name = {:?} labels the run",
            sc.name
        );
    }
    // What the summary records of the input.
    let text = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let digest = sha2::Sha256::digest(&text);
    let hash: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    let mut provenance = vec![
        ("scenario", serde_json::json!(path.display().to_string())),
        ("scenario_sha256", serde_json::json!(hash)),
        ("overrides", serde_json::json!(set)),
        (
            "mbsolve_version",
            serde_json::json!(env!("CARGO_PKG_VERSION")),
        ),
    ];
    if let Some((_, json)) = assembly {
        provenance.push(("initial_assembly", json));
    }
    let mut running = serde_json::Map::new();
    running.insert("status".into(), "running".into());
    running.insert(
        "message".into(),
        "the run has not ended (or was killed): the table is incomplete; a killed run's \
         .csv.part holds whole rows up to its last flush, an .arrow.part is read with \
         `mbsolve recover DIR/STEM.arrow.part`"
            .into(),
    );
    for (k, v) in &provenance {
        running.insert((*k).into(), v.clone());
    }
    // the table's size against the free space, before any file is claimed
    let ncols = mbsolve::output::columns(&sc.system, &sc.run.outputs, &sc.sensors).len();
    if let Some(w) = stream::check_space(out, sc.run.output_intervals() + 1.0, ncols, sc.format)? {
        eprintln!("warning: {w}");
    }
    // before any file is claimed: a signal from here on ends the run with
    // its summary written, never the process with a "running" one
    stream::install_interrupt_handler();
    let mut files = stream::RunFiles::create(
        out,
        &stem,
        &sc.system,
        sc.run.outputs,
        &sc.sensors,
        sc.format,
        &running,
    )
    .map_err(|e| e.to_string())?;
    files.progress = stream::Progress::new(
        if quiet {
            stream::ProgressMode::Off
        } else {
            progress
        },
        &sc.name,
        sc.run.t0,
        sc.run.t_end,
    );

    let mut contacts = ContactMonitor::for_rods(&sc.rods);
    let mut element_contacts = ElementContacts::new(&sc.system, &sc.force_elements);
    let mut monitors: Vec<&mut dyn Monitor> = Vec::new();
    if let Some(c) = contacts.as_mut() {
        monitors.push(c);
    }
    if let Some(c) = element_contacts.as_mut() {
        monitors.push(c);
    }
    let mut summary = match simulation::simulate_into(
        &sc.system,
        &sc.q0,
        &sc.qd0,
        &sc.run,
        &mut monitors,
        &mut files,
    ) {
        Ok(s) => s,
        Err(e) => {
            let msg = format!("{}: {e}", path.display());
            files.abandon(&msg).map_err(|e| e.to_string())?;
            return Err(msg);
        }
    };
    for (k, v) in provenance {
        summary.extra.insert(k.into(), v);
    }
    if let Some(kb) = peak_memory_kb() {
        summary.extra.insert("peak_memory_kb".into(), kb.into());
    }
    files.finish(&summary).map_err(|e| e.to_string())?;
    report!(
        "{}: {} steps ({} failed), {} RHS evaluations, {:.3} s; max ‖Φ‖ = {:.3e}, final ‖Φ‖ = {:.3e}",
        sc.name,
        summary.steps,
        summary.failed_steps,
        summary.rhs_evals,
        summary.wall_s,
        summary.max_constraint_norm,
        summary.final_constraint_norm
    );
    // the thread rule's decision (crate::parallel::Rule)
    let extra = |k: &str| summary.extra.get(k).cloned().unwrap_or_default();
    report!(
        "threads: {} used, solves {}; {}",
        extra("threads"),
        if extra("split").as_bool() == Some(true) {
            "split"
        } else {
            "not split"
        },
        extra("threads_reason").as_str().unwrap_or("")
    );
    if let Some(reason) = extra("method_choice_reason").as_str() {
        report!("method: {reason}");
    }
    if let Some(c) = &contacts {
        match c.first_contact() {
            Some(t) => report!(
                "contacts: first at t = {t:.4} s, {} starts, peak normal force {:.1} N",
                c.events.iter().filter(|e| e.kind == "start").count(),
                c.peak.as_ref().map_or(0.0, |p| p.force)
            ),
            None => report!("contacts: none"),
        }
    }
    for c in element_contacts.iter().flat_map(|c| &c.contacts) {
        match c.first_contact_time {
            Some(t) => report!(
                "contact {}: first at t = {t:.4} s, {} starts, {} ends, peak normal force {:.4e} N at t = {:.4} s",
                c.force,
                c.starts.len(),
                c.ends.len(),
                c.peak_normal_force,
                c.peak_time.unwrap_or(t)
            ),
            None => report!("contact {}: none", c.force),
        }
    }
    for w in summary.warnings.iter().skip(files.warnings) {
        eprintln!("warning: {w}");
    }
    report!(
        "wrote {} ({} rows) and {}",
        files.csv.display(),
        summary.output_rows,
        files.json.display()
    );
    match summary.status.as_str() {
        "completed" => Ok(ExitCode::SUCCESS),
        status => {
            eprintln!(
                "error: run {status} at t = {}: {}",
                stream::time_text(summary.t_reached),
                summary.message.unwrap_or_default()
            );
            Ok(ExitCode::from(if status == "interrupted" {
                130
            } else {
                1
            }))
        }
    }
}

fn reproduce_all(out: &std::path::Path) -> Result<ExitCode, String> {
    let cases = reproduce::fourbar_study(out).map_err(|e| e.to_string())?;
    say!(
        "four-bar study (ode23, RelTol 1e-3, AbsTol 1e-6): {} runs",
        cases.len()
    );
    say!("{}", reproduce::fourbar_table(&cases).trim_end());
    say!("wrote {}", out.join("fourbar").display());
    let rod = reproduce::rod_study(out).map_err(|e| e.to_string())?;
    say!("falling rod, N = 10: {} runs", rod.len());
    say!("{}", reproduce::rod_table(&rod).trim_end());
    say!("wrote {}", out.join("falling_rod").display());
    let modes = reproduce::chain_modes_study(out).map_err(|e| e.to_string())?;
    say!(
        "cantilevered chain, N = {}: modes {:.3?} Hz (Euler–Bernoulli {:.3?} Hz), \
         largest shape difference {:.1e}",
        modes.n,
        modes.chain_hz,
        modes.beam_hz,
        modes.shape_difference.iter().fold(0.0f64, |a, &b| a.max(b))
    );
    say!("wrote {}", out.join("chain_modes").display());
    Ok(ExitCode::SUCCESS)
}

fn study_constraints(out: &std::path::Path) -> Result<ExitCode, String> {
    let rows = study::constraints(out)?;
    say!("{}", study::table(&rows).trim_end());
    say!("wrote {}", out.join("constraints").display());
    Ok(ExitCode::SUCCESS)
}

fn bench_gate(json: Option<&std::path::Path>) -> Result<ExitCode, String> {
    let checks = gate::run();
    let mut ok = true;
    for c in &checks {
        let op = if c.at_most { "<=" } else { ">=" };
        say!(
            "{} {}: ratio {:.2} ({op} {}) — {}",
            if c.passed { "PASS" } else { "FAIL" },
            c.name,
            c.ratio,
            c.threshold,
            c.detail
        );
        ok &= c.passed;
    }
    if let Some(p) = json {
        let text = serde_json::to_string_pretty(&checks).map_err(|e| e.to_string())?;
        std::fs::write(p, text).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    Ok(if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// This process's peak resident memory so far \[kB\]: `VmHWM` of
/// `/proc/self/status` (Linux; `None` elsewhere). It is this program's
/// own, where a parent's `wait4` (`ru_maxrss`) also counts the memory of
/// the process that spawned it, up to its `exec`.
fn peak_memory_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
