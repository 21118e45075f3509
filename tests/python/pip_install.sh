#!/usr/bin/env bash
# pip_install.sh SOURCE_DIR WORK_DIR LIBRARY: pip-install the binding from a copy of
# the source tree (hosts/python and abi/, the layout setup.py expects) into a fresh
# venv under WORK_DIR (system site packages for Debian's numpy; no index: offline),
# then import it from outside any source folder and step a world.
set -euo pipefail
src=$1 work=$2 lib=$3
rm -rf "$work"
mkdir -p "$work/tree/hosts" "$work/tree/abi"
cp -r "$src/hosts/python" "$work/tree/hosts/python"
rm -rf "$work/tree/hosts/python/build" "$work/tree/hosts/python/"*.egg-info
cp "$src/abi/rbcloth.h" "$work/tree/abi/"
/usr/bin/python3 -m venv --system-site-packages "$work/venv"
"$work/venv/bin/python" -m pip install --quiet --no-index --no-build-isolation \
  "$work/tree/hosts/python"
cd "$work"
RBCLOTH_LIBRARY=$lib "$work/venv/bin/python" - "$work/venv" <<'PY'
import sys, numpy as np, rbcloth
venv = sys.argv[1]
assert rbcloth.__file__.startswith(venv), rbcloth.__file__  # the installed copy
assert rbcloth.abi_version()[0] == 1
with rbcloth.World() as w:
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], np.float32)
    c = w.cloth(p, [[0, 1, 2, 3]], pins=[0])
    w.step(1 / 60)
    assert c.positions()[2, 1] < 0
print("installed", rbcloth.__file__, "ABI", rbcloth.abi_version())
PY
