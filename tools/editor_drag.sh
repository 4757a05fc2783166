#!/usr/bin/env bash
# Times a drag in the real editor window: starts `kage edit` (the built-in scene, a fresh
# database) under Xvfb, waits for its first bakes, selects the sphere, drags its X arrow
# 105 px to the right as a user would (xdotool), and prints the log lines of the re-bake that
# follows (refinement, BSPVT, PRT, the bounce), which the editor also writes to stderr, after
# the time the mouse was released, on the log's clock (seconds since the editor started).
# usage: tools/editor_drag.sh PATH/TO/kage [SECONDS to wait for the first bakes, default 60]
set -euo pipefail
kage=$(realpath "$1")
wait_s=${2:-60}
work=$(mktemp -d)
# shellcheck source=tools/xvfb.sh
source "$(dirname "$0")/xvfb.sh"
started=$(date +%s.%N)
(cd "$work" && DISPLAY=$display XDG_RUNTIME_DIR=$work exec "$kage" edit --db "$work/kage.redb" 2>"$work/kage.log") &
app=$!
sleep "$wait_s"
export DISPLAY=$display
xdotool windowfocus --sync "$(xdotool search --name kage | head -1)"
# The 1280×800 window as it opens: the sphere at (670, 390), its X arrow's tip at (762, 402).
xdotool mousemove 670 390 click 1
sleep 2
lines=$(wc -l <"$work/kage.log")
xdotool mousemove 745 402
sleep 0.5
xdotool mousedown 1
for x in 755 770 790 810 830 850; do xdotool mousemove "$x" 402; sleep 0.2; done
sleep 1
xdotool mouseup 1
released=$(date +%s.%N)
sleep 25
awk -v a="$started" -v b="$released" 'BEGIN { printf "%9.2f s  mouse released\n", b - a }'
tail -n +"$((lines + 1))" "$work/kage.log" | grep -v XDG_RUNTIME_DIR
