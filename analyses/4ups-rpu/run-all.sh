#!/usr/bin/env bash
# Runs every 4-UPS/RPU study of book/src/results/reproduction.md that takes minutes, not hours: sections
# 2.2-2.5 of Chen et al. 2023, the geometry variants, the step-size check, the gravity-sign screen
# and the short section-3 analysis; then regenerates the document's tables from their HDF5 files
# and copies the figures the document shows into book/src/results/figures (the converged section-2 figures
# and the short section-3 analysis's). The ramped start (ramp, its table
# in OUT_DIR/ramp.md) and the ensembles of perturbed starts
# (section2-ensemble, section3-ensemble-0.3 and -0.7) are run too and their summaries printed,
# for the hand-kept tables of the document.
#
#   analyses/4ups-rpu/run-all.sh [OUT_DIR]      (default out/4ups-rpu)
#
# JOINTPLAY=target/debug/jointplay uses the dev build instead of building the release one.
# tests/reproduction_tables.rs checks that the committed tables of the cheap studies still match
# what the program computes. The 50-period section-3 studies (section3-portraits,
# section3-bifurcation, section3-chaos) and the continuations of the period-1 orbit
# (periodic-hanging, 8 minutes; periodic, 2.5 hours) take much longer and are run on their own
# (see the document). The whole script takes about 10 minutes with the dev build on 2 cores.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
out=${1:-out/4ups-rpu}
if [[ -z "${JOINTPLAY:-}" ]]; then
  cargo build --release --quiet
  JOINTPLAY=target/release/jointplay
fi
export JOINTPLAY
tables=(clearance-type clearance-size drive-speed friction geometry step-size gravity-screen stiffness-gap section2-converged)
for s in "${tables[@]}" section3-quick section3-updown; do
  start=$SECONDS
  "$JOINTPLAY" run "analyses/4ups-rpu/$s.toml" --out "$out" -q
  echo "$s: $((SECONDS - start)) s wall"
done
python3 analyses/4ups-rpu/splice_report.py book/src/results/reproduction.md "$out" "${tables[@]}"
for f in section3-quick-bifurcation-S2_vy section3-quick-bifurcation-R1_vy \
  section3-quick-bifurcation-platform_vy section3-quick-poincare-S2_ey-S2_vy \
  section3-quick-phase-platform_y-platform_vy section3-updown-bifurcation-platform_vy; do
  cp "$out/$f.png" book/src/results/figures/
done
for f in type-motion type-forces type-orbits size-forces speed-motion speed-forces friction-forces; do
  cp "$out/section2-converged-$f.png" book/src/results/figures/
done
for s in ramp section2-ensemble section3-ensemble-0.3 section3-ensemble-0.7; do
  start=$SECONDS
  "$JOINTPLAY" run "analyses/4ups-rpu/$s.toml" --out "$out" -q
  echo "$s: $((SECONDS - start)) s wall"
done
python3 analyses/4ups-rpu/section2_ensemble_summary.py "$out/section2-ensemble.md"
if python3 -c "import h5py, numpy" 2>/dev/null; then
  for c in 0.3 0.7; do
    python3 analyses/4ups-rpu/section3_ensemble_summary.py "$out/section3-ensemble-$c.h5"
  done
else
  echo "section3_ensemble_summary.py needs h5py and numpy (pip install h5py): summaries skipped"
fi
