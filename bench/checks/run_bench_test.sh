#!/bin/sh
# run_bench_test.sh CLI KIND OUT CHECKER [CHECKER ARGS...]
# Runs `CLI bench KIND` as its quick test does into a fresh OUT, then CHECKER with its
# arguments: accuracy --quick --frames 12; peers, perf and stability --quick (perf:
# cloths of at most 10K particles with 1 and 2 threads, a few seconds); scenes
# --frames 3 (2 warm-up + 3 measured frames of six scenes with 1 and 2 threads, the
# scenes from $RBC_SCENES_DIR). Exits 77 (CTest SKIP_RETURN_CODE) when the plugin
# predates the ABI the bench needs (1.1; the paper's scenes 1.3); any other failure
# of the bench or the checker fails.
cli=$1
kind=$2
out=$3
shift 3
rm -rf "$out"
case $kind in
  accuracy) options="--quick --frames 12" ;;
  scenes) options="--quick --frames 3" ;;
  *) options=--quick ;;
esac
if [ "$kind" = scenes ]; then
  abi=1.3 needs="the scenes bench needs ABI 1.3"
else
  abi=1.1 needs="the benches need ABI 1.1"
fi
output=$("$cli" bench "$kind" $options --out "$out" 2>&1)
status=$?
printf '%s\n' "$output"
if [ "$status" -ne 0 ]; then
  if printf '%s\n' "$output" | grep -q "$needs"; then
    echo "run_bench_test: the plugin predates ABI $abi: skipped" >&2
    exit 77
  fi
  echo "run_bench_test: rbcloth bench $kind exited with $status" >&2
  exit 1
fi
exec "$@"
