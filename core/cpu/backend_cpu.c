/* backend_cpu.c -- the CPU backend of the seam (backend.h): memory is plain memory,
 * copies are memcpy, and a launch is a loop on the calling thread over the kernel's
 * per-element body. It exists so that the schedule the CUDA backend runs
 * (backend_step.c) runs, and is tested, on every machine. */
#include "../backend.h"

#include <stdlib.h>
#include <string.h>

#include "../../abi/rbcloth.h"
#include "../energy.h"
#include "../kernels/collide_kernels.h"
#include "../kernels/pd_kernels.h"
#include "../strain.h"

static void *cpu_alloc(void *be, size_t bytes) {
    (void)be;
    return calloc(1, bytes);
}

static void cpu_release(void *be, void *ptr) {
    (void)be;
    free(ptr);
}

static int32_t cpu_copy(void *be, void *dst, const void *src, size_t bytes) {
    (void)be;
    if (bytes) memcpy(dst, src, bytes);
    return RBC_OK;
}

/* The host's loop over each kernel: what a CUDA thread does for one element. */
static int32_t cpu_launch(void *be, rbc_kernel k, const rbc_kargs *a) {
    (void)be;
    const rbc_dcloth *c = a->c;
    const uint32_t b = a->first, e = a->first + a->count;
    switch (k) {
    case RBC_KERNEL_PREDICT:
        for (uint32_t i = b; i < e; ++i)
            rbc_k_predict(i, c->x[0], c->x[1], c->x[2], c->q[0], c->q[1], c->q[2], c->y[0],
                          c->y[1], c->y[2], c->p[0], c->p[1], c->p[2], a->keep, a->g_h2[0],
                          a->g_h2[1], a->g_h2[2]);
        break;
    case RBC_KERNEL_PINS:
        for (uint32_t m = b; m < e; ++m)
            rbc_k_pin(m, c->pin_idx, c->pin_start, c->pin_target, a->f, a->last, c->p[0],
                      c->p[1], c->p[2]);
        break;
    case RBC_KERNEL_LOCAL:
        for (uint32_t s = b; s < e; ++s)
            rbc_k_local(s, c->sa, c->sb, c->rest, c->ux, c->uy, c->uz, c->he_a, c->he_b, c->p[0],
                        c->p[1], c->p[2], c->d[0], c->d[1], c->d[2]);
        break;
    case RBC_KERNEL_RHS:
        for (uint32_t i = b; i < e; ++i)
            rbc_k_rhs(i, c->adj_start, c->adj_k, c->d[0], c->d[1], c->d[2], c->w, c->y[0],
                      c->y[1], c->y[2], c->b[0], c->b[1], c->b[2]);
        break;
    case RBC_KERNEL_GS:
        for (uint32_t i = b; i < e; ++i)
            rbc_k_gs(i, a->variant, a->omega, c->adj_start, c->adj_nbr, c->adj_k, c->b[0],
                     c->b[1], c->b[2], c->inv_denom, c->pinned, c->p[0], c->p[1], c->p[2],
                     c->alt[0], c->alt[1], c->alt[2]);
        break;
    case RBC_KERNEL_JACOBI:
        for (uint32_t i = b; i < e; ++i)
            rbc_k_jacobi(i, a->variant, a->omega, c->adj_start, c->adj_nbr, c->adj_k, c->b[0],
                         c->b[1], c->b[2], c->inv_denom, c->pinned, a->src[0], a->src[1],
                         a->src[2], a->dst[0], a->dst[1], a->dst[2], c->prev[0], c->prev[1],
                         c->prev[2]);
        break;
    case RBC_KERNEL_CHEB_BLEND:
        for (int ax = 0; ax < 3; ++ax)
            for (uint32_t i = b; i < e; ++i)
                rbc_k_cheb_blend(i, a->omega, c->pinned, c->p[ax], c->prev[ax], c->alt[ax]);
        break;
    case RBC_KERNEL_COPY:
        for (int ax = 0; ax < 3; ++ax)
            if (a->count) memcpy(a->dst[ax] + b, a->src[ax] + b, (size_t)a->count * sizeof(float));
        break;
    case RBC_KERNEL_CHECK:
        /* The lowest index, as the CUDA backend's atomicMin finds it. */
        for (uint32_t i = b; i < e; ++i)
            if (!rbc_k_finite(i, c->p[0], c->p[1], c->p[2])) {
                int32_t v = (int32_t)i + 1;
                if (c->bad[0] == 0 || v < c->bad[0]) c->bad[0] = v;
                break;
            }
        break;
    case RBC_KERNEL_SPRINGS:
        for (uint32_t s = b; s < e; ++s)
            if (!rbc_k_spring_ok(s, c->sa, c->sb, c->rest, a->stretch, a->floor_len, c->p[0],
                                 c->p[1], c->p[2])) {
                int32_t v = (int32_t)s + 1;
                if (c->bad[1] == 0 || v < c->bad[1]) c->bad[1] = v;
                break;
            }
        break;
    case RBC_KERNEL_RESIDUAL: {
        /* As rbc_global_residual on one thread: the range's sums, then added. */
        double r = 0.0, bb = 0.0;
        for (uint32_t i = b; i < e; ++i)
            if (!c->pinned[i])
                rbc_k_residual(i, c->adj_start, c->adj_nbr, c->adj_k, c->b[0], c->b[1], c->b[2],
                               c->inv_denom, c->p[0], c->p[1], c->p[2], c->pinned, &r, &bb);
        c->sums[0] += r;
        c->sums[1] += bb;
        break;
    }
    case RBC_KERNEL_STRAIN:
        /* strain.c's own block sum (its flags reassociate it): the pool's value. */
        for (uint32_t k2 = b; k2 < e; ++k2) {
            uint32_t s0 = k2 * RBC_STRAIN_BLOCK, s1 = s0 + RBC_STRAIN_BLOCK;
            if (s1 > c->ns) s1 = c->ns;
            double n = 0.0;
            c->strain_blk[2 * (size_t)k2] = rbc_strain_block_sum_f(
                c->sa, c->sb, c->rest, c->stiff, 0, a->pos[0], a->pos[1], a->pos[2], s0, s1, &n);
            c->strain_blk[2 * (size_t)k2 + 1] = n;
        }
        break;
    case RBC_KERNEL_ENERGY:
        for (uint32_t k2 = b; k2 < e; ++k2) {
            uint32_t i0 = k2 * RBC_ENERGY_BLOCK, i1 = i0 + RBC_ENERGY_BLOCK;
            if (i1 > c->n) i1 = c->n;
            rbc_energy_particle_block(a->pos, a->prev, c->w, c->mass, c->pinned, a->g, i0, i1,
                                      c->e_blk + (size_t)RBC_EPB * k2);
        }
        break;
    case RBC_KERNEL_PIN_WORK:
        if (a->count)
            c->sums[2] += rbc_energy_pin_work_list(c->pin_springs, c->pin_spring_count, c->sa,
                                                   c->sb, c->rest, c->stiff, c->pinned, a->prev,
                                                   a->pos);
        break;
    case RBC_KERNEL_COLLIDE_FRAMES:
        for (uint32_t ci = b; ci < e; ++ci) rbc_kc_frames(ci, c->cols, a->f0, a->f);
        break;
    case RBC_KERNEL_COLLIDE_DETECT: {
        const float inv_h = 1.0f / a->h;
        for (uint32_t i = b; i < e; ++i) {
            uint32_t m = rbc_kc_detect(i, c->cols, c->ncols, c->x, c->p, c->pinned, a->thick,
                                       a->mu, a->margin, inv_h, c->n, c->slots, c->ct, c->ncon);
            /* The lowest particle past the slots, as the CUDA backend's atomicMin. */
            if (m > c->slots && c->bad[2] == 0) c->bad[2] = (int32_t)i + 1;
            if (a->last) c->bad[3] += (int32_t)m;
        }
        break;
    }
    case RBC_KERNEL_COLLIDE_PROJECT:
        for (uint32_t i = b; i < e; ++i)
            rbc_kc_project_particle(i, c->n, c->slots, c->ncon, c->ct, c->x, a->dst, a->h);
        break;
    case RBC_KERNEL_COLLIDE_NORMAL:
        for (uint32_t i = b; i < e; ++i)
            rbc_kc_normal_particle(i, c->n, c->slots, c->ncon, c->ct, c->adj_start, c->adj_nbr,
                                   c->adj_k, c->mass, c->ksum, c->b, c->p, a->h);
        break;
    case RBC_KERNEL_COLLIDE_FINISH:
        for (uint32_t i = b; i < e; ++i)
            rbc_kc_finish_particle(i, c->n, c->slots, c->ncon, c->ct, c->mass, c->x, c->p, a->h);
        break;
    case RBC_KERNEL_COLLIDE_POST:
        for (uint32_t i = b; i < e; ++i)
            rbc_kc_post_particle(i, c->cols, c->ncols, c->x, c->y, c->p, c->pinned, a->thick,
                                 a->margin);
        break;
    default: return RBC_ERR_INVALID_ARGUMENT;
    }
    return RBC_OK;
}

static int32_t cpu_sync(void *be) {
    (void)be;
    return RBC_OK;
}

static const char *cpu_last_error(void *be) {
    (void)be;
    return "no error";
}

static const char *cpu_describe(void *be) {
    (void)be;
    return "CPU (the calling thread)";
}

static void cpu_close(void *be) { (void)be; }

static const rbc_backend_ops cpu_ops = {
    .name = "cpu",
    .alloc = cpu_alloc,
    .release = cpu_release,
    .upload = cpu_copy,
    .download = cpu_copy,
    .launch = cpu_launch,
    .sync = cpu_sync,
    .last_error = cpu_last_error,
    .describe = cpu_describe,
    .close = cpu_close,
};

int32_t rbc_backend_cpu_open(rbc_backend_handle *out) {
    out->ops = &cpu_ops;
    out->be = NULL;
    return RBC_OK;
}
