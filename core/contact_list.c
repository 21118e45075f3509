/* contact_list.c -- a list of contacts (contact_list.h). */
#include "contact_list.h"

#include <string.h>

int rbc_contact_list_reserve(rbc_contact_list *list, const rbc_allocator *a) {
    if (list->need <= list->cap) return 0;
    uint32_t cap = list->cap ? list->cap : 256;
    while (cap < list->need) cap = cap > 0x7fffffffu / 2 ? list->need : cap * 2;
    rbc_col_contact *c = rbc_mem_alloc(a, sizeof(*c) * cap);
    if (!c) return -1;
    rbc_mem_free(a, list->c, sizeof(*list->c) * list->cap);
    list->c = c;
    list->cap = cap;
    return 0;
}

void rbc_contact_list_free(rbc_contact_list *list, const rbc_allocator *a) {
    rbc_mem_free(a, list->c, sizeof(*list->c) * list->cap);
    memset(list, 0, sizeof *list);
}
