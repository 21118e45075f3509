#!/bin/sh
# run.sh CC ABI_DIR OUT_DIR -- the mono_binding test (tests/mono/CMakeLists.txt):
# prints the C layouts of the bound structs with CC (layout.c), compiles the binding
# (../../Runtime/Native/*.cs) with its test program using mcs -unsafe, and runs it
# under mono. The library comes from LD_LIBRARY_PATH. Exit status is the program's.
set -e
cc=$1 abi=$2 out=$3
here=$(cd "$(dirname "$0")" && pwd)
"$cc" -std=c11 -I"$abi" "$here/layout.c" -o "$out/rbc_layout"
"$out/rbc_layout" > "$out/rbc_layout.txt"
mcs -unsafe -out:"$out/BindingTest.exe" "$here"/../../Runtime/Native/*.cs "$here/BindingTest.cs"
exec mono "$out/BindingTest.exe" "$out/rbc_layout.txt"
