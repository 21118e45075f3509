#!/bin/sh
# check_scene_stats.sh CSV FRAMES MAX_STRAIN MAX_KINETIC: a scene run with
# `rbcloth run --frame-stats CSV` went through all FRAMES frames (the run itself
# failing is caught by its own test), and in every frame its most stretched spring
# stayed under MAX_STRAIN and its kinetic energy under MAX_KINETIC joules, with no
# field NaN. Prints the largest of each, and the fail-safe's and the cap's totals.
csv=$1
frames=$2
strain=$3
kinetic=$4
[ -f "$csv" ] || { echo "no file $csv"; exit 1; }
awk -F, -v frames="$frames" -v smax="$strain" -v kmax="$kinetic" '
NR == 1 { next }
{
    for (i = 2; i <= NF; ++i)
        if ($i !~ /^-?[0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?$/) {
            printf "frame %s field %d is \"%s\"\n", $1, i, $i; bad = 1; exit
        }
    if ($10 > s) { s = $10; sf = $1 }
    if ($4 > k) { k = $4; kf = $1 }
    frozen += $12; capped += $13; rows = NR - 1; ms += $2
}
END {
    if (bad) exit 1
    printf "%d frames (%.1f s of steps): largest strain %g (frame %d), kinetic energy at most %g J (frame %d); fail-safe froze %d vertices; contact cap reached by %d vertices (summed over the last substeps of the frames)\n", rows, ms / 1000, s, sf, k, kf, frozen, capped
    if (rows != frames) { printf "%d frames, expected %d\n", rows, frames; exit 1 }
    if (!(s < smax)) { printf "strain %g reached the bound %g\n", s, smax; exit 1 }
    if (!(k < kmax)) { printf "kinetic energy %g J reached the bound %g J\n", k, kmax; exit 1 }
}' "$csv"
