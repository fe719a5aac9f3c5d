#!/usr/bin/env bash
# What merging shards costs: the Duffing cascade (analyses/duffing/cascade.toml) at 1000 values,
# computed once in one process and once in 100 shards (two processes at a time), then merged;
# the times side by side in one run, and the merged file checked against the single-process one.
#
#   bench/merge.sh [JOINTPLAY]      # default target/release/jointplay; about 1 minute on 2 cores
#
# scripts/regress compare needs Python 3 with h5py (bench/requirements.txt); without it the check
# is skipped.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jp=$(realpath "${1:-$root/target/release/jointplay}")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
sed 's/^count = 601$/count = 1000/' "$root/analyses/duffing/cascade.toml" >cascade.toml
grep -q '^count = 1000$' cascade.toml || { echo "bench/merge.sh: cascade.toml has no 'count = 601'" >&2; exit 1; }
now() { date +%s.%N; }
span() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", b - a }'; }
ratio() { awk -v a="$1" -v b="$2" -v d="$3" 'BEGIN { printf "%." d "f", a / b }'; }

t0=$(now)
"$jp" run cascade.toml --out single -q --no-plots >/dev/null
t1=$(now)
seq 0 99 | xargs -P 2 -I{} "$jp" run cascade.toml --out shards -q --shard {}/100 >/dev/null
t2=$(now)
"$jp" merge shards/duffing-cascade.shard-*-of-100.h5 --out merged/duffing-cascade.h5 --no-plots >/dev/null
t3=$(now)
"$jp" merge shards/duffing-cascade.shard-*-of-100.h5 --out figures/duffing-cascade.h5 >/dev/null
t4=$(now)

single=$(span "$t0" "$t1")
sharded=$(span "$t1" "$t2")
merge=$(span "$t2" "$t3")
figs=$(span "$t3" "$t4")
size=$(du -sh shards | cut -f1)
echo "| step (1000 values, 100 shards) | wall time (s) | / single process |"
echo "|---|---|---|"
echo "| sweep in one process | $single | 1 |"
echo "| 100 shards, two processes at a time | $sharded | $(ratio "$sharded" "$single" 3) |"
echo "| merge ($size of shard files) | $merge | $(ratio "$merge" "$single" 4) |"
echo "| merge with the figures | $figs | $(ratio "$figs" "$single" 4) |"
if python3 -c 'import h5py' 2>/dev/null; then
  mkdir cmp && cp merged/duffing-cascade.h5 cmp/
  "$root/scripts/regress" compare "$work/single" "$work/cmp"
else
  echo "(h5py missing: merged file not compared)"
fi
