//! The `mbsolve` binary as the CLI tests call it: run from the package
//! root (so `scenarios/…` paths resolve), without Rust backtraces (so a
//! panic is the message, not a trace), output captured.

use std::path::Path;
use std::process::{Command, Output};

/// The binary, to be given arguments: run from the package root, with
/// `RUST_BACKTRACE=0`.
pub fn exe() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mbsolve"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_BACKTRACE", "0");
    c
}

/// Runs the binary with `args` to its end; its status and output.
pub fn mbsolve(args: &[&str]) -> Output {
    exe().args(args).output().expect("binary runs")
}

/// stderr of a finished command, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// stdout of a finished command, as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The absolute path of the shipped scenario `name` (`scenarios/NAME`).
pub fn scenario(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

/// `mbsolve run SCENARIO --out DIR -q` with `--set` for each of `set`,
/// asserted to succeed; the path of the CSV it wrote.
pub fn run_csv(dir: &Path, scenario: &str, set: &[&str]) -> String {
    let mut args = vec!["run", scenario, "--out", dir.to_str().unwrap(), "-q"];
    for s in set {
        args.extend(["--set", s]);
    }
    let o = mbsolve(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let stem = Path::new(scenario).file_stem().unwrap().to_str().unwrap();
    dir.join(format!("{stem}.csv"))
        .to_str()
        .unwrap()
        .to_string()
}

/// `mbsolve animate SCENARIO CSV ARGS… --out OUT`: its status and output.
pub fn animate(scenario: &str, csv: &str, out: &Path, args: &[&str]) -> Output {
    let mut all = vec!["animate", scenario, csv];
    all.extend(args);
    all.extend(["--out", out.to_str().unwrap()]);
    mbsolve(&all)
}

/// Width, height and pixels (RGB rows) of a PNG file.
pub fn png_rgb(path: &Path) -> (usize, usize, Vec<u8>) {
    let dec = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    let rgb = buf[..info.buffer_size()]
        .chunks(ch)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width as usize, info.height as usize, rgb)
}
