/* contact_list.h -- the contacts of a substep with colliders or from the host: what a
 * world holds (one list per thread and the host's) and collide.h fills and projects
 * (contact_list.c). */
#ifndef RBC_CORE_CONTACT_LIST_H
#define RBC_CORE_CONTACT_LIST_H
#include <stdint.h>

#include "alloc.h"

typedef struct rbc_col_contact {
    uint32_t cloth;    /* index in the solver's dense cloth list */
    uint32_t idx;      /* internal particle index */
    float n[3];        /* unit normal, world */
    float d;           /* the constraint n . p >= d, m */
    float u[3];        /* velocity of the collider's surface at the contact, m/s */
    float depth;       /* d - n . y when positive: how far the prediction went in, m */
    float last;        /* correction of the latest projection pass, m */
    float mu;          /* Coulomb coefficient */
    uint32_t collider; /* index in the solver's dense collider list */
    float fn_row;      /* normal force for friction, N (rbc_collide_normal_forces) */
    float ft[3];       /* friction correction of the latest pass that applied it, m */
    uint32_t color;    /* the particle's color in its cloth (rbc_collide_project_color) */
} rbc_col_contact;

typedef struct rbc_contact_list {
    rbc_col_contact *c;
    uint32_t count, cap;
    uint32_t need;     /* contacts found, also past cap (then the list must grow) */
} rbc_contact_list;

/* Grow a list to hold list->need contacts. 0 on success, -1 out of memory (the list
 * keeps its old buffer). */
int rbc_contact_list_reserve(rbc_contact_list *list, const rbc_allocator *a);
void rbc_contact_list_free(rbc_contact_list *list, const rbc_allocator *a);
#endif
