"""The wrapper's overhead against the CLI, measured in one session (a
bench, not a test): the four-bar and a rod of N segments, each run R times,
CLI and Python interleaved. Three figures per case, all medians:

- **library call**: the summary's `wall_s` — the time of the library's
  `simulate_into` (integration and the rows handed to the sink) in each
  front end. The CLI's sink formats and writes the CSV as it goes; the
  wrapper's copies each row into memory (and checks Python's signals every
  50 ms). Their ratio is the wrapper's cost inside the run.
- **wrapper call**: the wall time of `Scenario.run()` — the scenario text
  parsed and built, the library call, the summary, the rows transposed to
  column-major and handed to NumPy — against the CLI's library call. This
  is the ratio the targets (≤ 5 % four-bar, ≤ 1 % 1000-segment rod) are
  about: what a Python user pays over the library call the CLI makes.
- **CPU**: the CPU time of `Scenario.run()` (`time.process_time`, every
  thread of this process) against the CPU time of the whole `mbsolve run`
  process (`getrusage(RUSAGE_CHILDREN)`: start, parse, run, CSV and
  summary files). Both parse and build the scenario and check its rates
  at t0 outside the library call; CPU time is steadier than wall time on a
  loaded machine. Both runs are single-threaded here (the rod's state has
  6000 entries, below the 12000 from which a second thread pays).
- **process**: the CLI's process wall time, for reference.

    python python/bench/overhead.py [--rod-segments 1000] [--rod-end 0.02] [--repeats 7]
"""

import argparse
import json
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import mbsolve

ROOT = pathlib.Path(__file__).resolve().parents[2]


def children_cpu():
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def cli_run(exe, path, sets, out):
    """(process wall, summary wall_s, process CPU) of one `mbsolve run --quiet`."""
    cmd = [str(exe), "run", str(path), "--quiet", "--out", str(out)]
    for s in sets:
        cmd += ["--set", s]
    c = children_cpu()
    t = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t
    cpu = children_cpu() - c
    summary = json.loads((pathlib.Path(out) / f"{path.stem}.summary.json").read_text())
    return wall, summary["wall_s"], cpu


def py_run(sc):
    """(Scenario.run() wall, summary wall_s, CPU, result) of one run."""
    c = time.process_time()
    t = time.perf_counter()
    r = sc.run()
    wall = time.perf_counter() - t
    cpu = time.process_time() - c
    return wall, r.summary["wall_s"], cpu, r


def compare(label, exe, path, sets, repeats):
    sc = mbsolve.load(path, dict(s.split("=", 1) for s in sets))
    cli_proc, cli_lib, cli_cpu, py_call, py_lib, py_cpu = [], [], [], [], [], []
    with tempfile.TemporaryDirectory() as out:
        cli_run(exe, path, sets, out)  # warm the file cache
        py_run(sc)
        for _ in range(repeats):
            w, l, c = cli_run(exe, path, sets, out)
            cli_proc.append(w)
            cli_lib.append(l)
            cli_cpu.append(c)
            w, l, c, r = py_run(sc)
            py_call.append(w)
            py_lib.append(l)
            py_cpu.append(c)
    m = statistics.median
    print(f"{label} (rows {len(r)}, columns {len(r.columns)}; median of {repeats}):")
    print(f"  library call  CLI {m(cli_lib):.4f} s  Python {m(py_lib):.4f} s  "
          f"Python/CLI {m(py_lib) / m(cli_lib):.3f}")
    print(f"  wrapper call  Scenario.run() {m(py_call):.4f} s  / CLI library call "
          f"{m(py_call) / m(cli_lib):.3f}  (outside the library call: "
          f"{(m(py_call) - m(py_lib)) * 1e3:.2f} ms)")
    print(f"  CPU           Scenario.run() {m(py_cpu):.4f} s  CLI process {m(cli_cpu):.4f} s  "
          f"Python/CLI {m(py_cpu) / m(cli_cpu):.3f}")
    print(f"  CLI process   {m(cli_proc):.4f} s wall")
    per_round = [p / c for p, c in zip(py_call, cli_lib)]
    print(f"  per-round wrapper/CLI-library ratios: min {min(per_round):.3f}, "
          f"median {m(per_round):.3f}, max {max(per_round):.3f}")
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rod-segments", type=int, default=1000)
    ap.add_argument("--rod-end", type=float, default=0.02)
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
    exe = ROOT / "target" / "release" / "mbsolve"
    compare("four-bar (2 s, ode23)", exe, ROOT / "scenarios" / "fourbar.toml", [], a.repeats)
    r = compare(f"rod N = {a.rod_segments} ({a.rod_end} s, genalpha h = 1e-4)", exe,
                ROOT / "scenarios" / "falling_rod.toml",
                [f"rod.segments={a.rod_segments}", f"time.end={a.rod_end}",
                 "integrator.method=genalpha", "integrator.step=1e-4"], a.repeats)
    t = time.perf_counter()
    x = r["rod.segment[1].x"]
    t_view = time.perf_counter() - t
    assert np.shares_memory(x, r.data)
    print(f"rod result ({r.data.nbytes / 1e6:.1f} MB): column view {t_view * 1e6:.1f} us")
    try:
        import pandas  # noqa: F401  (imports are not the conversion's cost)
        import pyarrow  # noqa: F401
    except ImportError:
        print("(pandas/pyarrow not installed: conversions not timed)")
        return
    t = time.perf_counter()
    r.to_pandas()
    t_pd = time.perf_counter() - t
    t = time.perf_counter()
    r.to_arrow()
    t_pa = time.perf_counter() - t
    print(f"  to_pandas {t_pd * 1e3:.1f} ms, to_arrow {t_pa * 1e3:.1f} ms")


if __name__ == "__main__":
    sys.exit(main())
