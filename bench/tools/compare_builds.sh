#!/usr/bin/env bash
# compare_builds.sh -- what a refactoring must leave unchanged, measured between two
# builds of rbcloth, as a Markdown page:
#   1. every sample scene's caches bitwise (tests/scene/cache_digests.sh) on 1 and 2
#      threads;
#   2. rbcloth bench perf --quick alternating A and B (compare_perf.sh);
#   3. the instructions of the step (valgrind --tool=callgrind, rbc_solver_step
#      only) for the default cloth under rbgs, gauss_seidel and jacobi: stable where
#      times are not.
#
#   bench/tools/compare_builds.sh A_BUILD B_BUILD OUT.md [ROUNDS=41] [TITLE]
#
# A_BUILD, B_BUILD: build folders (bin/rbcloth and the plugin beside it). Needs
# valgrind. docs/results/refactor-step.md is its page for issue 18.
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 A_BUILD B_BUILD OUT.md [ROUNDS] [TITLE]" >&2
    exit 2
fi
a=$1 b=$2 page=$3 rounds=${4:-41} title=${5:-"Two builds compared"}
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scenes=$root/samples/scenes
commit=$(git -C "$root" rev-parse --short HEAD)
dirty=$(git -C "$root" status --porcelain | grep -q . && echo " + uncommitted changes" || true)
cpu=$(grep -m1 "model name" /proc/cpuinfo | sed 's/.*: //')
load=$(cut -d' ' -f1 /proc/loadavg)
start=$(date -u '+%Y-%m-%d %H:%M UTC')

for side in a b; do
    bin=$a/bin/rbcloth
    [ $side = b ] && bin=$b/bin/rbcloth
    for t in 1 2; do bash "$root/tests/scene/cache_digests.sh" "$bin" "$scenes" "$work/dig_$side" $t > /dev/null; done
done
caches=$(wc -l < "$work/dig_a/digests-t1.txt")
same() { if cmp -s "$1" "$2"; then echo "identical"; else echo "**different** ($(diff "$1" "$2" | grep -c '^<') lines)"; fi; }
d1=$(same "$work/dig_a/digests-t1.txt" "$work/dig_b/digests-t1.txt")
d2=$(same "$work/dig_a/digests-t2.txt" "$work/dig_b/digests-t2.txt")
d12=$(same "$work/dig_b/digests-t1.txt" "$work/dig_b/digests-t2.txt")

perf=$("$here/compare_perf.sh" "$a/bin/rbcloth" "$b/bin/rbcloth" "$work/perf" "$rounds")

cg() { # BIN SOLVER -> instructions of rbc_solver_step
    valgrind --tool=callgrind --toggle-collect=rbc_solver_step --callgrind-out-file="$work/cg.out" \
        "$1" run "$scenes/hanging_cloth.json" --frames 3 --threads 1 --solver "$2" --no-view -q \
        --out "$work/cg_run" > /dev/null 2>&1
    sed -n 's/^summary: //p' "$work/cg.out"
}
cgrows=""
for solver in rbgs gauss_seidel jacobi; do
    ia=$(cg "$a/bin/rbcloth" $solver) ib=$(cg "$b/bin/rbcloth" $solver)
    cgrows+="| $solver | $ia | $ib | $(awk -v x="$ia" -v y="$ib" 'BEGIN { printf "%+.3f %%", 100 * (y - x) / x }') |"$'\n'
done

{
    echo "# $title"
    echo
    echo "Regenerate: \`bench/tools/compare_builds.sh A_BUILD B_BUILD $page $rounds\`"
    echo
    echo "Measured: $start; commit $commit$dirty (B); A and B as named below; $cpu, $(nproc) cores, Debian $(cut -d. -f1 /etc/debian_version); load average $load at the start."
    echo
    echo "A: \`$a\` (commit $(git -C "$a/.." rev-parse --short HEAD 2>/dev/null || echo unknown)); B: \`$b\` (commit $(git -C "$b/.." rev-parse --short HEAD 2>/dev/null || echo unknown))."
    echo
    echo "## Caches, bitwise"
    echo
    echo "\`tests/scene/cache_digests.sh\`: the SHA-256 of the $caches caches of every sample scene (the tearing scene 90 frames, the others 30) and of the default cloth under every global solver and the iteration modes that do not read the clock."
    echo
    echo "| comparison | result |"
    echo "|---|---|"
    echo "| A against B, 1 thread | $d1 |"
    echo "| A against B, 2 threads | $d2 |"
    echo "| B, 1 thread against 2 | $d12 |"
    echo
    echo "## Speed: \`rbcloth bench perf --quick\`, $rounds rounds, A and B alternating"
    echo
    echo "Step time per frame. B/A: the quartiles of the per-round ratio (each round runs A, then B, a second apart). A quick run times 20 frames of microseconds each, so one round's ratio scatters by about ±10 %; the median of the per-round ratios is the figure."
    echo
    echo '```'
    echo "$perf"
    echo '```'
    echo
    echo "## Instructions of the step (callgrind)"
    echo
    echo "\`valgrind --tool=callgrind --toggle-collect=rbc_solver_step\` on \`rbcloth run samples/scenes/hanging_cloth.json --frames 3 --threads 1 --solver S\`."
    echo
    echo "| solver | A | B | B − A |"
    echo "|---|---:|---:|---:|"
    printf '%s' "$cgrows"
} > "$page"
echo "$page"
