#!/bin/sh
# A second run over the same place extends a map by floor features (CTest app/run_twice):
#   run_twice_test.sh MONOPLANE SEQUENCE WORK_DIR
# Run 1 maps the first 60 frames of SEQUENCE into WORK_DIR/twice.db; run 2 drives the same path
# again, starting 3 frames later (so its keyframes fall elsewhere), into the same map. Fails unless
# every stored keyframe has its floor features, run 2 closes a loop against the saved map by floor
# features, and the map grows by at most a quarter (a map without stored floor features doubled).
set -eu
mp=$1
seq=$(cd "$2" && pwd)  # absolute: the images are linked from another folder
dir=$3
rm -rf "$dir/twice.db"* "$dir/twice_input"
mkdir -p "$dir/twice_input"
ln -s "$seq/images" "$dir/twice_input/images"
cp "$seq/calib.yaml" "$dir/twice_input/"
awk 'NR > 3' "$seq/times.txt" > "$dir/twice_input/times.txt"

# keyframes, local maps, keyframes with floor features: the map's totals from `monoplane info`.
counts() {
  "$mp" info "$dir/twice.db" --json |
    sed -n 's/.*"keyframes": \([0-9]*\), "local_maps": \([0-9]*\), "floor_feature_sets": \([0-9]*\).*/\1 \2 \3/p'
}
fail() {
  echo "FAIL: $*"
  exit 1
}

"$mp" run --input "$seq" --map "$dir/twice.db" --max-frames 60 --quiet > /dev/null
set -- $(counts)
k1=$1
echo "run 1: $1 keyframes, $2 local maps, $3 with floor features"
[ "$k1" -gt 0 ] && [ "$2" -eq "$k1" ] && [ "$3" -eq "$k1" ] || fail "keyframes without floor features"

"$mp" run --input "$dir/twice_input" --map "$dir/twice.db" --max-frames 60 --quiet
set -- $(counts)
k2=$1
echo "run 2: map $k1 -> $k2 keyframes, $2 local maps, $3 with floor features"
[ "$2" -eq "$k2" ] && [ "$3" -eq "$k2" ] || fail "merged keyframes left behind in the map"
[ "$k2" -le $((k1 + k1 / 4)) ] || fail "the map grew from $k1 to $k2 keyframes"
echo "map growth bounded"
