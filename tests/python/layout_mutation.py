"""layout_mutation.py GEN_ABI MODULE LISTING: the layout check can fail.

The build already ran gen_abi.py --check on the generated module (a difference
fails the build). This is its negative control: copies of the module with one
field's type widened (rbc_cloth_def.stiffness float -> double, which moves every
later field) and with one field dropped (rbc_cache_def's last) must each be refused
by --check, and the module itself accepted."""
import subprocess
import sys
import tempfile

gen, module, listing = sys.argv[1:4]
src = open(module).read()


def check(text):
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(text)
    return subprocess.run([sys.executable, gen, "--check", f.name, listing],
                          capture_output=True, text=True)


assert check(src).returncode == 0, "the generated module itself fails the check"
start = src.index("rbc_cloth_def._fields_")
widened = src[:start] + src[start:].replace("('stiffness', ctypes.c_float)",
                                            "('stiffness', ctypes.c_double)", 1)
assert widened != src
r = check(widened)
assert r.returncode == 1 and "rbc_cloth_def.damping" in r.stderr, r.stderr
start = src.index("rbc_cache_def._fields_")
end = src.index("]", start)
body = src[start:end].rstrip().split("\n")
dropped = src[:start] + "\n".join(body[:-1]) + "\n" + src[end:]
r = check(dropped)
assert r.returncode == 1 and "rbc_cache_def" in r.stderr, r.stderr
print("layout check refuses a widened and a dropped field")
