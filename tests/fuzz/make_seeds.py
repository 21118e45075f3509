#!/usr/bin/env python3
"""Write the seed corpora of tests/fuzz (standard library only; rerun after editing):

  corpus/scene/   small scenes using every key of samples/scenes/README.md (grids of at
                  most 12 x 12, so the fuzz target builds and steps them), plus the
                  sample scenes whose meshes are small enough as they are
  corpus/cloth/   byte strings for fuzz_cloth.c: grids with and without colliders,
                  every solver, masses, shear/bend, contact, tearing, a cut
  corpus/import/  one extension byte (fuzz_import.c's table) + a small mesh: the OBJs of
                  samples/meshes and hand-written OBJ, PLY (ascii and binary), OFF, STL
                  (ascii and binary) and a minimal glTF; no third-party model is copied
                  (run_fuzz.sh adds small files of assimp-testmodels at run time)

  python3 tests/fuzz/make_seeds.py
"""
import json
import os
import shutil
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def write(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    mode = "wb" if isinstance(data, bytes) else "w"
    with open(path, mode) as f:
        f.write(data)


def scenes():
    out = os.path.join(HERE, "corpus", "scene")
    grid = {"nx": 8, "ny": 8, "spacing": 0.05, "origin": [0, 1, 0], "plane": "xz"}
    base = {"name": "s", "frames": 3, "dt": 1 / 60,
            "cloths": [{"name": "c", "grid": grid, "pins": [0, 7]}]}
    s = {}
    s["minimal"] = base
    s["world_keys"] = dict(base, world={
        "gravity": [0, -9.81, 0], "substeps": 2, "nonlinear_iterations": 2,
        "linear_iterations": 5, "threads": 2, "backend": "cpu",
        "solver": {"preset": "cloth", "kind": "rbgs_sor", "omega": 1.5, "energy_guard": "fail"}})
    for kind in ["rbgs", "jacobi", "jacobi_chebyshev", "gauss_seidel", "rbgs_sor",
                 "rbgs_chebyshev", "multicolor_gs", "direct"]:
        s["solver_" + kind] = dict(base, world={"substeps": 1, "solver": {"kind": kind}})
    s["mode_tolerance"] = dict(base, world={"solver": {"mode": "tolerance", "tolerance": 1e-4,
                                                       "max_linear_iterations": 50}})
    s["mode_budget"] = dict(base, world={"solver": {"mode": "budget", "budget_ms": 0.5}})
    s["mode_target"] = dict(base, world={"solver": {"preset": "game_60hz", "mode": "target",
                                                    "target_strain": 0.05, "max_substeps": 4}})
    s["rate"] = dict(base, world={"substeps": 0, "substep_rate": 240,
                                  "solver": {"chebyshev_delay": 3, "rho": 0.9}})
    s["wind"] = dict(base, world={"wind": {"velocity": [1, 0, 0.5], "drag": 0.6, "lift": 0.1}})
    cloth = {"name": "c", "grid": dict(grid, plane="xy"), "vertex_mass": 2e-4, "stiffness": 500,
             "damping": 0.5, "shear_stiffness": 100, "bend_stiffness": 10, "thickness": 0.004,
             "friction": 0.3, "self_collision": True, "cloth_collision": True,
             "tear_strain": 0.3, "pins": [56, 63],
             "drags": [{"vertex": 27, "keyframes": [{"time": 0.0, "target": [0.2, 1.1, 0.1]},
                                                    {"time": 0.03, "target": [0.2, 1.0, 0.5]}],
                        "release": 0.04}]}
    s["cloth_keys"] = dict(base, cloths=[cloth])
    s["inline_mesh"] = dict(base, cloths=[
        {"name": "q", "vertices": [[0, 1, 0], [0.1, 1, 0], [0.1, 1, 0.1], [0, 1, 0.1],
                                   [0.2, 1, 0], [0.2, 1, 0.1]],
         "quads": [[0, 1, 2, 3], [1, 4, 5, 2]], "pins": [0]}])
    s["two_cloths"] = dict(base, cloths=[
        {"name": "a", "grid": grid, "thickness": 0.003, "cloth_collision": True},
        {"name": "b", "grid": dict(grid, origin=[0, 1.01, 0]), "thickness": 0.003,
         "cloth_collision": True}])
    colliders = [
        {"shape": "sphere", "radius": 0.1, "position": [0.2, 0.8, 0.2], "thickness": 0.002,
         "friction": 0.2, "velocity": [0, 1, 0], "angular_velocity": [0, 1, 0]},
        {"shape": "plane", "position": [0, 0.5, 0], "rotation": [0, 0, 0.0998, 0.995]},
        {"shape": "capsule", "radius": 0.05, "half_length": 0.1, "position": [0.1, 0.9, 0.1]},
        {"shape": "box", "half_extents": [0.1, 0.02, 0.1], "position": [0.2, 0.9, 0.2],
         "keyframes": [{"time": 0, "position": [0.2, 0.9, 0.2]},
                       {"time": 0.05, "position": [0.2, 1.2, 0.2], "rotation": [0, 0.383, 0, 0.924]}]},
        {"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 0, 1], [0, 1, 0]],
         "triangles": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
         "position": [-0.1, 0.7, -0.1], "thickness": 0.001}]
    s["colliders"] = dict(base, colliders=colliders)
    s["description_and_flags"] = dict(base, description="a d\u00e9scription with \"quotes\"",
                                      frames=1, dt=0.002)
    for name, scene in s.items():
        write(os.path.join(out, name + ".json"), json.dumps(scene, indent=1) + "\n")
    # Sample files that are small or fail cleanly as they are (big grids are parsed,
    # not built: the target's cap), and the CLI tests' small scenes.
    for f in ["hanging_cloth.json", "hanging_cloth_60hz.json", "cannonballs_tearing.json",
              "cloth_on_chair.json"]:
        shutil.copy(os.path.join(ROOT, "samples", "scenes", f), os.path.join(out, "sample_" + f))
    for f in ["two_cloths.json", "bad_pin.json", "typo.json"]:
        shutil.copy(os.path.join(ROOT, "tests", "scene", "data", f), os.path.join(out, "data_" + f))


FLOATS = [0.0, 1.0, -1.0, 0.5, 2.0, 1e-3, 1e3, 1e-6, 1e6, 0.01, 100.0, -0.5, 1e-30, 1e30,
          0.1, 10.0]


class ClothSeed:
    """Bytes in the order fuzz_cloth.c reads them (keep the two in step)."""

    def __init__(self):
        self.b = bytearray()

    def u8(self, v):
        self.b.append(v & 255)

    def u16(self, v):
        self.b += struct.pack("<H", v & 0xFFFF)

    def f(self, v):
        """A float: table entries by index, anything else as raw bits."""
        if v in FLOATS:
            self.u8(FLOATS.index(v))
        else:
            self.u8(255)
            self.b += struct.pack("<f", v)


def cloth_seed(flags=4 | 8 | 128, preset=2, solver=4, mode=0, guard=1, substeps=2, linear=8,
               nonlinear=1, collider=None, cols=6, rows=5, jitter=None, vertices=None,
               quads=None, springs=(), pins=(0, 5), masses=None, material=None, size_index=None,
               steps=2, dt=None, cut=None):
    e = ClothSeed()
    e.u8(flags)
    e.u8(preset)
    e.u8(solver)
    e.u8(mode)
    e.u8(guard)
    if mode == 1:
        e.f(1e-3)
    if mode == 3:
        e.f(0.1)
    e.u8(substeps)
    e.u8(linear - 1)
    e.u8(nonlinear - 1)
    if flags & 2:
        shape, radius, thickness, pos, half, friction = collider
        e.u8(shape - 1)
        e.f(radius)
        e.f(thickness)
        for v in pos:
            e.f(v)
        for v in half:
            e.f(v)
        e.f(friction)
    if flags & 4:
        e.u8(cols - 1)
        e.u8(rows - 1)
        nv = cols * rows
        for i in range(nv):
            e.u8(128 + (jitter[i] if jitter else 0))
    else:
        nv = len(vertices)
        e.u8(nv)
        for v in vertices:
            for c in v:
                e.f(c)
    if flags & 8 and cols > 1:
        edits = quads or []
        e.u8(len(edits))
        for at, value in edits:
            e.u16(at)
            e.u16(value)
    else:
        e.u8(len(quads))
        for q in quads:
            for i in q:
                e.u16(i)
    e.u8(len(springs))
    for sp in springs:
        for i in sp:
            e.u16(i)
    e.u8(len(pins))
    for i in pins:
        e.u16(i)
    if flags & 16:
        for m in masses:
            e.f(m)
    material = material or {}
    which = 0
    order = ["density", "vertex_mass", "stiffness", "damping", "shear", "bend", "contact", "tear"]
    for k, name in enumerate(order):
        if name in material:
            which |= 1 << k
    e.u8(which)
    for name in order:
        if name in material:
            if name == "contact":
                thickness, friction, cflags = material[name]
                e.f(thickness)
                e.f(friction)
                e.u8(cflags)
            else:
                e.f(material[name])
    if flags & 32:
        e.u8(size_index)
    e.u8(steps - 1)
    if not flags & 128:
        e.f(dt)
    if flags & 64:
        for i in cut:
            e.u16(i)
    return bytes(e.b)


def cloths():
    out = os.path.join(HERE, "corpus", "cloth")
    seeds = {}
    for kind in range(8):
        seeds["grid_solver%d" % kind] = cloth_seed(solver=kind)
    for mode in range(4):
        seeds["grid_mode%d" % mode] = cloth_seed(solver=0, mode=mode, preset=1)
    seeds["guard_fail_paper"] = cloth_seed(preset=0, solver=1, guard=2, linear=1)
    seeds["two_threads"] = cloth_seed(flags=1 | 4 | 8 | 128, cols=12, rows=10, pins=(0, 11))
    for shape in range(1, 5):
        seeds["collider%d" % shape] = cloth_seed(
            flags=2 | 4 | 8 | 128, collider=(shape, 0.1, 0.01, (0.25, -0.1, 0.2), (0.5, 0.1, 0.5), 0.5),
            pins=())
    seeds["masses_shear_bend"] = cloth_seed(
        flags=4 | 8 | 16 | 128, cols=4, rows=4, masses=[1e-3] * 16,
        material={"stiffness": 100.0, "damping": 0.5, "shear": 10.0, "bend": 1.0})
    seeds["density"] = cloth_seed(material={"density": 0.1, "vertex_mass": 1e-3})
    seeds["contact_self_tear_cut"] = cloth_seed(
        flags=4 | 8 | 64 | 128, cols=8, rows=8, pins=(0, 7),
        material={"contact": (0.1, 0.5, 3), "tear": 0.1}, cut=(0, 1, 1, 2, 8, 9, 63, 64))
    seeds["quad_edits"] = cloth_seed(quads=[(0, 3), (5, 29)])
    seeds["raw_quads_springs"] = cloth_seed(
        flags=0, vertices=[(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1), (2, 0, 0), (2, 0, 1)],
        quads=[(0, 1, 2, 3), (1, 4, 5, 2)], springs=[(0, 2), (3, 5)], pins=(0,), dt=0.01)
    seeds["raw_nan"] = cloth_seed(flags=0, vertices=[(0, 0, 0), (1, 0, 0), (1, 0, 1),
                                                     (float("nan"), 0, 1)],
                                  quads=[(0, 1, 2, 3)], dt=0.01)
    seeds["v1_0_size"] = cloth_seed(flags=4 | 8 | 32 | 128, size_index=0)
    seeds["bad_size"] = cloth_seed(flags=4 | 8 | 32 | 128, size_index=3)
    seeds["bad_solver"] = bytes([0, 0, 250, 0xff, 0xff, 0xff, 0x7f])
    seeds["empty"] = b""
    for name, data in seeds.items():
        write(os.path.join(out, name + ".bin"), data)


EXT = ["obj", "ply", "off", "stl", "dae", "gltf", "glb", "fbx", "3ds", "x", "md2", "ms3d",
       "ase", "ac", "lwo", "blend", "smd", "nff", "raw", "dxf", "cob", "irrmesh", "ogex", "3mf",
       "amf", "md5mesh", "q3o", "xgl", "b3d", "lws", "mdl", "csm"]


def imports():
    out = os.path.join(HERE, "corpus", "import")

    def seed(name, ext, body, opts=0):
        if isinstance(body, str):
            body = body.encode()
        write(os.path.join(out, name), bytes([EXT.index(ext) | opts]) + body)

    for f in sorted(os.listdir(os.path.join(ROOT, "samples", "meshes"))):
        with open(os.path.join(ROOT, "samples", "meshes", f), "rb") as fh:
            seed("sample_" + f.replace(".", "_"), "obj", fh.read())
    quad = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 2 0 0\nv 2 0 1\nf 1 2 3 4\nf 2 5 6 3\n"
    seed("obj_quads", "obj", quad)
    seed("obj_quads_noweld_nopair_refuse", "obj", quad, 32 | 64 | 128)
    seed("obj_ngon_tris_groups", "obj",
         "o a\nv 0 0 0\nv 1 0 0\nv 1.5 0 1\nv 0.5 0 1.5\nv -0.5 0 1\nf 1 2 3 4 5\n"
         "g b\nv 3 0 0\nv 4 0 0\nv 3 0 1\nf 6 7 8\nf 7 8 6\nl 1 2\np 3\n")
    seed("ply_ascii_colors", "ply",
         "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
         "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
         "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0 255 0 0\n1 0 0 255 255 255\n1 1 0 0 0 0\n0 1 0 255 0 0\n4 0 1 2 3\n")
    verts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    body = b"".join(struct.pack("<3f", *v) for v in verts) + struct.pack("<B4i", 4, 0, 1, 2, 3)
    seed("ply_binary", "ply",
         b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
         b"property float y\nproperty float z\nelement face 1\n"
         b"property list uchar int vertex_indices\nend_header\n" + body)
    seed("off", "off", "OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n4 0 1 2 3\n3 1 4 2\n")
    seed("stl_ascii", "stl",
         "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\n"
         "endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\n"
         "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n")
    tris = [((0, 0, 0), (1, 0, 0), (1, 1, 0)), ((0, 0, 0), (1, 1, 0), (0, 1, 0))]
    stl = b"\0" * 80 + struct.pack("<I", len(tris))
    for t in tris:
        stl += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *v) for v in t) + b"\0\0"
    seed("stl_binary", "stl", stl)
    pos = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0)
    idx = struct.pack("<6H", 0, 1, 2, 0, 2, 3)
    import base64
    buf = pos + idx
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "name": "n"}],
            "meshes": [{"name": "m", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "buffers": [{"byteLength": len(buf),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                            {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]}
    seed("gltf_embedded", "gltf", json.dumps(gltf))
    seed("dae_garbage", "dae", "<?xml version=\"1.0\"?><COLLADA version=\"1.4.1\"></COLLADA>")
    seed("empty_obj", "obj", "")


if __name__ == "__main__":
    for d in ["scene", "cloth", "import"]:
        shutil.rmtree(os.path.join(HERE, "corpus", d), ignore_errors=True)
    scenes()
    cloths()
    imports()
