#!/usr/bin/env bash
# Regenerate screenshots/ with the tool itself (needs a display: e.g. Xvfb, and a Vulkan/GL driver
# such as Mesa's lavapipe). Usage: screenshots/regenerate.sh [path/to/radlab]
set -euo pipefail
bin="${1:-target/release/radlab}"
out="$(dirname "$0")"
# The viewer's pictures are interactive solves (`--preset`: one solve, not the way on to quality).
"$bin" view --preset interactive builtin:cornell --screenshot "$out/cornell.png"
"$bin" view --preset interactive builtin:cornell --screenshot "$out/cornell-quadtree.png" --overlay quadtree
"$bin" view --preset interactive builtin:cornell --screenshot "$out/cornell-links.png" --overlay links
"$bin" view --preset interactive builtin:cornell --screenshot "$out/cornell-error.png" --overlay error
"$bin" view --preset interactive builtin:cornell --screenshot "$out/cornell-picked.png" --pick 0.45,0.4 --window
"$bin" view --preset interactive builtin:cornell --screenshot "$out/cornell-plots.png" --plots --window
"$bin" view --preset interactive builtin:splash_room --screenshot "$out/splash_room-quadtree.png" --overlay quadtree
"$bin" view --preset interactive builtin:table-room --screenshot "$out/table-room-error.png" --overlay error
# The refinement replay: the first round of the Cornell box's solve, and its result cut at depth 3.
"$bin" view --preset interactive builtin:cornell --screenshot "$out/replay-round1.png" --replay 1 --overlay quadtree
"$bin" view --preset interactive builtin:cornell --screenshot "$out/replay-depth3.png" --replay 99 --depth-cut 3
# The split view: the linear-links figure's sweep (with an empty cache: its solves alone, no
# reference among them), and the Cornell box beside its Monte Carlo reference (computed once and
# cached, a few minutes, when it is not cached yet).
no_cache="$(mktemp -d)"
RADLAB_CACHE="$no_cache" "$bin" view --figure linear-links --split 3 --window --screenshot "$out/split-view.png"
rmdir "$no_cache"
"$bin" reference builtin:cornell >/dev/null
"$bin" view --preset interactive builtin:cornell --split 2 --window --screenshot "$out/split-reference.png"
# The table room's reference, its quality solve and a coarse uniform mesh (two figures in turn).
"$bin" reference builtin:table-room >/dev/null
"$bin" view --figure reference-table --figure uniform-coarse --split 3 --window \
  --screenshot "$out/split-three.png"
"$bin" solve builtin:furnished-9000 --method progressive --max-shots 300 --element-size 100 \
  --png "$out/furnished-9k.png" --width 800 --height 500 --quiet
"$bin" figures --screenshots "$out/figures"
echo "screenshots written to $out"
