#!/bin/bash
# The preset ladder and the teaching presets on the three rooms: wall time of `radlab solve`
# (median of 3, one run for `reference`, 2 threads) and the pointwise error against radlab's
# path-traced reference (65 537 points x 1 024 paths, cached in CACHE), scored against batch 2,
# which did not place the points.
#   scripts/preset_ladder.sh [RADLAB_BINARY] [CACHE_DIR] > ladder.tsv
set -euo pipefail
B=${1:-target/release/radlab}
CACHE=${2:-.radlab-cache}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
printf "scene\tpreset\telements\tlinks\tnot_gathered_of_emitted\ttimes_s\tpointwise\n"
for s in cornell table-room splash_room; do
  for p in draft interactive quality fine reference bf lecture splash2; do
    times=""
    n=3; [ "$p" = reference ] && n=1
    for _ in $(seq $n); do
      "$B" solve "builtin:$s" --preset "$p" --threads 2 -q --json "$TMP/s.json"
      times="$times $(python3 -c "import json,sys;print(round(json.load(open(sys.argv[1]))['stats']['time_s']['total'],3))" "$TMP/s.json")"
    done
    meta=$(python3 -c "import json,sys;d=json.load(open(sys.argv[1]));e=d['energy'];print(d['stats']['elements'],d['stats']['links'],round(e['not_gathered'][0]/e['emitted'][0],6),sep='\t')" "$TMP/s.json")
    err=$("$B" reference "builtin:$s" --cache-dir "$CACHE" --batches 2 --compare --preset "$p" 2>&1 | grep "^scene: rel L1" | head -1)
    printf "%s\t%s\t%s\t%s\t%s\n" "$s" "$p" "$meta" "$times" "$err"
  done
done
