#!/usr/bin/env bash
# check_abi.sh SRC_DIR SO -- compare the built plugin's ABI with the committed
# baseline abi/rbcloth.abi (written by `make abi-baseline`, see the Makefile).
#
#   abidiff --no-added-syms --headers-dir2 SRC/abi SRC/abi/rbcloth.abi SO
#
# --headers-dir2 restricts the comparison to types reachable from the public
# header; --no-added-syms tolerates appended functions (allowed within a major).
# abidiff's exit status is a bit field (1 error, 2 usage, 4 ABI change, 8
# incompatible change): anything non-zero fails this test. The tools missing is a
# failure too, never a skip: `make test` installs abigail-tools (.ci/deps.sh).
#
# Two guards keep the comparison from passing vacuously (both seen with
# libabigail 2.2 on Debian bookworm):
#  - A baseline written by plain `abidw` binds only a few functions to their ELF
#    symbols (here 3 of 30, the ones defined in plugin/api.c; apparently abidw
#    keeps the first DWARF entry of a function, and api.c's CU declares all the
#    others for the function table, so it keeps a declaration without a symbol
#    instead of the definition in world.c, cloth.c, ...). Functions
#    without a symbol are ignored when the baseline is read back, so a changed
#    rbc_world_def went unnoticed. `abidw --exported-interfaces-only` binds all
#    of them. The baseline must bind every function the header declares.
#  - A .so without DWARF compares equal to any baseline (symbols only, even with
#    --fail-no-debug-info), so the .so must carry .debug_info. CMakeLists.txt builds
#    with -g in every configuration (Release too), so only a stripped .so lacks it.
set -uo pipefail
src=${1:?usage: check_abi.sh SRC_DIR path/to/librbcloth.so}
so=${2:?usage: check_abi.sh SRC_DIR path/to/librbcloth.so}
baseline="$src/abi/rbcloth.abi"
header="$src/abi/rbcloth.h"

for tool in abidiff readelf; do
  if ! command -v "$tool" >/dev/null; then
    echo "FAIL: $tool not found: install abigail-tools and binutils (make deps / .ci/deps.sh)" >&2
    exit 1
  fi
done
[ -f "$so" ] || { echo "FAIL: $so does not exist" >&2; exit 1; }
if [ ! -s "$baseline" ]; then
  echo "FAIL: no ABI baseline at $baseline: run 'make abi-baseline' and commit it" >&2
  exit 1
fi

# (readelf's output is captured first: with pipefail, `readelf | grep -q` fails at
# random when grep exits early and readelf dies of SIGPIPE.)
sections=$(readelf -S "$so")
if ! grep -q '\.debug_info' <<< "$sections"; then
  # CMakeLists.txt adds -g to every configuration (Release and MinSizeRel too), so
  # a plugin built by this tree always has it: one without was stripped (strip,
  # install/strip, a packager) or built by other means. abidiff would compare its
  # symbols only and pass whatever its types became, so this fails rather than skip.
  echo "FAIL: $so has no DWARF (.debug_info section): abidiff cannot compare types without it." >&2
  echo "      This tree builds the plugin with -g in every configuration; was the .so stripped" >&2
  echo "      (strip, cmake --install --strip) or built outside CMakeLists.txt? Check an unstripped build." >&2
  exit 1
fi

# Every function of the header, and whether the baseline binds it to its symbol.
funcs=$(tr '\n' ' ' < "$header" | grep -o 'RBC_API[^;(]*RBC_CALL[[:space:]]*rbc_[A-Za-z0-9_]*[[:space:]]*(' |
        sed -E 's/.*RBC_CALL[[:space:]]*(rbc_[A-Za-z0-9_]*).*/\1/' | sort -u)
nfuncs=$(grep -c . <<< "$funcs" || true)
if [ "$nfuncs" -lt 30 ]; then
  echo "FAIL: found only $nfuncs functions in $header (parser broken?)" >&2
  exit 1
fi
unbound=()
while IFS= read -r f; do
  # the symbol id carries the version node (rbc_x@@RBCLOTH_1) since 1.9
  grep -q "<function-decl name='$f'[^>]*elf-symbol-id='$f\(@@RBCLOTH_1\)\?'" "$baseline" || unbound+=("$f")
done <<< "$funcs"
if [ ${#unbound[@]} -ne 0 ]; then
  echo "FAIL: the baseline binds only $((nfuncs - ${#unbound[@]})) of $nfuncs header functions to" \
       "their ELF symbols; the others would not be compared at all." >&2
  echo "      Unbound: ${unbound[*]}" >&2
  echo "      Regenerate with: abidw --no-corpus-path --exported-interfaces-only --headers-dir abi" \
       "--out-file abi/rbcloth.abi build/lib/librbcloth.so" >&2
  exit 1
fi

out=$(abidiff --no-added-syms --headers-dir2 "$src/abi" "$baseline" "$so" 2>&1)
rc=$?
if [ "$rc" -ne 0 ]; then
  echo "FAIL: abidiff exit status $rc (1 error, 2 usage, 4 ABI change, 8 incompatible)" >&2
  echo "$out" >&2
  exit 1
fi
echo "abi_baseline: $so matches $baseline ($nfuncs functions compared)"
