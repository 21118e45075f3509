/* main.c -- rbcloth-import, the import helper. rbc_mesh_import spawns it for every
 * import so that assimp runs outside the host's process: whatever a crafted file
 * does to assimp (a crash, an abort from an exception that escapes it, an endless
 * loop, an allocation without bound) ends this process, and the host gets an error
 * (docs/design/import.md, "Isolation"). It reads one request on descriptor 3,
 * answers on the same descriptor and exits; it prints nothing. */
#define _GNU_SOURCE
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>

#include "convert.h"
#include "errors.h"
#include "wire.h"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RBCI_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define RBCI_SANITIZED 1
#endif
#endif
#ifndef RBCI_SANITIZED
#define RBCI_SANITIZED 0
#endif

#if defined(__SANITIZE_ADDRESS__)
#define RBCI_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RBCI_ASAN 1
#endif
#endif
#ifdef RBCI_ASAN
/* An ASan build of the helper: crash signals stay signals (the plugin reports them
 * as assimp's crash), ASan's own findings abort, and the leak check is off: assimp
 * leaks on some error paths, after the answer is sent. ASAN_OPTIONS overrides. */
const char *__asan_default_options(void);
__attribute__((visibility("default"))) const char *__asan_default_options(void) {
    return "handle_segv=0:handle_sigbus=0:handle_abort=0:handle_sigfpe=0:handle_sigill=0:"
           "abort_on_error=1:detect_leaks=0:allocator_may_return_null=1";
}
#endif

/* ------------------------------------------------------------------------- */
/* Allocation failures                                                       */
/* ------------------------------------------------------------------------- */

/* Under the memory limit (RLIMIT_AS) an allocation fails; assimp may then return an
 * error, throw std::bad_alloc out of its C API (std::terminate, SIGABRT) or crash on
 * its own out-of-memory paths. To report all of these as running out of memory the
 * helper notices the failure itself: it defines malloc and friends, which every
 * library of the process (libstdc++'s operator new included) calls, forwards them
 * to glibc's and tells the plugin at the first failure ('M', write(2) is safe here).
 * Sanitizer builds keep the sanitizer's allocator and have no memory limit. */
static volatile sig_atomic_t g_alloc_failed;
/* Failure injection for the tests (tests/import/test_isolation.c): with
 * RBC_IMPORT_HELPER_FAIL_ALLOC=N in the environment, the N-th allocation after the
 * request is read fails, and the count of the import's allocations is written to
 * stderr (kept with RBC_IMPORT_HELPER_STDERR=1), so a test can walk every one.
 * 0 = off. Not thread-safe, nor need it be: assimp's import runs on this thread. */
__attribute__((unused)) static unsigned long g_fail_at, g_alloc_count;
__attribute__((unused)) static int g_counting;

__attribute__((unused)) static void alloc_failed(void) {
    if (g_alloc_failed) return;
    g_alloc_failed = 1;
    char tag = 'M';
    ssize_t k = write(RBC_WIRE_FD, &tag, 1);
    (void)k;
}

#if !RBCI_SANITIZED
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);
/* Default visibility: the project builds with hidden symbols, and a hidden malloc
 * would be this file's alone. */
#define RBCI_EXPORT __attribute__((visibility("default")))

static int inject(void) {
    if (!g_counting || ++g_alloc_count != g_fail_at) return 0;
    errno = ENOMEM; /* what glibc's malloc sets */
    return 1;
}

RBCI_EXPORT void *malloc(size_t n) {
    void *p = inject() ? NULL : __libc_malloc(n);
    if (!p && n) alloc_failed();
    return p;
}
RBCI_EXPORT void *calloc(size_t k, size_t n) {
    void *p = inject() ? NULL : __libc_calloc(k, n);
    if (!p && k && n) alloc_failed();
    return p;
}
RBCI_EXPORT void *realloc(void *q, size_t n) {
    void *p = n && inject() ? NULL : __libc_realloc(q, n);
    if (!p && n) alloc_failed();
    return p;
}
RBCI_EXPORT void *memalign(size_t a, size_t n) {
    void *p = inject() ? NULL : __libc_memalign(a, n);
    if (!p && n) alloc_failed();
    return p;
}
RBCI_EXPORT void *aligned_alloc(size_t a, size_t n) { return memalign(a, n); }
RBCI_EXPORT int posix_memalign(void **out, size_t a, size_t n) {
    if (a < sizeof(void *) || (a & (a - 1))) return EINVAL;
    void *p = memalign(a, n);
    if (!p && n) return ENOMEM;
    *out = p;
    return 0;
}
#endif

/* ------------------------------------------------------------------------- */
/* The request and the answer                                                */
/* ------------------------------------------------------------------------- */

static char *read_string(int fd, int *ok) {
    uint32_t len;
    if (rbc_wire_recv(fd, &len, sizeof len)) return *ok = 0, NULL;
    if (len == RBC_WIRE_NULL) return NULL;
    if (len > RBC_WIRE_MAX_STRING) return *ok = 0, NULL;
    char *s = malloc((size_t)len + 1);
    if (!s || rbc_wire_recv(fd, s, len)) return free(s), *ok = 0, NULL;
    s[len] = '\0';
    return s;
}

typedef struct out_buf {
    char *p;
    size_t n, cap;
    int failed;
} out_buf;

static void put(out_buf *o, const void *src, size_t n) {
    if (o->failed) return;
    if (o->n + n > o->cap) {
        size_t cap = o->cap ? o->cap : 4096;
        while (cap < o->n + n) cap *= 2;
        char *q = realloc(o->p, cap);
        if (!q) {
            o->failed = 1;
            return;
        }
        o->p = q;
        o->cap = cap;
    }
    if (n) memcpy(o->p + o->n, src, n);
    o->n += n;
}

static void put_u32(out_buf *o, uint32_t v) { put(o, &v, sizeof v); }

/* The answer goes out in one piece built first, so that a failure to build it is
 * still answered (with the short error frame below). */
static int answer(int fd, rbc_result code, const char *message, const rbc_mesh *m) {
    out_buf o = {0};
    char tag = 'R';
    put(&o, &tag, 1);
    put_u32(&o, RBC_WIRE_ANSWER);
    put_u32(&o, (uint32_t)code);
    uint32_t len = (uint32_t)strlen(message);
    put_u32(&o, len);
    put(&o, message, len);
    if (code == RBC_OK) {
        put_u32(&o, (uint32_t)sizeof m->info);
        put(&o, &m->info, sizeof m->info);
        uint32_t counts[RBC_MESH_COUNTS];
        rbc_mesh_get_counts(m, counts);
        put(&o, counts, sizeof counts);
        rbc_mesh_array arr[RBC_MESH_ARRAYS];
        rbc_mesh_arrays((rbc_mesh *)m, counts, arr);
        for (int i = 0; arr[i].p; ++i) put(&o, *arr[i].p, arr[i].bytes);
    }
    int rc;
    if (o.failed) {
        static const char oom[] = "rbc_mesh_import: out of memory in the import helper "
                                  "while sending the mesh";
        char small[1 + 3 * sizeof(uint32_t) + sizeof oom];
        uint32_t w[3] = {RBC_WIRE_ANSWER, (uint32_t)RBC_ERR_OUT_OF_MEMORY, sizeof oom - 1};
        small[0] = 'R';
        memcpy(small + 1, w, sizeof w);
        memcpy(small + 1 + sizeof w, oom, sizeof oom - 1);
        rc = rbc_wire_send(fd, small, sizeof small - 1);
    } else {
        rc = rbc_wire_send(fd, o.p, o.n);
    }
    free(o.p);
    return rc;
}

int main(int argc, char **argv) {
    if (argc != 2 || strcmp(argv[1], RBC_WIRE_ARG) != 0) {
        fprintf(stderr,
                "rbcloth-import: the mesh import helper of librbcloth. rbc_mesh_import runs "
                "it, one process per import, with a request on descriptor 3; it is not "
                "meant to be run by hand.\n");
        return 2;
    }
    /* Gone with the host: an import must not outlive the process that asked for it. */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() == 1) return 3;

    const int fd = RBC_WIRE_FD;
    uint32_t head[2];
    rbc_mesh_import_def def;
    uint64_t limit;
    int ok = 1;
    if (rbc_wire_recv(fd, head, sizeof head) || head[0] != RBC_WIRE_REQUEST ||
        head[1] != sizeof def || rbc_wire_recv(fd, &def, sizeof def) ||
        rbc_wire_recv(fd, &limit, sizeof limit))
        return 4;
    char *path = read_string(fd, &ok);
    char *name = read_string(fd, &ok);
    char *group = read_string(fd, &ok);
    if (!ok || !path) return 4;
    def.mesh_name = name;
    def.pin_group = group;

    if (limit && !RBCI_SANITIZED) {
        struct rlimit rl = {(rlim_t)limit, (rlim_t)limit};
        setrlimit(RLIMIT_AS, &rl);
    }

#if !RBCI_SANITIZED
    const char *fail = getenv("RBC_IMPORT_HELPER_FAIL_ALLOC");
    g_fail_at = fail ? strtoul(fail, NULL, 10) : 0;
    g_counting = g_fail_at != 0;
#endif
    rbc_mesh m;
    rbc_result rc = rbc_import_convert(path, &def, &m);
    g_counting = 0;
#if !RBCI_SANITIZED
    if (g_fail_at) fprintf(stderr, "rbcloth-import: %lu allocations\n", g_alloc_count);
#endif
    char message[RBC_ERROR_CAP];
    snprintf(message, sizeof message, "%s", rc ? rbc_error_buffer() : "");
    if (!rc && g_alloc_failed) {
        /* assimp caught a failed allocation and went on: what it read may lack what
         * that allocation was for. A mesh that may be incomplete is not sent. */
        rbc_import_mesh_free(&m);
        snprintf(message, sizeof message, "%s: %.300s: an allocation failed during the import",
                 "rbc_mesh_import", path);
        rc = RBC_ERR_OUT_OF_MEMORY;
    }
    if (rc && g_alloc_failed) {
        /* assimp turned the failed allocation into an error of its own (often
         * "std::bad_alloc"): it ran out of memory, whatever it says. The message
         * keeps assimp's words after the limit. */
        char inner[RBC_ERROR_CAP];
        snprintf(inner, sizeof inner, "%s", message);
        const char *what = strstr(inner, path);
        what = what ? what + strlen(path) + 2 : inner;
        if (what > inner + strlen(inner)) what = inner;
        snprintf(message, sizeof message,
                 "rbc_mesh_import: %.300s: out of memory: the import needed more than its %llu "
                 "MiB (def->memory_limit_mb); %.600s",
                 path, (unsigned long long)(limit >> 20), what);
        rc = RBC_ERR_OUT_OF_MEMORY;
    }
    int sent = answer(fd, rc, message, &m);
    rbc_import_mesh_free(&m);
    free(path);
    free(name);
    free(group);
    return sent ? 5 : 0;
}
