#!/usr/bin/env bash
# run_consumer.sh MODE BUILD SOURCE WORK MESH -- a consumer of rbcloth built and run:
#   install          cmake --install BUILD --prefix WORK/prefix, and the tree's files
#                    (header, versioned library and SONAME, symbol versions, helper,
#                    CMake package, pkg-config file, the conformance kit) checked, and
#                    the installed rbcloth-conformance passes on the installed library
#   find_package     tests/install/consumer configured against WORK/prefix
#   pkg-config       consumer.c compiled with `pkg-config --cflags --libs rbcloth`
#   subdirectory     tests/install/consumer with add_subdirectory(SOURCE): only the
#                    library and its helper are built (RBC_BUILD_EXTRAS is off there)
#   closure          the installed library's dependencies are glibc's own (issue 20:
#                    an engine loads no assimp, no CHOLMOD): its NEEDED entries and
#                    ldd's whole closure are within libc, libm, libpthread and the
#                    dynamic loader (NEEDED for __tls_get_addr, the TLS of a shared
#                    library); CHOLMOD and assimp are reached by name only (dlopen,
#                    the helper beside it)
# Each runs the consumer on MESH (an import through the helper of that tree).
set -euo pipefail
mode=$1 build=$2 src=$3 work=$4 mesh=$5
prefix=$work/prefix
here=$(cd "$(dirname "$0")" && pwd)
case $mode in
install)
  rm -rf "$prefix"
  cmake --install "$build" --prefix "$prefix" > "$work/install.log"
  lib=$(find "$prefix" -name 'librbcloth.so.1.*' -type f | head -1)
  libdir=$(dirname "$lib")
  for f in "$prefix/include/rbcloth.h" "$lib" "$libdir/librbcloth.so.1" "$libdir/librbcloth.so" \
           "$libdir/cmake/rbcloth/rbclothConfig.cmake" \
           "$libdir/cmake/rbcloth/rbclothConfigVersion.cmake" \
           "$libdir/cmake/rbcloth/rbclothTargets.cmake" "$libdir/pkgconfig/rbcloth.pc" \
           "$libdir/../libexec/rbcloth/rbcloth-import" "$prefix/bin/rbcloth" \
           "$prefix/bin/rbcloth-conformance"; do
    [ -e "$f" ] || { echo "FAIL: not installed: $f" >&2; exit 1; }
  done
  soname=$(readelf -d "$lib" | sed -n 's/.*Library soname: \[\(.*\)\]/\1/p')
  [ "$soname" = librbcloth.so.1 ] || { echo "FAIL: SONAME is '$soname'" >&2; exit 1; }
  nver=$(nm -D --defined-only "$lib" | grep -c ' rbc_.*@@RBCLOTH_1$' || true)
  [ "$nver" -ge 50 ] || { echo "FAIL: $nver symbols carry RBCLOTH_1" >&2; exit 1; }
  # the installed CLI finds the installed plugin and runs
  "$prefix/bin/rbcloth" info > "$work/info.txt"
  grep -q "$libdir/librbcloth.so" "$work/info.txt" || { echo "FAIL: rbcloth info:" >&2; cat "$work/info.txt" >&2; exit 1; }
  # the installed conformance kit passes on the installed library
  "$prefix/bin/rbcloth-conformance" "$lib" > "$work/conformance.txt" ||
    { grep -A2 '^not ok' "$work/conformance.txt" >&2; echo "FAIL: rbcloth-conformance on $lib" >&2; exit 1; }
  echo "install: $(find "$prefix" -type f | wc -l) files; SONAME $soname; $nver symbols @@RBCLOTH_1;" \
       "$(tail -n 1 "$work/conformance.txt" | sed 's/^# //') (rbcloth-conformance)"
  ;;
find_package)
  rm -rf "$work/fp"
  cmake -S "$here/consumer" -B "$work/fp" -DCMAKE_PREFIX_PATH="$prefix" > "$work/fp.log"
  cmake --build "$work/fp" >> "$work/fp.log"
  "$work/fp/consumer" "$mesh"
  ;;
pkg-config)
  export PKG_CONFIG_PATH=$(dirname "$(find "$prefix" -name rbcloth.pc | head -1)")
  [ "$(pkg-config --modversion rbcloth)" = "$(sed -n 's/^Version: //p' "$PKG_CONFIG_PATH/rbcloth.pc")" ]
  libdir=$(pkg-config --variable=libdir rbcloth)
  cc -o "$work/pc_consumer" "$here/consumer/consumer.c" $(pkg-config --cflags --libs rbcloth) -lm \
     -Wl,-rpath,"$libdir"
  "$work/pc_consumer" "$mesh"
  ;;
subdirectory)
  rm -rf "$work/sub"
  cmake -S "$here/consumer" -B "$work/sub" -DMODE=subdirectory -DRBCLOTH_SOURCE="$src" > "$work/sub.log"
  cmake --build "$work/sub" -j "$(nproc)" >> "$work/sub.log"
  # only the library and its helper: no CLI, no tests were configured
  [ ! -e "$work/sub/rbcloth/tests" ] || { echo "FAIL: add_subdirectory built the tests" >&2; exit 1; }
  "$work/sub/consumer" "$mesh"
  ;;
closure)
  lib=$(find "$prefix" -name 'librbcloth.so.1.*' -type f | head -1)
  allowed='^(libc\.so\.6|libm\.so\.6|libpthread\.so\.0|ld-linux-x86-64\.so\.2|linux-vdso\.so\.1)$'
  needed=$(readelf -d "$lib" | sed -n 's/.*Shared library: \[\(.*\)\]/\1/p')
  [ -n "$needed" ] || { echo "FAIL: no NEEDED entries read from $lib" >&2; exit 1; }
  # ldd lists the loader by path: keep the file name
  closure=$(ldd "$lib" | awk '{print $1}' | sed 's,.*/,,')
  bad=$(printf '%s\n%s\n' "$needed" "$closure" | grep -Ev "$allowed" || true)
  [ -z "$bad" ] || { echo "FAIL: $lib depends on: $bad" >&2; ldd "$lib" >&2; exit 1; }
  # CHOLMOD is loaded by its SONAME, never linked
  grep -qaF 'libcholmod.so.3' "$lib" || { echo "FAIL: no libcholmod.so.3 in $lib" >&2; exit 1; }
  echo "closure of $(basename "$lib"): NEEDED $(echo $needed); ldd $(echo $closure | wc -w) objects: $(echo $closure)"
  ;;
*) echo "usage: $0 install|find_package|pkg-config|subdirectory|closure BUILD SOURCE WORK MESH" >&2; exit 2 ;;
esac
