#!/usr/bin/env bash
# Crash safety of `monoplane run` at the process level (issue 27): N runs on one map ended by
# SIGKILL and N by SIGTERM at times spread over 0.3-3 s. After each: the map opens (`info`),
# SQLite's integrity_check says ok, no frame committed before is lost, and the next run extends
# the map. A last uninterrupted run must extend it too. Prints one line per run and a tally.
#   tools/kill_soak.sh [BUILD_DIR] [N]        (default: build 20; OUT=/tmp/monoplane-soak)
set -euo pipefail
build=${1:-build}
n=${2:-20}
out=${OUT:-/tmp/monoplane-soak}
mp=$build/app/monoplane
mkdir -p "$out"
if [ ! -f "$out/seq/times.txt" ]; then
  "$build/tools/sim/monoplane-sim" "$(dirname "$0")/../tests/data/scenes/corridor.yaml" \
    --out "$out/seq" --frames 120 >/dev/null
fi
# A long input: the 120 frames forward and backward 10 times (stamps keep increasing).
mkdir -p "$out/long"
cp "$out/seq/calib.yaml" "$out/long/"
awk 'BEGIN { k = 0; for (p = 0; p < 10; ++p) for (i = 0; i < 120; ++i) {
  printf "%.6f ../seq/images/%06d.png\n", k / 15.0, (p % 2) ? 119 - i : i; ++k } }' \
  >"$out/long/times.txt"
map=$out/soak.db
rm -f "$map" "$map-wal" "$map-shm"
frames() { "$mp" info "$map" --json | python3 -c 'import json, sys; print(json.load(sys.stdin)["frames"])'; }
ok=0
total=0
committed=0
for sig in KILL TERM; do
  for i in $(seq 1 "$n"); do
    delay=$(awk -v i="$i" -v n="$n" 'BEGIN { printf "%.2f", 0.3 + 2.7 * (i - 1) / (n > 1 ? n - 1 : 1) }')
    "$mp" run --input "$out/long" --map "$map" --quiet >/dev/null 2>&1 &
    pid=$!
    sleep "$delay"
    kill -s "$sig" "$pid" 2>/dev/null || true
    rc=0
    wait "$pid" || rc=$?
    total=$((total + 1))
    verdict=ok
    if ! now=$(frames 2>/dev/null); then
      verdict="map does not open"
    elif [ "$(sqlite3 "$map" 'PRAGMA integrity_check;')" != ok ]; then
      verdict="integrity_check failed"
    elif [ "$now" -lt "$committed" ]; then
      verdict="lost frames ($committed -> $now)"
    fi
    [ "$verdict" = ok ] && ok=$((ok + 1))
    printf 'SIG%-4s after %4s s: exit %3d, frames %6s, %s\n' "$sig" "$delay" "$rc" "${now:-?}" "$verdict"
    committed=${now:-$committed}
  done
done
before=$(frames)
"$mp" run --input "$out/seq" --map "$map" --quiet >/dev/null
after=$(frames)
echo "last run: frames $before -> $after"
[ "$after" -gt "$before" ] && ok=$((ok + 1))
total=$((total + 1))
echo "$ok of $total checks passed"
[ "$ok" -eq "$total" ]
