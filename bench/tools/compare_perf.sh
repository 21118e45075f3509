#!/usr/bin/env bash
# compare_perf.sh -- `rbcloth bench perf` of two builds, alternating A and B in one run
# (this machine is shared and noisy: a drift hits both), then per row the median
# step time of each and their ratio B / A.
#
#   bench/tools/compare_perf.sh OLD/bin/rbcloth NEW/bin/rbcloth OUT_DIR [ROUNDS=5] [-- BENCH OPTIONS]
#
# writes OUT_DIR/compare.csv (mesh, solver, particles, threads, median A, median B,
# and the quartiles of the per-round ratio B / A) and prints it as a table, with the
# median ratio over all rows last.
# Default bench options: --quick.
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 RBCLOTH_A RBCLOTH_B OUT_DIR [ROUNDS] [-- BENCH OPTIONS]" >&2
    exit 2
fi
a=$1 b=$2 out=$3 rounds=${4:-5}
shift $(( $# >= 4 ? 4 : 3 ))
[ "${1:-}" = "--" ] && shift
opts=("$@")
[ ${#opts[@]} -eq 0 ] && opts=(--quick)
mkdir -p "$out"
for r in $(seq 1 "$rounds"); do
    for side in A B; do
        bin=$a
        [ $side = B ] && bin=$b
        "$bin" bench perf "${opts[@]}" --out "$out/$side$r" > "$out/$side$r.log" 2>&1 ||
            { echo "$0: $side round $r failed (log: $out/$side$r.log)" >&2; exit 1; }
    done
done
python3 - "$out" "$rounds" <<'PY'
import csv, statistics, sys
out, rounds = sys.argv[1], int(sys.argv[2])
def rows(path):
    with open(path) as f:
        for r in csv.DictReader(f):
            yield (r['mesh'], r['solver'], int(r['particles']), int(r['threads'])), float(r['step_ms'])
# times[key][side][round]; a round's B / A pairs runs a second apart, so a drift of
# the machine over the run cancels in the ratio.
times = {}
for side in 'AB':
    for k in range(rounds):
        for key, ms in rows(f'{out}/{side}{k + 1}/perf.csv'):
            times.setdefault(key, {'A': [None] * rounds, 'B': [None] * rounds})[side][k] = ms
def quartiles(v):
    q = statistics.quantiles(v, n=4) if len(v) > 1 else [v[0]] * 3
    return q[0], statistics.median(v), q[2]
meds = []
with open(f'{out}/compare.csv', 'w') as f:
    f.write('mesh,solver,particles,threads,median_ms_a,median_ms_b,ratio_q1,ratio_median,ratio_q3\n')
    print(f'{"mesh":<9} {"solver":<13} {"particles":>9} {"thr":>3} {"A ms":>8} {"B ms":>8} '
          f'{"B/A q1":>7} {"median":>7} {"q3":>6}')
    for key in sorted(times):
        a, b = times[key]['A'], times[key]['B']
        q1, qm, q3 = quartiles([y / x for x, y in zip(a, b) if x and y])
        meds.append(qm)
        ma, mb = statistics.median(a), statistics.median(b)
        f.write(f'{key[0]},{key[1]},{key[2]},{key[3]},{ma:.4f},{mb:.4f},{q1:.3f},{qm:.3f},{q3:.3f}\n')
        print(f'{key[0]:<9} {key[1]:<13} {key[2]:>9} {key[3]:>3} {ma:>8.3f} {mb:>8.3f} '
              f'{q1:>7.3f} {qm:>7.3f} {q3:>6.3f}')
print(f'median over {len(meds)} rows of the per-round B / A medians: {statistics.median(meds):.3f} '
      f'({rounds} rounds, A and B alternating)')
PY
