#!/bin/sh
# End-to-end throughput and memory of `monoplane run` (issue 8): renders tools/bench/
# throughput_scene.yaml (640x480, FRAMES frames, once, cached in OUT), then maps it with the map
# written and DDS publishing on (loopback), timed and with the peak RSS from GNU time. Then a
# REPEAT times longer input (the same images forward and backward, so the robot drives the loops
# back and forth) for the memory bound: peak RSS after FRAMES and after REPEAT x FRAMES frames.
#   tools/bench/throughput.sh            # BUILD=build OUT=/tmp/monoplane-throughput FRAMES=1000 REPEAT=10
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
for input in seq long; do
  rm -f "$OUT/$input.db" "$OUT/$input.db-wal" "$OUT/$input.db-shm"
  echo "== monoplane run --input $OUT/$input --map $OUT/$input.db --publish $cfg"
  /usr/bin/time -f "peak RSS %M kB, wall %e s, user %U s, system %S s" \
    "$MP" run --input "$OUT/$input" --map "$OUT/$input.db" --publish --quiet $cfg 2>&1 |
    grep -E "frames read|keyframes|wall time|time per frame|DDS|peak RSS"
done
