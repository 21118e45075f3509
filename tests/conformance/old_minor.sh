#!/usr/bin/env bash
# old_minor.sh SRC WORK KIT COMMIT MINOR: rbcloth-conformance against the library of an
# older ABI minor, built here from the repository's history: COMMIT's tree (git
# archive) configured and built (target rbcloth alone) in WORK, then the kit of this
# tree run against it; every check must pass. Exit 77 (skip) where SRC has no git
# history holding COMMIT (a source tarball, a shallow clone).
set -uo pipefail
src=$1 work=$2 kit=$3 commit=$4 minor=$5
if ! git -C "$src" cat-file -e "$commit^{commit}" 2>/dev/null; then
  echo "SKIP: $commit is not in $src's git history (a tarball or a shallow clone); fetch it with git fetch --unshallow"
  exit 77
fi
rm -rf "$work/src" "$work/build"
mkdir -p "$work/src"
git -C "$src" archive "$commit" | tar -x -C "$work/src" || { echo "FAIL: git archive $commit"; exit 1; }
if ! cmake -S "$work/src" -B "$work/build" -DCMAKE_BUILD_TYPE=RelWithDebInfo >"$work/configure.log" 2>&1 ||
   ! cmake --build "$work/build" -j2 --target rbcloth >"$work/build.log" 2>&1; then
  tail -n 30 "$work/configure.log" "$work/build.log"
  echo "FAIL: the library of $commit did not build"
  exit 1
fi
lib=$(find "$work/build" -name 'librbcloth.so*' -type f | head -n 1)
[ -n "$lib" ] || { echo "FAIL: no librbcloth.so in $work/build"; exit 1; }
"$kit" "$lib" >"$work/conformance.txt"
rc=$?
cat "$work/conformance.txt"
grep -qF "# library: ABI $minor," "$work/conformance.txt" || { echo "FAIL: $commit's library does not report ABI $minor"; exit 1; }
[ $rc -eq 0 ] || { echo "FAIL: rbcloth-conformance exited $rc on ABI $minor"; exit 1; }
echo PASS
