#!/usr/bin/python3
# compare_import.py -- rbc_mesh_import's time in two builds, alternating A and B per
# file and round (this machine is shared: only paired medians mean anything), as a
# CSV and a Markdown section: per file the median of A, of B and of the per-round
# ratio B/A.
#
#   bench/tools/compare_import.py A_BUILD B_BUILD ROUNDS OUT.csv OUT.md FILE...
#
# Each build's bin/import_cost runs one import in the helper (and assimp alone in
# process, not used here) per call. Large test meshes: a 1000 x 1000 quad grid is
# written by `--grid DIR` (OBJ), and Blender exports it as FBX and Collada (blender
# -b --python-expr; see the page for the command).
import csv
import os
import statistics
import subprocess
import sys
import time

if len(sys.argv) >= 3 and sys.argv[1] == "--grid":
    n, out = 1000, os.path.join(sys.argv[2], "grid1m.obj")
    with open(out, "w") as f:
        for j in range(n):
            for i in range(n):
                f.write("v %.6f 0 %.6f\n" % (i / (n - 1), j / (n - 1)))
        for j in range(n - 1):
            for i in range(n - 1):
                a = 1 + i + n * j
                f.write("f %d %d %d %d\n" % (a, a + 1, a + 1 + n, a + n))
    print(out)
    sys.exit(0)
if len(sys.argv) < 7:
    sys.exit("usage: compare_import.py A_BUILD B_BUILD ROUNDS OUT.csv OUT.md FILE... "
             "| --grid DIR")
a_build, b_build, rounds, out_csv, out_md = sys.argv[1:6]
files = sys.argv[6:]
rows = []
for r in range(int(rounds)):
    for f in files:
        for name, build in (("A", a_build), ("B", b_build)):
            p = subprocess.run([os.path.join(build, "bin", "import_cost"), "--runs", "1", f],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
            lines = [l for l in p.stdout.splitlines() if l and not l.startswith("file,")]
            if p.returncode or not lines:
                sys.exit("import_cost failed on %s (%s)" % (f, name))
            rows.append({"build": name, "file": f, "round": r,
                         "ms": float(lines[0].split(",")[2])})
with open(out_csv, "w", newline="") as fh:
    w = csv.DictWriter(fh, fieldnames=["build", "file", "round", "ms"])
    w.writeheader()
    w.writerows(rows)
lines = ["| file | A, ms | B, ms | B / A (median of rounds) |", "|---|---:|---:|---:|"]
for f in files:
    pa = {x["round"]: x["ms"] for x in rows if x["file"] == f and x["build"] == "A"}
    pb = {x["round"]: x["ms"] for x in rows if x["file"] == f and x["build"] == "B"}
    lines.append("| %s | %.1f | %.1f | %.3f |" % (
        os.path.basename(f), statistics.median(pa.values()), statistics.median(pb.values()),
        statistics.median(pb[k] / pa[k] for k in pa)))
with open(out_md, "w") as fh:
    fh.write("\n".join(lines) + "\n")
print("\n".join(lines))
