"""The Python binding (hosts/python) against the C library and the CLI.

Run by ctest (tests/python/CMakeLists.txt) with Debian's /usr/bin/python3 -m pytest,
PYTHONPATH = build/python (the assembled package) and RBCLOTH_CLI = build/bin/rbcloth.
Scenes driven from Python are compared with `rbcloth run` of the same scene JSON
bit for bit: both call the same library with the same floats in the same order, so
any difference is a binding bug (a def field set wrongly, a float rounded twice).
"""
import ctypes
import json
import os
import struct
import subprocess

import numpy as np
import pytest

import rbcloth

CLI = os.environ.get("RBCLOTH_CLI")
DT = 1.0 / 60.0


def grid(nx, ny, spacing, origin=(0.0, 0.0, 0.0)):
    """An nx x ny grid in the xz plane, as samples/scenes/README.md numbers it."""
    p = np.array([[origin[0] + i * spacing, origin[1], origin[2] + j * spacing]
                  for j in range(ny) for i in range(nx)], np.float32)
    q = np.array([[i + nx * j, i + 1 + nx * j, i + 1 + nx * (j + 1), i + nx * (j + 1)]
                  for j in range(ny - 1) for i in range(nx - 1)], np.uint32)
    return p, q


def read_pc2(path):
    data = open(path, "rb").read()
    assert data[:12] == b"POINTCACHE2\0"
    points, start, rate, samples = struct.unpack("<iffi", data[16:32])
    frames = np.frombuffer(data[32:], "<f4").reshape(samples, points, 3)
    return start, rate, frames


def run_cli(scene, tmp_path):
    """`rbcloth run` of `scene` (a dict); its PC2's frames."""
    if not CLI:
        pytest.fail("RBCLOTH_CLI is not set (ctest sets it to build/bin/rbcloth)")
    path = tmp_path / (scene["name"] + ".json")
    path.write_text(json.dumps(scene))
    out = tmp_path / "cli"
    r = subprocess.run([CLI, "run", str(path), "--out", str(out), "--no-view"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return read_pc2(out / (scene["name"] + ".pc2"))


def floats(a):
    """Exact JSON numbers for float32 values (repr of the double round-trips)."""
    return [[float(x) for x in row] for row in a]


def test_pinned_cloth_on_sphere_matches_cli(tmp_path):
    p, q = grid(20, 20, 0.05)
    frames = 45
    scene = {"name": "drop", "frames": frames, "dt": DT,
             "world": {"solver": {"preset": "cloth"}},
             "cloths": [{"vertices": floats(p), "quads": q.tolist(), "pins": [0, 19],
                         "stiffness": 800, "vertex_mass": 2e-4}],
             "colliders": [{"shape": "sphere", "radius": 0.2, "position": [0.5, -0.35, 0.5]}]}
    start, rate, cli = run_cli(scene, tmp_path)
    assert (start, rate, cli.shape) == (1.0, 1.0, (frames, 400, 3))
    pc2 = tmp_path / "py.pc2"
    with rbcloth.World(preset="cloth") as w:
        c = w.cloth(p, q, pins=[0, 19], stiffness=800, vertex_mass=2e-4)
        w.sphere(0.2, position=(0.5, -0.35, 0.5))
        with rbcloth.Cache(str(pc2), c.vertex_count, start_frame=1, sample_rate=1) as cache:
            for _ in range(frames):
                w.step(DT)
                cache.write(c.positions())
        assert w.stats()["collider_contacts"] > 0  # the cloth lies on the sphere
    assert pc2.read_bytes()[32:] == (tmp_path / "cli" / "drop.pc2").read_bytes()[32:]
    assert pc2.read_bytes() == (tmp_path / "cli" / "drop.pc2").read_bytes()
    # The pins held, the rest fell: not a cloth that never moved.
    _, _, py = read_pc2(pc2)
    assert np.array_equal(py[-1, [0, 19]], p[[0, 19]])
    assert py[-1, 210, 1] < -0.1


def test_every_collider_shape_moving_matches_cli(tmp_path):
    """Plane, box, capsule and a triangle mesh, the mesh moved every frame with
    set_transform to the keyframe the scene format gives for that frame's end
    (rbc_scene_apply_frame: t = (frame + 1) dt, which it copies exactly)."""
    p, q = grid(16, 16, 0.06, origin=(-0.45, 0.0, -0.45))
    frames = 30
    tri_v = np.array([[-0.3, 0, -0.3], [0.3, 0, -0.3], [0.3, 0, 0.3], [-0.3, 0, 0.3]], np.float32)
    tri_t = np.array([[0, 2, 1], [0, 3, 2]], np.uint32)
    dt32 = float(np.float32(DT))
    path = [np.array([0.0, -0.3 + 0.02 * k, 0.0], np.float32) for k in range(frames + 1)]
    scene = {"name": "shapes", "frames": frames, "dt": DT,
             "world": {"substeps": 4},
             "cloths": [{"vertices": floats(p), "quads": q.tolist(), "pins": [0, 15, 240, 255],
                         "thickness": 0.01, "friction": 0.2}],
             "colliders": [
                 {"shape": "plane", "position": [0, -1.0, 0]},
                 {"shape": "box", "half_extents": [0.1, 0.1, 0.1], "position": [0.3, -0.3, 0.3],
                  "friction": 0.5},
                 {"shape": "capsule", "radius": 0.05, "half_length": 0.2,
                  "position": [-0.3, -0.2, 0.0], "rotation": [0.0, 0.0, 0.7071067811865476,
                                                              0.7071067811865476]},
                 {"shape": "mesh", "vertices": floats(tri_v), "triangles": tri_t.tolist(),
                  "position": floats([path[0]])[0],
                  "keyframes": [{"time": dt32 * k, "position": floats([path[k]])[0]}
                                for k in range(frames + 1)]}]}
    _, _, cli = run_cli(scene, tmp_path)
    with rbcloth.World(substeps=4) as w:
        c = w.cloth(p, q, pins=[0, 15, 240, 255], thickness=0.01, friction=0.2)
        w.plane(position=(0, -1.0, 0))
        w.box((0.1, 0.1, 0.1), position=(0.3, -0.3, 0.3), friction=0.5)
        # The loader normalises the quaternion in double, then rounds: the same here.
        r = np.array([0.0, 0.0, 0.7071067811865476, 0.7071067811865476])
        w.capsule(0.05, 0.2, position=(-0.3, -0.2, 0.0), rotation=(r / np.sqrt((r * r).sum())).astype(np.float32))
        m = w.triangle_mesh(tri_v, tri_t, position=path[0])
        out = []
        for k in range(frames):
            m.set_transform(path[k + 1])
            w.step(DT)
            out.append(c.positions())
        assert w.stats()["collider_count"] == 4
    assert np.array_equal(np.array(out), cli)
    assert cli[-1, :, 1].max() > 0.0  # the rising mesh lifted the cloth above its pins


def test_bad_index_raises_and_world_is_intact():
    p, q = grid(4, 4, 0.1)
    with rbcloth.World() as w, rbcloth.World() as twin:
        c = w.cloth(p, q, pins=[0, 3])
        t = twin.cloth(p, q, pins=[0, 3])
        bad = q.copy()
        bad[5, 2] = 99
        with pytest.raises(rbcloth.Error) as e:
            w.cloth(p, bad)
        assert e.value.result == rbcloth.CONSTANTS["RBC_ERR_BAD_MESH"]
        assert e.value.name == "RBC_ERR_BAD_MESH"
        assert "quad 5" in e.value.message and "vertex 99" in e.value.message
        with pytest.raises(rbcloth.Error) as e:
            c.set_pin(16, (0, 0, 0))
        assert e.value.result == rbcloth.CONSTANTS["RBC_ERR_INVALID_ARGUMENT"]
        assert "vertex 16" in e.value.message
        with pytest.raises(rbcloth.Error) as e:
            w.cloth(p, q, pins=[2, 40])
        assert "pin 1 is vertex 40" in e.value.message
        # Intact: one cloth, and it steps exactly as the twin that saw no bad call.
        assert w.stats()["cloth_count"] == 1
        for _ in range(10):
            w.step(DT)
            twin.step(DT)
        assert np.array_equal(c.positions(), t.positions())
        assert not np.array_equal(c.positions(), p)


def test_arrays_are_checked_before_c():
    """Wrong dtypes and shapes are refused in Python: the C library's last error
    (set to a known message first) is untouched."""
    p, q = grid(3, 3, 0.1)
    with rbcloth.World() as w:
        with pytest.raises(rbcloth.Error):
            w.cloth(p, q, pins=[77])
        before = rbcloth.api.table.last_error()
        assert b"77" in before
        for args, exc in [((p.astype(np.float64), q), TypeError),
                          ((p, q.astype(np.int64)), TypeError),
                          ((p[:, :2].copy(), q), ValueError),
                          ((p.reshape(-1), q), ValueError),
                          ((p, q[:, :3].copy()), ValueError)]:
            with pytest.raises(exc):
                w.cloth(*args)
        with pytest.raises(ValueError):
            w.cloth(p, q, pins=[-1])
        c = w.cloth(p, q)
        with pytest.raises(ValueError):
            c.set_state(p[:4])
        with pytest.raises(TypeError):
            w.sphere(0.1, no_such_field=1)
        with pytest.raises(ValueError):
            w.collider("torus")
        assert rbcloth.api.table.last_error() == before
        # Non-contiguous float32 is accepted (copied), not refused.
        wide = np.zeros((9, 6), np.float32)
        wide[:, ::2] = p
        c2 = w.cloth(wide[:, ::2], q)
        assert np.array_equal(c2.positions(), p)


def test_presets_and_target_strain():
    with rbcloth.World(preset="game_60hz") as w:
        s = w.solver()
        assert (s["mode"], s["max_linear_iterations"], s["max_substeps"]) == (
            rbcloth.CONSTANTS["RBC_ITERATE_TARGET"], 8, 32)
    with rbcloth.World(preset="paper") as w:
        assert w.solver()["solver"] == rbcloth.CONSTANTS["RBC_SOLVER_RBGS"]
    with rbcloth.World(target_strain=0.02) as w:
        s = w.solver()
        assert s["mode"] == rbcloth.CONSTANTS["RBC_ITERATE_TARGET"]
        assert s["target_strain"] == float(np.float32(0.02))
        assert s["solver"] == rbcloth.CONSTANTS["RBC_SOLVER_RBGS_SOR"]  # over "cloth"
        p, q = grid(10, 10, 0.05)
        w.cloth(p, q, pins=[0, 9])
        w.step(DT, steps=5)
        st = w.stats()
        assert st["target_met"] == 1 and st["target_reached"] <= 0.02
    with rbcloth.World(solver={"kind": "jacobi", "mode": "tolerance", "tolerance": 1e-4}) as w:
        s = w.solver()
        assert (s["solver"], s["mode"], s["tolerance"]) == (
            rbcloth.CONSTANTS["RBC_SOLVER_JACOBI"], rbcloth.CONSTANTS["RBC_ITERATE_TOLERANCE"],
            float(np.float32(1e-4)))
        w.set_solver("game_60hz")
        assert w.solver()["max_linear_iterations"] == 8
    with pytest.raises(ValueError):
        rbcloth.World(preset="fast")
    with pytest.raises(rbcloth.Error) as e:
        rbcloth.World(target_strain=-1.0)
    assert "target_strain" in e.value.message


def test_cache_context_manager(tmp_path):
    p, q = grid(3, 3, 0.1)
    good, bad = tmp_path / "good.pc2", tmp_path / "bad.pc2"
    with rbcloth.Cache(str(good), 9) as c:
        c.write(p)
        c.write(p + 1)
    start, rate, frames = read_pc2(good)
    assert (start, rate) == (0.0, 1.0) and np.array_equal(frames, [p, p + 1])
    with pytest.raises(RuntimeError):
        with rbcloth.Cache(str(bad), 9) as c:
            c.write(p)
            raise RuntimeError("bake cancelled")
    assert sorted(os.listdir(tmp_path)) == ["good.pc2"]  # no bad.pc2, no bad.pc2.tmp
    with pytest.raises(ValueError):
        with rbcloth.Cache(str(bad), 8) as c:
            c.write(p)  # 9 rows for 8 points
    assert sorted(os.listdir(tmp_path)) == ["good.pc2"]


def test_mdd_and_obj_sequence_and_write_obj(tmp_path):
    p, q = grid(4, 3, 0.25)
    with rbcloth.Cache(str(tmp_path / "a.mdd"), len(p), format="mdd") as c:
        c.write(p)
        c.write(p * 2)
    data = (tmp_path / "a.mdd").read_bytes()
    frames, points = struct.unpack(">ii", data[:8])
    assert (frames, points) == (2, 12)
    xyz = np.frombuffer(data[8 + 4 * frames:], ">f4").reshape(2, 12, 3)
    assert np.array_equal(xyz, [p, p * 2])
    with rbcloth.Cache(str(tmp_path / "seq"), len(p), format="obj_sequence", quads=q) as c:
        c.write(p)
    lines = (tmp_path / "seq_0001.obj").read_text().split("\n")
    v = np.array([[float(x) for x in l.split()[1:]] for l in lines if l.startswith("v ")],
                 np.float32)
    f = [[int(x) - 1 for x in l.split()[1:]] for l in lines if l.startswith("f ")]
    assert np.array_equal(v, p) and np.array_equal(f, q)
    rbcloth.write_obj(str(tmp_path / "m.obj"), p, q)
    body = [l for l in lines if not l.startswith("#")]  # the comment names the frame
    assert [l for l in (tmp_path / "m.obj").read_text().split("\n")
            if not l.startswith("#")] == body


def test_mesh_import_and_cloth_from_mesh(tmp_path):
    p, q = grid(6, 5, 0.1)
    obj = tmp_path / "g.obj"
    rbcloth.write_obj(str(obj), p, q)
    with rbcloth.Mesh(str(obj), pin_top_axis=2) as m:
        info = m.info()
        assert (info["vertex_count"], info["quad_count"], info["file_quads"]) == (30, 20, 20)
        # The import numbers vertices in face order; %.9g reads back exactly, so
        # the faces' corners are the written ones bit for bit.
        mp, mq = m.positions(), m.quads()
        assert np.array_equal(mp[mq], p[q])
        assert np.array_equal(np.sort(mp[m.pins()][:, 0]), p[24:, 0])  # the row of largest z
        assert np.all(mp[m.pins()][:, 2] == p[:, 2].max())
        assert m.springs().shape == (0, 2)
        assert m.triangles().shape == (40, 3)
        with rbcloth.World() as w:
            c = w.cloth_from_mesh(m, stiffness=500)
            assert c.vertex_count == 30
            assert c.topology()[0] == 6 * 4 + 5 * 5  # structural springs of the grid
            w.step(DT)
            moved = c.positions()
            pinned = np.zeros(30, bool)
            pinned[m.pins()] = True
            assert np.array_equal(moved[pinned], mp[pinned]) and np.all(moved[~pinned, 1] < 0)
    with pytest.raises(rbcloth.Error) as e:
        rbcloth.Mesh(str(tmp_path / "missing.obj"))
    assert e.value.name == "RBC_ERR_IO" and "missing.obj" in e.value.message


def test_stale_handles_after_close():
    p, q = grid(3, 3, 0.1)
    w = rbcloth.World()
    c = w.cloth(p, q)
    w.close()
    w.close()  # twice is harmless
    with pytest.raises(rbcloth.Error) as e:
        c.positions()
    assert e.value.result == rbcloth.CONSTANTS["RBC_ERR_STALE_HANDLE"]


def test_table_and_abi_module():
    major, minor = rbcloth.abi_version()
    assert major == 1 and minor >= 8
    assert rbcloth.abi_version() == (rbcloth.CONSTANTS["RBC_ABI_VERSION_MAJOR"],
                                     rbcloth.CONSTANTS["RBC_ABI_VERSION_MINOR"])
    from rbcloth import _abi
    assert rbcloth.api.size == ctypes.sizeof(_abi.rbc_api_v1)
    assert all(rbcloth.api.has(n) for n in _abi.API_ENTRIES)
    assert _abi.RBC_CLOTH_DEF_SIZE_V1_0 == _abi.rbc_cloth_def.shear_stiffness.offset


def test_log_hook_gets_the_strain_warnings():
    """The paper's step (1 substep of 11 RBGS iterations) at 1/60 s overstretches a
    40 x 40 grid; the library logs the first such step and every power of two after
    it (rbc_world_def.strain_warning), each through the Python hook."""
    msgs = []
    p, q = grid(40, 40, 0.025)
    with rbcloth.World(preset="paper", substeps=1, log=lambda l, m: msgs.append((l, m))) as w:
        w.cloth(p, q, pins=[0, 39])
        w.step(DT, steps=30)
        n = w.stats()["strain_warning_steps"]
    assert n > 0
    assert len(msgs) == n.bit_length()  # steps 1, 2, 4, ... up to n
    assert all(l == rbcloth.CONSTANTS["RBC_LOG_WARNING"] for l, _ in msgs)
    assert "times its rest length" in msgs[0][1]


def test_entries_of_a_newer_header_are_optional():
    """An entry the header does not have (or the library's table lacks) raises
    Error(RBC_ERR_UNSUPPORTED) naming it, instead of an AttributeError or a crash."""
    from rbcloth import _abi
    assert not rbcloth.api.has("no_such_entry")
    with pytest.raises(rbcloth.Error) as e:
        rbcloth.api("no_such_entry")
    assert e.value.result == rbcloth.CONSTANTS["RBC_ERR_UNSUPPORTED"]
    assert "no_such_entry" in e.value.message
    assert rbcloth.api.has("mesh_get_file_map") == ("mesh_get_file_map" in _abi.API_ENTRIES)


def test_an_older_library_gets_an_older_def_size():
    """A library older than the header refuses sizeof(rbc_cloth_def): the binding
    falls back to the header's older sizes (RBC_CLOTH_DEF_SIZE_V1_1 here), and a field
    beyond it is refused by name instead of being dropped silently. The older
    library is played by a copy of the table whose cloth_def_init takes only the 1.1
    size (the real one behind it)."""
    from rbcloth import _abi
    real = rbcloth.api.table
    v11 = _abi.RBC_CLOTH_DEF_SIZE_V1_1
    sizes = []

    @ctypes.CFUNCTYPE(
        ctypes.c_int32, ctypes.POINTER(_abi.rbc_cloth_def), ctypes.c_uint32)
    def old_init(d, size):
        sizes.append(size)
        return real.cloth_def_init(d, size) if size == v11 else -1

    fake = _abi.rbc_api_v1.from_buffer_copy(
        ctypes.string_at(ctypes.addressof(real), ctypes.sizeof(real)))
    fake.cloth_def_init = ctypes.cast(old_init, type(fake.cloth_def_init))
    p, q = grid(3, 3, 0.1)
    rbcloth.api.table = fake
    try:
        with rbcloth.World() as w:
            c = w.cloth(p, q, pins=[0], stiffness=300)
            assert sizes == [ctypes.sizeof(_abi.rbc_cloth_def), v11]
            w.step(DT)
            assert c.positions()[8, 1] < 0
            with pytest.raises(rbcloth.Error) as e:
                w.cloth(p, q, thickness=0.01)
            assert e.value.name == "RBC_ERR_UNSUPPORTED" and "cloth.thickness" in e.value.message
    finally:
        rbcloth.api.table = real


@pytest.mark.skipif(not rbcloth.api.has("mesh_get_file_map"), reason="needs ABI 1.9")
def test_file_map_and_file_positions(tmp_path):
    """ABI 1.9: the import numbers its vertices in face order, not the file's; the
    file map, to_file_positions and write_file_obj give states back in the file's
    order and coordinates (scale 2 undone; powers of two keep every bit)."""
    p, q = grid(6, 5, 0.1)
    obj = tmp_path / "g.obj"
    rbcloth.write_obj(str(obj), p, q)
    with rbcloth.Mesh(str(obj), scale=2.0) as m:
        info = m.info()
        assert (info["file_vertex_count"], info["unmapped_file_vertices"]) == (30, 0)
        assert info["file_order"] == rbcloth.CONSTANTS["RBC_FILE_ORDER_FILE"]
        assert info["applied_scale"] == 2.0
        fm, mp = m.file_map(), m.positions()
        assert fm.dtype == np.uint32 and sorted(fm) == list(range(30))
        assert not np.array_equal(fm, np.arange(30))  # a real permutation to undo
        assert np.array_equal(mp[fm], p * 2)
        assert np.array_equal(m.to_file_positions(), p)
        assert np.array_equal(m.to_file_positions(mp), p)
        with rbcloth.World() as w:
            c = w.cloth_from_mesh(m, pins=[fm[0], fm[5]])  # file vertices 0 and 5
            w.step(DT, steps=3)
            x = c.positions()
        fx = m.to_file_positions(x)
        assert np.array_equal(fx, x[fm] / 2)
        assert np.array_equal(fx[[0, 5]], p[[0, 5]]) and np.all(fx[6:, 1] < 0)
        m.write_file_obj(str(tmp_path / "state.obj"), x)
        v = [[float(t) for t in l.split()[1:4]]
             for l in (tmp_path / "state.obj").read_text().split("\n") if l.startswith("v ")]
        assert np.array_equal(np.array(v, np.float32), fx)
        with pytest.raises(rbcloth.Error) as e:
            m.to_file_positions(mp[:-1])
        assert e.value.result == rbcloth.CONSTANTS["RBC_ERR_INVALID_ARGUMENT"]
        with pytest.raises(rbcloth.Error) as e:
            with rbcloth.World() as w:
                w.cloth_from_mesh(m, pins=[30])
        assert "30" in e.value.message


@pytest.mark.skipif("frame_rate" not in rbcloth.FIELD_TYPES["rbc_cache_def"],
                    reason="needs ABI 1.9")
def test_cache_frame_rate(tmp_path):
    """A field the header appended (1.9's rbc_cache_def.frame_rate) is set by name
    with no edit to the binding: MDD times are (start_frame + k) / frame_rate s."""
    p, _ = grid(2, 2, 0.5)
    with rbcloth.Cache(str(tmp_path / "t.mdd"), 4, format="mdd", start_frame=1,
                       frame_rate=30) as c:
        for _ in range(3):
            c.write(p)
    data = (tmp_path / "t.mdd").read_bytes()
    times = np.frombuffer(data[8:20], ">f4")
    assert np.array_equal(times, np.float32([1 / 30, 2 / 30, 3 / 30]))


def test_masses():
    """Per-vertex masses: equal masses step exactly as vertex_mass does; a heavier
    cloth with the same springs sags further; a masses array of the wrong length is
    refused in Python (C would read past its end), a non-positive mass by C."""
    p, q = grid(8, 8, 0.05)
    n = len(p)
    with rbcloth.World() as a, rbcloth.World() as b, rbcloth.World() as c:
        ca = a.cloth(p, q, pins=[0, 7], masses=np.full(n, 2e-4, np.float32))
        cb = b.cloth(p, q, pins=[0, 7], vertex_mass=2e-4)
        cc = c.cloth(p, q, pins=[0, 7], masses=np.full(n, 2e-2, np.float32))
        for w in (a, b, c):
            w.step(DT, steps=20)
        assert np.array_equal(ca.positions(), cb.positions())
        assert cc.positions()[:, 1].min() < ca.positions()[:, 1].min()
        with pytest.raises(ValueError):
            a.cloth(p, q, masses=np.full(n - 1, 1e-4, np.float32))
        with pytest.raises(TypeError):
            a.cloth(p, q, masses=np.full(n, 1e-4))
        bad = np.full(n, 1e-4, np.float32)
        bad[5] = 0
        with pytest.raises(rbcloth.Error) as e:
            a.cloth(p, q, masses=bad)
        assert "5" in e.value.message


def test_game_loop_readback_triangles_transform_split_step():
    """ABI 1.10 from Python: interleaved vertices equal positions(), a flat sheet's
    normals are (0, -1, 0) ((c - a) x (d - b) of the grid's quads points down), the
    triangles are (a b c)(a c d) per quad with a revision a cut moves, a translation
    moves every vertex, and the split step equals the plain one bitwise."""
    p, q = grid(6, 5, 0.1, (0.0, 1.0, 0.0))
    with rbcloth.World() as w, rbcloth.World() as twin:
        c = w.cloth(p, q, pins=[0, 5])
        t = twin.cloth(p, q, pins=[0, 5])
        n = c.normals()
        assert np.array_equal(n[:, [0, 2]], np.zeros((30, 2), np.float32))
        assert np.allclose(n[:, 1], -1.0, atol=2.4e-7)
        tris, rev = c.triangles()
        assert rev == 1 and tris.shape == (2 * len(q), 3)
        assert np.array_equal(tris[0::2], q[:, [0, 1, 2]])
        assert np.array_equal(tris[1::2], q[:, [0, 2, 3]])
        for _ in range(5):
            w.step_begin(DT)
            with pytest.raises(rbcloth.Error) as e:
                c.positions()
            assert e.value.name == "RBC_ERR_BUSY"
            w.step_wait()
            twin.step(DT)
        assert np.array_equal(c.positions(), t.positions())
        v = c.vertices()
        assert v.shape == (30, 6) and np.array_equal(v[:, :3], c.positions())
        assert np.allclose(np.linalg.norm(v[:, 3:], axis=1), 1.0, atol=2.4e-7)
        before = c.positions()
        c.transform((0.0, 2.0, 0.0), reset_velocity=True)
        assert np.allclose(c.positions() - before, [0.0, 2.0, 0.0], atol=2.4e-7)
        with pytest.raises(rbcloth.Error) as e:
            c.transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 2.0))
        assert "not a unit quaternion" in e.value.message
        assert c.cut([[7, 8]]) == 1
        tris, rev = c.triangles()
        assert rev == 2 and tris.shape == (2 * len(q) - 4, 3)
        assert c.vertices(normals=False).shape == (30, 3) and c.triangle_revision == 2
