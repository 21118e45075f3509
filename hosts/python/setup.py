"""pip install hosts/python: the rbcloth binding without a CMake build.

The ctypes layer (rbcloth/_abi.py) is generated here as the CMake build generates
it: gen_abi.py reads abi/rbcloth.h (../../abi from this folder, or $RBCLOTH_HEADER),
writes the module and a C program printing every struct's sizeof/offsetof, which is
compiled with the system C compiler ($CC, else cc) and run; any difference from
ctypes fails the install. The library itself is not packaged: point RBCLOTH_LIBRARY
at librbcloth.so (see rbcloth/__init__.py's docstring for the search order).
Offline: pip install --no-build-isolation (setuptools and wheel from Debian).
"""
import os
import shlex
import subprocess
import sys
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import gen_abi  # noqa: E402 (beside this file)


class build_py_with_abi(build_py):
    def run(self):
        super().run()
        header = os.environ.get("RBCLOTH_HEADER") or os.path.join(HERE, "..", "..", "abi",
                                                                   "rbcloth.h")
        if not os.path.exists(header):
            raise SystemExit("rbcloth: %s not found: build from the rbcloth source tree or "
                             "set RBCLOTH_HEADER" % header)
        out = os.path.join(self.build_lib, "rbcloth", "_abi.py")
        with tempfile.TemporaryDirectory() as tmp:
            checker = os.path.join(tmp, "layout_check.c")
            gen_abi.write_module(header, out, checker)
            exe = os.path.join(tmp, "layout_check")
            cc = shlex.split(os.environ.get("CC", "cc"))
            subprocess.check_call(cc + ["-std=c11", "-I", os.path.dirname(header), checker,
                                        "-o", exe])
            listing = os.path.join(tmp, "layout.txt")
            with open(listing, "w") as f:
                subprocess.check_call([exe], stdout=f)
            if gen_abi.check(out, listing) != 0:
                raise SystemExit("rbcloth: the ctypes layouts differ from the C compiler's")


setup(name="rbcloth", version="0.1.0",
      description="Python binding of librbcloth (ctypes over its C ABI)",
      packages=["rbcloth"], install_requires=[], python_requires=">=3.9",
      cmdclass={"build_py": build_py_with_abi})
