#!/usr/bin/env bash
# Regenerates the numbers of book/src/results/work-precision.md (what accuracy costs), part by
# part, printing each part's tables and the lines of `jointplay run` the page quotes:
#
#   studies  the 14 work-precision studies of analyses/precision (their tables are the page's
#            included tables), and the variants whose tables are not kept: ros34pw2 with onset
#            events, ros34pw2 and bs3 with all three kinds of event (about 45 min in all)
#   census   the step census of both mechanisms (crates/solver/examples/step_census.rs), with and
#            without events, and its stability floors (about 2 min with the example's build)
#   runs     6 s step counts (ideal, mixed, effects disabled), RK4 at 5e-4 s (the guard's mode),
#            the 50-period runs (five in turn, five times over, with peak memory), the longer
#            ros34pw2 runs and their distance from DOPRI5's orbit, the 10 s runs with and without
#            events, and the 4-value sweep on one and two threads (about 10 min)
#   benches  cargo bench --bench integrators and --bench effects (about 3 min with the build)
#   diagram  section3-diagram.toml at rtol 1e-6 and 1e-7, then section3_tolerance.py with DOPRI5
#            and with bs3 (about 15 min)
#
#   bench/results-work-precision.sh [PART...]     (default: every part; about 1 h 30 min on 2 cores)
#
# Errors, evaluation and step counts are exact and repeat to the last digit; wall times drift with
# the machine's speed, so compare those of one invocation. Not rerun here: comparisons with
# earlier builds of the program (bench/writer.sh OLD NEW does those of the file's writer), the
# `perf` profiles, and two counts read by hand from recorded runs (the friction kinks crossed in
# 2 s of the 4-UPS/RPU, and the share of contact time where a clipped force ends before the
# penetration on the slider-crank). JOINTPLAY=path/to/jointplay uses that binary instead of
# building the release one; OUT (default out/precision) receives the studies' files. The orbit
# distances need Python 3 with h5py (bench/requirements.txt) or the jointplay Python package.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
out=${OUT:-out/precision}
. bench/lib.sh
program
parts=("$@")
[[ ${#parts[@]} -gt 0 ]] || parts=(studies census runs benches diagram)

# solver SCENE LINES...: SCENE with its [solver] table replaced by LINES (one key each)
solver() {
  local scene=$1
  shift
  awk -v lines="$(printf '%s\n' "$@")" '
    /^\[solver\]/ { print; printf "%s\n", lines; skip = 1; next }
    /^\[/ { skip = 0 }
    !skip { print }' "$scene"
}
# study FILE [SET]: a copy of a study whose scene path is absolute, with SET added under [study]
study() {
  local dir
  dir=$(cd "$(dirname "$1")" && pwd)
  if [[ $# -ge 2 ]]; then
    sed -e "s|^scene = \"|scene = \"$dir/|" -e "/^\[study\]/a $2" "$1"
  else
    sed -e "s|^scene = \"|scene = \"$dir/|" "$1"
  fi
}
# summary: the lines of `jointplay run` the page quotes
summary() { grep -E '^(steps|RHS|wall time|drift)' || true; }
mixed=data/scenes/4ups-rpu-mixed.toml
crank=data/scenes/slider-crank-clearance.toml
events='set = { "solver.onset_events" = true }'
all3='set = { "solver.onset_events" = true, "solver.end_events" = true, "solver.friction_events" = true }'

studies() {
  local s start
  for s in 4ups-rpu slider-crank duffing 4ups-rpu-events slider-crank-events 4ups-rpu-ends \
    slider-crank-ends 4ups-rpu-kinks 4ups-rpu-loose slider-crank-loose 4ups-rpu-bs3 slider-crank-bs3 \
    4ups-rpu-ros34pw2 slider-crank-ros34pw2; do
    start=$SECONDS
    "$bin" precision "analyses/precision/$s.toml" --out "$out" -q >/dev/null
    echo "### precision-$s ($((SECONDS - start)) s wall)"
    cat "$out/precision-$s.md"
  done
  echo "### variants, tables not kept"
  study analyses/precision/4ups-rpu-ros34pw2.toml "$events" >"$work/ros-events.toml"
  study analyses/precision/4ups-rpu-ros34pw2.toml "$all3" >"$work/ros-all3.toml"
  study analyses/precision/slider-crank-ros34pw2.toml "$all3" >"$work/crank-ros-all3.toml"
  study analyses/precision/4ups-rpu-bs3.toml "$all3" >"$work/bs3-all3.toml"
  study analyses/precision/slider-crank-bs3.toml "$all3" >"$work/crank-bs3-all3.toml"
  for s in ros-events ros-all3 crank-ros-all3 bs3-all3 crank-bs3-all3; do
    echo "#### $s"
    "$bin" precision "$work/$s.toml" --out "$work/$s" -q --no-plots >/dev/null
    cat "$work/$s"/*.md
  done
}

census() {
  cargo build --release --quiet -p jointplay-solver --example step_census
  local c=target/release/examples/step_census r
  echo "### 4-UPS/RPU, first second"
  for r in "dopri5 1e-3" "dopri5 1e-4" "dopri5 1e-5" "dopri5 1e-6" "dopri5 1e-8" "bs3 1e-3" \
    "dop853 1e-2" "dop853 1e-4" "dop853 1e-5" "dop853 1e-6"; do
    $c $mixed $r --until 1
  done
  for r in 1e-3 1e-4 1e-5 1e-6; do $c $mixed dopri5 $r --until 1 --events --ends --friction; done
  echo "### slider-crank, 0.12 s"
  for r in "dopri5 1e-3" "dopri5 1e-4" "dopri5 1e-5" "dopri5 1e-6" "dopri5 1e-8" "dopri5 1e-10" \
    "dop853 1e-4" "dop853 1e-5" "dop853 1e-8" "dop853 1e-10" "ros34pw2 1e-6"; do
    $c $crank $r --until 0.12
  done
  for r in 1e-3 1e-4 1e-5 1e-6; do $c $crank dopri5 $r --until 0.12 --events; done
}

# fifty NAME SOLVER-LINES...: the mixed scene over 50 periods with that [solver], 1 ms output
fifty() {
  local name=$1
  shift
  solver $mixed "$@" 'periods = 50' >"$work/$name.toml"
}
# timed NAME: one run of $work/NAME.toml; prints its summary and peak memory (MB)
timed() {
  /usr/bin/time -f 'peak memory %M kB' -o "$work/$1.mem" "$bin" run "$work/$1.toml" \
    --out "$work/$1" --no-plots -q | summary
  cat "$work/$1.mem"
}
runs() {
  local r name tol
  echo "### 6 s of the 4-UPS/RPU with DOPRI5 (steps)"
  for tol in "1e-3 1e-6" "1e-4 1e-7" "1e-6 1e-9"; do
    set -- $tol
    for name in 4ups-rpu 4ups-rpu-mixed; do
      echo "$name, rtol $1:"
      solver "data/scenes/$name.toml" 'integrator = "dopri5"' "rtol = $1" "atol = $2" 'periods = 3' \
        >"$work/six.toml"
      "$bin" run "$work/six.toml" --out "$work/six" --no-plots -q | summary
    done
    for r in friction contact_damping; do
      [[ $1 == 1e-4 ]] && continue
      echo "4ups-rpu-mixed, rtol $1, disable = [\"$r\"]:"
      { echo "disable = [\"$r\"]"; cat "$work/six.toml"; } >"$work/six-off.toml" # six.toml: the mixed scene
      "$bin" run "$work/six-off.toml" --out "$work/six" --no-plots -q | summary
    done
  done
  echo "### RK4 at 5e-4 s: the step-size guard's mode of S2"
  solver $mixed 'integrator = "rk4"' 'step = 5e-4' 'periods = 2' >"$work/rk4-5e-4.toml"
  "$bin" run "$work/rk4-5e-4.toml" --out "$work/rk4" --no-plots -q 2>&1 | grep -E "^(warning|error)" || true

  echo "### 50 periods: five runs in turn, five times over"
  fifty rk4 'integrator = "rk4"' 'step = 1e-4'
  fifty dopri5 'integrator = "dopri5"' 'rtol = 1e-6' 'atol = 1e-9'
  fifty dopri5-events 'integrator = "dopri5"' 'rtol = 1e-4' 'atol = 1e-7' 'onset_events = true'
  fifty bs3 'integrator = "bs3"' 'rtol = 1e-3' 'atol = 1e-6'
  fifty ros34pw2 'integrator = "ros34pw2"' 'rtol = 1e-3' 'atol = 1e-6'
  for r in 1 2 3 4 5; do
    for name in rk4 dopri5 dopri5-events bs3 ros34pw2; do
      echo "$name, round $r:"
      timed $name
    done
  done
  echo "### 50 periods, DOPRI5 with and without onset events (evaluations)"
  fifty d3 'integrator = "dopri5"' 'rtol = 1e-3' 'atol = 1e-6'
  fifty d3-events 'integrator = "dopri5"' 'rtol = 1e-3' 'atol = 1e-6' 'onset_events = true'
  fifty d4 'integrator = "dopri5"' 'rtol = 1e-4' 'atol = 1e-7'
  for name in d3 d3-events d4; do echo "$name:"; timed $name; done
  echo "### 50 periods, ros34pw2 at tighter tolerances, and the distance from DOPRI5's orbit"
  fifty ros4 'integrator = "ros34pw2"' 'rtol = 1e-4' 'atol = 1e-7'
  fifty ros5 'integrator = "ros34pw2"' 'rtol = 1e-5' 'atol = 1e-8'
  fifty ros6 'integrator = "ros34pw2"' 'rtol = 1e-6' 'atol = 1e-9'
  for name in ros4 ros5 ros6; do echo "$name:"; timed $name; done
  python3 - "$work" <<'PY'
import sys
import numpy as np
work = sys.argv[1]
try:
    import h5py
    def read(name, key):
        with h5py.File(f"{work}/{name}/4ups-rpu-mixed.h5", "r") as f:
            return np.asarray(f[key][...], dtype=float)
except ImportError:
    import jointplay
    def read(name, key):
        return np.asarray(jointplay.load(f"{work}/{name}/4ups-rpu-mixed.h5")[key], dtype=float)
t = read("dopri5", "time")
ref = read("dopri5", "bodies/platform/position")
last = t >= t[-1] - 10.0
for name in ["bs3", "ros34pw2", "ros4", "ros5", "ros6"]:
    p = read(name, "bodies/platform/position")
    print(f"{name}: off DOPRI5's orbit over the last 10 s: {np.abs(p[last] - ref[last]).max():.1e} m")
PY
  echo "### 10 s, DOPRI5 rtol 1e-6, without and with the three kinds of event: fastest of ten"
  scene 5 "$work/ten.toml"
  sed 's/^periods = 5$/periods = 5\nonset_events = true\nend_events = true\nfriction_events = true/' \
    "$work/ten.toml" >"$work/ten-events.toml"
  for name in ten ten-events; do
    "$bin" run "$work/$name.toml" --out "$work/$name" --no-plots -q | grep -E '^(steps|RHS)'
    for r in $(seq 10); do
      "$bin" run "$work/$name.toml" --out "$work/$name" --no-plots -q | awk '/^wall time/ { print $3 }'
    done | sort -g | head -1 | sed "s/^/$name: fastest integrating time (s) /"
  done
  echo "### a 4-value clearance sweep on one and two threads"
  study analyses/4ups-rpu/section3-bifurcation.toml |
    sed -e 's/^periods = 50/periods = 4/' -e 's/^transient = 10/transient = 1/' \
      -e 's/^from = 1e-4/from = 2e-4/' -e 's/^count = 8/count = 4/' >"$work/sweep4.toml"
  for r in 1 2; do
    echo "RAYON_NUM_THREADS=$r:"
    RAYON_NUM_THREADS=$r "$bin" run "$work/sweep4.toml" --out "$work/sweep$r" --no-plots -q | grep -E '^(RHS|wall time|parallel)' || true
  done
}

benches() {
  cargo bench -p jointplay-analysis --bench integrators
  cargo bench -p jointplay-analysis --bench effects
}

diagram() {
  study analyses/4ups-rpu/section3-diagram.toml >"$work/diagram6.toml"
  sed 's/"solver.rtol" = 1e-6, "solver.atol" = 1e-9/"solver.rtol" = 1e-7, "solver.atol" = 1e-10/' \
    "$work/diagram6.toml" >"$work/diagram7.toml"
  grep -q '"solver.rtol" = 1e-7' "$work/diagram7.toml"
  for name in diagram6 diagram7; do
    echo "### section3-diagram.toml, $name"
    /usr/bin/time -f 'peak memory %M kB' "$bin" run "$work/$name.toml" --out "$work/$name" --no-plots -q
  done
  python3 analyses/4ups-rpu/section3_tolerance.py --jointplay "$bin"
  python3 analyses/4ups-rpu/section3_tolerance.py --jointplay "$bin" --integrator bs3 \
    --out "$work/tolerance-bs3"
}

for p in "${parts[@]}"; do
  case $p in
  studies | census | runs | benches | diagram)
    echo "## $p"
    $p
    ;;
  *)
    echo "bench/results-work-precision.sh: unknown part '$p' (studies, census, runs, benches, diagram)" >&2
    exit 2
    ;;
  esac
done
