#!/usr/bin/env bash
# run_fuzz.sh BUILD_DIR TARGET SECONDS [LIBFUZZER_ARGS...] -- run the libFuzzer binary
# BUILD_DIR/bin/fuzz_TARGET (a build with RBC_FUZZ=ON, `make check-fuzz` makes one)
# for SECONDS, from the seed corpus and the regression inputs of tests/fuzz, and keep
# what it finds.
#
#   TARGET   scene, cloth or import
#   KEEP_GOING=1  continue past crashes, timeouts and ooms (libFuzzer's fork mode),
#                 for long runs by hand: every one found is kept
#
# The corpus it grows lives in BUILD_DIR/tests/fuzz/work/TARGET/corpus (kept between
# runs, never committed). Every crash, timeout, oom or leak is copied to
# tests/fuzz/regress/TARGET/ (commit it: fuzz_TARGET_replay replays that folder in
# every build) and the script exits 1 naming them; it also exits 1 if the fuzzer
# failed to start or ran fewer than 100 inputs. The import target adds, at run time,
# the files of Debian's assimp-testmodels under 8 KB with an extension it knows
# (none is copied into the tree).
set -uo pipefail
usage() { echo "usage: $0 BUILD_DIR scene|cloth|import SECONDS [LIBFUZZER_ARGS...]" >&2; exit 2; }
[ $# -ge 3 ] || usage
build=$1 target=$2 secs=$3
shift 3
src=$(cd "$(dirname "$0")" && pwd)
bin=$build/bin/fuzz_$target
case $target in
  scene)  max_len=16384 unit_timeout=10 ;;
  cloth)  max_len=4096  unit_timeout=10 ;;
  import) max_len=65536 unit_timeout=30 ;;
  *) usage ;;
esac
if [ ! -x "$bin" ]; then
  echo "FAIL: $bin not found: configure $build with CC=clang-14 -DRBC_FUZZ=ON (make check-fuzz)" >&2
  exit 1
fi
work=$build/tests/fuzz/work/$target
rm -rf "$work/artifacts"
mkdir -p "$work/corpus" "$work/artifacts"
dirs=("$work/corpus" "$src/corpus/$target" "$src/regress/$target")

if [ "$target" = import ]; then
  # fuzz_import.c's extension table: index = the first byte's low 5 bits.
  exts=(obj ply off stl dae gltf glb fbx 3ds x md2 ms3d ase ac lwo blend smd nff raw dxf cob
        irrmesh ogex 3mf amf md5mesh q3o xgl b3d lws mdl csm)
  models=${RBC_ASSIMP_MODELS:-/usr/share/assimp/models}
  seeds=$work/assimp_seeds
  rm -rf "$seeds"
  mkdir -p "$seeds"
  if [ -d "$models" ]; then
    n=0
    while IFS= read -r -d '' f; do
      name=${f##*/}
      ext=${name##*.}
      ext=${ext,,}
      for i in "${!exts[@]}"; do
        if [ "${exts[$i]}" = "$ext" ]; then
          out=$seeds/$(printf '%04d' $n)_${name//[^A-Za-z0-9._-]/_}
          { printf "\\x$(printf %02x "$i")"; cat "$f"; } > "$out"
          n=$((n + 1))
          break
        fi
      done
    done < <(find "$models" -type f -size -8k -print0 | sort -z)
    echo "run_fuzz: $n seed files from $models" >&2
    dirs+=("$seeds")
  else
    echo "run_fuzz: $models not found (assimp-testmodels): only the committed seeds" >&2
  fi
fi

args=(-max_total_time="$secs" -timeout="$unit_timeout" -rss_limit_mb=2048 -max_len="$max_len"
      -artifact_prefix="$work/artifacts/" -print_final_stats=1)
if [ "${KEEP_GOING:-0}" = 1 ]; then
  args+=(-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1)
fi
# The sanitizers' settings for the fuzz build (libFuzzer checks leaks after each input
# that allocated more than it freed).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1:allocator_may_return_null=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
log=$work/fuzz.log
echo "run_fuzz: $bin ${args[*]} $* ${dirs[*]}" >&2
start=$(date +%s)
"$bin" "${args[@]}" "$@" "${dirs[@]}" > "$log" 2>&1
rc=$?
took=$(( $(date +%s) - start ))
tail -n 30 "$log" >&2
execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -n 1)
if [ -z "$execs" ]; then
  # fork mode: the last status line counts the executions
  execs=$(grep -o '#[0-9]*' "$log" | tail -n 1 | tr -d '#')
fi
execs=${execs:-0}

kept=()
mkdir -p "$src/regress/$target"
for a in "$work/artifacts"/crash-* "$work/artifacts"/timeout-* "$work/artifacts"/oom-* \
         "$work/artifacts"/leak-*; do
  [ -f "$a" ] || continue
  cp "$a" "$src/regress/$target/"
  kept+=("tests/fuzz/regress/$target/${a##*/}")
done
echo "run_fuzz: fuzz_$target: ${took} s, $execs inputs run, exit status $rc, ${#kept[@]} found" >&2
if [ ${#kept[@]} -gt 0 ]; then
  echo "FAIL: fuzz_$target found ${#kept[@]} input(s), kept for the replay test (commit them):" >&2
  printf '  %s\n' "${kept[@]}" >&2
  echo "  reproduce: $bin FILE   (or $build/bin/fuzz_${target}_replay FILE)" >&2
  exit 1
fi
if [ "$rc" -ne 0 ]; then
  echo "FAIL: fuzz_$target exited with status $rc (log: $log)" >&2
  exit 1
fi
if [ "$execs" -lt 100 ]; then
  echo "FAIL: fuzz_$target ran only $execs inputs in $took s (log: $log)" >&2
  exit 1
fi
exit 0
