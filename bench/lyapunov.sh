#!/usr/bin/env bash
# What the Lyapunov exponents cost, as ratios to the plain run of the same flow, measured side by
# side in one invocation (the machine's speed drifts between days; the ratios do not).
#
#   bench/lyapunov.sh target/release/jointplay [PERIODS]
#
# For the Duffing oscillator (analytic tangent dynamics) and the mixed-clearance 4-UPS/RPU
# (central differences through the L-N contacts, DOPRI5 at rtol 1e-6), it times with the
# program's own wall-time output:
#   plain      the analysis run over 1 + P periods;
#   k          1 period, then the Lyapunov run over P periods with k exponents (Duffing P x 2000);
#   k = 1 + 2  the same with the two-trajectory estimate;
#   forward    the mechanism's k exponents again with forward differences (difference = "forward":
#              one right-hand side per vector instead of two).
# Each is run 3 times; the median is reported.
set -euo pipefail
bin=$(realpath "$1")
periods=${2:-2}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

study() { # name flow-lines periods lyapunov-table
  cat > "$work/$1.toml" <<TOML
[study]
name = "$1"
$2
[analysis]
periods = $3
samples_per_period = 0
[[observables]]
name = "o"
path = "$5"
$4
TOML
}

wall() { # study -> median wall time of 3 runs
  local t=()
  for _ in 1 2 3; do
    t+=("$("$bin" run "$work/$1.toml" --out "$work/out" -q --no-plots | awk '/^wall time/ {print $3}')")
  done
  printf '%s\n' "${t[@]}" | sort -g | sed -n 2p
}

duffing='system = { kind = "duffing", delta = 0.25, alpha = -1.0, beta = 1.0, gamma = 0.4, omega = 1.0, initial = [1.0, 0.0], solver = { rtol = 1e-9, atol = 1e-11 } }'
mech="scene = \"$root/data/scenes/4ups-rpu-mixed.toml\"
set = { \"solver.integrator\" = \"dopri5\", \"solver.rtol\" = 1e-6, \"solver.atol\" = 1e-9 }
remove = [\"solver.step\"]"

for flow in duffing 4ups-rpu; do
  if [ "$flow" = duffing ]; then
    lines=$duffing; obs=x; p=$((periods * 2000)); per=4; ks="1 2"; diffs="central"
  else
    lines=$mech; obs=bodies.platform.position.x; p=$periods; per=20; ks="1 2 4"
    diffs="central forward"
  fi
  study plain "$lines" $((p + 1)) "" "$obs"
  base=$(wall plain)
  printf '%-9s plain %d periods: %.3f s\n' "$flow" $((p + 1)) "$base"
  for d in $diffs; do
    for k in $ks; do
      study "k$k" "$lines" 1 "[lyapunov]
exponents = $k
periods = $p
per_period = $per
difference = \"$d\"" "$obs"
      w=$(wall "k$k")
      printf '%-9s k = %d (%s): %.3f s, %.2f x plain\n' "$flow" "$k" "$d" "$w" "$(awk -v a="$w" -v b="$base" 'BEGIN {print a / b}')"
    done
  done
  study two "$lines" 1 "[lyapunov]
exponents = 1
periods = $p
per_period = $per
two_trajectory = true" "$obs"
  w=$(wall two)
  printf '%-9s k = 1 + two trajectories: %.3f s, %.2f x plain\n' "$flow" "$w" "$(awk -v a="$w" -v b="$base" 'BEGIN {print a / b}')"
done
