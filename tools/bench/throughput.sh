#!/bin/sh
# End-to-end throughput and memory of `monoplane run` (issue 8): renders tools/bench/
# throughput_scene.yaml (640x480, FRAMES frames, once, cached in OUT), then maps it with the map
# written and DDS publishing on (loopback), timed and with the peak RSS from GNU time. Then a
# REPEAT times longer input (the same images forward and backward, so the robot drives the loops
# back and forth) for the memory bound: peak RSS after FRAMES and after REPEAT x FRAMES frames.
#   tools/bench/throughput.sh            # BUILD=build OUT=/tmp/monoplane-throughput FRAMES=1000 REPEAT=10
# With COMPARE=/path/to/another/monoplane it instead runs the FRAMES frames RUNS times (default 3)
# with each binary in turn: the machine's speed drifts by up to a third, so a before/after comparison
# needs runs of both in the same minutes.
#   COMPARE=/tmp/old/monoplane tools/bench/throughput.sh
set -eu
BUILD=${BUILD:-build}
OUT=${OUT:-/tmp/monoplane-throughput}
FRAMES=${FRAMES:-1000}
REPEAT=${REPEAT:-10}
CONFIG=${CONFIG:-}
MP=$BUILD/app/monoplane
mkdir -p "$OUT"
if [ ! -f "$OUT/seq/times.txt" ] || [ "$(wc -l < "$OUT/seq/times.txt")" -ne "$FRAMES" ]; then
  echo "rendering $FRAMES frames into $OUT/seq ..."
  rm -rf "$OUT/seq"
  "$BUILD/tools/sim/monoplane-sim" tools/bench/throughput_scene.yaml --out "$OUT/seq" --frames "$FRAMES"
fi
# The long input: forward, backward, forward, ... with steadily increasing stamps at 15 fps.
mkdir -p "$OUT/long"
cp "$OUT/seq/calib.yaml" "$OUT/long/calib.yaml"
awk -v n="$FRAMES" -v r="$REPEAT" 'BEGIN {
  k = 0
  for (p = 0; p < r; ++p) for (i = 0; i < n; ++i) {
    f = (p % 2 == 0) ? i : n - 1 - i
    printf "%.6f ../seq/images/%06d.png\n", k / 15.0, f
    ++k
  }
}' > "$OUT/long/times.txt"
export CYCLONEDDS_URI="${CYCLONEDDS_URI:-<CycloneDDS><Domain Id='any'><General><Interfaces><NetworkInterface name='lo'/></Interfaces><AllowMulticast>false</AllowMulticast></General></Domain></CycloneDDS>}"
cfg=""
[ -n "$CONFIG" ] && cfg="--config $CONFIG"
# run BINARY INPUT: maps OUT/INPUT into OUT/INPUT.db, timed, and prints the summary's lines that
# match $show.
run() {
  rm -f "$OUT/$2.db" "$OUT/$2.db-wal" "$OUT/$2.db-shm"
  echo "== $1 run --input $OUT/$2 --map $OUT/$2.db --publish $cfg"
  /usr/bin/time -f "peak RSS %M kB, wall %e s, user %U s, system %S s" \
    "$1" run --input "$OUT/$2" --map "$OUT/$2.db" --publish --quiet $cfg 2>&1 | grep -E "$show"
}
if [ -n "${COMPARE:-}" ]; then
  show="wall time|peak RSS"
  for i in $(seq "${RUNS:-3}"); do
    run "$COMPARE" seq
    run "$MP" seq
  done
  exit 0
fi
show="frames read|keyframes|wall time|time per frame|DDS|peak RSS"
for input in seq long; do
  run "$MP" "$input"
done
