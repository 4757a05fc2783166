#!/usr/bin/env bash
# Smoke test of the real editor window: starts `kage edit` under Xvfb, waits for its first
# bakes, takes a screenshot of the X screen and checks it is not blank. With SCENE (a .gltf),
# edits a copy of it as a user would with xdotool — a click in the middle of the viewport picks
# what is there, Delete deletes it, Ctrl+S saves — and checks the saved file lost one root node
# and kept a .bak of the original.
# usage: tools/editor_smoke.sh PATH/TO/kage [SECONDS] [SCENE]   (run by cli/tests/smoke.rs)
set -euo pipefail
kage=$(realpath "$1")
wait_s=${2:-25}
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
# shellcheck source=tools/xvfb.sh
source "$(dirname "$0")/xvfb.sh"
scene=()
if [ -n "${3:-}" ]; then
  cp "$3" "$work/scene.gltf"
  scene=("$work/scene.gltf")
fi
(cd "$work" && DISPLAY=$display exec "$kage" edit "${scene[@]}" --face-res 16 >"$work/kage.log" 2>&1) &
app=$!
sleep "$wait_s"
if ! kill -0 $app 2>/dev/null; then
  echo "editor smoke test: kage edit exited early:"; cat "$work/kage.log"; exit 1
fi
DISPLAY=$display xwd -root -silent >"$work/screen.xwd"
mkdir -p "$root/target"
python3 "$root/tools/xwd_check.py" "$work/screen.xwd" "$root/target/editor-smoke.png"
if [ ${#scene[@]} -gt 0 ]; then
  # Keyboard focus (there is no window manager to give it), then a click in the viewport's
  # middle of the 1280×800 window (outliner left, inspector right, log below).
  DISPLAY=$display xdotool windowfocus --sync "$(DISPLAY=$display xdotool search --name kage | head -1)"
  DISPLAY=$display xdotool mousemove 570 390 click 1
  sleep 2
  DISPLAY=$display xdotool key Delete
  sleep 2
  DISPLAY=$display xdotool key ctrl+s
  # The save lands when the editor's next frame runs: wait for it (up to 60 s on a busy runner)
  # rather than for a fixed time.
  python3 - "$work/scene.gltf" <<'PY'
import json, sys, time
path = sys.argv[1]
roots = lambda p: len(json.load(open(p))["scenes"][0]["nodes"])
deadline = time.monotonic() + 60
while True:
    try:
        before, after = roots(path + ".bak"), roots(path)
        if after == before - 1:
            break
    except (OSError, ValueError):  # no backup yet, or one being copied
        before = after = None
    found = "no backup written" if before is None else f"{after} root nodes, the original {before}"
    assert time.monotonic() < deadline, f"no save within 60 s: {found}"
    time.sleep(0.1)
print(f"editor smoke test: a click, Delete and Ctrl+S saved the scene with {after} of {before} root nodes")
PY
fi
echo "editor smoke test: ok (screenshot in target/editor-smoke.png)"
