#!/usr/bin/env bash
# cache_digests.sh -- the point caches of every sample scene (and of the hanging cloth
# under every solver and iteration mode), as SHA-256 digests, so that two builds, or
# two thread counts, can be compared bit for bit.
#
#   cache_digests.sh RBCLOTH SCENES_DIR OUT_DIR THREADS [FRAMES]
#
# writes OUT_DIR/digests-tTHREADS.txt ("case  file  sha256" per cache) and prints its
# path. A refactoring of the step must leave every line unchanged:
#
#   cache_digests.sh old/bin/rbcloth samples/scenes /tmp/a 1
#   cache_digests.sh new/bin/rbcloth samples/scenes /tmp/b 1
#   diff /tmp/a/digests-t1.txt /tmp/b/digests-t1.txt
#
# The test `caches_thread_independent` compares 1 and 2 threads of one build (the
# solver's results do not depend on the thread count). The budget mode is left out:
# its iteration count depends on the clock.
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 RBCLOTH SCENES_DIR OUT_DIR THREADS [FRAMES]" >&2
    exit 2
fi
rbcloth=$1 scenes=$2 out=$3 threads=$4 frames=${5:-30}
mkdir -p "$out"
digests="$out/digests-t$threads.txt"
: > "$digests"

run_case() { # NAME FRAMES SCENE [OPTIONS...]
    local name=$1 n=$2 scene=$3
    shift 3
    local dir="$out/t$threads/$name"
    rm -rf "$dir"
    mkdir -p "$out/t$threads"
    if ! "$rbcloth" run "$scene" --out "$dir" --frames "$n" --threads "$threads" \
        --no-view -q "$@" > "$dir.log" 2>&1; then
        echo "$0: case $name failed (log: $dir.log):" >&2
        tail -5 "$dir.log" >&2
        exit 1
    fi
    (cd "$dir" && sha256sum -- *.pc2) | while read -r sum file; do
        printf '%-28s %-24s %s\n' "$name" "$file" "$sum" >> "$digests"
    done
}

for scene in "$scenes"/*.json; do
    name=$(basename "$scene" .json)
    n=$frames
    # The tearing scene tears only once the first sphere reaches the cloth.
    [ "$name" = cannonballs_tearing ] && n=$((frames * 3))
    # The 100K crumpled cloth takes seconds a frame and touches itself only from
    # frame 13: its small copy below stands in for it.
    [ "$name" = crumpled_cloth ] && continue
    run_case "$name" "$n" "$scene"
done
# The crumpled cloth's 41 x 41 copy, into its walls and folded (self contact on a heap).
small="$(dirname "$0")/data/crumpled_cloth_41.json"
[ -f "$small" ] && run_case crumpled_cloth_41 $((frames * 2)) "$small"
# Every global solver, and the iteration modes that do not read the clock, on the
# default cloth (a shorter run: the scene above already covers the default solve).
hang="$scenes/hanging_cloth.json"
short=$(( frames / 3 > 4 ? frames / 3 : 4 ))
for solver in rbgs jacobi jacobi_chebyshev gauss_seidel rbgs_chebyshev multicolor_gs direct; do
    run_case "solver_$solver" "$short" "$hang" --solver "$solver" --substeps 4 --iterations 8
done
run_case mode_tolerance "$short" "$hang" --mode tolerance --tolerance 1e-3 --substeps 4
run_case mode_target "$short" "$hang" --mode target --target-strain 0.05
run_case nonlinear_2 "$short" "$hang" --nonlinear 2 --substeps 4
run_case guard_off "$short" "$hang" --energy-guard off --solver jacobi --substeps 2
echo "$digests"
