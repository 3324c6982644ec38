#!/usr/bin/env python3
"""The share of a one-thread run's samples outside any two-half pass.

    MBSOLVE_THREADS=1 perf record -e cpu-clock -F 499 --call-graph dwarf,32768 \
        -o one.data target/release/examples/threads_table 10000 radau5 0.01 1
    scripts/serial_share.py one.data [TOP]

A sample counts as "halves" when a frame of its stack (inlined frames
included) is a two-half pass (`parallel::join_if`, `team::join`,
`split_pass`, `in_halves`, the chain solve's interleaved one-thread form,
`rayon::join`), as "startup" when it is in the run's set-up (the system,
the stability check's `fastest_modes`, the solvers' analysis), else as
"serial". With two threads the serial share s of the integration caps the
gain at 1 / (s + (1 - s) / 2) (Amdahl), before any hand-over cost.
Prints the counts, the cap and the TOP (default 15) serial functions.
"""
import collections
import re
import subprocess
import sys

data = sys.argv[1]
top = int(sys.argv[2]) if len(sys.argv) > 2 else 15
out = subprocess.run(["perf", "script", "-i", data, "-F", "tid,ip,sym", "--inline"],
                     capture_output=True, text=True, check=True).stdout
samples, cur = [], None
for line in out.splitlines():
    if not line.strip():
        if cur:
            samples.append(cur)
        cur = None
        continue
    if cur is None:  # the sample's header (thread id)
        cur = []
        continue
    parts = line.strip().split(None, 1)
    cur.append(parts[1] if len(parts) > 1 else parts[0])
if cur:
    samples.append(cur)
HALF = re.compile(r"parallel::team::join|parallel::join_if|parallel::split_pass|"
                  r"parallel::in_halves|_interleaved|rayon_core::join")
START = re.compile(r"stability::fastest_modes|stiffness::stability_check|SystemBuilder|"
                   r"Index3Complex::new|with_newton_solver|ChainLdlt.*analyze|"
                   r"Envelope.*layout|chain::order")
cls, serial = collections.Counter(), collections.Counter()
for s in samples:
    if any(START.search(f) for f in s):
        cls["startup"] += 1
    elif any(HALF.search(f) for f in s):
        cls["halves"] += 1
    else:
        cls["serial"] += 1
        serial[re.sub(r"\+0x[0-9a-f]+", "", s[0])[:90] if s else "?"] += 1
total = sum(cls.values())
run = cls["halves"] + cls["serial"]
print(f"{data}: {total} samples; " + ", ".join(
    f"{k} {v} ({100 * v / total:.1f} %)" for k, v in sorted(cls.items())))
if run:
    s = cls["serial"] / run
    print(f"serial share of the integration (set-up left out): {100 * s:.1f} %; "
          f"two-thread cap {1 / (s + (1 - s) / 2):.2f}x")
for k, v in serial.most_common(top):
    print(f"  {v:6d}  {k}")
