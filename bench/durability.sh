#!/usr/bin/env bash
# What durable results cost (book/src/explanation/durability.md): two builds of jointplay side by side,
# alternating, on the 601-value Duffing cascade (analyses/duffing/cascade.toml, both cores), a
# single streamed run of the mixed 4-UPS/RPU (10 s and 100 s, DOPRI5 rtol 1e-6, 1 ms output) and, with
# FULL=1, the section-3 diagram (analyses/4ups-rpu/section3-diagram.toml, about 4 minutes each).
# Each row gives the median elapsed time of the whole command (journal, file, fsyncs included)
# over the repeats and the ratio of the second build to the first.
#
#   bench/durability.sh OLD NEW [REPEATS]      # two jointplay binaries (release builds);
#                                              # REPEATS default 3, about 3 minutes on 2 cores
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
old=$(realpath "$1")
new=$(realpath "$2")
reps=${3:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
. "$root/bench/lib.sh"
scene 5 p5.toml
scene 50 p50.toml
# one BIN TAG ARGS...: elapsed seconds of `BIN run ARGS --out out-TAG --no-plots -q`
one() {
  local bin=$1 tag=$2 t0 t1
  shift 2
  rm -rf "out-$tag"
  t0=$(date +%s.%N)
  "$bin" run "$@" --out "out-$tag" --no-plots -q >/dev/null
  t1=$(date +%s.%N)
  echo "$t1 - $t0" | bc -l
}
row() { # row NAME ARGS...
  local name=$1 a=() b=() i
  shift
  for i in $(seq "$reps"); do
    a+=("$(one "$old" old "$@")")
    b+=("$(one "$new" new "$@")")
  done
  local ma mb
  ma=$(printf '%s\n' "${a[@]}" | median)
  mb=$(printf '%s\n' "${b[@]}" | median)
  printf '| %s | %.2f s | %.2f s | %.3f |\n' "$name" "$ma" "$mb" "$(echo "$mb / $ma" | bc -l)"
}
echo "| workload | old | new | new / old |"
echo "|---|---|---|---|"
row "Duffing cascade, 601 values" "$root/analyses/duffing/cascade.toml"
row "4-UPS/RPU mixed, one streamed 10 s run" p5.toml
row "4-UPS/RPU mixed, one streamed 100 s run" p50.toml
if [ "${FULL:-0}" = 1 ]; then
  row "section-3 diagram, 40 values" "$root/analyses/4ups-rpu/section3-diagram.toml"
fi
