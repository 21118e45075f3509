#!/usr/bin/env bash
# Install the Debian packages rbcloth needs to build and test, if any is missing.
# Runs as root (CI and a fresh machine); with sudo otherwise.
set -euo pipefail
# What `make demo` needs to build (`deps.sh build`), and what `make test` adds (no
# argument: everything).
# zlib1g-dev: assimp's CMake config links /usr/lib/x86_64-linux-gnu/libz.so, which
# libassimp-dev does not pull in (a fresh bookworm root fails to link without it).
# libpng-dev: the viewer's PNG stills (hosts/cli/viewer.c).
# libxml2-dev: the import helper reads a Collada file's own vertex order itself
# (plugin/importer/file_vertices_dae.c), which assimp does not keep; zlib1g-dev also
# serves its binary FBX reader's compressed arrays.
# libglfw3-dev, libgl-dev, libgl1-mesa-dri: the real-time viewer (hosts/viewer),
# part of the normal build: GLFW for its window and input, the OpenGL headers and
# libGL (glvnd) it links, and Mesa's drivers (llvmpipe) that draw where no GPU is.
# python3: the build generates the Python binding's ctypes module from abi/rbcloth.h
# (hosts/python/gen_abi.py, standard library only) and zips the Blender add-on.
build_pkgs=(cmake make gcc libc6-dev pkg-config libcjson-dev libsuitesparse-dev binutils
            libassimp-dev zlib1g-dev libpng-dev libxml2-dev python3
            libglfw3-dev libgl-dev libgl1-mesa-dri)
# slurm-wlm, munge: tests/slurm starts a one-node Slurm on localhost to run
# samples/slurm/ (about 12 s to install on bookworm; the test skips without them).
# chromium: tests/viewer loads the player page in headless Chromium (software WebGL)
# to check that it draws and plays. blender: tests/blender brings a run's cache into
# Blender with the README's settings.
# python3-numpy, python3-pytest: the Python binding (hosts/python) and its tests
# (tests/python) run with Debian's /usr/bin/python3, never a python3 on PATH.
# python3-venv, python3-pip, python3-setuptools, python3-wheel: python_pip_install
# pip-installs the binding into a venv offline (--no-build-isolation: setuptools'
# build backend needs wheel for bdist_wheel, and no index is reached for either).
# clang-14, libclang-rt-14-dev, llvm-14: `make check-sanitizers` (which .ci/run
# calls after `make test`; tests/README.md): ThreadSanitizer and libFuzzer need clang (libclang-rt-14-dev has libFuzzer and
# the sanitizer runtimes), llvm-14 the llvm-symbolizer that puts names on their stacks.
# gcc's own ASan/UBSan runtimes (libasan8, libubsan1) come with gcc.
# xvfb, xauth: tests/glviewer runs the viewer under xvfb-run (an X server in memory,
# drawn by Mesa's llvmpipe); xvfb-run needs xauth for its cookie.
# mono-mcs, mono-runtime: tests/mono runs a C# host (Mono 6.8) against the library.
# gcc-mingw-w64-x86-64 (with binutils-mingw-w64-x86-64 and the -posix compiler),
# wine64, wine: tests/windows cross-builds rbcloth.dll and runs hosts under wine 8.
test_pkgs=(abigail-tools assimp-testmodels valgrind slurm-wlm munge chromium blender
           mono-mcs mono-runtime gcc-mingw-w64-x86-64 wine64 wine
           clang-14 libclang-rt-14-dev llvm-14 python3-numpy python3-pytest python3-venv
           python3-pip python3-setuptools python3-wheel xvfb xauth)
if [ "${1:-}" = build ]; then
  pkgs=("${build_pkgs[@]}")
else
  pkgs=("${build_pkgs[@]}" "${test_pkgs[@]}")
fi
missing=()
for p in "${pkgs[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [ "$status" = "install ok installed" ] || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "rbcloth: installing ${missing[*]}" >&2
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
