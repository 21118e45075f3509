/* wire.h -- what rbc_mesh_import (plugin/import.c) and the import helper
 * (rbcloth-import, importer/main.c) say to each other over one Unix socket: the
 * helper's descriptor 3. Both are built from one tree, so structs travel as their
 * bytes; the magic carries a version and the sizes are checked, so a helper from
 * another build is refused rather than misread.
 *
 * Request (plugin -> helper):
 *   u32 RBC_WIRE_REQUEST, u32 sizeof(rbc_mesh_import_def), the def (pointers zeroed),
 *   u64 memory limit in bytes (0 = none), then three strings, each u32 length
 *   (RBC_WIRE_NULL for NULL) and its bytes: path, mesh_name, pin_group.
 * Answer (helper -> plugin), frames that start with a tag byte:
 *   'M'  an allocation failed in the helper (sent once; no body). A crash or an
 *        error that follows it is reported as running out of memory.
 *   'R'  the result: u32 RBC_WIRE_ANSWER, i32 code, u32 message length and the
 *        message; with code 0 then u32 sizeof(rbc_mesh_info), the info, the
 *        RBC_MESH_COUNTS u32 counts and the arrays they size, in the order of
 *        rbc_mesh_arrays (importer/convert.h). The helper exits after it. */
#ifndef RBC_IMPORTER_WIRE_H
#define RBC_IMPORTER_WIRE_H
#include <errno.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#define RBC_WIRE_REQUEST 0x31514252u /* "RBQ1" */
#define RBC_WIRE_ANSWER 0x32414252u  /* "RBA2": the 1.9 mesh (file map, faces) */
#define RBC_WIRE_NULL 0xffffffffu
#define RBC_WIRE_MAX_STRING (1u << 16)
#define RBC_WIRE_FD 3
/* The helper's first argument, so that running it by hand says what it is for. */
#define RBC_WIRE_ARG "--rbcloth-import-v1"

/* Write all of buf; 0 on success, else -1 with errno. MSG_NOSIGNAL: a peer that has
 * gone is EPIPE, not a SIGPIPE that would end the host. */
static inline int rbc_wire_send(int fd, const void *buf, size_t n) {
    const char *p = (const char *)buf;
    while (n) {
        ssize_t k = send(fd, p, n, MSG_NOSIGNAL);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

/* Read exactly n bytes (blocking); 0 on success, -1 on error or end of stream. */
static inline int rbc_wire_recv(int fd, void *buf, size_t n) {
    char *p = (char *)buf;
    while (n) {
        ssize_t k = read(fd, p, n);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}
#endif
