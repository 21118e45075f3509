/* fuzz_common.h -- what the three fuzz targets share: the library's promises checked
 * as aborts (a failed promise is a crash to libFuzzer, kept like any other), and the
 * check that nothing reaches stdout.
 *
 * Each target defines LLVMFuzzerTestOneInput (and may define LLVMFuzzerInitialize):
 * linked with -fsanitize=fuzzer it is a libFuzzer binary (RBC_FUZZ=ON, clang); linked
 * with replay_main.c it is a plain program that runs the files and folders given on
 * its command line through the same function (every build: the ctest replays). */
#ifndef RBC_FUZZ_COMMON_H
#define RBC_FUZZ_COMMON_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "rbcloth.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerInitialize(int *argc, char ***argv);

/* A broken promise: say which on stderr, then abort (a crash with a stack). */
static inline void fuzz_fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("FUZZ PROMISE BROKEN: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    abort();
}

#define FUZZ_CHECK(cond, ...)                                                                      \
    do {                                                                                           \
        if (!(cond)) fuzz_fail(__VA_ARGS__);                                                       \
    } while (0)

/* The result codes the header defines (rbc_result_string knows them all). */
static inline int fuzz_known_result(rbc_result r) {
    return strcmp(rbc_result_string(r), "unknown result") != 0;
}

/* A failed call: a known error code and a non-empty message. */
static inline void fuzz_check_error(rbc_result r, const char *call) {
    FUZZ_CHECK(r != RBC_OK, "%s: expected a failure", call);
    FUZZ_CHECK(fuzz_known_result(r), "%s returned %d, not a documented result code", call,
               (int)r);
    const char *msg = rbc_last_error();
    FUZZ_CHECK(msg && msg[0], "%s failed with %s but rbc_last_error() is empty", call,
               rbc_result_string(r));
}

/* stdout goes to an unlinked temporary file for the whole run: anything the library
 * writes there grows it, checked after every input. (libFuzzer itself reports on
 * stderr.) */
static int fuzz_stdout_fd = -1;

static inline void fuzz_capture_stdout(void) {
    if (fuzz_stdout_fd >= 0) return;
    char path[] = "/tmp/rbc_fuzz_stdout_XXXXXX";
    int fd = mkstemp(path);
    if (fd < 0) return;
    unlink(path);
    fflush(stdout);
    if (dup2(fd, STDOUT_FILENO) < 0) {
        close(fd);
        return;
    }
    close(fd);
    fuzz_stdout_fd = STDOUT_FILENO;
}

static inline void fuzz_check_stdout(const char *what) {
    if (fuzz_stdout_fd < 0) return;
    fflush(stdout);
    struct stat st;
    if (fstat(fuzz_stdout_fd, &st) == 0 && st.st_size != 0)
        fuzz_fail("%s printed %lld bytes to stdout", what, (long long)st.st_size);
}

/* RBC_FUZZ_VERBOSE=1: each input's outcome on stderr (to see what seeds reach). */
static inline void fuzz_note(const char *fmt, ...) {
    static int verbose = -1;
    if (verbose < 0) verbose = getenv("RBC_FUZZ_VERBOSE") != NULL;
    if (!verbose) return;
    va_list ap;
    va_start(ap, fmt);
    fputs("  ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* Reads the input as a little stream of numbers: what runs out reads as 0. */
typedef struct fuzz_reader {
    const uint8_t *p;
    size_t left;
} fuzz_reader;

static inline uint32_t fuzz_u8(fuzz_reader *r) {
    if (!r->left) return 0;
    r->left--;
    return *r->p++;
}
static inline uint32_t fuzz_u16(fuzz_reader *r) {
    uint32_t lo = fuzz_u8(r);
    return lo | fuzz_u8(r) << 8;
}
static inline uint32_t fuzz_u32(fuzz_reader *r) {
    uint32_t lo = fuzz_u16(r);
    return lo | fuzz_u16(r) << 16;
}
/* A float: mostly from a small table of interesting values, sometimes raw bits. */
static inline float fuzz_float(fuzz_reader *r) {
    static const float table[] = {0.0f, 1.0f, -1.0f, 0.5f, 2.0f, 1e-3f, 1e3f, 1e-6f, 1e6f,
                                  0.01f, 100.0f, -0.5f, 1e-30f, 1e30f, 0.1f, 10.0f};
    uint32_t tag = fuzz_u8(r);
    if (tag < 128) return table[tag % (sizeof table / sizeof table[0])];
    if (tag < 224) return (float)(int32_t)(fuzz_u16(r) - 32768) / 256.0f;
    uint32_t bits = fuzz_u32(r);
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}
#endif
