#!/usr/bin/python3
# roundtrip_report.py BUILD_DIR OUT.md -- docs/results/roundtrip.md: the DCC round
# trip of tests/blender measured and written up. Runs what the ctest tests
# blender_roundtrip_* run (Blender's export of the curtain, `rbcloth batch`, each
# format's check in Blender), with the time of each step, and a control: the same
# check on the simulation-order cache, which is what a cache of the user's own file
# held before ABI 1.9 (the "scrambled" curtain). Needs Debian's blender.
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

build, out_md = os.path.abspath(sys.argv[1]), sys.argv[2]
here = os.path.dirname(os.path.abspath(__file__))
root = os.path.dirname(os.path.dirname(here))
blender = shutil.which("blender")
if not blender:
    sys.exit("roundtrip_report: blender is not installed (.ci/deps.sh installs it)")
work = tempfile.mkdtemp(prefix="rbc_roundtrip_")
formats = [("obj", "curtain.obj"), ("fbx", "curtain.fbx"), ("dae", "curtain.dae"),
           ("gltf", "curtain.glb")]


def run(cmd):
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return p.returncode, p.stdout, time.monotonic() - t0


def blender_py(script, *args):
    return run([blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
                script, "--"] + list(args))


rc, text, t_export = blender_py(os.path.join(here, "roundtrip_export.py"), work)
if rc:
    sys.exit("export failed:\n" + text)
rc, text, t_batch = run([os.path.join(build, "bin", "rbcloth"), "batch",
                         os.path.join(work, "manifest.json"), "--out",
                         os.path.join(work, "batch"), "-q"])
if rc:
    sys.exit("batch failed:\n" + text)

# The control: the check pointed at the simulation-order cache.
control = os.path.join(work, "control_check.py")
with open(os.path.join(here, "roundtrip_check.py")) as f:
    src = f.read()
src = src.replace('file_pc2 = "%s/%s/%s.pc2" % (batch_dir, fmt, fmt)',
                  'file_pc2 = "%s/%s_sim/%s_sim.pc2" % (batch_dir, fmt, fmt)')
with open(control, "w") as f:
    f.write(src)

rows, controls = [], []
for fmt, name in formats:
    path = os.path.join(work, name)
    rc, text, secs = blender_py(os.path.join(here, "roundtrip_check.py"),
                                os.path.join(work, "batch"), fmt, path)
    counts = re.search(r"importer made (\d+) vertices; the file-order cache has (\d+), the "
                       r"simulation (\d+)", text)
    rest = re.search(r"rest: every Blender vertex within (\S+) m", text)
    errs = {}
    for mode, frame, err in re.findall(r"(PC2|MDD) frame (\d+): largest \|Blender - "
                                       r"simulation\| = (\S+) m", text):
        errs.setdefault(mode, []).append(float(err))
    off = re.findall(r"(PC2|MDD) frame 1: (\d+) of (\d+) edges", text)
    bound = re.search(r"bound (\S+);", text)
    rows.append((fmt, rc, counts.groups() if counts else ("?", "?", "?"),
                 rest.group(1) if rest else "?", errs, off, bound.group(1) if bound else "?",
                 secs))
    rc2, text2, _ = blender_py(control, os.path.join(work, "batch"), fmt, path)
    c_counts = re.search(r"importer made (\d+) vertices; the file-order cache has (\d+)", text2)
    c_err = re.search(r"PC2 frame 1: largest \|Blender - simulation\| = (\S+) m", text2)
    c_off = re.search(r"PC2 frame 1: (\d+) of (\d+) edges", text2)
    if c_err:
        what = "largest error %s m at frame 1, %s of %s edges more than 10 %% off" % (
            c_err.group(1), c_off.group(1), c_off.group(2))
    elif c_counts:
        what = "refused: the cache has %s points, Blender's mesh %s vertices" % (
            c_counts.group(2), c_counts.group(1))
    else:
        what = "(no figure)"
    controls.append((fmt, rc2, what))

commit = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"],
                        stdout=subprocess.PIPE, text=True).stdout.strip()
rc, bver, _ = run([blender, "--version"])
bver = bver.splitlines()[0] if bver else "?"
cpu = "?"
try:
    with open("/proc/cpuinfo") as f:
        cpu = next(l.split(":", 1)[1].strip() for l in f if l.startswith("model name"))
except (OSError, StopIteration):
    pass
lines = [
    "# The round trip to the user's own mesh, in Blender",
    "",
    "%s, commit %s, %s (%d cores), %s. Regenerate: `tests/blender/roundtrip_report.py "
    "build docs/results/roundtrip.md`." % (time.strftime("%Y-%m-%d"), commit, cpu,
                                           os.cpu_count(), bver),
    "",
    "Blender exports a 22 x 22 curtain (484 vertices, a UV seam down the middle, level "
    "at 2 m, pinned along one edge) as OBJ, FBX, Collada and glTF "
    "(`roundtrip_export.py`); `rbcloth batch` simulates each file for 24 frames at 60 "
    "Hz; Blender imports each file with its own importer and plays the cache with the "
    "Mesh Cache modifier (`roundtrip_check.py`). Error: the largest coordinate "
    "difference between Blender's evaluated mesh and the simulation, over all vertices, "
    "at frames 1, 12 and 24; the bound is 4 float roundings of the largest coordinate.",
    "",
    "| format | Blender's vertices | cache points | simulated vertices | rest match | PC2 "
    "error (frames 1, 12, 24) | MDD error, Time mode | edges > 10 % off at frame 1 | "
    "bound | check |",
    "|---|---:|---:|---:|---:|---|---|---|---:|---:|",
]
for fmt, rc, (nb, nc, ns), rest, errs, off, bound, secs in rows:
    fmt_errs = lambda m: ", ".join("%.3g" % e for e in errs.get(m, [])) or "?"
    lines.append("| %s | %s | %s | %s | %s m | %s m | %s m | %s | %s m | %s, %.1f s |" % (
        fmt, nb, nc, ns, rest, fmt_errs("PC2"), fmt_errs("MDD"),
        ", ".join("%s of %s" % (a, b) for _, a, b in off) or "?", bound,
        "passed" if rc == 0 else "FAILED", secs))
lines += [
    "",
    "Times: Blender's export %.1f s, the batch of 8 jobs %.1f s; each check above is one "
    "Blender start, import and 6 evaluated frames." % (t_export, t_batch),
    "",
    "## The control: the simulation's order on Blender's mesh",
    "",
    "The same check on the simulation-order cache (`\"cache_order\": \"simulation\"`, "
    "what every cache of an imported file held before ABI 1.9):",
    "",
    "| format | on Blender's import of the file |",
    "|---|---|",
]
for fmt, rc2, what in controls:
    lines.append("| %s | %s |" % (fmt, what))
lines.append("")
with open(out_md, "w") as f:
    f.write("\n".join(lines))
shutil.rmtree(work)
print("roundtrip_report: wrote %s" % out_md)
