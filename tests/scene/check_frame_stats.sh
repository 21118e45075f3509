#!/bin/sh
# check_frame_stats.sh CSV FRAMES: `rbcloth run --frame-stats CSV` wrote its header
# and one row per frame (1..FRAMES), every field a finite number, and the figures a
# hanging cloth must show after its first frames: time spent (step_ms > 0), motion
# (kinetic_energy > 0), stretch (max_strain > 0; strain_rms <= max_strain).
csv=$1
frames=$2
header="frame,step_ms,collide_ms,kinetic_energy,potential_energy,energy_budget,energy_removed,collider_contacts,cloth_contacts,max_strain,strain_rms,cloth_contact_frozen,cloth_contact_capped"
[ -f "$csv" ] || { echo "no file $csv"; exit 1; }
first=$(head -n 1 "$csv")
[ "$first" = "$header" ] || { echo "header is '$first', expected '$header'"; exit 1; }
awk -F, -v frames="$frames" '
NR == 1 { next }
{
    if (NF != 13) { printf "row %d has %d fields\n", NR - 1, NF; bad = 1; exit }
    if ($1 != NR - 1) { printf "row %d is frame %s\n", NR - 1, $1; bad = 1; exit }
    for (i = 2; i <= NF; ++i)
        if ($i !~ /^-?[0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?$/) {
            printf "frame %s field %d is \"%s\", not a finite number\n", $1, i, $i; bad = 1; exit
        }
    if (!($2 > 0)) { printf "frame %s: step_ms %s\n", $1, $2; bad = 1; exit }
    if ($11 > $10 + 1e-12) { printf "frame %s: strain_rms %s > max_strain %s\n", $1, $11, $10; bad = 1; exit }
    last_ke = $4; last_strain = $10; rows = NR - 1
}
END {
    if (bad) exit 1
    if (rows != frames) { printf "%d rows, expected %d\n", rows, frames; exit 1 }
    if (!(last_ke > 0) || !(last_strain > 0)) {
        printf "last frame: kinetic_energy %s, max_strain %s: a hanging cloth moves and stretches\n", last_ke, last_strain
        exit 1
    }
    printf "%d frames of figures, kinetic energy %s J and max strain %s at the last\n", rows, last_ke, last_strain
}' "$csv"
