#!/usr/bin/env bash
# Times `simgap diagnose` on the embedded 7-DOF arm (`crates/simgap-core/models/arm7.urdf`, tip
# `panda_hand`) at 200 Hz: two 20 s fit runs and one faster 10 s held-out run, simulated with
# viscous and Coulomb friction on every joint, torque offsets on four joints and rotor inertia.
#
# Two cases, each diagnosed with the same logs:
#   pd      the closed-loop PD + gravity runs as simulated;
#   replay  the same logs with `controller: replay` in their sidecar (the logged effort applied
#           open loop), as a user's torque-controlled arm logs them.
#
# Usage: scripts/arm7_speed.sh [BIN ...]
#   BIN: simgap binaries to compare side by side (default target/release/simgap); e.g. a copy
#   of the binary before a change and the current one. Set CASES="replay" to run one case,
#   CORES="0" to pin to one core (taskset), OUT=DIR for the logs and reports, FIT_S and HELD_S
#   for the durations of the fit and held-out runs (default 20 and 10 s). FILTER_HZ=3 passes the
#   replayed logs' effort through a causal first-order low-pass of that cutoff (a recorder's
#   filter); LINK=1 diagnoses with `--link-side-torque` (a torque-sensing arm's joint sensors);
#   TIMINGS=1 adds `--timings` (the per-stage table goes to CASE/diagnose.BIN.txt).
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
bins=("$@")
[ ${#bins[@]} -gt 0 ] || bins=("$root/target/release/simgap")
out="${OUT:-/tmp/simgap-arm7-speed}"
cases="${CASES:-replay pd}"
pin=()
[ -n "${CORES:-}" ] && pin=(taskset -c "$CORES")
mkdir -p "$out"
cd "$out"
cp "$root/crates/simgap-core/models/arm7.urdf" arm7.urdf
sim="${bins[0]}"

# gains: 3 Hz natural frequency, damping 0.7 on the diagonal of H at q0 (as bench::gains_for)
q0="0,0,0,-1.5,0,1.5,0"
kp="457,948,444,312,17,19.2,2.59"
kv="34,70.4,33,23.1,1.26,1.43,0.193"
effects=(
  --effect 'viscous_friction:b=1.2,1.5,0.9,0.8,0.08,0.08,0.02'
  --effect 'coulomb_friction:fc=1.5,2.0,1.2,1.0,0.2,0.2,0.05'
  --effect 'torque_offset:offset=0.8,-1.2,0,0.6,0,-0.15,0'
  --effect 'armature:ia=0.2,0.2,0.15,0.15,0.02,0.02,0.005'
)
run() { # name duration amplitude base-frequency
  local a=$3 f=$4
  "$sim" simulate --urdf arm7.urdf --tip panda_hand --controller pd_gravity --kp "$kp" --kv "$kv" \
    --target "$q0" --q0 "$q0" --duration "$2" --sample-period 0.005 "${effects[@]}" \
    --fourier "amplitude=$a,$a,$a,$a,$a,$a,$a;frequency=$f,$(echo "$f*1.13" | bc -l),$(echo "$f*1.27" | bc -l),$(echo "$f*1.41" | bc -l),$(echo "$f*1.53" | bc -l),$(echo "$f*1.67" | bc -l),$(echo "$f*1.79" | bc -l);phase=0,1,2,3,4,5,0.5" \
    --fourier "amplitude=$(echo "$a/3" | bc -l),$(echo "$a/3" | bc -l),$(echo "$a/3" | bc -l),$(echo "$a/3" | bc -l),$(echo "$a/3" | bc -l),$(echo "$a/3" | bc -l),$(echo "$a/3" | bc -l);frequency=$(echo "$f*2.9" | bc -l),$(echo "$f*3.3" | bc -l),$(echo "$f*2.3" | bc -l),$(echo "$f*3.7" | bc -l),$(echo "$f*2.6" | bc -l),$(echo "$f*3.1" | bc -l),$(echo "$f*2.2" | bc -l)" \
    --out "pd/$1.csv" > "pd/$1.sim.txt"
}
mkdir -p pd replay
run fit0 "${FIT_S:-20}" 0.4 0.15
run fit1 "${FIT_S:-20}" 0.35 0.19
run held "${HELD_S:-10}" 0.3 0.3
# the replay case: the same logs, the logged effort applied open loop
for f in fit0 fit1 held; do
  cp "pd/$f.csv" "replay/$f.csv"
  python3 - "pd/$f.experiment.json" "replay/$f.experiment.json" <<'EOF'
import json, sys
e = json.load(open(sys.argv[1]))
n = len(e["joints"].split(","))
e.update(controller="replay", kp=",".join(["0"] * n), kv=",".join(["0"] * n))
json.dump(e, open(sys.argv[2], "w"), indent=2)
EOF
  if [ -n "${FILTER_HZ:-}" ]; then
    python3 - "replay/$f.csv" "$FILTER_HZ" <<'EOF'
import csv, math, sys
path, fc = sys.argv[1], float(sys.argv[2])
rows = list(csv.reader(open(path)))
head, body = rows[0], rows[1:]
t = head.index("time")
cols = [i for i, h in enumerate(head) if h.startswith("tau_")]
state, prev = {}, None
for r in body:
    now = float(r[t])
    a = 1.0 if prev is None else 1.0 - math.exp(-2 * math.pi * fc * (now - prev))
    for i in cols:
        v = float(r[i])
        state[i] = v if prev is None else state[i] + a * (v - state[i])
        r[i] = repr(state[i])
    prev = now
csv.writer(open(path, "w", newline="")).writerows(rows)
EOF
  fi
done

uptime
printf '%-8s %-40s %10s  %s\n' case binary wall_s 'selected (effect@joints)'
for c in $cases; do
  for b in "${bins[@]}"; do
    tag="$(basename "$b")"
    start=$(date +%s.%N)
    "${pin[@]}" "$b" diagnose --urdf arm7.urdf --tip panda_hand --log "$c/fit0.csv" --log "$c/fit1.csv" \
      --holdout "$c/held.csv" --json "$c/report.$tag.json" ${LINK:+--link-side-torque} ${TIMINGS:+--timings} > "$c/diagnose.$tag.txt" 2>&1
    end=$(date +%s.%N)
    sel=$(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print(' '.join(e['effect'] + '@' + str(len(e['joints'])) for e in r['selected_effects']))" "$c/report.$tag.json" 2>/dev/null || echo '?')
    printf '%-8s %-40s %10.2f  %s\n' "$c" "$tag" "$(echo "$end - $start" | bc -l)" "$sel"
  done
done
