"""The wrapper's overhead against the CLI, measured in one session (not a
test): the four-bar and a rod of N segments, each run R times by
`mbsolve run --quiet` (process wall time, CSV written) and by
`Scenario.run()` (in-process wall time); the median of each and their
ratio. Also the cost of the result's conversions for the rod (NumPy view,
pandas, Arrow).

    python python/bench/overhead.py [--rod-segments 1000] [--repeats 5]
"""

import argparse
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import mbsolve

ROOT = pathlib.Path(__file__).resolve().parents[2]


def cli_time(exe, path, sets, out):
    cmd = [str(exe), "run", str(path), "--quiet", "--out", str(out)]
    for s in sets:
        cmd += ["--set", s]
    t = time.perf_counter()
    subprocess.run(cmd, check=True)
    return time.perf_counter() - t


def py_time(sc):
    t = time.perf_counter()
    r = sc.run()
    return time.perf_counter() - t, r


def compare(label, exe, path, sets, repeats):
    sc = mbsolve.load(path, dict(s.split("=", 1) for s in sets))
    with tempfile.TemporaryDirectory() as out:
        cli = [cli_time(exe, path, sets, out) for _ in range(repeats)]
    py = []
    for _ in range(repeats):
        dt, r = py_time(sc)
        py.append(dt)
    c, p = statistics.median(cli), statistics.median(py)
    print(f"{label}: CLI {c:.4f} s, Python {p:.4f} s, Python/CLI {p / c:.3f} "
          f"(median of {repeats}; rows {len(r)}, columns {len(r.columns)}, "
          f"integration wall_s {r.summary['wall_s']:.4f} s)")
    return r


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rod-segments", type=int, default=1000)
    ap.add_argument("--rod-end", type=float, default=0.002)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    exe = ROOT / "target" / "release" / "mbsolve"
    compare("four-bar (2 s)", exe, ROOT / "scenarios" / "fourbar.toml", [], a.repeats)
    r = compare(f"rod N = {a.rod_segments} ({a.rod_end} s, genalpha h = 1e-4)", exe,
                ROOT / "scenarios" / "falling_rod.toml",
                [f"rod.segments={a.rod_segments}", f"time.end={a.rod_end}",
                 "integrator.method=genalpha", "integrator.step=1e-4"], a.repeats)
    t = time.perf_counter()
    x = r["rod.segment[1].x"]
    t_view = time.perf_counter() - t
    assert np.shares_memory(x, r.data)
    import pandas  # noqa: F401  (imports are not the conversion's cost)
    import pyarrow  # noqa: F401

    t = time.perf_counter()
    r.to_pandas()
    t_pd = time.perf_counter() - t
    t = time.perf_counter()
    r.to_arrow()
    t_pa = time.perf_counter() - t
    print(f"rod result ({r.data.nbytes / 1e6:.1f} MB): column view {t_view * 1e6:.1f} us, "
          f"to_pandas {t_pd * 1e3:.1f} ms, to_arrow {t_pa * 1e3:.1f} ms")


if __name__ == "__main__":
    sys.exit(main())
