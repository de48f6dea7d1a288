#!/bin/bash
# The add-on in a windowed Blender (the modal path, progress, Cancel) with screenshots:
#   apt-get install blender xvfb xauth xdotool; make blender-addon
#   xvfb-run -a -s "-screen 0 1600x1600x24" blender/ui_check/run.sh /tmp/mrlib_ui
# Writes OUT/ui_{training,generated,cancelled}.png, OUT/ui_log.json and OUT/panel.png (the
# three sidebars side by side: docs/blender.md's picture, blender/ui_check/panel.png). Run from the
# repository root; Blender's user folders go to OUT/home (yours are not touched).
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
OUT="$(mkdir -p "${1:?usage: run.sh OUT_DIR}" && cd "$1" && pwd)"
rm -rf "$OUT/home" "$OUT/work" "$OUT/ready"
export HOME="$OUT/home" BLENDER_USER_CONFIG="$OUT/home/config" BLENDER_USER_SCRIPTS="$OUT/home/scripts"
"$ROOT/.venv/bin/python" - "$OUT" <<'PY'
import sys
from mrlib.io import load_motion, save_motion
for n in ("walk_sad", "walk_happy"):
    save_motion(load_motion(f"data_samples/{n}.npz").resample(15), f"{sys.argv[1]}/{n}.bvh", overwrite=True)
PY
blender --factory-startup --python "$HERE/no_splash.py" >/dev/null 2>&1
blender --python "$HERE/ui_check.py" -- "$ROOT/dist/mrlib_addon.zip" "$ROOT/.venv/bin/python" \
    "$OUT/work" "$OUT/walk_sad.bvh" "$OUT/walk_happy.bvh" "$OUT" &
pid=$!
for _ in $(seq 60); do [ -f "$OUT/ready" ] && break; sleep 1; done
xdotool search --sync --onlyvisible --name Blender >/dev/null
sleep 2
# the sidebar's "mrlib" tab, 242 px below the top at 1600 px wide (Blender 3.4; 4.x: the
# script sets the region's category itself)
xdotool mousemove 1307 242 click 1
sleep 1
xdotool mousemove 700 500
wait $pid
"$ROOT/.venv/bin/python" "$HERE/compose.py" "$OUT"
