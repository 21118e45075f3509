/* attach.h -- attachments (attach.c): pins whose target follows a collider, at a
 * point fixed in the collider's frame. */
#ifndef RBC_CORE_ATTACH_H
#define RBC_CORE_ATTACH_H
#include <stdint.h>

#include "solver.h"

/* Attach a host vertex to a collider (local NULL: where the vertex is now); pins it. */
int32_t rbc_attach(rbc_solver *s, rbc_cloth_state *c, uint32_t host_vertex,
                   uint32_t collider_public_id, const float local[3]);
/* Forget the attachment of a vertex (its pin stays). */
void rbc_detach_vertex(rbc_cloth_state *c, uint32_t host_vertex);
/* Before a step: every attached vertex's pin target from its collider's pose now. */
void rbc_attachments_update(rbc_solver *s);
/* A collider is going away: release the vertices attached to it. */
int32_t rbc_attachments_drop_collider(rbc_solver *s, uint32_t collider_public_id);
#endif
