#!/bin/sh
# binding.sh CC OUT_DIR -- the mono_binding test (CMakeLists.txt here): prints the C
# layouts of the bound structs with CC (binding_layout.c), compiles the Unity
# package's binding (hosts/unity/Runtime/Native/*.cs) with its test program
# (hosts/unity/Tests/Mono/BindingTest.cs) using mcs -unsafe, and runs it under mono.
# The library comes from LD_LIBRARY_PATH. Exit status is the program's. The C file
# lives here, not in the package, because Unity would build a .c file in a package
# into IL2CPP players.
set -e
cc=$1 out=$2
here=$(cd "$(dirname "$0")" && pwd)
root=$here/../..
unity=$root/hosts/unity
"$cc" -std=c11 -I"$root/abi" "$here/binding_layout.c" -o "$out/rbc_layout"
"$out/rbc_layout" > "$out/rbc_layout.txt"
mcs -unsafe -out:"$out/BindingTest.exe" "$unity"/Runtime/Native/*.cs "$unity/Tests/Mono/BindingTest.cs"
exec mono "$out/BindingTest.exe" "$out/rbc_layout.txt"
