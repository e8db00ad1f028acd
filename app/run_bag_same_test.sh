#!/bin/sh
# The same frames from an image folder and from lossless rosbag2 recordings of them give
# byte-identical results (CTest app/run_bag_same_as_folder):
#   run_bag_same_test.sh MONOPLANE CALIB WORK_DIR NAME:INPUT ...
# Each INPUT is run with CALIB for 40 frames into WORK_DIR/NAME (per-frame outputs and a map); the
# map's grid and trajectory are exported. The first input is the reference: every other one must
# have the same per-frame outputs, the same grid (PGM and YAML) and the same poses (the stamps may
# differ: a bag's are its messages' header stamps). Prints "NAME: same as REFERENCE, N frames".
set -eu
mp=$1
calib=$2
dir=$3
shift 3
rm -rf "$dir"
reference=""
for entry in "$@"; do
  name=${entry%%:*}
  input=${entry#*:}
  out="$dir/$name"
  "$mp" run --input "$input" --calib "$calib" --max-frames 40 --frames-out "$out/f" \
    --map "$out/m.db" --quiet > /dev/null
  "$mp" export "$out/m.db" --grid "$out/map.yaml" --trajectory "$out/t.txt" > /dev/null
  cut -d' ' -f2- "$out/t.txt" > "$out/poses.txt"
  if [ -z "$reference" ]; then
    reference=$name
    continue
  fi
  ref="$dir/$reference"
  diff -r "$ref/f" "$out/f"
  cmp "$ref/map.pgm" "$out/map.pgm"
  diff "$ref/map.yaml" "$out/map.yaml"
  diff "$ref/poses.txt" "$out/poses.txt"
  echo "$name: same as $reference, $(ls "$out/f/labels" | wc -l) frames"
done
