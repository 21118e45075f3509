#!/usr/bin/env bash
# windows_dll: rbcloth cross-built for 64-bit Windows with Debian's mingw-w64 and run
# under Debian's wine.
#   1. configure and build SRC with cmake/mingw-w64-x86_64.cmake in WORK/build (the
#      library alone, no CHOLMOD) and the conformance kit (rbcloth-conformance);
#      install into WORK/prefix and check the layout:
#      bin/rbcloth.dll, lib/librbcloth.dll.a, include/rbcloth.h
#   2. objdump -p: the DLL imports Windows' own DLLs only (no libgcc_s_seh-1.dll:
#      the toolchain file links libgcc statically; no libwinpthread-1.dll: the
#      threads are Win32's, core/threads.h, and the toolchain's -win32 compiler does
#      not link winpthreads, so a pthread call fails step 1's link) and exports
#      exactly the RBC_API functions of abi/rbcloth.h
#   3. linked_host.c, linked to the installed import library, runs under wine; the
#      same source linked to the native librbcloth.so (NATIVE_LIBDIR) runs here,
#      and their positions and PC2 caches must be the same bytes
#   4. the conformance kit (rbcloth-conformance.exe) under wine against the DLL: it
#      must pass every check
# Exit 77 (skip) when mingw-w64 or wine is not installed.
#
#   run.sh SRC WORK NATIVE_LIBDIR NATIVE_CC
set -uo pipefail
src=$1 work=$2 native_libdir=$3 native_cc=$4
# The toolchain file's compiler: the -win32 flavour, whose libgcc needs no winpthreads.
mingw=x86_64-w64-mingw32-gcc-win32
objdump=x86_64-w64-mingw32-objdump
for tool in "$mingw" "$objdump" wine wineboot wineserver; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "SKIP: $tool not installed (.ci/deps.sh: gcc-mingw-w64-x86-64, wine64, wine)"
    exit 77
  fi
done

fail=0
bad() { echo "FAIL: $*"; fail=1; }
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }

build=$work/build prefix=$work/prefix out=$work/out
rm -rf "$prefix" "$out"
mkdir -p "$build" "$out"

# --- 1. cross build and install -------------------------------------------------
t=$(now)
if ! cmake -S "$src" -B "$build" \
     -DCMAKE_TOOLCHAIN_FILE="$src/cmake/mingw-w64-x86_64.cmake" \
     -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRBC_BUILD_EXTRAS=OFF -DRBC_WITH_CHOLMOD=OFF \
     >"$out/configure.log" 2>&1; then
  cat "$out/configure.log"
  echo "FAIL: the cross configure failed"
  exit 1
fi
# The install step installs both, so both are built: a partial build would make
# `cmake --install` fail on whatever was left out.
targets=(rbcloth rbcloth-conformance)
if ! cmake --build "$build" -j2 --target "${targets[@]}" >"$out/build.log" 2>&1; then
  cat "$out/build.log"
  echo "FAIL: the cross build of ${targets[*]} failed"
  exit 1
fi
# Warnings are the compiler's findings about the port: none may pass unseen.
if grep -E 'warning:' "$out/build.log"; then bad "the cross build warns (above)"; fi
echo "# cross build of ${targets[*]}: $(since "$t") s"
if ! cmake --install "$build" --prefix "$prefix" >"$out/install.log" 2>&1; then
  cat "$out/install.log"
  echo "FAIL: cmake --install failed"
  exit 1
fi
for f in bin/rbcloth.dll lib/librbcloth.dll.a include/rbcloth.h; do
  [ -f "$prefix/$f" ] || bad "the install has no $f"
done
# No import helper on Windows (plugin/CMakeLists.txt), and no Linux library names.
if find "$prefix" -name 'rbcloth-import*' -o -name 'librbcloth.so*' -o -name 'librbcloth.dll' |
   grep .; then
  bad "the install has files a Windows build must not have (above)"
fi
dll=$prefix/bin/rbcloth.dll
[ -f "$dll" ] || { echo "FAIL: no DLL to check"; exit 1; }

# --- 2. imports and exports -------------------------------------------------------
"$objdump" -p "$dll" >"$out/objdump.txt"
echo "# DLLs rbcloth.dll imports:"
grep 'DLL Name:' "$out/objdump.txt" | sed 's/^[[:space:]]*/#   /'
# Windows' own: KERNEL32, the C runtime (msvcrt, or the UCRT's ucrtbase and its
# api-ms-win-crt-* sets), and the api-ms-win-core-* API sets (WaitOnAddress:
# api-ms-win-core-synch-l1-2-0.dll).
while read -r name; do
  shopt -s nocasematch
  if [[ ! $name =~ ^(kernel32|msvcrt|ucrtbase|api-ms-win-(core|crt)-[a-z0-9-]+)\.dll$ ]]; then
    bad "rbcloth.dll imports $name, which Windows does not have"
  fi
  shopt -u nocasematch
done < <(sed -n 's/^[[:space:]]*DLL Name: //p' "$out/objdump.txt")
# The export table's names: the lines "[ n] name" after "[Ordinal/Name Pointer] Table".
sed -n '/\[Ordinal\/Name Pointer\] Table/,/^$/p' "$out/objdump.txt" |
  sed -nE 's/^[[:space:]]*\[[[:space:]]*[0-9]+\][[:space:]]+([^[:space:]]+).*/\1/p' |
  sort -u >"$out/exports.txt"
grep -E '^RBC_API' "$src/abi/rbcloth.h" |
  sed -nE 's/.*RBC_CALL[[:space:]]+(rbc_[a-z0-9_]+)[[:space:]]*\(.*/\1/p' | sort -u >"$out/header.txt"
n_header=$(wc -l <"$out/header.txt")
# Every RBC_API line must have given a name (a declaration the pattern misses would
# otherwise go unchecked).
n_api=$(grep -cE '^RBC_API' "$src/abi/rbcloth.h")
[ "$n_header" -eq "$n_api" ] || bad "$n_api RBC_API lines in the header, $n_header names parsed"
[ "$n_header" -gt 0 ] || bad "no RBC_API function parsed from abi/rbcloth.h"
missing=$(comm -23 "$out/header.txt" "$out/exports.txt")
extra=$(comm -13 "$out/header.txt" "$out/exports.txt")
[ -z "$missing" ] || bad "the header's functions the DLL does not export: $missing"
[ -z "$extra" ] || bad "the DLL exports what the header does not declare: $extra"
if grep -v '^rbc_' "$out/exports.txt"; then bad "exports not starting with rbc_ (above)"; fi
echo "# exports: $(wc -l <"$out/exports.txt") (the header declares $n_header)"

# --- 3. a linked host under wine, and the same natively -----------------------------
# The .exe beside the DLL: Windows looks for a program's DLLs in its own folder first.
exe=$prefix/bin/linked_host.exe
if ! "$mingw" -std=c11 -O2 -Wall -Wextra -Werror -I "$prefix/include" \
     "$src/tests/windows/linked_host.c" -L "$prefix/lib" -lrbcloth -static-libgcc -o "$exe"; then
  bad "linked_host.exe did not build"
fi
native=$out/linked_host
if ! "$native_cc" -std=c11 -O2 -Wall -Wextra -Werror -I "$src/abi" \
     "$src/tests/windows/linked_host.c" -L "$native_libdir" -lrbcloth \
     -Wl,-rpath,"$native_libdir" -lm -o "$native"; then
  bad "the native linked_host did not build"
fi

# A private wine prefix (first use creates it), no display, no Mono or Gecko
# installer (mscoree, mshtml disabled), no debug chatter.
export WINEPREFIX=$work/wineprefix WINEDEBUG=-all WINEDLLOVERRIDES="mscoree,mshtml="
unset DISPLAY WAYLAND_DISPLAY
# wineserver outlives the programs by a few seconds; ctest would wait for it (it
# holds the test's output), so it is ended with the script.
trap 'wineserver -k >/dev/null 2>&1' EXIT
t=$(now)
if [ ! -f "$WINEPREFIX/system.reg" ]; then
  wineboot -i >"$out/wineboot.log" 2>&1 || { cat "$out/wineboot.log"; bad "wineboot -i failed"; }
  echo "# first wine start (wineboot -i, a new prefix): $(since "$t") s"
else
  wineboot >"$out/wineboot.log" 2>&1 || true
  echo "# wine start (prefix exists): $(since "$t") s"
fi
winpath() { winepath -w "$1" 2>/dev/null; }

if [ -f "$exe" ]; then
  t=$(now)
  (cd "$out" && wine "$exe" win_positions.bin win_cache.pc2) >"$out/linked_host_wine.txt" 2>&1
  rc=$?
  sed 's/^/wine: /' "$out/linked_host_wine.txt" | tr -d '\r'
  [ $rc -eq 0 ] || bad "linked_host.exe under wine exited $rc"
  echo "# linked_host.exe under wine: $(since "$t") s"
fi
if [ -x "$native" ]; then
  (cd "$out" && "$native" linux_positions.bin linux_cache.pc2) >"$out/linked_host_linux.txt" 2>&1
  rc=$?
  [ $rc -eq 0 ] || { sed 's/^/linux: /' "$out/linked_host_linux.txt"; bad "the native linked_host exited $rc"; }
fi
# Bit for bit, no tolerance. The DLL has no target_clones (PE has no ifunc:
# core/simd.h) and runs the baseline SSE2 loops, where the Linux library picks its
# AVX2 or AVX-512 clone; neither clone target enables FMA, so no multiply-add is
# contracted differently, and the only reassociated sums (energy.c, strain.c) feed
# the energy and strain reports, not the positions. x86-64 float arithmetic is IEEE
# in both. Measured equal (an AVX-512 machine); a difference is a finding to explain,
# not rounding to tolerate.
for f in positions.bin cache.pc2; do
  if [ -f "$out/win_$f" ] && [ -f "$out/linux_$f" ]; then
    cmp "$out/win_$f" "$out/linux_$f" || bad "the Windows and Linux $f differ"
  else
    bad "no $f from both builds to compare"
  fi
done

# --- 4. the conformance kit ------------------------------------------------------------
# The installed one, beside the DLL, as a user would run it.
kit=$prefix/bin/rbcloth-conformance.exe
if [ ! -f "$kit" ]; then
  bad "the install has no bin/rbcloth-conformance.exe"
else
  t=$(now)
  wine "$kit" "$(winpath "$dll")" >"$out/conformance.txt" 2>&1
  rc=$?
  tr -d '\r' <"$out/conformance.txt" | sed 's/^/conformance: /'
  [ $rc -eq 0 ] || bad "rbcloth-conformance.exe under wine exited $rc"
  echo "# conformance kit under wine: $(since "$t") s"
fi

[ $fail -eq 0 ] && echo "PASS"
exit $fail
