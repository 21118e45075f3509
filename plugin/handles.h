/* handles.h -- 32-bit ids with a kind and a generation (Box2D's id idea): a stale or
 * foreign id is detected and reported, never dereferenced.
 *
 *   bits 31..28 kind (1 world, 2 cloth, 3 collider, 4 cache, 5 mesh)
 *   bits 27..16 generation, 1..4095 (never 0, so no valid id is 0)
 *   bits 15..0  slot index
 */
#ifndef RBC_PLUGIN_HANDLES_H
#define RBC_PLUGIN_HANDLES_H
#include <stdint.h>

enum { RBC_KIND_WORLD = 1, RBC_KIND_CLOTH = 2, RBC_KIND_COLLIDER = 3, RBC_KIND_CACHE = 4,
       RBC_KIND_MESH = 5 };
#define RBC_MAX_SLOTS 65536u

static inline uint32_t rbc_id_make(uint32_t kind, uint32_t gen, uint32_t slot) {
    return (kind << 28) | ((gen & 0xFFFu) << 16) | (slot & 0xFFFFu);
}
static inline uint32_t rbc_id_kind(uint32_t id) { return id >> 28; }
static inline uint32_t rbc_id_gen(uint32_t id) { return (id >> 16) & 0xFFFu; }
static inline uint32_t rbc_id_slot(uint32_t id) { return id & 0xFFFFu; }
/* Next generation after g, skipping 0. */
static inline uint32_t rbc_gen_next(uint32_t g) { return g >= 0xFFFu ? 1u : g + 1u; }

static inline const char *rbc_kind_name(uint32_t kind) {
    switch (kind) {
    case RBC_KIND_WORLD: return "world";
    case RBC_KIND_CLOTH: return "cloth";
    case RBC_KIND_COLLIDER: return "collider";
    case RBC_KIND_CACHE: return "cache";
    case RBC_KIND_MESH: return "mesh";
    default: return "unknown";
    }
}
#endif
