/* standin_module.c -- a stand-in for the CUDA module with the CPU backend behind the
 * module's entry point, for machines without a GPU. Loaded by the plugin through
 * $RBC_CUDA_MODULE, it lets the plugin's whole device path (world creation with
 * RBC_BACKEND_CUDA, the refusals, the step through the seam, readback, stats, the
 * bench's --backend cuda) run on every machine. It proves the plugin's wiring, not
 * the GPU: the kernels' loops are the CPU backend's (core/cpu/backend_cpu.c).
 *
 * It also keeps the contract a CUDA graph relies on (backend.h, step_begin and
 * step_end): between them it records each launch with copies of its arguments, as
 * a stream capture does, runs them only at step_end, and fails any copy or sync in
 * between. So a schedule that read the state inside a recorded step, or relied on
 * arguments changing after their launch, fails here as it would on a device.
 *
 * And it injects faults for test_backend_faults: rbc_standin_fail_at(n) makes the
 * n-th backend call from then on fail (an allocation returns NULL, a copy, launch,
 * sync or step_end returns RBC_ERR_BACKEND_UNAVAILABLE, as a lost device does), and
 * rbc_standin_calls() counts the calls, so a test can fail each call of a step in
 * turn. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backend.h"
#include "rbcloth.h"

typedef struct recorded {
    rbc_kernel k;
    rbc_kargs a;
    rbc_dcloth c; /* the cloth's arrays as they were at the launch */
} recorded;

typedef struct standin {
    rbc_backend_handle cpu;
    int recording;
    recorded *log;
    size_t count, cap;
    char err[128];
} standin;

static rbc_backend_ops standin_ops;

/* Fault injection (one process, one test thread). */
static long fail_at, calls;

__attribute__((visibility("default"))) void rbc_standin_fail_at(long n) {
    fail_at = n;
    calls = 0;
}
__attribute__((visibility("default"))) long rbc_standin_calls(void) { return calls; }

/* Whether this call is the one to fail. */
static int faulty(standin *s, const char *what) {
    ++calls;
    if (fail_at <= 0 || calls != fail_at) return 0;
    snprintf(s->err, sizeof s->err, "injected fault: %s (call %ld)", what, calls);
    return 1;
}

static void *si_alloc(void *be, size_t bytes) {
    standin *s = be;
    if (faulty(s, "alloc")) return NULL;
    return s->cpu.ops->alloc(s->cpu.be, bytes);
}
static void si_release(void *be, void *ptr) {
    standin *s = be;
    s->cpu.ops->release(s->cpu.be, ptr);
}
static int32_t refuse_inside(standin *s, const char *what) {
    snprintf(s->err, sizeof s->err, "%s inside a recorded step (a schedule bug)", what);
    return RBC_ERR_INVALID_ARGUMENT;
}
static int32_t si_upload(void *be, void *dst, const void *src, size_t bytes) {
    standin *s = be;
    if (s->recording) return refuse_inside(s, "upload");
    if (faulty(s, "upload")) return RBC_ERR_BACKEND_UNAVAILABLE;
    return s->cpu.ops->upload(s->cpu.be, dst, src, bytes);
}
static int32_t si_download(void *be, void *dst, const void *src, size_t bytes) {
    standin *s = be;
    if (s->recording) return refuse_inside(s, "readback");
    if (faulty(s, "readback")) return RBC_ERR_BACKEND_UNAVAILABLE;
    return s->cpu.ops->download(s->cpu.be, dst, src, bytes);
}
static int32_t si_launch(void *be, rbc_kernel k, const rbc_kargs *a) {
    standin *s = be;
    if (faulty(s, "launch")) return RBC_ERR_BACKEND_UNAVAILABLE;
    if (!s->recording) return s->cpu.ops->launch(s->cpu.be, k, a);
    if (s->count == s->cap) {
        size_t cap = s->cap ? 2 * s->cap : 256;
        recorded *log = realloc(s->log, cap * sizeof *log);
        if (!log) {
            snprintf(s->err, sizeof s->err, "out of memory recording a step");
            return RBC_ERR_OUT_OF_MEMORY;
        }
        s->log = log;
        s->cap = cap;
    }
    recorded *r = &s->log[s->count++];
    r->k = k;
    r->a = *a;
    r->c = *a->c; /* r->a.c is pointed at it at step_end: the log may still move */
    return RBC_OK;
}
static int32_t si_sync(void *be) {
    standin *s = be;
    if (s->recording) return refuse_inside(s, "sync");
    return faulty(s, "sync") ? RBC_ERR_BACKEND_UNAVAILABLE : RBC_OK;
}
static const char *si_last_error(void *be) {
    standin *s = be;
    return s->err[0] ? s->err : s->cpu.ops->last_error(s->cpu.be);
}
static const char *si_describe(void *be) {
    (void)be;
    return "the CUDA stand-in (the CPU backend, launches of a fixed step recorded)";
}
static void si_close(void *be) {
    standin *s = be;
    s->cpu.ops->close(s->cpu.be);
    free(s->log);
    free(s);
}
static int32_t si_step_begin(void *be) {
    standin *s = be;
    s->recording = 1;
    s->count = 0;
    return RBC_OK;
}
/* Run the recorded launches in order, each with its own record's copy of the cloth. */
static int32_t si_step_end(void *be) {
    standin *s = be;
    s->recording = 0;
    if (faulty(s, "step_end")) return RBC_ERR_BACKEND_UNAVAILABLE;
    for (size_t i = 0; i < s->count; ++i) {
        s->log[i].a.c = &s->log[i].c;
        int32_t rc = s->cpu.ops->launch(s->cpu.be, s->log[i].k, &s->log[i].a);
        if (rc != RBC_OK) return rc;
    }
    s->count = 0;
    return RBC_OK;
}

__attribute__((visibility("default"))) int32_t
rbc_cuda_backend_open(uint32_t interface_version, rbc_backend_handle *out, char *why,
                      size_t whylen) {
    if (interface_version != RBC_BACKEND_INTERFACE) {
        snprintf(why, whylen, "the stand-in module is for backend interface %u, not %u",
                 (unsigned)RBC_BACKEND_INTERFACE, (unsigned)interface_version);
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    standin *s = calloc(1, sizeof *s);
    if (!s) {
        snprintf(why, whylen, "out of host memory");
        return RBC_ERR_OUT_OF_MEMORY;
    }
    rbc_backend_cpu_open(&s->cpu);
    standin_ops = (rbc_backend_ops){
        .name = "cuda",
        .alloc = si_alloc,
        .release = si_release,
        .upload = si_upload,
        .download = si_download,
        .launch = si_launch,
        .sync = si_sync,
        .last_error = si_last_error,
        .describe = si_describe,
        .close = si_close,
        .step_begin = si_step_begin,
        .step_end = si_step_end,
    };
    out->ops = &standin_ops;
    out->be = s;
    return RBC_OK;
}
