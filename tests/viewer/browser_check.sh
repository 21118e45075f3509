#!/usr/bin/env bash
# browser_check.sh -- load an rbcloth player page (hosts/cli/viewer.c) in Debian's
# headless Chromium and check that it loads, that WebGL draws the cloth (where the
# still says it is, with --still) and that it plays (the frame counter advances in
# real time; two frames' screenshots differ).
#
# usage: browser_check.sh --tool PATH/viewer_pngtool [options] PAGE.html
#   --still PNG        the still (cli_view_write_png) of --frame: the page shown at
#                      that frame with the still's camera must put cloth where the still
#                      has it (cloth-mask overlap >= --min-overlap)
#   --frame N          frame to show for the still comparison (default 0)
#   --frames N         frames the page must say it holds
#   --min-overlap F    default 0.9 (see below)
#   --grey-overlap F   also compare the collider (grey) masks, at least F
#   --min-cloth F      without --still: cloth-coloured share of the screenshot (0.002)
#   --min-differ F     share of pixels two frames half the clip apart differ in (0.001)
#   --no-play          skip the playback checks (a clip that does not move)
#   --out DIR          where screenshots, DOM dumps and Chromium's log go
#   --index            PAGE is a batch's index page (cli_view_write_index): check
#                      only that it shows stills (cloth pixels, --min-cloth)
# Environment: CHROMIUM (default /usr/bin/chromium).
# Exit 0 when every check holds; 1 otherwise, saying which and why.
set -uo pipefail

CHROMIUM=${CHROMIUM:-/usr/bin/chromium}
# Every Chromium flag in one place. The machine has no display, no GPU and no
# network: --headless with software WebGL through ANGLE's SwiftShader backend
# (--use-angle=swiftshader; --enable-unsafe-swiftshader opts in to it, as Chromium
# no longer falls back to it silently); no sandbox (CI runs as root), /tmp instead
# of a small /dev/shm in containers, a fixed device scale so the screenshot has the
# still's pixels, and nothing that would reach for the network.
CHROMIUM_FLAGS=(--headless --no-sandbox --disable-gpu --use-angle=swiftshader
  --enable-unsafe-swiftshader --disable-dev-shm-usage --force-device-scale-factor=1
  --hide-scrollbars --no-first-run --no-default-browser-check --disable-background-networking
  --disable-component-update --disable-sync --disable-extensions --mute-audio)
# One Chromium run: the page loads, inflates and draws in well under 30 s on two
# cores (about 2 s for a 3 MB page); 60 s then a kill is the bound.
RUN_TIMEOUT=60
# Virtual time a capture lets the page run (it advances only when the page is idle,
# so loading costs none of it): 3 s, and 12 s for the one retry.
BUDGET=3000
RETRY_BUDGET=12000

tool="" still="" frame=0 frames="" min_overlap=0.9 grey_overlap="" min_cloth=0.002
min_differ=0.001 play=1 out="" page="" index=0
while [ $# -gt 0 ]; do
  case "$1" in
    --tool) tool=$2; shift 2 ;;
    --still) still=$2; shift 2 ;;
    --frame) frame=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --min-overlap) min_overlap=$2; shift 2 ;;
    --grey-overlap) grey_overlap=$2; shift 2 ;;
    --min-cloth) min_cloth=$2; shift 2 ;;
    --min-differ) min_differ=$2; shift 2 ;;
    --no-play) play=0; shift ;;
    --index) index=1; shift ;;
    --out) out=$2; shift 2 ;;
    -*) echo "browser_check: unknown option $1" >&2; exit 2 ;;
    *) page=$1; shift ;;
  esac
done
if [ -z "$page" ] || [ -z "$tool" ]; then
  sed -n '6,19p' "$0" >&2
  exit 2
fi
fail() { echo "browser_check: FAIL: $*" >&2; exit 1; }
[ -f "$page" ] || fail "no page at $page"
[ -x "$tool" ] || fail "no viewer_pngtool at $tool"
if [ ! -x "$CHROMIUM" ]; then
  fail "Chromium is not installed ($CHROMIUM): run .ci/deps.sh as root (make test does) to install Debian's chromium"
fi
page=$(cd "$(dirname "$page")" && pwd)/$(basename "$page")
[ -n "$out" ] || out=$(mktemp -d)
mkdir -p "$out" || fail "cannot create $out"
log=$out/chromium.log
: > "$log"
url="file://${page// /%20}"

# chromium ARGS...: one headless run with a fresh profile, bounded in time.
chromium() {
  local profile rc
  profile=$(mktemp -d) || return 1
  timeout -k 5 "$RUN_TIMEOUT" "$CHROMIUM" "${CHROMIUM_FLAGS[@]}" --user-data-dir="$profile" "$@" \
    2>>"$log"
  rc=$?
  rm -rf "$profile"
  [ $rc -eq 124 ] && echo "browser_check: Chromium ran past ${RUN_TIMEOUT} s: $*" >&2
  return $rc
}

# status FILE ATTR: an attribute of the page's <div id="status"> in a DOM dump.
status() {
  grep -o '<div id="status"[^>]*>' "$1" | head -n 1 | sed -n "s/.* data-$2=\"\\([^\"]*\\)\".*/\\1/p"
}

# dump NAME HASH: the DOM after the page ran; retried once, with more virtual time,
# when the page was not ready yet.
dump() {
  local name=$1 hash=$2 budget
  for budget in $BUDGET $RETRY_BUDGET; do
    chromium --dump-dom --virtual-time-budget="$budget" "$url#$hash" > "$out/$name.html"
    if [ "$(status "$out/$name.html" ready)" = 1 ] || [ -n "$(status "$out/$name.html" error)" ]; then
      return 0
    fi
    [ "$budget" = "$RETRY_BUDGET" ] ||
      echo "browser_check: $name: the page was not ready after $budget ms; retrying once with $RETRY_BUDGET ms"
  done
  return 0
}

# dump_at NAME HASH BUDGET: the DOM after exactly BUDGET ms; captured again once
# (same budget) if the page was not ready.
dump_at() {
  chromium --dump-dom --virtual-time-budget="$3" "$url#$2" > "$out/$1.html"
  if [ "$(status "$out/$1.html" ready)" != 1 ]; then
    echo "browser_check: $1: the page was not ready after $3 ms; capturing once more"
    chromium --dump-dom --virtual-time-budget="$3" "$url#$2" > "$out/$1.html"
  fi
}

shot() { # shot NAME HASH BUDGET W H
  chromium --screenshot="$out/$1.png" --window-size="$4,$5" --virtual-time-budget="$3" "$url#$2" \
    > /dev/null || fail "$1: Chromium could not take the screenshot (see $log)"
  [ -s "$out/$1.png" ] || fail "$1: no screenshot written (see $log)"
}

explain() {
  echo "--- last lines of $log:" >&2
  grep -v -e dbus -e 'unexpected operator' "$log" | tail -n 15 >&2
}

# A batch's index: plain HTML with a still per job; the stills must be drawn.
if [ "$index" = 1 ]; then
  shot index "" "$BUDGET" 1200 900
  "$tool" cloth "$out/index.png" "$min_cloth" || { explain; fail "the index shows no stills ($out/index.png)"; }
  echo "browser_check: OK (index $page)"
  exit 0
fi

# 1. It loads: WebGL context, data inflated, the asked frame shown, paused.
dump load "frame=$frame&paused=1"
err=$(status "$out/load.html" error)
if [ -n "$err" ]; then
  msg=$(sed -n 's/.*<div id="message"[^>]*>\([^<]*\)<.*/\1/p' "$out/load.html" | head -n 1)
  explain
  fail "the page reports error '$err': $msg"
fi
[ "$(status "$out/load.html" ready)" = 1 ] || { explain; fail "the page never became ready (see $out/load.html)"; }
webgl=$(status "$out/load.html" webgl)
shown=$(status "$out/load.html" frame)
stride=$(status "$out/load.html" stride)
held=$(status "$out/load.html" frames)
dt=$(status "$out/load.html" dt)
echo "browser_check: loaded with WebGL $webgl; frame $shown shown; $held frames, stride $stride, dt $dt s"
[ -z "$frames" ] || [ "$held" = "$frames" ] || fail "the page holds $held frames, expected $frames"
expect_shown=$(( frame / stride * stride ))
[ "$expect_shown" -lt "$held" ] || expect_shown=$(( (held - 1) / stride * stride ))
[ "$shown" = "$expect_shown" ] || fail "#frame=$frame shows frame $shown, expected $expect_shown"
[ "$(status "$out/load.html" playing)" = 0 ] || fail "#paused=1 left the page playing"
grep -q 'id="legend"' "$out/load.html" && grep -q 'id="slider"' "$out/load.html" ||
  fail "the legend or the frame slider is missing"
if [ "$stride" -gt 1 ]; then
  grep -q "<div id=\"note\">Showing 1 frame in $stride " "$out/load.html" ||
    fail "the page keeps 1 frame in $stride but does not say so"
fi

# 2. WebGL draws the cloth: at the still's frame and camera, where the still has it
# and in its colours. The rasterizer and WebGL differ along outlines (antialiasing,
# coverage rules): a band of a pixel or so, 1-3 % of a cloth of 1e4-1e5 pixels
# (measured: overlap 0.996-0.999). 0.9 leaves room for that and still fails a
# wrong camera or a missing part of the cloth; torn holes are checked on the still
# by the unit test.
if [ -n "$still" ]; then
  read -r w h < <("$tool" size "$still") || fail "cannot read $still"
  cmp=("$tool" compare "$still" "$out/frame.png" "$min_overlap" ${grey_overlap:+"$grey_overlap"})
  shot frame "frame=$frame&paused=1&ui=0&fit=frame" "$BUDGET" "$w" "$h"
  if ! "${cmp[@]}"; then
    echo "browser_check: frame: the screenshot does not match the still; retrying the capture once with $RETRY_BUDGET ms"
    shot frame "frame=$frame&paused=1&ui=0&fit=frame" "$RETRY_BUDGET" "$w" "$h"
    "${cmp[@]}" || { explain; fail "WebGL's cloth is not where the still has it ($out/frame.png vs $still)"; }
  fi
else
  w=960 h=720
  shot frame "frame=$frame&paused=1&ui=0" "$BUDGET" "$w" "$h"
  "$tool" cloth "$out/frame.png" "$min_cloth" || { explain; fail "WebGL drew no cloth ($out/frame.png)"; }
fi

# 3. It plays. Each capture runs the page from frame 0 for a budget of virtual time;
# the page reports when it started playing (data-play-start), its last tick
# (data-tick) and the frames it advanced since (data-advanced). Loading takes an
# unknown share of the budget, so the checks lean on those times, not on the budget:
#  - it was still ticking when captured: the last tick no earlier than 250 ms before
#    the budget ran out (ticks come every 40 ms at worst; the capture itself lands
#    up to a few hundred ms of virtual time after the budget on a large page);
#  - real time: advanced = floor((tick - start) / dt), and the frame shown is
#    (play-frame + advanced) mod frames, rounded down to a kept frame; 1 frame of
#    slack for where the page's and awk's floor() fall on a boundary;
#  - it moves on: the later capture has advanced further.
# Then two stills of the page (paused at two frames half the clip apart) differ.
if [ "$play" = 1 ]; then
  [ "$held" -gt 1 ] || fail "one frame: nothing to play (use --no-play)"
  awk -v dt="$dt" 'BEGIN { exit !(dt + 0 > 0) }' || fail "the page gives no frame time (data-dt '$dt')"
  t1=1500 t2=3000
  dump_at play1 "ui=0" "$t1"
  dump_at play2 "ui=0" "$t2"
  prev=-1
  for cap in "play1 $t1" "play2 $t2"; do
    set -- $cap
    f=$(status "$out/$1.html" frame) start=$(status "$out/$1.html" play-start)
    from=$(status "$out/$1.html" play-frame) tick=$(status "$out/$1.html" tick)
    adv=$(status "$out/$1.html" advanced)
    [ "$(status "$out/$1.html" playing)" = 1 ] || fail "$1: the page is not playing without #paused=1"
    [ -n "$f" ] && [ -n "$start" ] && [ -n "$tick" ] && [ -n "$adv" ] ||
      fail "$1: the playing page's status lacks frame, play-start, tick or advanced"
    awk -v f="$f" -v s0="$start" -v f0="$from" -v t="$tick" -v a="$adv" -v b="$2" -v n="$held" \
        -v dt="$dt" -v k="$stride" -v name="$1" 'BEGIN {
      e = int((t - s0) / 1000 / dt); want = int(((f0 + e) % n) / k) * k;
      d = f - want; if (d < 0) d = -d; if (n - d < d) d = n - d;
      printf "browser_check: %s: played %.0f ms of the %d ms budget, last tick at %.0f ms: %d frames advanced (%d by the clock), frame %d shown (%d by the clock)\n", name, t - s0, b, t, a, e, f, want;
      ok = t >= b - 250 && t <= b + 5000 && (a - e <= 1 && e - a <= 1) && d <= k;
      exit !ok }' || fail "$1: playback is not in real time, or stopped before the capture"
    [ "$adv" -gt "$prev" ] || fail "play2 advanced $adv frames, no more than play1 ($prev)"
    prev=$adv
  done
  other=$(( (frame + held / 2) % held ))
  shot still1 "frame=$frame&paused=1&ui=0" "$BUDGET" "$w" "$h"
  shot still2 "frame=$other&paused=1&ui=0" "$BUDGET" "$w" "$h"
  "$tool" differ "$out/still1.png" "$out/still2.png" "$min_differ" ||
    fail "frames $frame and $other look the same"
fi
echo "browser_check: OK ($page)"
