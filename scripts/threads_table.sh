#!/usr/bin/env bash
# The two-thread table of docs/scaling.md: the stiff chain (N = 10 000 by
# default) with radau5, ndf and generalized-α, one thread against two
# (`examples/threads_table.rs`: a rayon pool of 1 or 2 threads, setting
# `auto`), on the machine as it is ("quiet") and beside one busy process
# per core (`yes > /dev/null`, started and stopped by this script).
# Rounds interleave 1 and 2 threads; every run is its own process.
#
#   scripts/threads_table.sh [N] [ROUNDS]
#
# Environment: T_RADAU5, T_NDF, T_GENALPHA (simulated seconds; defaults
# 0.02, 0.02, 0.005), BUSY_MODES ("quiet busy" by default; "busy" or
# "quiet" for one), OUT (a file for the raw JSON lines; default a
# temporary file, printed at the end), BIN (a `threads_table` binary to
# run instead of building this tree's: another build's, for a before /
# after table from one run of this script), CLOCK (1: the runs keep their
# `threads_clock`, MBSOLVE_THREADS_CLOCK=1, at the cost of a few system
# calls per pass; default 0). Its columns from the summary's
# `threads_clock`, for the one- and the two-thread run: the share of the
# run inside passes in halves, the gain a free second thread would bound
# (Amdahl, each pass as long as its longer half), the seconds outside and
# inside the halves, and of the two-thread run's halves the longer halves'
# seconds and the rest (the hand-over's cost and waits), and the one-thread
# run's serial stretches between two passes of at least 0.3 ms and 1 ms
# (the helper's spin) of CPU. The summary's `threads_caller_parks` and
# `threads_helper_wakes` of the two-thread run: waits that parked, and
# wake-ups of a parked helper.
set -euo pipefail
cd "$(dirname "$0")/.."
N=${1:-10000}
ROUNDS=${2:-2}
T_RADAU5=${T_RADAU5:-0.02}
T_NDF=${T_NDF:-0.02}
T_GENALPHA=${T_GENALPHA:-0.005}
BUSY_MODES=${BUSY_MODES:-"quiet busy"}
OUT=${OUT:-$(mktemp /tmp/threads_table.XXXXXX.jsonl)}
export CARGO_PROFILE_RELEASE_INCREMENTAL=true
if [ "${CLOCK:-0}" = 1 ]; then export MBSOLVE_THREADS_CLOCK=1; fi
if [ -n "${BIN:-}" ]; then
  bin=$BIN
else
  cargo build --release --example threads_table >&2
  bin=target/release/examples/threads_table
fi

busy_pids=()
stop_busy() {
  for p in "${busy_pids[@]}"; do kill "$p" 2>/dev/null || true; done
  busy_pids=()
}
trap stop_busy EXIT

: >"$OUT"
echo "start: $(date -u '+%Y-%m-%d %H:%M UTC'); $(uptime)" >&2
for mode in $BUSY_MODES; do
  if [ "$mode" = busy ]; then
    for _ in $(seq "$(nproc)"); do
      yes >/dev/null &
      busy_pids+=($!)
    done
  fi
  for method in radau5 ndf genalpha; do
    case $method in
      radau5) t=$T_RADAU5 ;;
      ndf) t=$T_NDF ;;
      genalpha) t=$T_GENALPHA ;;
    esac
    for round in $(seq "$ROUNDS"); do
      for threads in 1 2; do
        load=$(cut -d' ' -f1 /proc/loadavg)
        line=$("$bin" "$N" "$method" "$t" "$threads")
        echo "$line" | jq -c --arg mode "$mode" --arg round "$round" --arg load "$load" \
          '. + {mode: $mode, round: ($round | tonumber), load: ($load | tonumber)}' >>"$OUT"
        echo "$mode $method round $round threads $threads: $(echo "$line" | jq -c '{wall_s, cpu_s, halves_split, halves_taken_back, halves_taken_back_awake, halves_solo, threads_passes, caller_parks, helper_wakes, newton_iterations, threads_rule, gaps: .threads_clock.gaps}')" >&2
      done
    done
  done
  stop_busy
done
echo "end: $(date -u '+%Y-%m-%d %H:%M UTC'); $(uptime)" >&2
echo "raw lines: $OUT" >&2
python3 - "$OUT" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
print("| method | machine | round | load | 1 thread wall (CPU) [s] | 2 threads wall (CPU) [s] | 1/2 wall | in halves 1 / 2 | bound 1 / 2 | outside halves 1 / 2 [s] | in halves 1 / 2 [s] | 2: longer halves, hand-over [s] | halves split / taken back / solo | parks: caller, helper | serial gaps ≥ 0.3 / 1 ms (1 thread) | probes: team, alone, skipped | same tip |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
key = lambda r: (r["mode"], r["method"], r["round"])
groups = {}
for r in rows:
    groups.setdefault(key(r), {})[r["threads"]] = r
for (mode, method, rnd), g in groups.items():
    if 1 not in g or 2 not in g:
        continue
    a, b = g[1], g[2]
    rule = b.get('threads_rule') or {}
    # the run's clock (summary `threads_clock`): share of the run in
    # passes in halves, Amdahl's bound with each pass as long as its
    # longer half, the time outside / inside the halves, and with two
    # threads the longer halves and the rest of the passes' time (hand-over)
    ca, cb = a.get('threads_clock') or {}, b.get('threads_clock') or {}
    if ca.get('run_s') and cb.get('run_s'):
        share = lambda c: f"{100 * c['halves_s'] / c['run_s']:.0f} %"
        bound = lambda c: f"{c['run_s'] / (c['run_s'] - c['halves_s'] + c['longer_s']):.2f}×"
        out = lambda c: f"{c['run_s'] - c['halves_s']:.2f}"
        clock = (f"{share(ca)} / {share(cb)} | {bound(ca)} / {bound(cb)} "
                 f"| {out(ca)} / {out(cb)} | {ca['halves_s']:.2f} / {cb['halves_s']:.2f} "
                 f"| {cb['longer_s']:.2f}, {cb['halves_s'] - cb['longer_s']:.2f}")
    else:
        clock = "– | – | – | – | –"
    print(f"| {method} | {mode} | {rnd} | {a['load']:.1f} | {a['wall_s']:.2f} ({a['cpu_s']:.2f}) "
          f"| {b['wall_s']:.2f} ({b['cpu_s']:.2f}) | {a['wall_s'] / b['wall_s']:.2f}× | {clock} "
          f"| {b['halves_split']} / {b['halves_taken_back']} / {b['halves_solo']} "
          f"| {b.get('caller_parks', '–')}, {b.get('helper_wakes', '–')} "
          f"| {' / '.join(str(g) for g in ca['gaps'][2:4]) if 'gaps' in ca else '–'} "
          f"| {rule.get('team', '–')}, {rule.get('alone', '–')}, {rule.get('skipped', '–')} "
          f"| {'yes' if a['tip_bits'] == b['tip_bits'] else 'NO'} |")
PY
