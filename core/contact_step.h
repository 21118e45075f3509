/* contact_step.h -- the contact stages of a step (contact_step.c): detection of the
 * substep's collider, host and cloth contacts, their projection inside the solve,
 * friction and the colliders' work after it, and cloth contact's fail-safe. The
 * geometry and the projections themselves are collide.h and clothcontact.h. */
#ifndef RBC_CORE_CONTACT_STEP_H
#define RBC_CORE_CONTACT_STEP_H
#include "stage.h"

/* Which contacts a contact pass projects (rbc_step_project_contacts). */
enum {
    RBC_PASS_CLOTH = 1,     /* one pass of cloth contact */
    RBC_PASS_COLLIDERS = 2, /* collider and host contacts */
    RBC_PASS_FRICTION = 4,  /* with their friction (the first pass, under color_pass) */
    RBC_PASS_ALT = 8        /* the latest iterate is the Jacobi destination buffer */
};
/* All threads; ends at a barrier when it projects anything. */
void rbc_step_project_contacts(step_ctx *ctx, unsigned pass, uint32_t tid, uint32_t nt);
/* The stages (stage.h): DETECT also moves the prediction onto the contacts found. */
void rbc_stage_detect(step_ctx *ctx, const rbc_step_at *at);
void rbc_stage_friction(step_ctx *ctx, const rbc_step_at *at);
void rbc_stage_cloth_contact(step_ctx *ctx, const rbc_step_at *at);
#endif
