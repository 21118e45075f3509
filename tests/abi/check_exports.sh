#!/usr/bin/env bash
# check_exports.sh SO HEADER -- the plugin exports only rbc_ symbols, and every
# function declared in the public header is among them.
#
# `nm -D --defined-only` lists the dynamic symbols the .so defines. Everything
# must start with rbc_, except these exact names, which GNU ld (not our code)
# may define in every shared object and which carry no code of ours:
#   _init, _fini          the ELF DT_INIT/DT_FINI entry points (crti.o/crtn.o)
#   __bss_start, _edata,  section boundary markers ld defines when they are
#   _end                  not hidden (older binutils export them from .so files)
#   RBCLOTH_1             the version node's own definition (plugin/exports.map)
# Nothing else is tolerated: a leaked internal (core_*, cJSON_*, a static
# library's symbols) fails the test. Every rbc_ symbol must carry the version node
# of ABI major 1, rbc_x@@RBCLOTH_1: a host linked against it binds to that major.
set -euo pipefail
so=${1:?usage: check_exports.sh path/to/librbcloth.so path/to/rbcloth.h}
header=${2:?usage: check_exports.sh path/to/librbcloth.so path/to/rbcloth.h}

command -v nm >/dev/null || { echo "FAIL: nm not found (install binutils)" >&2; exit 1; }
[ -f "$so" ] || { echo "FAIL: $so does not exist" >&2; exit 1; }
[ -f "$header" ] || { echo "FAIL: $header does not exist" >&2; exit 1; }

# Symbol names (last field), version suffixes (@VER, @@VER) stripped.
syms=$(nm -D --defined-only "$so" | awk 'NF >= 2 { print $NF }' | sed 's/@.*//' | sort -u)
[ -n "$syms" ] || { echo "FAIL: nm lists no defined dynamic symbols in $so" >&2; exit 1; }

fail=0
allowed='^(_init|_fini|__bss_start|_edata|_end|RBCLOTH_1)$'
while IFS= read -r s; do
  [[ "$s" == rbc_* ]] && continue
  if [[ "$s" =~ $allowed ]]; then continue; fi
  echo "FAIL: exported symbol without rbc_ prefix: $s" >&2
  fail=1
done <<< "$syms"

unversioned=$(nm -D --defined-only "$so" | awk 'NF >= 2 { print $NF }' | grep '^rbc_' |
              grep -v '@@RBCLOTH_1$' || true)
if [ -n "$unversioned" ]; then
  echo "FAIL: rbc_ symbols without the version node RBCLOTH_1: $(echo $unversioned)" >&2
  fail=1
fi

# Every function of the header: "RBC_API <type> RBC_CALL name(".
want=$(tr '\n' ' ' < "$header" | grep -o 'RBC_API[^;(]*RBC_CALL[[:space:]]*rbc_[A-Za-z0-9_]*[[:space:]]*(' |
       sed -E 's/.*RBC_CALL[[:space:]]*(rbc_[A-Za-z0-9_]*).*/\1/' | sort -u)
nwant=$(printf '%s\n' "$want" | grep -c . || true)
[ "$nwant" -ge 30 ] || { echo "FAIL: found only $nwant functions in $header (parser broken?)" >&2; fail=1; }
while IFS= read -r f; do
  [ -z "$f" ] && continue
  grep -qx "$f" <<< "$syms" || { echo "FAIL: $f is declared in the header but not exported" >&2; fail=1; }
done <<< "$want"

if [ "$fail" -ne 0 ]; then
  echo "--- nm -D --defined-only $so:" >&2
  nm -D --defined-only "$so" >&2
  exit 1
fi
echo "abi_exports: $(grep -c . <<< "$syms") exported symbols, all rbc_ (or ld's markers); all $nwant header functions present"
