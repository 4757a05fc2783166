# Sourced by the editor's window scripts (editor_smoke.sh, editor_drag.sh): starts Xvfb with a
# 1280×800 screen on a free display, its log in $work, and waits for its socket. Sets $display
# and $xvfb (its pid); both are stopped on exit, with the editor's $app once started.
display=:$((90 + RANDOM % 100))
Xvfb "$display" -screen 0 1280x800x24 -nolisten tcp >"$work/xvfb.log" 2>&1 &
xvfb=$!
trap 'kill $xvfb 2>/dev/null || true; kill ${app:-} 2>/dev/null || true' EXIT
for _ in $(seq 50); do [ -e "/tmp/.X11-unix/X${display#:}" ] && break; sleep 0.1; done
