#!/usr/bin/env bash
# Smoke test of the real editor window: starts `kage edit` on the built-in scene under Xvfb,
# waits for its first bakes, takes a screenshot of the X screen and checks it is not blank.
# usage: tools/editor_smoke.sh PATH/TO/kage [SECONDS]   (run by cli/tests/smoke.rs)
set -euo pipefail
kage=$(realpath "$1")
wait_s=${2:-25}
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
display=:$((90 + RANDOM % 100))
Xvfb "$display" -screen 0 1280x800x24 -nolisten tcp >"$work/xvfb.log" 2>&1 &
xvfb=$!
trap 'kill $xvfb 2>/dev/null || true; kill $app 2>/dev/null || true' EXIT
for _ in $(seq 50); do [ -e "/tmp/.X11-unix/X${display#:}" ] && break; sleep 0.1; done
(cd "$work" && DISPLAY=$display exec "$kage" edit --face-res 16 >"$work/kage.log" 2>&1) &
app=$!
sleep "$wait_s"
if ! kill -0 $app 2>/dev/null; then
  echo "editor smoke test: kage edit exited early:"; cat "$work/kage.log"; exit 1
fi
DISPLAY=$display xwd -root -silent >"$work/screen.xwd"
mkdir -p "$root/target"
python3 "$root/tools/xwd_check.py" "$work/screen.xwd" "$root/target/editor-smoke.png"
echo "editor smoke test: ok (screenshot in target/editor-smoke.png)"
