#!/usr/bin/env bash
# What writing a run's file costs: two builds of jointplay side by side, alternating, on the mixed
# 4-UPS/RPU (data/scenes/4ups-rpu-mixed.toml with DOPRI5 at rtol 1e-6, atol 1e-9, 1 ms output):
# one run of 10 s and of 100 s, two runs of 10 s and of 40 s at once (both cores busy), and the
# bundled study analyses/4ups-rpu/clearance-size.toml (4 cases written whole at its end). Each row
# gives the median process time (elapsed, of the pair for two runs at once) over the repeats, the
# file size and the peak memory (/usr/bin/time), and the ratio of the second build to the first.
#
#   bench/writer.sh OLD NEW [REPEATS]    # two jointplay binaries; REPEATS default 3;
#                                        # about 3 minutes on 2 cores at 3 repeats
#
# The files of the two builds are compared value for value when Python 3 with h5py is there
# (bench/requirements.txt), wall times excepted.
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
scene 20 p20.toml
scene 50 p50.toml
# one BIN TAG INPUT COPIES: elapsed time of COPIES runs at once; sets $size and $mem (of the first)
one() {
  local bin=$1 tag=$2 input=$3 copies=$4 t0 t1 k
  rm -rf "out-$tag"-*
  t0=$(date +%s.%N)
  local pids=()
  for k in $(seq "$copies"); do
    /usr/bin/time -f "%M" -o "mem-$tag-$k" "$bin" run "$input" --out "out-$tag-$k" --no-plots -q \
      >/dev/null 2>"err-$tag-$k" &
    pids+=($!)
  done
  for k in "${pids[@]}"; do
    wait "$k" || { echo "bench/writer.sh: $bin run $input failed:" >&2; cat "err-$tag"-* >&2; exit 1; }
  done
  t1=$(date +%s.%N)
  size=$(du -b "out-$tag-1"/*.h5 | cut -f1)
  mem=$(cat "mem-$tag-1")
  awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f\n", b - a }'
}
row() { # row LABEL INPUT COPIES
  local label=$1 input=$2 copies=$3 i to tn so sn mo mn
  : >"t-old"; : >"t-new"
  for i in $(seq "$reps"); do
    one "$old" old "$input" "$copies" >>t-old; so=$size; mo=$mem
    one "$new" new "$input" "$copies" >>t-new; sn=$size; mn=$mem
  done
  to=$(median <t-old); tn=$(median <t-new)
  awk -v l="$label" -v to="$to" -v tn="$tn" -v so="$so" -v sn="$sn" -v mo="$mo" -v mn="$mn" 'BEGIN {
    printf "| %s | %.2f s | %.2f s | %.2f | %.1f / %.1f MB | %.0f / %.0f MB |\n", l, to, tn, tn / to, so / 1e6, sn / 1e6, mo / 1e3, mn / 1e3 }'
  if command -v python3 >/dev/null && python3 -c "import h5py" 2>/dev/null; then
    python3 - "out-old-1" "out-new-1" <<'PY'
import sys, glob, h5py, numpy as np
a = h5py.File(glob.glob(sys.argv[1] + "/*.h5")[0], "r")
b = h5py.File(glob.glob(sys.argv[2] + "/*.h5")[0], "r")
bad = []
def same(x, y):
    try:
        return np.array_equal(x, y, equal_nan=np.asarray(x).dtype.kind == "f")
    except TypeError:
        return np.array_equal(x, y)
def check(name, o):
    p = b.get(name)
    if p is None:
        bad.append(name); return
    for k, v in o.attrs.items():
        if "wall" not in k and not same(v, p.attrs.get(k)):
            bad.append(f"{name}@{k}")
    if isinstance(o, h5py.Dataset) and not same(o[...], p[...]):
        bad.append(name)
check("/", a)
a.visititems(check)
extra = []
b.visititems(lambda name, o: extra.append(name) if name not in a else None)
bad += extra
if bad:
    sys.exit("bench/writer.sh: the files differ: " + ", ".join(bad[:10]))
PY
  fi
}
echo "| run (median of $reps, alternating) | $(basename "$old") | $(basename "$new") | ratio | file | peak memory |"
echo "|---|---|---|---|---|---|"
row "10 s, one run" p5.toml 1
row "10 s, two runs at once" p5.toml 2
row "40 s, two runs at once" p20.toml 2
row "100 s, one run" p50.toml 1
row "study clearance-size.toml (4 cases)" "$root/analyses/4ups-rpu/clearance-size.toml" 1
