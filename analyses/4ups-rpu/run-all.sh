#!/usr/bin/env bash
# Runs every 4-UPS/RPU study (sections 2.2-2.5 of Chen et al. 2023, the geometry variants and the
# step-size check) and regenerates the tables of docs/reproduction.md from their HDF5 files.
#
#   analyses/4ups-rpu/run-all.sh [OUT_DIR]      (default out/4ups-rpu)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
out=${1:-out/4ups-rpu}
cargo build --release --quiet
jp=target/release/jointplay
studies=(clearance-type clearance-size drive-speed friction geometry step-size)
for s in "${studies[@]}"; do
  start=$SECONDS
  "$jp" run "analyses/4ups-rpu/$s.toml" --out "$out" -q
  echo "$s: $((SECONDS - start)) s wall"
done
python3 analyses/4ups-rpu/splice_report.py docs/reproduction.md "$out" "${studies[@]}"
