#!/bin/sh
# check_bench_defaults.sh CLI OUT -- `rbcloth bench defaults --quick` (0.5 s of each
# cloth at 1/60 s, the default and the paper's solve) writes its CSV, page and plot
# script, and its figures say what the defaults promise:
#  - every run finished (ok = 1) with finite figures;
#  - the default solve: no step past the strain warning on any cloth, and the pinned
#    64 x 48 grid under 0.5 (a spring at 1.5 times its length; its converged motion
#    peaks at 0.28: docs/results/defaults.md, the reference row);
#  - the paper's solve on the same grid passes 10 (the full run: 51), so the bench
#    tells the two apart;
#  - the page is headed with the command, the date and the commit.
set -u
cli=$1 out=$2
rm -rf "$out"
"$cli" bench defaults --quick --out "$out" || { echo "FAIL: the bench exited with $?"; exit 1; }
csv=$out/defaults.csv
for f in "$csv" "$out/defaults.md" "$out/defaults.gp"; do
  [ -s "$f" ] || { echo "FAIL: $f missing or empty"; exit 1; }
done
grep -q '^Regenerate: `rbcloth bench defaults --out .* --quick`$' "$out/defaults.md" ||
  { echo "FAIL: defaults.md does not name its command"; exit 1; }
grep -Eq '^Measured: [0-9]{4}-[0-9]{2}-[0-9]{2} [0-9:]+ UTC; commit ' "$out/defaults.md" ||
  { echo "FAIL: defaults.md has no date and commit"; exit 1; }
awk -F, '
  NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
  {
    rows++
    c = $col["cloth"]; k = $col["config"]; s = $col["max_strain"] + 0
    if ($col["ok"] != 1) { print "FAIL: " c " " k " did not finish: " $col["error"]; bad = 1 }
    if ($col["max_strain"] !~ /^[0-9.e+-]+$/) { print "FAIL: " c " " k ": max_strain " $col["max_strain"]; bad = 1 }
    if (k == "default" && $col["strain_warnings"] != 0) { print "FAIL: the default warned on " c; bad = 1 }
    if (k == "default" && c == "grid_64x48" && !(s < 0.5)) { print "FAIL: the default reached " s " on the grid"; bad = 1 }
    if (k == "paper" && c == "grid_64x48") { paper = s }
  }
  END {
    if (rows != 6) { print "FAIL: " rows " rows, expected 3 cloths x 2 configurations"; bad = 1 }
    if (!(paper > 10)) { print "FAIL: the paper'"'"'s solve reached only " paper " on the grid"; bad = 1 }
    if (!bad) print "bench defaults: " rows " runs; the paper'"'"'s solve reached " paper " on the grid"
    exit bad
  }' "$csv"
