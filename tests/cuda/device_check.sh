#!/bin/sh
# device_check.sh BUILD OUT -- what to run when a machine with a CUDA device is lent
# (issue 22, item 5), in one go and within a few minutes: the device tests, then the
# bench on the device, its output in OUT for docs/results/cuda.md.
#   cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo && cmake --build build -j
#   sh tests/cuda/device_check.sh build "$OUT"
# RBC_REQUIRE_CUDA=1 turns the device tests' "skipped" into a failure: on a machine
# with a GPU a skip means the module was not built or the driver is older than the
# CUDA 13 runtime the module links (R580 or later is needed).
set -u
build=$1
out=$2
mkdir -p "$out"
nvidia-smi > "$out/nvidia-smi.txt" 2>&1
if [ ! -f "$build/lib/librbcloth_cuda.so" ]; then
  echo "FAIL: $build/lib/librbcloth_cuda.so was not built (no nvcc?)" | tee "$out/summary.txt"
  exit 1
fi
(cd "$build" && RBC_REQUIRE_CUDA=1 ctest -R '^cuda_' -V) > "$out/ctest_cuda.txt" 2>&1
echo "ctest cuda_*: exit $?" | tee "$out/summary.txt"
grep -E "cuda_parity|cuda_colliders_parity|cuda_abi|CUDA against|CUDA device|with a sphere" "$out/ctest_cuda.txt" | tee -a "$out/summary.txt"
"$build/bin/rbcloth" bench perf --backend cuda --out "$out/perf_cuda" > "$out/perf_cuda.txt" 2>&1
echo "bench perf --backend cuda: exit $?" | tee -a "$out/summary.txt"
tail -40 "$out/perf_cuda.txt"
