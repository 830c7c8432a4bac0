#!/usr/bin/env bash
# Real-window smoke test of the viewer under Xvfb.
#
# Usage: .ci/xvfb_smoke.sh PATH/TO/radlab [SCENE (default builtin:table-room)]
# Assumes: apt-get install xvfb xauth imagemagick xdotool mesa-vulkan-drivers libvulkan1
#
# Starts Xvfb, opens `radlab view SCENE --solve`, waits for the solve, clicks the middle of the
# viewport (picks an element), grabs the screen with `import`, and checks that
#   1. the viewer is still running after the click,
#   2. the viewport region is not blank (enough distinct colours: a shaded room has hundreds;
#      an empty viewport has one),
#   3. the inspector shows the picked element (its panel region changed after the click),
#   4. dragging BFeps finer re-solves without a blank frame,
#   5. a lecture figure with a split view (h-vs-p-linear) writes its window screenshot and exits,
#   6. `--bench-thresholds` sets each threshold in turn, reports each picture's time, and exits.
# Exits non-zero on any failure. Screenshots are left in $OUT_DIR (default: target/xvfb-smoke).
set -euo pipefail

BIN=${1:?usage: $0 PATH/TO/radlab [SCENE]}
SCENE=${2:-builtin:table-room}  # solves in seconds even in a debug build
OUT_DIR=${OUT_DIR:-target/xvfb-smoke}
# Distinct colours the viewport crop must have: smooth-shaded walls give hundreds.
MIN_VIEWPORT_COLOURS=${MIN_VIEWPORT_COLOURS:-64}
# Seconds to wait for the window and the solve (the interactive preset on a 2-core machine).
WAIT_START=${WAIT_START:-20}

mkdir -p "$OUT_DIR"
export XDG_RUNTIME_DIR
XDG_RUNTIME_DIR=$(mktemp -d)
chmod 700 "$XDG_RUNTIME_DIR"

# A free display number.
DISP=99
while [ -e "/tmp/.X11-unix/X$DISP" ] || [ -e "/tmp/.X$DISP-lock" ]; do DISP=$((DISP + 1)); done
export DISPLAY=":$DISP"

Xvfb "$DISPLAY" -screen 0 1280x800x24 -nolisten tcp >"$OUT_DIR/xvfb.log" 2>&1 &
XVFB_PID=$!
APP_PID=
cleanup() {
    [ -n "$APP_PID" ] && kill "$APP_PID" 2>/dev/null || true
    kill "$XVFB_PID" 2>/dev/null || true
    rm -rf "$XDG_RUNTIME_DIR"
}
trap cleanup EXIT

for _ in $(seq 50); do
    xdpyinfo >/dev/null 2>&1 && break
    [ -e "/tmp/.X11-unix/X$DISP" ] && break
    sleep 0.1
done

"$BIN" view "$SCENE" --solve >"$OUT_DIR/radlab.log" 2>&1 &
APP_PID=$!

# Wait until the window exists, then for the solve.
for _ in $(seq $((WAIT_START * 2))); do
    if ! kill -0 "$APP_PID" 2>/dev/null; then
        echo "xvfb_smoke: radlab exited early:" >&2
        cat "$OUT_DIR/radlab.log" >&2
        exit 1
    fi
    if xdotool search --name '^radlab$' >/dev/null 2>&1; then break; fi
    sleep 0.5
done
sleep "$WAIT_START"

import -window root "$OUT_DIR/before.png"
# The viewport is the middle of the window (side panels ~270 and ~300 px wide).
xdotool mousemove 620 400 click 1
sleep 3
import -window root "$OUT_DIR/after.png"

if ! kill -0 "$APP_PID" 2>/dev/null; then
    echo "xvfb_smoke: radlab died after the click:" >&2
    cat "$OUT_DIR/radlab.log" >&2
    exit 1
fi

colours=$(convert "$OUT_DIR/after.png" -crop 400x300+420+250 +repage -format %k info:)
echo "xvfb_smoke: viewport crop has $colours distinct colours (need >= $MIN_VIEWPORT_COLOURS)"
if [ "$colours" -lt "$MIN_VIEWPORT_COLOURS" ]; then
    echo "xvfb_smoke: the viewport looks blank (see $OUT_DIR/after.png)" >&2
    exit 1
fi

# The inspector (right panel) must change when an element is picked.
convert "$OUT_DIR/before.png" -crop 280x300+990+20 +repage "$OUT_DIR/inspector_before.png"
convert "$OUT_DIR/after.png" -crop 280x300+990+20 +repage "$OUT_DIR/inspector_after.png"
diff_px=$(compare -metric AE "$OUT_DIR/inspector_before.png" "$OUT_DIR/inspector_after.png" null: 2>&1 || true)
diff_px=${diff_px%% *}
echo "xvfb_smoke: inspector region changed in $diff_px pixels after the click"
if [ "${diff_px%.*}" -lt 100 ] 2>/dev/null; then
    echo "xvfb_smoke: the click did not pick an element (see $OUT_DIR/after.png)" >&2
    exit 1
fi
# A warm re-solve in a real window: drag BFeps finer (its slider in the side panel at 1280 x 800;
# the interactive preset's 0.1 sits at x = 87) and grab the screen as each value re-solves: no
# frame may be blank (the last finished picture stays, marked stale, until the new one is ready).
xdotool mousemove 87 153 mousedown 1
for x in 85 83 81; do
    xdotool mousemove "$x" 153
    sleep 0.7
    import -window root "$OUT_DIR/drag-$x.png"
    colours=$(convert "$OUT_DIR/drag-$x.png" -crop 400x300+420+250 +repage -format %k info:)
    echo "xvfb_smoke: while re-solving (slider at x = $x) the viewport has $colours distinct colours"
    if [ "$colours" -lt "$MIN_VIEWPORT_COLOURS" ]; then
        echo "xvfb_smoke: the viewport went blank while re-solving (see $OUT_DIR/drag-$x.png)" >&2
        exit 1
    fi
done
xdotool mouseup 1
if ! kill -0 "$APP_PID" 2>/dev/null; then
    echo "xvfb_smoke: radlab died during the drag:" >&2
    cat "$OUT_DIR/radlab.log" >&2
    exit 1
fi
# A lecture figure in a real window: the split view of two solves scored against the closed
# form (its reference), written as a PNG and exited; a panic or a hang fails here.
if ! timeout 120 "$BIN" view --figure h-vs-p-linear --window --screenshot "$OUT_DIR/h-vs-p-linear.png" \
    >"$OUT_DIR/figure.log" 2>&1; then
    echo "xvfb_smoke: the h-vs-p-linear figure did not write its screenshot:" >&2
    cat "$OUT_DIR/figure.log" >&2
    exit 1
fi
colours=$(convert "$OUT_DIR/h-vs-p-linear.png" -format %k info:)
echo "xvfb_smoke: h-vs-p-linear window has $colours distinct colours"
if [ "$colours" -lt "$MIN_VIEWPORT_COLOURS" ]; then
    echo "xvfb_smoke: the figure's window looks blank (see $OUT_DIR/h-vs-p-linear.png)" >&2
    exit 1
fi
# The slider's benchmark: a threshold change each, a finer one (warm) and back (the kept state).
if ! timeout 180 "$BIN" view "$SCENE" --preset draft --bench-thresholds 0.1,0.2 >"$OUT_DIR/thresholds.log" 2>&1; then
    echo "xvfb_smoke: --bench-thresholds did not finish:" >&2
    cat "$OUT_DIR/thresholds.log" >&2
    exit 1
fi
reported=$(grep -c "^radlab: threshold .* picture on screen in" "$OUT_DIR/thresholds.log" || true)
grep "^radlab: threshold" "$OUT_DIR/thresholds.log" | sed 's/^/xvfb_smoke: /'
if [ "$reported" -ne 2 ]; then
    echo "xvfb_smoke: --bench-thresholds reported $reported of 2 changes:" >&2
    cat "$OUT_DIR/thresholds.log" >&2
    exit 1
fi
echo "xvfb_smoke: ok"
