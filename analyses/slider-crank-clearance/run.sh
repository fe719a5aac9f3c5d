#!/usr/bin/env bash
# Slider-crank with a 0.5 mm revolute clearance between rod and slider, against the ideal
# mechanism (Flores & Ambrosio 2004 benchmark), two crank turns at 5000 rpm.
#
#   analyses/slider-crank-clearance/run.sh [OUT_DIR]      (default out/slider-crank-clearance)
#
# Writes both runs' HDF5 files and figures, and overlays of the slider acceleration, the slider
# position and the crank torque, ideal against clearance.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
out=${1:-out/slider-crank-clearance}
jp() { cargo run --quiet -- "$@"; }
jp run data/scenes/slider-crank.toml --out "$out" -q
jp run data/scenes/slider-crank-clearance.toml --out "$out" -q
files=("$out/slider-crank.h5" "$out/slider-crank-clearance.h5")
jp compare "${files[@]}" --dataset bodies/slider/acceleration --component 0 \
  --title "Slider acceleration, ideal joint vs 0.5 mm clearance" --out "$out/compare-slider-acceleration"
jp compare "${files[@]}" --dataset bodies/slider/velocity --component 0 \
  --title "Slider velocity, ideal joint vs 0.5 mm clearance" --out "$out/compare-slider-velocity"
jp compare "${files[@]}" --dataset drives/motor/force \
  --title "Crank driving torque, ideal joint vs 0.5 mm clearance" --out "$out/compare-crank-torque"
