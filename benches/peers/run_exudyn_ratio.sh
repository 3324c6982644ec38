#!/usr/bin/env bash
# Exudyn beside mbsolve on the cantilevered stiff chain of the peers
# (issue 12): the same N and step h, index-3 generalized-α in both (Exudyn:
# ρ∞ = 0.9, Eigen sparse LU; mbsolve: `examples/stiff_chain.rs`), one process
# tree. Prints CPU seconds, the tip x error at t = 0.1 s against the
# reference (`builders::stiff_chain_reference_tip`) and the CPU ratio
# Exudyn / mbsolve, at equal h, where both tip errors are printed beside it.
# Not part of CI (Exudyn alone takes ~2 min of CPU at N = 1000).
#
#   benches/peers/run_exudyn_ratio.sh [N ...]        (default: 100 1000)
#
# MBS_EXTRA adds mbsolve runs at other methods, each as EXAMPLE:SPEC run for
# every N, e.g. MBS_EXTRA="stiff_chain_rtol:ndf:1e-5:3 radau_chain:radau5:4e-4"
# (examples/stiff_chain_rtol.rs, examples/radau_chain.rs); the table gives
# Exudyn's CPU over each run's and says whether that run's tip error is at
# most Exudyn's (the issue's ratio at equal tip error).
#
# Environment: MBSOLVE_PEERS  directory of exudyn_chain.py and chain_model.py
#                             (default: ../shared/peers beside the repository;
#                             they are not copied into the repository: no licence)
#              H              step (default 1e-5)
#              PEERS_VENV     virtual environment (default target/peers/venv;
#                             created with pip install "exudyn==1.13.*" scipy numpy)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
peers=${MBSOLVE_PEERS:-$root/../shared/peers}
h=${H:-1e-5}
venv=${PEERS_VENV:-$root/target/peers/venv}
if [[ ! -f $peers/exudyn_chain.py || ! -f $peers/chain_model.py ]]; then
    echo "run_exudyn_ratio: no exudyn_chain.py / chain_model.py in MBSOLVE_PEERS=$peers" >&2
    exit 2
fi
if [[ ! -x $venv/bin/python ]] || ! "$venv/bin/python" -c "import exudyn, scipy" 2>/dev/null; then
    echo "run_exudyn_ratio: installing Exudyn 1.13 into $venv" >&2
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q "exudyn==1.13.*" scipy numpy
fi
extra=(${MBS_EXTRA:-})
examples=(--example stiff_chain)
for e in "${extra[@]}"; do examples+=(--example "${e%%:*}"); done
(cd "$root" && cargo build --release "${examples[@]}" >&2)
export OMP_NUM_THREADS=1
out=$(mktemp)
trap 'rm -f "$out"' EXIT
sizes=("$@")
[[ ${#sizes[@]} -gt 0 ]] || sizes=(100 1000)
for n in "${sizes[@]}"; do
    echo "run_exudyn_ratio: N = $n, h = $h" >&2
    "$root/target/release/examples/stiff_chain" "$n" "genalpha:$h" | sed 's/^/mbsolve /' >>"$out"
    for e in "${extra[@]}"; do
        "$root/target/release/examples/${e%%:*}" "$n" "${e#*:}" | sed "s/^/extra:${e#*:} /" >>"$out"
    done
    (cd "$peers" && "$venv/bin/python" exudyn_chain.py "$n" "ga-sparse:$h") | sed 's/^/exudyn /' >>"$out"
done
"$venv/bin/python" - "$out" <<'PY'
import json, sys
rows = {}
for line in open(sys.argv[1]):
    code, _, js = line.partition(" ")
    d = json.loads(js)
    if code.startswith("extra:"):
        # examples/stiff_chain_rtol.rs or examples/radau_chain.rs fields
        tip = d.get("tip_x", d.get("tip"))
        its = d.get("newton_per_step")
        if its is None and d.get("steps"):
            its = float(d["newton_iterations"]) / d["steps"]
        rows.setdefault(d["n"], {})[code[6:]] = dict(
            h=d.get("h_or_rtol", d.get("rtol", d.get("h"))), cpu=d.get("cpu_s", d.get("cpu")),
            tip=tip, status=d["status"], extra=f"{d['steps']} steps, {its:.2f} Newton/step")
        continue
    if code == "mbsolve":
        ref = None if d["tip_error"] is None else d["tip_x"] - d["tip_error"]
        rows.setdefault(d["n"], {})["mbsolve"] = dict(
            h=d["h_or_rtol"], cpu=d["cpu_s"], tip=d["tip_x"], ref=ref, status=d["status"],
            extra=f"{d['steps']} steps, {d['newton_per_step']:.2f} Newton/step")
    else:
        r = d["runs"][0]
        cpu = r.get("cpu_s") or r.get("extrapolated_cpu_s")
        rows.setdefault(d["N"], {})["exudyn"] = dict(
            h=r["h"], cpu=cpu, tip=r.get("tip_x"), status="completed" if r["success"] else r.get("error"),
            extra=f"{r.get('newton_it_per_step', float('nan')):.2f} Newton/step, {r.get('timed_runs')} timed run(s)")
print("| N | code | h | CPU [s] | tip x [m] | tip error [m] | notes |")
print("|---|---|---|---|---|---|---|")
for n in sorted(rows):
    ref = rows[n].get("mbsolve", {}).get("ref")
    for code in ["mbsolve", "exudyn"] + [c for c in rows[n] if c not in ("mbsolve", "exudyn")]:
        r = rows[n].get(code)
        if not r:
            continue
        err = "–" if ref is None or r["tip"] is None else f"{r['tip'] - ref:.2e}"
        tip = "–" if r["tip"] is None else f"{r['tip']:.9f}"
        cpu = "–" if r["cpu"] is None else f"{r['cpu']:.2f}"
        print(f"| {n} | {code} | {r['h']:g} | {cpu} | {tip} | {err} | {r['status']}; {r['extra']} |")
    m, e = rows[n].get("mbsolve"), rows[n].get("exudyn")
    if m and e and m["cpu"] and e["cpu"]:
        print(f"| {n} | **Exudyn / mbsolve CPU** | | **{e['cpu'] / m['cpu']:.1f}** | | | same h |")
    for c, x in rows[n].items():
        if c in ("mbsolve", "exudyn") or not (e and e["cpu"] and x["cpu"]):
            continue
        if ref is None or e["tip"] is None or x["tip"] is None:
            cmp = "no reference"
        else:
            cmp = "tip error ≤ Exudyn's" if abs(x["tip"] - ref) <= abs(e["tip"] - ref) else "tip error > Exudyn's"
        print(f"| {n} | **Exudyn / mbsolve {c} CPU** | | **{e['cpu'] / x['cpu']:.1f}** | | | {cmp} |")
PY
