//! A run's files, written as the run goes: CSV rows streamed to a
//! temporary name and renamed when the run ends, the summary JSON replaced
//! atomically (a `"running"` summary at the start, the final one at the
//! end, also on failure and interrupt), no writing through symlinks;
//! progress on stderr; SIGINT/SIGTERM finish the step and end the run
//! with status `"interrupted"`.

use crate::output::{
    columns_json, create_fresh, remove_stale, sibling, write_atomic, write_summary_json,
    OutputError,
};
use mbsolve::integrate::Stats;
use mbsolve::model::{Sensor, System};
use mbsolve::output::{columns, Format, RowBuilder, TableWriter};
use mbsolve::simulation::{OutputQuantities, Sample, Sink, Summary};
use std::io::{IsTerminal, Write};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Set by SIGINT/SIGTERM; the running step finishes, the files are
/// written, the run ends with status "interrupted".
pub static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Install the SIGINT/SIGTERM handler (once). A second signal while the
/// first is being handled exits at once with 130, leaving a summary that
/// says which of the run's files are whole ([`second_signal`]).
pub fn install_interrupt_handler() {
    let _ = ctrlc::set_handler(|| {
        if INTERRUPTED.swap(true, Ordering::SeqCst) {
            second_signal();
            std::process::exit(130);
        }
    });
}

/// Ignore SIGXFSZ, so that a write beyond the file-size limit (`ulimit -f`)
/// fails with "File too large" and the run ends as `"failed"` with its
/// summary written, instead of the signal killing the process and leaving
/// a `"running"` summary and the lock.
pub fn ignore_file_size_signal() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to SIG_IGN, before any thread
    // that writes files is started
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// The files of the run in progress, for the second signal's handler;
/// `None` before they are claimed.
static CLAIMED: std::sync::Mutex<Option<Claimed>> = std::sync::Mutex::new(None);

/// What a run has claimed in its output directory.
struct Claimed {
    /// `DIR/<stem>.summary.json`.
    summary: PathBuf,
    /// The finished table, `DIR/<stem>.csv` or `.arrow`.
    table: PathBuf,
    /// The table being written, `DIR/<stem>.csv.part` or `.arrow.part`.
    part: PathBuf,
    /// `DIR/<stem>.lock`.
    lock: PathBuf,
    /// The final summary is written (or being written, under the lock):
    /// the second signal's handler only removes the lock.
    summary_written: bool,
}

/// A second signal: the summary must not stay "running" nor claim what is
/// not so. It is written in place (no temporary file) with status
/// `"interrupted"` and says whether the table was finished (renamed from
/// its `.part`) or not; this process's temporary summary and its lock are
/// removed.
fn second_signal() {
    let mut claim = CLAIMED.lock().unwrap_or_else(|p| p.into_inner());
    let Some(c) = claim.take() else {
        return;
    };
    if c.summary_written {
        let _ = std::fs::remove_file(&c.lock);
        return;
    }
    let _ = std::fs::remove_file(sibling(&c.summary, &format!(".{}.tmp", std::process::id())));
    let message = if c.part.exists() || !c.table.exists() {
        format!(
            "a second signal ended the process at once: the table was not finished; its rows \
             up to the last flush are in {}",
            c.part.display()
        )
    } else {
        format!(
            "a second signal ended the process at once while the run's files were finished: \
             the table {} is complete up to where the first signal stopped the run; the rest \
             of this summary was lost",
            c.table.display()
        )
    };
    let text = serde_json::json!({"status": "interrupted", "message": message});
    let _ = std::fs::write(&c.summary, format!("{text:#}\n"));
    let _ = std::fs::remove_file(&c.lock);
}

/// Write `summary`; where the atomic write fails (disk full, file too
/// large), overwrite the existing summary in place with its status and
/// message, so that it never stays "running".
fn write_final_summary(path: &Path, summary: &Summary) -> Result<(), OutputError> {
    write_summary_json(path, summary).inspect_err(|_| {
        let short = serde_json::json!({"status": summary.status, "message": summary.message});
        let _ = std::fs::write(path, format!("{short}\n"));
    })
}

/// A time \[s\] for a message: plain decimals between 10⁻³ and 10⁶ (and
/// 0), scientific notation otherwise (never hundreds of digits).
pub fn time_text(t: f64) -> String {
    if t == 0.0 || (1e-3..1e6).contains(&t.abs()) {
        format!("{t}")
    } else {
        format!("{t:e}")
    }
}

/// A size in bytes for a message: kB, MB or GB (10³, 10⁶, 10⁹ bytes) with
/// three decimals, the unit chosen so the number is at least 1 (kB below).
fn bytes_text(b: f64) -> String {
    let (div, unit) = if b >= 1e9 {
        (1e9, "GB")
    } else if b >= 1e6 {
        (1e6, "MB")
    } else {
        (1e3, "kB")
    };
    format!("{:.3} {unit}", b / div)
}

/// Free bytes for an unprivileged writer on the file system holding
/// `dir` (or its nearest existing ancestor), and the process's file-size
/// limit (`RLIMIT_FSIZE`, `None` when unlimited); `None` where unknown.
#[cfg(unix)]
fn free_space(dir: &Path) -> (Option<f64>, Option<f64>) {
    use std::os::unix::ffi::OsStrExt;
    let mut d = dir;
    while !d.exists() {
        match d.parent() {
            Some(p) if !p.as_os_str().is_empty() => d = p,
            _ => {
                d = Path::new(".");
                break;
            }
        }
    }
    let free = std::ffi::CString::new(d.as_os_str().as_bytes())
        .ok()
        .and_then(|c| {
            // SAFETY: a valid C string and a zeroed statvfs to fill
            let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
            let r = unsafe { libc::statvfs(c.as_ptr(), &mut st) };
            (r == 0).then_some(st.f_bavail as f64 * st.f_frsize as f64)
        });
    // SAFETY: a zeroed rlimit to fill
    let mut rl: libc::rlimit = unsafe { std::mem::zeroed() };
    let limit = (unsafe { libc::getrlimit(libc::RLIMIT_FSIZE, &mut rl) } == 0
        && rl.rlim_cur != libc::RLIM_INFINITY)
        .then_some(rl.rlim_cur as f64);
    (free, limit)
}

#[cfg(not(unix))]
fn free_space(_: &Path) -> (Option<f64>, Option<f64>) {
    (None, None)
}

/// The table's size before the run, at least `rows × columns ×`
/// [`Format::bytes_per_value`], against the free space of the output's
/// file system and the file-size limit. More than either: an error naming the
/// size, the space and what to change; more than half the free space: a
/// warning (returned).
pub fn check_space(
    dir: &Path,
    rows: f64,
    columns: usize,
    format: Format,
) -> Result<Option<String>, String> {
    let bytes = rows * columns as f64 * format.bytes_per_value();
    let gb = bytes_text;
    let size = format!(
        "the table will take at least {} ({rows:.0} rows × {columns} columns × {} bytes, \
         {} format)",
        gb(bytes),
        format.bytes_per_value(),
        format.extension()
    );
    let fix = "raise output.dt, trim output.quantities, or choose another --out";
    let (free, limit) = free_space(dir);
    if let Some(l) = limit.filter(|&l| bytes > l) {
        return Err(format!(
            "{}: {size}, more than the process's file-size limit of {} (ulimit -f); {fix}",
            dir.display(),
            gb(l)
        ));
    }
    match free {
        Some(f) if bytes > f => Err(format!(
            "{}: {size}, more than the {} free on its file system; {fix}",
            dir.display(),
            gb(f)
        )),
        Some(f) if bytes > 0.5 * f => Ok(Some(format!(
            "{}: {size}, more than half the {} free on its file system",
            dir.display(),
            gb(f)
        ))),
        _ => Ok(None),
    }
}

/// `DIR/<stem>.lock`, holding the process id of the run writing
/// `DIR/<stem>.*`: a second run into the same files refuses up front; a
/// lock whose process is gone (killed) is taken over. Removed on drop.
pub struct RunLock {
    path: PathBuf,
}

/// Whether process `pid` exists.
fn alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        // SAFETY: signal 0 only checks that the process exists
        let r = unsafe { libc::kill(pid as libc::pid_t, 0) };
        r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

impl RunLock {
    /// Take the lock of `DIR/<stem>.*` (module docs).
    pub fn take(dir: &Path, stem: &str) -> Result<Self, OutputError> {
        let path = dir.join(format!("{stem}.lock"));
        for _ in 0..3 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    writeln!(f, "{}", std::process::id())
                        .map_err(|e| OutputError::new(&path, e))?;
                    return Ok(Self { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let holder = std::fs::read_to_string(&path)
                        .ok()
                        .and_then(|s| s.trim().parse::<u32>().ok());
                    match holder {
                        Some(pid) if pid != std::process::id() && alive(pid) => {
                            return Err(OutputError::new(
                                &path,
                                format!(
                                    "another mbsolve run (process {pid}) is writing {stem}.* in \
                                     this directory; choose another --out or wait for it to end"
                                ),
                            ))
                        }
                        // a killed run's lock, or one being written: take it over
                        _ => remove_stale(&path)?,
                    }
                }
                Err(e) => return Err(OutputError::new(&path, e)),
            }
        }
        Err(OutputError::new(&path, "could not be taken"))
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// `mbsolve recover`: [`mbsolve::output::recover_arrow`] from `part` into
/// `out` (default: `part` without `.part`), written beside it and renamed.
pub fn recover(part: &Path, out: Option<&Path>) -> Result<std::process::ExitCode, String> {
    #[cfg(feature = "arrow")]
    {
        let name = part.to_string_lossy();
        let out = match (out, name.strip_suffix(".part")) {
            (Some(o), _) => o.to_path_buf(),
            (None, Some(stem)) => PathBuf::from(stem),
            (None, None) => {
                return Err(format!(
                    "{}: not a .part file; name the file to write with --out",
                    part.display()
                ))
            }
        };
        let r = std::fs::File::open(part).map_err(|e| format!("{}: {e}", part.display()))?;
        let tmp = sibling(&out, &format!(".{}.tmp", std::process::id()));
        let w = std::io::BufWriter::new(create_fresh(&tmp).map_err(|e| e.to_string())?);
        let rows = mbsolve::output::recover_arrow(r, w).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            format!("{}: {e}", part.display())
        })?;
        std::fs::rename(&tmp, &out).map_err(|e| format!("{}: {e}", out.display()))?;
        println!("wrote {} ({rows} rows recovered)", out.display());
        Ok(std::process::ExitCode::SUCCESS)
    }
    #[cfg(not(feature = "arrow"))]
    {
        let _ = (part, out);
        Err("recover: this build has no Arrow support (feature 'arrow')".into())
    }
}

/// How progress is shown on stderr.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ProgressMode {
    /// A live line when stderr is a terminal, nothing otherwise.
    Auto,
    /// A plain line every 10 s (for logs).
    Plain,
    /// No progress.
    Off,
}

/// Progress of one run on stderr: simulated time, percentage, steps,
/// rejected steps, wall time, ETA.
pub struct Progress {
    live: bool,
    every: Duration,
    t0: f64,
    t_end: f64,
    start: Instant,
    last: Option<Instant>,
    label: String,
}

impl Progress {
    /// Progress of a run over `[t0, t_end]`.
    pub fn new(mode: ProgressMode, label: &str, t0: f64, t_end: f64) -> Option<Self> {
        let live = match mode {
            ProgressMode::Off => return None,
            ProgressMode::Auto if !std::io::stderr().is_terminal() => return None,
            ProgressMode::Auto => true,
            ProgressMode::Plain => false,
        };
        Some(Self {
            live,
            every: if live {
                Duration::from_millis(200)
            } else {
                Duration::from_secs(10)
            },
            t0,
            t_end,
            start: Instant::now(),
            last: None,
            label: label.to_string(),
        })
    }

    fn line(&self, t: f64, stats: &Stats) -> String {
        let frac = ((t - self.t0) / (self.t_end - self.t0)).clamp(0.0, 1.0);
        let wall = self.start.elapsed().as_secs_f64();
        let eta = if frac > 0.0 {
            format!("{:.0} s", wall * (1.0 - frac) / frac)
        } else {
            "?".into()
        };
        format!(
            "{}: t = {t:.4e} s ({:.1} %), {} steps ({} rejected), {wall:.1} s, ETA {eta}",
            self.label,
            100.0 * frac,
            stats.steps,
            stats.failed_steps
        )
    }

    /// Show the state if it is time to.
    pub fn update(&mut self, t: f64, stats: &Stats) {
        let now = Instant::now();
        let due = match self.last {
            None => now.duration_since(self.start) >= self.every,
            Some(l) => now.duration_since(l) >= self.every,
        };
        if !due {
            return;
        }
        self.last = Some(now);
        let line = self.line(t, stats);
        let mut e = std::io::stderr().lock();
        if self.live {
            let _ = write!(e, "\r\x1b[2K{line}");
        } else {
            let _ = writeln!(e, "{line}");
        }
        let _ = e.flush();
    }

    /// Clear the live line (before other stderr output and at the end).
    pub fn clear(&self) {
        if self.live && self.last.is_some() {
            let _ = write!(std::io::stderr(), "\r\x1b[2K");
        }
    }
}

/// The files of one run: `DIR/<stem>.csv` or `.arrow` (streamed as
/// `DIR/<stem>.csv.part`), `DIR/<stem>.columns.json` (names and units) and
/// `DIR/<stem>.summary.json`.
pub struct RunFiles<'s> {
    /// Final table path.
    pub csv: PathBuf,
    /// Summary JSON path.
    pub json: PathBuf,
    part: PathBuf,
    table: Option<Box<dyn TableWriter + Send>>,
    rows: usize,
    last_flush: Instant,
    flush_every: Duration,
    builder: RowBuilder<'s>,
    /// Progress display, if any.
    pub progress: Option<Progress>,
    /// Warnings seen while running (printed as they come).
    pub warnings: usize,
    /// Held until the files are finished (dropped last).
    _lock: RunLock,
}

impl<'s> RunFiles<'s> {
    /// Check and claim the output files before the run starts: the
    /// directory exists (or is created) and is writable, a `"running"`
    /// summary replaces any previous run's summary, a previous table is
    /// removed, the table's header is written to the temporary file.
    pub fn create(
        out: &Path,
        stem: &str,
        sys: &'s System,
        quantities: OutputQuantities,
        sensors: &'s [Sensor],
        format: Format,
        running: &serde_json::Map<String, serde_json::Value>,
    ) -> Result<Self, OutputError> {
        std::fs::create_dir_all(out).map_err(|e| OutputError::new(out, e))?;
        let lock = RunLock::take(out, stem)?;
        let csv = out.join(format!("{stem}.{}", format.extension()));
        let json = out.join(format!("{stem}.summary.json"));
        let part = sibling(&csv, ".part");
        let text = serde_json::to_string_pretty(running).map_err(|e| OutputError::new(&json, e))?;
        write_atomic(&json, &(text + "\n"))?;
        {
            let mut g = CLAIMED.lock().unwrap_or_else(|p| p.into_inner());
            *g = Some(Claimed {
                summary: json.clone(),
                table: csv.clone(),
                part: part.clone(),
                lock: lock.path.clone(),
                summary_written: false,
            });
        }
        for f in Format::NAMES {
            remove_stale(&out.join(format!("{stem}.{f}")))?;
        }
        let cols = columns(sys, &quantities, sensors);
        let table = format
            .writer(create_fresh(&part)?, &cols)
            .map_err(|e| OutputError::new(&part, e))?;
        write_atomic(
            &out.join(format!("{stem}.columns.json")),
            &columns_json(&cols),
        )?;
        Ok(Self {
            csv,
            json,
            part,
            table: Some(table),
            rows: 0,
            last_flush: Instant::now(),
            flush_every: format.flush_interval(),
            builder: RowBuilder::new(sys, quantities, sensors),
            progress: None,
            warnings: 0,
            _lock: lock,
        })
    }

    /// End of the run, whatever its status: write the buffered rows and the
    /// format's trailer, rename the table into place, write the final
    /// summary.
    pub fn finish(&mut self, summary: &Summary) -> Result<(), OutputError> {
        if let Some(p) = &self.progress {
            p.clear();
        }
        // the trailer and the sync may take long: outside the claim, so a
        // second signal does not wait for them
        let table = match self.table.take() {
            Some(mut t) => t
                .finish()
                .map_err(|e| OutputError::new(&self.part, e))
                .and_then(|()| {
                    drop(t);
                    std::fs::File::open(&self.part)
                        .and_then(|f| f.sync_all())
                        .map_err(|e| OutputError::new(&self.part, e))
                })
                .map(|()| true),
            None => Ok(false),
        };
        under_claim(|| {
            let renamed = table.and_then(|finished| match finished {
                true => std::fs::rename(&self.part, &self.csv)
                    .map_err(|e| OutputError::new(&self.csv, e)),
                false => Ok(()),
            });
            match renamed {
                Ok(()) => write_final_summary(&self.json, summary),
                Err(e) => {
                    // the table could not be finished: the run failed, and
                    // its summary says so rather than staying "running"
                    let mut s = summary.clone();
                    s.message = Some(format!(
                        "{}; finishing the table failed: {e}",
                        s.message.as_deref().unwrap_or(&s.status)
                    ));
                    s.status = "failed".into();
                    let _ = write_final_summary(&self.json, &s);
                    Err(e)
                }
            }
        })
    }
}

/// Rename the table into place and write the final summary (`finish`)
/// while holding the claim, then mark it written: a second signal that
/// arrives meanwhile waits for it instead of racing it (its handler would
/// see a table half renamed, remove the temporary summary, and the process
/// exit could cut an in-place write short), and one that comes later only
/// removes the lock. Where the handler has already taken the claim, its
/// summary stands and nothing is written.
fn under_claim(finish: impl FnOnce() -> Result<(), OutputError>) -> Result<(), OutputError> {
    let mut claim = CLAIMED.lock().unwrap_or_else(|p| p.into_inner());
    let Some(c) = claim.as_mut().filter(|c| !c.summary_written) else {
        return Ok(());
    };
    c.summary_written = true;
    finish()
}

impl RunFiles<'_> {
    /// The run could not start: no CSV, a summary that says so.
    pub fn abandon(&mut self, message: &str) -> Result<(), OutputError> {
        self.table = None;
        remove_stale(&self.part)?;
        let s = serde_json::json!({"status": "failed", "message": message, "output_rows": 0});
        let text = serde_json::to_string_pretty(&s).map_err(|e| OutputError::new(&self.json, e))?;
        under_claim(|| write_atomic(&self.json, &(text + "\n")))
    }
}

impl Sink for RunFiles<'_> {
    fn output(&mut self, s: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        let t = self.table.as_mut().ok_or("output already closed")?;
        t.write_row(self.builder.row(s))
            .map_err(|e| OutputError::new(&self.part, e))?;
        self.rows += 1;
        // whole rows on disk at least every second (CSV)
        if self.last_flush.elapsed() >= self.flush_every {
            t.flush().map_err(|e| OutputError::new(&self.part, e))?;
            self.last_flush = Instant::now();
        }
        Ok(())
    }

    fn progress(&mut self, t: f64, stats: &Stats) -> ControlFlow<String> {
        if INTERRUPTED.load(Ordering::Relaxed) {
            return ControlFlow::Break(format!("interrupted by a signal at t = {t:e}"));
        }
        if let Some(p) = self.progress.as_mut() {
            p.update(t, stats);
        }
        ControlFlow::Continue(())
    }

    fn warning(&mut self, message: &str) {
        self.warnings += 1;
        if let Some(p) = &self.progress {
            p.clear();
        }
        eprintln!("warning: {message}");
    }
}
