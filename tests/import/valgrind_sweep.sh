#!/bin/sh
# valgrind_sweep.sh LOGDIR SUPP SWEEP ARGS... -- the import sweep under valgrind
# memcheck, following the sweep's forked children and the import helpers they start
# (--trace-children). A report in a sweep child fails its file (exit status 99,
# which the sweep sees); a helper's exit status comes after its answer, so a helper's
# report is found here instead: every log must be empty (--quiet logs only reports).
set -u
logdir=$1 supp=$2
shift 2
rm -f "$logdir"/valgrind.*.log
valgrind --quiet --tool=memcheck --leak-check=full --trace-children=yes \
  --suppressions="$supp" --error-exitcode=99 --log-file="$logdir/valgrind.%p.log" "$@"
rc=$?
reports=0
for f in "$logdir"/valgrind.*.log; do
  [ -s "$f" ] || continue
  reports=$((reports + 1))
  echo "valgrind_sweep: a report in $f:"
  head -40 "$f"
done
logs=$(ls "$logdir"/valgrind.*.log 2>/dev/null | wc -l)
echo "valgrind_sweep: $logs processes checked, $reports with a report; the sweep exited $rc"
[ "$rc" -eq 0 ] && [ "$reports" -eq 0 ]
