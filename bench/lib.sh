# Shell functions the bench scripts share (sourced; $root is the repository).

# scene PERIODS FILE: the mixed 4-UPS/RPU over PERIODS drive periods (2 s each), DOPRI5 at rtol
# 1e-6, atol 1e-9, 1 ms output
scene() {
  awk -v p="$1" '
    /^\[solver\]/ { print; print "integrator = \"dopri5\""; print "rtol = 1e-6"; print "atol = 1e-9";
                    print "baumgarte_alpha = 5.0"; print "baumgarte_beta = 5.0"; print "periods = " p; skip = 1; next }
    /^\[/ { skip = 0 }
    !skip { print }' "$root/data/scenes/4ups-rpu-mixed.toml" >"$2"
  grep -q "^periods = $1\$" "$2" || { echo "bench: no [solver] table in the scene" >&2; exit 1; }
}

# median: the median of the numbers on standard input, one a line
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

# program: sets $bin to the program the bench runs, $JOINTPLAY or the release build (built now),
# and $work to a scratch directory removed when the script exits. Call it in the script itself,
# not in a subshell, so that both stay set.
program() {
  if [[ -z "${JOINTPLAY:-}" ]]; then
    cargo build --release --quiet
    JOINTPLAY=target/release/jointplay
  fi
  bin=$(realpath "$JOINTPLAY")
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
}
