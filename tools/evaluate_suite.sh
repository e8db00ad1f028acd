#!/usr/bin/env bash
# Renders scenes of the simulated suite, runs monoplane on each, and scores the per-frame labels
# against ground truth with monoplane-eval. The README's perception table comes from this script.
#
#   tools/evaluate_suite.sh [BUILD_DIR] [SCENE ...]      (default: build, every scene)
#   OUT=/tmp/suite tools/evaluate_suite.sh build office   # keep the outputs somewhere else
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-build}
shift || true
out=${OUT:-$build/suite}
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then
  for f in "$root"/tests/data/scenes/*.yaml; do scenes+=("$(basename "$f" .yaml)"); done
fi
mkdir -p "$out"
for scene in "${scenes[@]}"; do
  seq="$out/$scene/sequence"
  pred="$out/$scene/frames"
  rm -rf "$out/$scene"
  "$build/tools/sim/monoplane-sim" "$root/tests/data/scenes/$scene.yaml" --out "$seq" >/dev/null
  "$build/app/monoplane" run --input "$seq" --frames-out "$pred" --quiet ${CONFIG:+--config "$CONFIG"} >"$out/$scene/run.txt"
  "$build/tools/eval/monoplane-eval" labels --pred "$pred" --gt "$seq" --json >"$out/$scene/labels.json"
  "$build/tools/eval/monoplane-eval" labels --pred "$pred" --gt "$seq" >"$out/$scene/labels.txt"
  echo "== $scene"
  grep -E "overall|0-1 m|1-2 m|2-4 m" "$out/$scene/labels.txt" || cat "$out/$scene/labels.txt"
done
