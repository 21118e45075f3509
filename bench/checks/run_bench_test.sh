#!/bin/sh
# run_bench_test.sh CLI KIND OUT CHECKER [CHECKER ARGS...]
# Runs `CLI bench KIND --quick OUT-options` into a fresh OUT, then CHECKER with its
# arguments. Exits 77 (CTest SKIP_RETURN_CODE) when the plugin predates ABI 1.1,
# which the benches need; any other failure of the bench or the checker fails.
cli=$1
kind=$2
out=$3
shift 3
rm -rf "$out"
if [ "$kind" = accuracy ]; then
  output=$("$cli" bench accuracy --quick --frames 12 --out "$out" 2>&1)
elif [ "$kind" = peers ]; then
  output=$("$cli" bench peers --quick --out "$out" 2>&1)
else
  output=$("$cli" bench stability --quick --out "$out" 2>&1)
fi
status=$?
printf '%s\n' "$output"
if [ "$status" -ne 0 ]; then
  if printf '%s\n' "$output" | grep -q "the benches need ABI 1.1"; then
    echo "run_bench_test: the plugin predates ABI 1.1: skipped" >&2
    exit 77
  fi
  echo "run_bench_test: rbcloth bench $kind exited with $status" >&2
  exit 1
fi
exec "$@"
