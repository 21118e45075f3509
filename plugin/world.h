/* world.h -- what the files of the ABI's objects share, private to the plugin: the
 * world (world.c), the id registries of worlds, cloths and colliders (world.c,
 * cloth.c, collider.c), the error and log helpers and lookups every call starts
 * with, and the defs' defaults and readers (defs.c). Nothing here is exported: the
 * plugin builds with hidden visibility and a version script (CMakeLists.txt). */
#ifndef RBC_PLUGIN_WORLD_H
#define RBC_PLUGIN_WORLD_H
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "format_attr.h"

#include "errors.h"
#include "rbcloth.h"
#include "registry.h"
#include "solver.h"

struct rbc_step_thread;

typedef struct rbc_world {
    rbc_solver solver;
    rbc_allocator alloc;
    rbc_world_def def;
    uint32_t id;
    /* The split step (1.10): the world's step thread, started by the first
     * rbc_world_step_begin (NULL before), and 1 from begin to wait. Written by the
     * host's thread only; every lookup but step_wait's and destroy's refuses the
     * world while it is set. */
    struct rbc_step_thread *stepper;
    _Atomic int stepping;
} rbc_world;

/* Ids of worlds, cloths and colliders (registry.h). Cloth and collider ids are
 * unique across worlds, so a foreign id is told apart from a live one. Each is
 * defined in its object's file; rbc_world_destroy removes a world's cloths and
 * colliders from theirs. */
extern rbc_registry rbc_plugin_worlds;
extern rbc_registry rbc_plugin_cloths;
extern rbc_registry rbc_plugin_colliders;

static inline int rbc_plugin_finite3(const float *v) {
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* world.c */

/* Send msg to the world's log hook if it has one and the level passes its filter
 * (w may be NULL: nothing is sent). */
void rbc_plugin_world_log(rbc_world *w, rbc_log_level level, const char *msg);
/* Set the error, send it to the world's log hook (if any) and return the code. */
rbc_result rbc_plugin_world_error(rbc_world *w, rbc_result code, const char *fmt, ...)
    RBC_PRINTF(3, 4);
/* Look up a live world id; RBC_ERR_STALE_HANDLE (error set, message starting with
 * fn) if it is not one. */
rbc_result rbc_plugin_lookup_world(rbc_world_id id, const char *fn, rbc_world **out);
/* The start of a call that creates an object in world wid: *w the world, and *out
 * (out_name in the message when it is NULL) zeroed, so that a failed call hands back
 * no id. */
rbc_result rbc_plugin_create_begin(rbc_world_id wid, const char *fn, uint32_t *out,
                                   const char *out_name, rbc_world **w);
/* rbc_plugin_read_def in a call on world w: a refused def also goes to its log hook. */
rbc_result rbc_plugin_world_read_def(rbc_world *w, void *dst, const rbc_struct_sizes *s,
                                     const void *src, const char *fn, const char *what);

/* cloth.c */

/* Look up a live cloth of world wid: *ow its world, *oc its state. */
rbc_result rbc_plugin_lookup_cloth(rbc_world_id wid, rbc_cloth_id cid, const char *fn,
                                   rbc_world **ow, rbc_cloth_state **oc);

/* render.c */

/* Keep an imported mesh's leftover triangles on a cloth made from it. */
rbc_result rbc_plugin_cloth_lone_triangles(rbc_world_id wid, rbc_cloth_id cid, const char *fn,
                                           const uint32_t *tris, uint32_t count);

/* collider.c */

/* Look up a live collider of world wid: *ow its world, *index its place in the
 * solver's dense array. */
rbc_result rbc_plugin_lookup_collider(rbc_world_id wid, rbc_collider_id cid, const char *fn,
                                      rbc_world **ow, uint32_t *index);

/* defs.c */

/* Copy a def of a size s accepts into a defaults-filled struct of its current size;
 * the fields an older size lacks keep their defaults. */
rbc_result rbc_plugin_read_def(void *dst, const rbc_struct_sizes *s, const void *src,
                               const char *fn, const char *what);
/* The field defaults of each def, as rbc_*_def_init gives them. */
rbc_world_def rbc_plugin_world_def_defaults(void);
rbc_cloth_def rbc_plugin_cloth_def_defaults(void);
rbc_collider_def rbc_plugin_collider_def_defaults(void);
rbc_solver_def rbc_plugin_solver_def_defaults(void);
/* RBC_PRESET_CLOTH, the default solve since 1.6. */
rbc_solver_def rbc_plugin_solver_def_cloth(void);
/* Validate a solver def (already read at a released size) into core settings;
 * errors go to w's log hook (w may be NULL). */
rbc_result rbc_plugin_solver_settings_from(rbc_world *w, const char *fn, const rbc_solver_def *d,
                                           rbc_solver_settings *out);
#endif
