#!/bin/sh
# run_bench_perf_test.sh CLI OUT CHECKER
# Runs `CLI bench perf --quick --out OUT` into a fresh OUT, then `CHECKER OUT`.
# Exits 77 (CTest SKIP_RETURN_CODE) when the plugin predates ABI 1.1, which the
# benches need; any other failure of the bench or the checker fails. The quick run
# measures cloths of at most 10K particles with 1 and 2 threads: a few seconds.
cli=$1
out=$2
checker=$3
rm -rf "$out"
output=$("$cli" bench perf --quick --out "$out" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" -ne 0 ]; then
  if printf '%s\n' "$output" | grep -q "the benches need ABI 1.1"; then
    echo "run_bench_perf_test: the plugin predates ABI 1.1: skipped" >&2
    exit 77
  fi
  echo "run_bench_perf_test: rbcloth bench perf exited with $status" >&2
  exit 1
fi
exec "$checker" "$out"
