"""rbcloth -- Python binding of librbcloth, the quad mass-spring cloth solver.

The library is loaded with ctypes and used only through its function table,
rbc_get_api(1), as every rbcloth host does. The structs and the table come from
_abi.py, generated from abi/rbcloth.h at build time (gen_abi.py) and checked there
against the C compiler's sizeof/offsetof, so no layout is written by hand here.

Finding the library (the first that exists):
  1. the environment variable RBCLOTH_LIBRARY (a path to librbcloth.so);
  2. librbcloth.so inside this package's folder (the Blender add-on ships it so);
  3. ../lib/librbcloth.so relative to the folder holding this package: the build
     tree's layout (build/python/rbcloth beside build/lib, as build/bin is).
Mesh import needs the rbcloth-import helper beside the library (or
$RBC_IMPORT_HELPER).

Arrays: positions are numpy float32 arrays of shape (n, 3), quads uint32 (m, 4),
springs uint32 (k, 2), triangles uint32 (t, 3), pins and other index lists uint32
(n,). A numpy array of another dtype or shape is refused (TypeError, ValueError)
before anything reaches C: no silent casting of float64 positions. Lists and tuples
are converted (indices must be integers in [0, 2^32)).

Errors: every failing call raises rbcloth.Error with .result (the rbc_result code),
.name ("RBC_ERR_BAD_MESH") and .message (rbc_last_error(): the object, the index and
what was wrong). A failing call leaves every object as it was.

    import numpy as np, rbcloth
    with rbcloth.World(preset="cloth", gravity=(0, -9.81, 0)) as w:
        c = w.cloth(positions, quads, pins=[0, 99])
        w.sphere(radius=0.2, position=(0.5, -0.5, 0.5))
        with rbcloth.Cache("out.pc2", c.vertex_count) as cache:
            for _ in range(60):
                w.step(1 / 60)
                cache.write(c.positions())
"""
import ctypes
import os

import numpy as np

from . import _abi
from ._abi import CONSTANTS, ENUMS, FIELD_TYPES

__all__ = ["Error", "World", "Cloth", "Collider", "Mesh", "Cache", "write_obj",
           "library_path", "api", "abi_version", "version", "CONSTANTS"]

_F32 = ctypes.POINTER(ctypes.c_float)
_U32 = ctypes.POINTER(ctypes.c_uint32)


def library_path():
    """The librbcloth.so this package loads (see the module docstring)."""
    env = os.environ.get("RBCLOTH_LIBRARY")
    if env:
        return env
    here = os.path.dirname(os.path.abspath(__file__))
    for p in (os.path.join(here, "librbcloth.so"),
              os.path.join(here, os.pardir, os.pardir, "lib", "librbcloth.so")):
        if os.path.exists(p):
            return os.path.normpath(p)
    raise ImportError("rbcloth: librbcloth.so not found: set RBCLOTH_LIBRARY, or put it in "
                      "%s, or in ../lib of the package's parent folder" % here)


class _Api:
    """The function table. Entries beyond the table's struct_size (an older library)
    are absent: has(name) says, calling one raises Error(RBC_ERR_UNSUPPORTED)."""

    def __init__(self, path):
        self.path = path
        self.dll = ctypes.CDLL(path)
        get = self.dll.rbc_get_api
        get.restype, get.argtypes = ctypes.c_void_p, [ctypes.c_uint32]
        addr = get(1)
        if not addr:
            raise ImportError("rbcloth: %s has no ABI major 1 table" % path)
        self.table = _abi.rbc_api_v1.from_address(addr)
        self.size = self.table.struct_size

    def has(self, name):
        """Whether the loaded table has entry `name` (False for a name this
        package's header does not know either)."""
        f = getattr(_abi.rbc_api_v1, name, None)
        return (f is not None and f.offset + f.size <= self.size
                and bool(getattr(self.table, name)))

    def __call__(self, name, *args):
        """Call entry `name`; raise Error unless it returns RBC_OK."""
        if not self.has(name):
            raise Error(CONSTANTS["RBC_ERR_UNSUPPORTED"],
                        "the library (%s) has no '%s' entry" % (self.path, name))
        r = getattr(self.table, name)(*args)
        if r != 0:
            raise Error(r, _decode(self.table.last_error()))
        return r


def _decode(b):
    return b.decode("utf-8", "replace") if b else ""


api = _Api(library_path())


def abi_version():
    """(major, minor) of the loaded library."""
    v = api.table.abi_version_fn()
    return v >> 16, v & 0xFFFF


def version():
    """The library's release version, e.g. "0.1.0"."""
    return _decode(api.table.version_string())


class Error(Exception):
    """A failing rbcloth call: .result (rbc_result), .name, .message."""

    def __init__(self, result, message):
        self.result = result
        self.name = _decode(api.table.result_string(result))
        self.message = message
        super().__init__("%s: %s" % (self.name, message))


# --- enums from strings -------------------------------------------------------

def _enum_values(typedef):
    """{"sphere": RBC_SHAPE_SPHERE, ...} from the names of the header's enum for
    `typedef`: the part after their common prefix, lower case; FORCE32 left out."""
    names = [n for n in ENUMS.get(typedef, []) if not n.endswith("FORCE32")]
    if len(names) < 2:
        return {}
    prefix = os.path.commonprefix(names)
    prefix = prefix[:prefix.rfind("_") + 1]
    return {n[len(prefix):].lower(): CONSTANTS[n] for n in names}


# The scene format's spellings where they differ from the header's (samples/scenes).
_ALIASES = {"rbc_shape": {"mesh": CONSTANTS["RBC_SHAPE_TRIANGLE_MESH"]},
            "rbc_cache_format": {"obj": CONSTANTS["RBC_CACHE_OBJ_SEQUENCE"]}}


def _enum(typedef, value, what):
    if isinstance(value, str):
        table = dict(_enum_values(typedef), **_ALIASES.get(typedef, {}))
        if value.lower() not in table:
            raise ValueError("%s: %r is not one of %s" % (what, value, sorted(table)))
        return table[value.lower()]
    return int(value)


# --- arrays -------------------------------------------------------------------

def _array(x, dtype, cols, what, allow_none=False):
    """x as a C-contiguous array of `dtype` and shape (n, cols) (or (n,) for cols
    None). Numpy arrays must already have that dtype and shape."""
    if x is None:
        if allow_none:
            return None
        raise TypeError("%s: an array is required" % what)
    dtype = np.dtype(dtype)
    if isinstance(x, np.ndarray):
        if x.dtype != dtype:
            raise TypeError("%s: dtype %s, expected %s (convert it explicitly)"
                            % (what, x.dtype, dtype))
        a = x
    else:
        if dtype.kind == "u":
            a = np.asarray(x, dtype=np.int64)
            if a.size and (a.min() < 0 or a.max() > 0xFFFFFFFF):
                raise ValueError("%s: indices must be in [0, 2^32)" % what)
            a = a.astype(dtype)
        else:
            a = np.asarray(x, dtype=dtype)
    want = "(n,)" if cols is None else "(n, %d)" % cols
    if cols is None:
        if a.ndim != 1:
            raise ValueError("%s: shape %s, expected %s" % (what, a.shape, want))
    elif a.ndim != 2 or a.shape[1] != cols:
        raise ValueError("%s: shape %s, expected %s" % (what, a.shape, want))
    return np.ascontiguousarray(a)


def _ptr(a, kind):
    return None if a is None else a.ctypes.data_as(kind)


def _vec(x, n, what):
    a = _array(x, np.float32, None, what)
    if a.shape != (n,):
        raise ValueError("%s: %d numbers expected, got shape %s" % (what, n, a.shape))
    return a


# --- defs ---------------------------------------------------------------------

def _sizes(cls):
    """sizeof(cls), then the older released sizes the header names for it (its
    RBC_*_SIZE_V* macros), largest first."""
    older = {getattr(cls, f).offset for s, f in _abi.SIZE_MACROS.values() if s == cls.__name__}
    return [ctypes.sizeof(cls)] + sorted(older, reverse=True)


def _sized(cls, entry, *args, init=True):
    """A struct filled by `entry`: `entry(&s, size, *args)` for an init function, or
    `entry(*args, &s)` with s.struct_size = size for a getter. A library older than
    this package's header refuses sizeof(cls) as an unknown size: the older sizes
    are tried in turn, and the fields beyond the one it takes keep their zeros
    (_set_fields refuses to set them). The first refusal is what is raised if none
    is taken."""
    first = None
    for size in _sizes(cls):
        s = cls()
        try:
            if init:
                api(entry, ctypes.byref(s), size, *args)
            else:
                s.struct_size = size
                api(entry, *args, ctypes.byref(s))
                # rbc_mesh_get_info before 1.9 copied its own record over the whole
                # struct, struct_size included (0): keep the size it was asked for.
                s.struct_size = size
            return s
        except Error as e:
            if e.result != CONSTANTS["RBC_ERR_INVALID_ARGUMENT"]:
                raise
            first = first or e
    raise first


def _new_def(cls, init):
    return _sized(cls, init)


def _set_fields(d, fields, what):
    """Set def fields by name: enums take their names as strings, arrays sequences.
    An unknown name is a TypeError (a field of a newer header appears by itself)."""
    types = FIELD_TYPES[type(d).__name__]
    for name, value in fields.items():
        if value is None:
            continue
        if name not in types or name == "struct_size":
            raise TypeError("%s: no field %r (fields: %s)"
                            % (what, name, ", ".join(n for n in types if n != "struct_size")))
        f = getattr(type(d), name)
        if f.offset + f.size > d.struct_size:
            raise Error(CONSTANTS["RBC_ERR_UNSUPPORTED"],
                        "%s.%s: the library (ABI %d.%d) takes the first %d bytes of %s, "
                        "not this field" % (what, name, *abi_version(), d.struct_size,
                                            type(d).__name__))
        if types[name] in ENUMS:
            value = _enum(types[name], value, "%s.%s" % (what, name))
        cur = getattr(d, name)
        if isinstance(cur, ctypes.Array):
            v = _vec(value, len(cur), "%s.%s" % (what, name))
            for i in range(len(cur)):
                cur[i] = v[i]
        else:
            setattr(d, name, value)


def _to_dict(s):
    """The fields the library filled (those within s.struct_size) as a dict."""
    out = {}
    for name, _t in s._fields_:
        f = getattr(type(s), name)
        if f.offset + f.size > s.struct_size:
            continue
        v = getattr(s, name)
        if isinstance(v, ctypes.Array):
            v = list(v)
        out[name] = v
    return out


def solver_def(preset=None, **fields):
    """An rbc_solver_def: rbc_solver_def_preset(preset) ("paper", "cloth",
    "game_60hz"; None = "cloth", the world's default solve), then `fields`.
    target_strain given without a mode switches the mode to "target"."""
    d = _sized(_abi.rbc_solver_def, "solver_def_preset",
               _enum("rbc_preset", "cloth" if preset is None else preset, "preset"))
    if "kind" in fields:  # the scene format's name for rbc_solver_def.solver
        fields["solver"] = fields.pop("kind")
    if fields.get("target_strain") is not None and fields.get("mode") is None:
        fields["mode"] = "target"
    _set_fields(d, fields, "solver")
    return d


# --- objects ------------------------------------------------------------------

class _Owned:
    """A library object this one owns by its id: destroyed by close() (again is
    harmless), at the end of a `with` block, or when collected."""

    _destroy = None  # the function table entry that destroys it
    id = 0

    def close(self):
        if self.id:
            oid, self.id = self.id, 0
            api(self._destroy, oid)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001 (interpreter shutdown)
            pass


class World(_Owned):
    """A world: rbc_world_create. Keyword arguments are rbc_world_def fields
    (gravity, substeps, substep_rate, nonlinear_iterations, linear_iterations,
    backend "auto"/"cpu"/"cuda", thread_count, strain_warning, ...); the solve is
    solver_def(preset, target_strain=..., **solver). `log`: a callable(level, message)
    receiving the library's messages (on the stepping thread).

    Use as a context manager (destroyed at the end of the block) or call close()."""

    def __init__(self, preset=None, target_strain=None, solver=None, log=None,
                 log_level=None, **fields):
        d = _new_def(_abi.rbc_world_def, "world_def_init")
        _set_fields(d, fields, "world")
        # The solve is always passed, as samples/scene.c does: the library's own
        # "cloth" preset when nothing is asked for, which is also its default.
        self._solver = solver_def(preset, target_strain=target_strain, **(solver or {}))
        d.solver = ctypes.pointer(self._solver)
        self._log = None
        if log is not None:
            def hook(user, level, message, _log=log):
                try:
                    _log(int(level), _decode(message))
                except Exception:  # noqa: BLE001 (an exception cannot cross C)
                    pass
            self._log = _abi.rbc_log_fn(hook)
            d.log = self._log
            d.log_level = _enum("rbc_log_level", log_level if log_level is not None
                                else "warning", "log_level")
        wid = ctypes.c_uint32()
        api("world_create", ctypes.byref(d), ctypes.byref(wid))
        self.id = wid.value

    _destroy = "world_destroy"  # close(): the world and everything in it

    def step(self, dt, steps=1):
        """rbc_world_step(dt) `steps` times (dt rounded to float32, as C would)."""
        for _ in range(steps):
            api("world_step", self.id, ctypes.c_float(dt))

    def step_begin(self, dt):
        """rbc_world_step_begin (ABI 1.10): the step runs on the world's step thread
        until step_wait(); other calls on the world raise RBC_ERR_BUSY meanwhile."""
        api("world_step_begin", self.id, ctypes.c_float(dt))

    def step_wait(self):
        """rbc_world_step_wait: the result of the step step_begin started."""
        api("world_step_wait", self.id)

    def set_gravity(self, gravity):
        api("world_set_gravity", self.id, _ptr(_vec(gravity, 3, "gravity"), _F32))

    def set_iterations(self, substeps, nonlinear_iterations, linear_iterations):
        api("world_set_iterations", self.id, substeps, nonlinear_iterations, linear_iterations)

    def set_solver(self, preset=None, **fields):
        self._solver = solver_def(preset, **fields)
        api("world_set_solver", self.id, ctypes.byref(self._solver))

    def solver(self):
        """The solver settings in use, as a dict of rbc_solver_def fields."""
        return _to_dict(_sized(_abi.rbc_solver_def, "world_get_solver", self.id, init=False))

    def stats(self, skip_measures=False):
        """rbc_world_get_stats as a dict of rbc_world_stats fields."""
        s = _sized(_abi.rbc_world_stats, "world_stats_init")
        s.skip_measures = 1 if skip_measures else 0
        api("world_get_stats", self.id, ctypes.byref(s))
        return _to_dict(s)

    def set_wind(self, velocity, drag=0.0, lift=0.0):
        api("world_set_wind", self.id, _ptr(_vec(velocity, 3, "velocity"), _F32), drag, lift)

    def pick(self, origin, direction, max_distance, radius):
        """(cloth id, vertex, t) of the vertex nearest the ray, or None."""
        c, v, t = ctypes.c_uint32(), ctypes.c_uint32(), ctypes.c_float()
        api("world_pick", self.id, _ptr(_vec(origin, 3, "origin"), _F32),
            _ptr(_vec(direction, 3, "direction"), _F32), max_distance, radius,
            ctypes.byref(c), ctypes.byref(v), ctypes.byref(t))
        return (c.value, v.value, t.value) if c.value else None

    # -- cloths and colliders
    def cloth(self, positions, quads=None, springs=None, pins=None, masses=None, **fields):
        """A cloth (rbc_cloth_create): positions float32 (n, 3), quads uint32 (m, 4),
        springs uint32 (k, 2), pins (vertex indices), masses float32 (n,); other
        rbc_cloth_def fields by name (vertex_mass, density, stiffness, damping,
        shear_stiffness, bend_stiffness, thickness, friction, tear_strain) and
        self_collision / cloth_collision (booleans, the collision_flags)."""
        return Cloth._create(self, None, positions, quads, springs, pins, masses, fields)

    def cloth_from_mesh(self, mesh, pins=None, masses=None, **fields):
        """A cloth from an imported Mesh (rbc_cloth_create_from_mesh): its geometry
        and pins, and (ABI 1.9) `pins` pinned besides; the other fields as cloth()."""
        return Cloth._create(self, mesh, None, None, None, pins, masses, fields)

    def collider(self, shape, **fields):
        """A collider (rbc_collider_create): shape "plane", "sphere", "capsule",
        "box", "triangle_mesh" (or "mesh"); rbc_collider_def fields by name
        (radius, thickness, position, rotation (x y z w), friction, half_extents);
        a mesh takes vertices float32 (n, 3) and triangles uint32 (t, 3)."""
        return Collider(self, shape, fields)

    def sphere(self, radius, **fields):
        return self.collider("sphere", radius=radius, **fields)

    def box(self, half_extents, **fields):
        return self.collider("box", half_extents=half_extents, **fields)

    def capsule(self, radius, half_length, **fields):
        return self.collider("capsule", radius=radius, half_extents=(0.5, half_length, 0.5),
                             **fields)

    def plane(self, **fields):
        return self.collider("plane", **fields)

    def triangle_mesh(self, vertices, triangles, **fields):
        return self.collider("triangle_mesh", vertices=vertices, triangles=triangles, **fields)


class Cloth:
    """A cloth of a World; its methods read and change it through the world."""

    @classmethod
    def _create(cls, world, mesh, positions, quads, springs, pins, masses, fields):
        self = cls.__new__(cls)
        self.world = world
        d = _new_def(_abi.rbc_cloth_def, "cloth_def_init")
        flags = 0
        if fields.pop("self_collision", False):
            flags |= CONSTANTS["RBC_CLOTH_COLLIDE_SELF"]
        if fields.pop("cloth_collision", False):
            flags |= CONSTANTS["RBC_CLOTH_COLLIDE_CLOTHS"]
        if flags:
            fields["collision_flags"] = flags
        keep = []
        pn = _array(pins, np.uint32, None, "pins", allow_none=True)
        if pn is not None:
            d.pin_count, d.pins = len(pn), _ptr(pn, _U32)
            keep.append(pn)
        if mesh is None:
            p = _array(positions, np.float32, 3, "positions")
            q = _array(quads if quads is not None else np.zeros((0, 4), np.uint32),
                       np.uint32, 4, "quads")
            s = _array(springs, np.uint32, 2, "springs", allow_none=True)
            d.vertex_count, d.positions = len(p), _ptr(p, _F32)
            d.quad_count, d.quads = len(q), _ptr(q, _U32)
            if s is not None:
                d.spring_count, d.springs = len(s), _ptr(s, _U32)
            keep += [p, q, s]
        m = _array(masses, np.float32, None, "masses", allow_none=True)
        if m is not None:
            # C reads vertex_count floats from `masses`: a shorter array would be
            # read past its end, so the count is checked here.
            n = d.vertex_count if mesh is None else mesh.info()["vertex_count"]
            if len(m) != n:
                raise ValueError("masses: %d values, the cloth has %d vertices" % (len(m), n))
            d.masses = _ptr(m, _F32)
            keep.append(m)
        _set_fields(d, fields, "cloth")
        cid = ctypes.c_uint32()
        if mesh is None:
            api("cloth_create", world.id, ctypes.byref(d), ctypes.byref(cid))
        else:
            api("cloth_create_from_mesh", world.id, mesh.id, ctypes.byref(d), ctypes.byref(cid))
        self.id = cid.value
        n = ctypes.c_uint32()
        api("cloth_get_vertex_count", world.id, self.id, ctypes.byref(n))
        self.vertex_count = n.value
        return self

    def destroy(self):
        api("cloth_destroy", self.world.id, self.id)

    def positions(self):
        """Current positions, float32 (n, 3)."""
        out = np.empty((self.vertex_count, 3), np.float32)
        written = ctypes.c_size_t()
        api("cloth_read_positions", self.world.id, self.id, _ptr(out, _F32), out.size,
            ctypes.byref(written))
        return out

    def vertices(self, normals=True):
        """rbc_world_read_vertices (ABI 1.10): float32 (n, 6), position then unit
        normal per row (one interleaved buffer, stride 24), or (n, 3) positions
        with normals=False."""
        cols = 6 if normals else 3
        out = np.empty((self.vertex_count, cols), np.float32)
        o = _abi.rbc_vertex_output()
        api("vertex_output_init", ctypes.byref(o), ctypes.sizeof(o))
        o.cloth, o.buffer, o.buffer_size = self.id, out.ctypes.data, out.nbytes
        o.stride, o.position_offset = 4 * cols, 0
        if normals:
            o.normal_offset = 12
        api("world_read_vertices", self.world.id, ctypes.byref(o), 1)
        self.triangle_revision = o.triangle_revision
        return out

    def normals(self):
        """Area-weighted unit normals, float32 (n, 3) (ABI 1.10)."""
        return self.vertices()[:, 3:].copy()

    def triangles(self):
        """(uint32 (k, 3) triangles, revision) (ABI 1.10): two per remaining quad and
        an import's own triangles; the revision grows when a tear or cut removes one."""
        n, rev = ctypes.c_size_t(), ctypes.c_uint32()
        api("cloth_get_triangles", self.world.id, self.id, None, 0, ctypes.byref(n),
            ctypes.byref(rev))
        out = np.empty((n.value // 3, 3), np.uint32)
        api("cloth_get_triangles", self.world.id, self.id, _ptr(out, _U32), out.size,
            ctypes.byref(n), ctypes.byref(rev))
        return out, rev.value

    def transform(self, translation, rotation=(0.0, 0.0, 0.0, 1.0), reset_velocity=False):
        """rbc_cloth_transform (ABI 1.10): p -> R p + t for the whole cloth (rotation a
        unit quaternion x y z w), keeping its velocity or, reset_velocity, at rest."""
        api("cloth_transform", self.world.id, self.id,
            _ptr(_vec(translation, 3, "translation"), _F32),
            _ptr(_vec(rotation, 4, "rotation"), _F32),
            CONSTANTS["RBC_TRANSFORM_RESET_VELOCITY" if reset_velocity
                      else "RBC_TRANSFORM_KEEP_VELOCITY"])

    def state(self):
        """(positions, previous positions), float32 (n, 3) each."""
        p = np.empty((self.vertex_count, 3), np.float32)
        q = np.empty_like(p)
        api("cloth_get_state", self.world.id, self.id, _ptr(p, _F32), _ptr(q, _F32), p.size)
        return p, q

    def set_state(self, positions, previous=None):
        p = self._xyz(positions, "positions")
        q = None if previous is None else self._xyz(previous, "previous")
        api("cloth_set_state", self.world.id, self.id, _ptr(p, _F32), _ptr(q, _F32))

    def _xyz(self, x, what):
        a = _array(x, np.float32, 3, what)
        if len(a) != self.vertex_count:
            raise ValueError("%s: %d rows, the cloth has %d vertices"
                             % (what, len(a), self.vertex_count))
        return a

    def set_pin(self, vertex, target):
        """Pin `vertex` at `target` (x, y, z), or release it with None."""
        t = None if target is None else _vec(target, 3, "target")
        api("cloth_set_pin", self.world.id, self.id, vertex, _ptr(t, _F32))

    def attach(self, vertex, collider, local=None):
        l_ = None if local is None else _vec(local, 3, "local")
        api("cloth_attach", self.world.id, self.id, vertex, collider.id, _ptr(l_, _F32))

    def cut(self, pairs):
        """Cut the springs joining the vertex pairs (uint32 (k, 2)); returns the count."""
        p = _array(pairs, np.uint32, 2, "pairs")
        n = ctypes.c_uint32()
        api("cloth_cut", self.world.id, self.id, _ptr(p, _U32), len(p), ctypes.byref(n))
        return n.value

    def _indices(self, entry, cols):
        n = ctypes.c_size_t()
        api(entry, self.world.id, self.id, None, 0, ctypes.byref(n))
        out = np.empty((n.value // cols, cols), np.uint32)
        api(entry, self.world.id, self.id, _ptr(out, _U32), out.size, ctypes.byref(n))
        return out

    def quads(self):
        return self._indices("cloth_get_quads", 4)

    def springs(self):
        return self._indices("cloth_get_springs", 2)

    def topology(self):
        """(spring count, color count)."""
        s, c = ctypes.c_uint32(), ctypes.c_uint32()
        api("cloth_get_topology", self.world.id, self.id, ctypes.byref(s), ctypes.byref(c))
        return s.value, c.value


class Collider:
    """A collider of a World (see World.collider)."""

    def __init__(self, world, shape, fields):
        self.world = world
        d = _new_def(_abi.rbc_collider_def, "collider_def_init")
        verts, tris = fields.pop("vertices", None), fields.pop("triangles", None)
        d.shape = _enum("rbc_shape", shape, "shape")
        keep = []
        if verts is not None or tris is not None:
            v = _array(verts, np.float32, 3, "vertices")
            t = _array(tris, np.uint32, 3, "triangles")
            d.mesh_positions, d.mesh_vertex_count = _ptr(v, _F32), len(v)
            d.mesh_triangles, d.mesh_triangle_count = _ptr(t, _U32), len(t)
            keep += [v, t]
        _set_fields(d, fields, "collider")
        cid = ctypes.c_uint32()
        api("collider_create", world.id, ctypes.byref(d), ctypes.byref(cid))
        self.id = cid.value

    def set_transform(self, position, rotation=(0.0, 0.0, 0.0, 1.0)):
        """Move the collider: position (x, y, z), unit quaternion (x, y, z, w)."""
        api("collider_set_transform", self.world.id, self.id,
            _ptr(_vec(position, 3, "position"), _F32), _ptr(_vec(rotation, 4, "rotation"), _F32))

    def destroy(self):
        api("collider_destroy", self.world.id, self.id)


class Mesh(_Owned):
    """A mesh read from a file (rbc_mesh_import, assimp in the rbcloth-import
    helper). Keyword arguments are rbc_mesh_import_def fields (scale, weld,
    weld_distance, pair_triangles, ngons "split"/"refuse", pin_top_axis,
    pin_group, mesh_name, timeout_ms, ...). Context manager: destroyed at the end."""

    def __init__(self, path, **fields):
        d = _new_def(_abi.rbc_mesh_import_def, "mesh_import_def_init")
        keep = []
        for name in ("mesh_name", "pin_group"):
            if fields.get(name) is not None:
                keep.append(ctypes.c_char_p(os.fsencode(fields.pop(name))))
                setattr(d, name, keep[-1])
        _set_fields(d, fields, "mesh_import")
        mid = ctypes.c_uint32()
        api("mesh_import", os.fsencode(path), ctypes.byref(d), ctypes.byref(mid))
        self.id = mid.value

    _destroy = "mesh_destroy"

    def info(self):
        """rbc_mesh_get_info as a dict of rbc_mesh_info fields."""
        return _to_dict(_sized(_abi.rbc_mesh_info, "mesh_get_info", self.id, init=False))

    def _get(self, entry, dtype, cols):
        n = ctypes.c_size_t()
        api(entry, self.id, None, 0, ctypes.byref(n))
        out = np.empty((n.value // cols, cols), dtype)
        kind = _F32 if dtype == np.float32 else _U32
        api(entry, self.id, _ptr(out, kind), out.size, ctypes.byref(n))
        return out

    def positions(self):
        return self._get("mesh_get_positions", np.float32, 3)

    def quads(self):
        return self._get("mesh_get_quads", np.uint32, 4)

    def springs(self):
        return self._get("mesh_get_springs", np.uint32, 2)

    def pins(self):
        return self._get("mesh_get_pins", np.uint32, 1)[:, 0]

    def triangles(self):
        return self._get("mesh_get_triangles", np.uint32, 3)

    def file_map(self):
        """For each vertex of the file, in the file's order, the simulated vertex it
        follows, or 0xFFFFFFFF for none: uint32 (n,). (ABI 1.9)"""
        return self._get("mesh_get_file_map", np.uint32, 1)[:, 0]

    def to_file_positions(self, xyz=None):
        """A state of a cloth made from this mesh (float32 (n, 3) in the mesh's
        vertex order, as Cloth.positions() gives it; None = the rest positions) in
        the file's vertex order and coordinates (scale, unit conversion and node
        transforms undone): float32 (file vertices, 3). (ABI 1.9)"""
        a = None if xyz is None else _array(xyz, np.float32, 3, "xyz")
        size = 0 if a is None else a.size
        n = ctypes.c_size_t()
        api("mesh_to_file_positions", self.id, _ptr(a, _F32), size, None, 0, ctypes.byref(n))
        out = np.empty((n.value // 3, 3), np.float32)
        api("mesh_to_file_positions", self.id, _ptr(a, _F32), size, _ptr(out, _F32),
            out.size, ctypes.byref(n))
        return out

    def write_file_obj(self, path, xyz=None, order="file"):
        """A state (as for to_file_positions; None = rest) as an OBJ with the file's
        own faces, UVs, normals and groups; order "file" (the file's vertices, order
        and coordinates) or "mesh" (the simulation's). Written atomically. (ABI 1.9)"""
        a = None if xyz is None else _array(xyz, np.float32, 3, "xyz")
        api("mesh_write_file_obj", self.id, _ptr(a, _F32), 0 if a is None else a.size,
            _enum("rbc_vertex_order", order, "order"), os.fsencode(path))


class Cache:
    """A point cache writer (rbc_cache_create): `path`, `point_count`, format
    "pc2" (default), "mdd" or "obj_sequence" ("obj"), quads (uint32 (m, 4), for the
    OBJ sequence) and other rbc_cache_def fields by name (start_frame,
    sample_rate, and those a newer header adds, e.g. frame_rate).

    The file appears only at finish(): data goes to "<path>.tmp" until then. As a
    context manager a block that ends normally finishes the cache; one that raises
    destroys it (the temporary file is removed, nothing half-written appears)."""

    def __init__(self, path, point_count, format=None, quads=None, **fields):
        d = _new_def(_abi.rbc_cache_def, "cache_def_init")
        self._path = ctypes.c_char_p(os.fsencode(path))
        d.path = self._path
        d.point_count = point_count
        if format is not None:
            d.format = _enum("rbc_cache_format", format, "format")
        q = _array(quads, np.uint32, 4, "quads", allow_none=True)
        if q is not None:
            d.quads, d.quad_count = _ptr(q, _U32), len(q)
        _set_fields(d, fields, "cache")
        cid = ctypes.c_uint32()
        api("cache_create", ctypes.byref(d), ctypes.byref(cid))
        self.id = cid.value
        self.point_count = point_count

    def write(self, xyz):
        """Append one frame: float32 (point_count, 3)."""
        a = _array(xyz, np.float32, 3, "xyz")
        if len(a) != self.point_count:
            raise ValueError("xyz: %d rows, the cache has %d points" % (len(a), self.point_count))
        api("cache_write_frame", self.id, _ptr(a, _F32))

    def finish(self):
        """Complete the file and put it in place; the writer is gone afterwards."""
        cid, self.id = self.id, 0
        if cid:
            api("cache_finish", cid)

    def destroy(self):
        """Abandon the cache: the temporary file is removed."""
        cid, self.id = self.id, 0
        if cid:
            api("cache_destroy", cid)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.finish()
        else:
            self.destroy()

    def __del__(self):
        try:
            self.destroy()
        except Exception:  # noqa: BLE001
            pass


def write_obj(path, positions, quads):
    """rbc_write_obj: the mesh as Wavefront OBJ, written atomically."""
    p = _array(positions, np.float32, 3, "positions")
    q = _array(quads, np.uint32, 4, "quads")
    api("write_obj", os.fsencode(path), _ptr(p, _F32), len(p), _ptr(q, _U32), len(q))
