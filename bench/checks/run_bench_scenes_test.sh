#!/bin/sh
# run_bench_scenes_test.sh CLI OUT CHECKER SCENES_DIR
# Runs `CLI bench scenes --frames 3 --out OUT` (scenes from SCENES_DIR) into a fresh
# OUT, then `CHECKER OUT`. Exits 77 (CTest SKIP_RETURN_CODE) when the plugin predates
# ABI 1.3, which the paper's scenes need; any other failure of the bench or the
# checker fails. 2 warm-up + 3 measured frames of six scenes with 1 and 2 threads.
cli=$1
out=$2
checker=$3
rm -rf "$out"
output=$(RBC_SCENES_DIR="$4" "$cli" bench scenes --frames 3 --out "$out" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" -ne 0 ]; then
  if printf '%s\n' "$output" | grep -q "the scenes bench needs ABI 1.3"; then
    echo "run_bench_scenes_test: the plugin predates ABI 1.3: skipped" >&2
    exit 77
  fi
  echo "run_bench_scenes_test: rbcloth bench scenes exited with $status" >&2
  exit 1
fi
exec "$checker" "$out"
