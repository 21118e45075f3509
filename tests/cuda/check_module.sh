#!/bin/sh
# check_module.sh MODULE -- the CUDA backend module as built (issue 22, item 4):
#   - it needs no CUDA library at load time (the runtime is linked statically; the
#     driver, libcuda.so.1, is loaded by the runtime only when a world asks): its
#     NEEDED entries are the C/C++ runtime's only;
#   - it exports one symbol, the backend's entry point;
#   - its fat binary holds SASS for sm_80 and sm_90 (the cubins' ELF headers: machine
#     190 = EM_CUDA, the architecture in bits 8-15 of e_flags, as nvcc 12-13 write it).
set -eu
mod=$1
needed=$(readelf -dW "$mod" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p' | sort | tr '\n' ' ')
echo "NEEDED: $needed"
for lib in $needed; do
  case $lib in
    ld-linux-x86-64.so.2|libc.so.6|libm.so.6|libgcc_s.so.1|libstdc++.so.6|libdl.so.2|librt.so.1|libpthread.so.0) ;;
    *) echo "FAIL: $mod needs $lib"; exit 1 ;;
  esac
done
exports=$(nm -D --defined-only "$mod" | awk '{print $3}' | sort | tr '\n' ' ')
echo "exports: $exports"
[ "$exports" = "rbc_cuda_backend_open " ] || { echo "FAIL: exports are not the entry point alone"; exit 1; }
archs=$(python3 - "$mod" <<'PY'
import struct, sys
d = open(sys.argv[1], 'rb').read()
found, i = set(), 0
while True:
    i = d.find(b'\x7fELF', i + 1)
    if i < 0:
        break
    if d[i + 4] == 2 and struct.unpack_from('<H', d, i + 18)[0] == 190:
        found.add((struct.unpack_from('<I', d, i + 48)[0] >> 8) & 0xff)
print(' '.join('sm_%d' % a for a in sorted(found)))
PY
)
echo "cubins: $archs"
case " $archs " in *" sm_80 "*) ;; *) echo "FAIL: no sm_80 SASS"; exit 1 ;; esac
case " $archs " in *" sm_90 "*) ;; *) echo "FAIL: no sm_90 SASS"; exit 1 ;; esac
echo "ok"
