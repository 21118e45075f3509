#!/usr/bin/env bash
# tests/glviewer: run rbcloth-viewer under Xvfb with a scripted drag and cut, then
# check its screenshots and printed state (check_glviewer.c).
#   run_glviewer.sh VIEWER CHECKER SCENE SCRIPT OUTDIR [keys]
# keys: keys.script's checks (check_glviewer keys) instead of drag_cut.script's.
# xvfb-run (Debian's xvfb, with xauth) is required: .ci/deps.sh installs both, and
# a machine without them fails this test rather than skipping it.
set -euo pipefail
viewer=$1 checker=$2 scene=$3 script=$4 out=$5 mode=${6:-drag}
if ! command -v xvfb-run >/dev/null 2>&1; then
  echo "run_glviewer.sh: xvfb-run not found: install xvfb and xauth (.ci/deps.sh)" >&2
  exit 1
fi
rm -rf "$out"
mkdir -p "$out"
cd "$out"
# -a: a free display number, so parallel tests do not collide. The screen is the
# window's size at 24 bits so glReadPixels sees true colours. The viewer's own time
# is about 1 s; 60 s bounds a hung X server.
status=0
timeout 60 xvfb-run -a -s "-screen 0 800x600x24" "$viewer" --size 800x600 --camera 0,0 \
  --script "$script" "$scene" >viewer.log 2>viewer.err || status=$?
cat viewer.log
if [ -s viewer.err ]; then sed 's/^/viewer stderr: /' viewer.err >&2; fi
if [ "$status" -ne 0 ]; then
  echo "run_glviewer.sh: rbcloth-viewer exited with status $status" >&2
  exit 1
fi
if [ "$mode" = keys ]; then
  exec "$checker" keys viewer.log keys_before.png keys_ball.png
fi
exec "$checker" viewer.log still.png before.png dragged.png precut.png cut.png
