#!/usr/bin/env bash
# Renders the scenes of the simulated suite (once; cached in OUT), maps each with `monoplane run`
# (per-frame outputs and a map), and scores the labels, the grid and the trajectory against ground
# truth with monoplane-eval. Prints one Markdown table row per scene; the README's tables come
# from this script.
#
#   tools/evaluate_suite.sh [BUILD_DIR] [SCENE ...]       (default: build, every scene)
#   OUT=/tmp/suite CONFIG=my.yaml tools/evaluate_suite.sh build office corridor
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
echo "| scene | frames | obstacle recall (<= 4 m) | of textured (<= 4 m) | floor as obstacle | coverage | dangerous | height error (median, <= 2 m) | grid precision | grid recall | grid recall of seen | seen floor free (<= 4 m) | dangerous cells | grid unknown | ATE (m) | frames/s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for scene in "${scenes[@]}"; do
  dir="$out/$scene"
  seq="$dir/sequence"
  # Rendered again when the scene or the simulator (its ground-truth formats) is newer.
  if [ ! -f "$seq/times.txt" ] || [ "$seq/times.txt" -ot "$root/tests/data/scenes/$scene.yaml" ] ||
    [ "$seq/times.txt" -ot "$build/tools/sim/monoplane-sim" ]; then
    rm -rf "$seq"
    "$build/tools/sim/monoplane-sim" "$root/tests/data/scenes/$scene.yaml" --out "$seq" >/dev/null
  fi
  rm -rf "$dir/frames" "$dir/map.db" "$dir/map.db-wal" "$dir/map.db-shm"
  "$build/app/monoplane" run --input "$seq" --frames-out "$dir/frames" --map "$dir/map.db" --quiet \
    ${CONFIG:+--config "$CONFIG"} >"$dir/run.txt"
  "$build/app/monoplane" export "$dir/map.db" --grid "$dir/map.yaml" --trajectory "$dir/trajectory.txt" \
    --png "$dir/map.png" >/dev/null
  "$build/tools/eval/monoplane-eval" labels --pred "$dir/frames" --gt "$seq" --min-texture 1 \
    --max-height-distance 2 >"$dir/labels.txt"
  "$build/tools/eval/monoplane-eval" labels --pred "$dir/frames" --gt "$seq" --min-texture 1 \
    --max-height-distance 2 --json >"$dir/labels.json"
  "$build/tools/eval/monoplane-eval" grid --pred "$dir/map.yaml" --gt "$seq/gt/map.yaml" --tolerance 1 \
    --seen-from "$seq" --json >"$dir/grid.json"
  "$build/tools/eval/monoplane-eval" traj --pred "$dir/trajectory.txt" --gt "$seq/gt/trajectory.txt" \
    --json >"$dir/traj.json"
  "$build/tools/eval/monoplane-eval" tracks --pred "$dir/frames" --gt "$seq" >"$dir/tracks.txt"
  python3 - "$scene" "$dir" <<'EOF'
import json, re, sys
scene, d = sys.argv[1], sys.argv[2]
all_labels = json.load(open(d + "/labels.json"))
labels, near = all_labels["overall"], all_labels["near"]
grid = json.load(open(d + "/grid.json"))
traj = json.load(open(d + "/traj.json"))
run = open(d + "/run.txt").read()
fps = re.search(r"([0-9.]+) frames/s", run)
frames = re.search(r"frames read (\d+)", run)
pct = lambda v: "-" if v is None else "%.1f %%" % (100 * v)
cm = lambda v: "-" if v is None else "%.1f cm" % (100 * v)
print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %.3f | %s |" % (
    scene, frames.group(1) if frames else "?", pct(near["obstacle_recall"]),
    pct(near["obstacle_recall_textured"]),
    pct(labels["floor_false_obstacle_rate"]), pct(labels["coverage"]), pct(labels["dangerous_rate"]),
    cm(labels["height_error_median_m"]), pct(grid.get("precision")), pct(grid.get("recall")),
    pct(grid.get("recall_seen")), pct(grid.get("free_recall_seen")), pct(grid.get("dangerous_share")), pct(grid.get("unknown_share")),
    traj["ate_m"]["rmse"], fps.group(1) if fps else "?"))
EOF
done
