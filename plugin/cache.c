/* cache.c -- writers of what DCC tools read: the rest mesh as OBJ, and point caches
 * as PC2, MDD or a sequence of OBJ files. Every file is written to "<path>.tmp" and
 * renamed into place only when complete, so a reader never sees half a file; an
 * abandoned or failed cache removes its temporary files. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "errors.h"
#include "handles.h"
#include "registry.h"
#include "replace_file.h"
#include "rbcloth.h"

#define RBC_MAX_CACHES 4096u

typedef struct cache {
    /* PC2: the temporary file (header + frames). MDD: the frames alone, in
     * frames_path; the header needs the frame count first, so finish assembles
     * the file in tmp_path. OBJ sequence: NULL (one file per frame). */
    FILE *f;
    char *path, *tmp_path, *frames_path;
    uint32_t *quads;
    rbc_cache_def def;
    uint32_t frames;
} cache;

/* Cache ids (registry.h); a cache, like a world, is used by one thread at a time. */
static rbc_reg_entry g_cache_entries[RBC_MAX_CACHES];
static rbc_registry g_caches = RBC_REGISTRY_INIT(RBC_KIND_CACHE, RBC_MAX_CACHES, g_cache_entries);

static char *dup_suffix(const char *s, const char *suffix) {
    size_t a = strlen(s), b = strlen(suffix);
    char *r = malloc(a + b + 1);
    if (!r) return NULL;
    memcpy(r, s, a);
    memcpy(r + a, suffix, b + 1);
    return r;
}

/* Little-endian writers (PC2 is little-endian whatever the host). */
static int put_u32le(FILE *f, uint32_t v) {
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 24)};
    return fwrite(b, 1, 4, f) == 4;
}
static int put_f32le(FILE *f, float x) {
    uint32_t v;
    memcpy(&v, &x, 4);
    return put_u32le(f, v);
}

static int put_u32be(FILE *f, uint32_t v) {
    unsigned char b[4] = {(unsigned char)(v >> 24), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 8), (unsigned char)v};
    return fwrite(b, 1, 4, f) == 4;
}
static int put_f32be(FILE *f, float x) {
    uint32_t v;
    memcpy(&v, &x, 4);
    return put_u32be(f, v);
}

static int host_is_little_endian(void) {
    uint32_t one = 1;
    unsigned char c;
    memcpy(&c, &one, 1);
    return c == 1;
}

RBC_API rbc_result RBC_CALL rbc_write_obj(const char *path, const float *xyz,
                                          uint32_t vertex_count, const uint32_t *quads,
                                          uint32_t quad_count) {
    static const char fn[] = "rbc_write_obj";
    if (!path || !*path) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: path is empty", fn);
    if (!xyz && vertex_count)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: xyz is NULL", fn);
    if (!quads && quad_count)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: quads is NULL", fn);
    for (uint32_t v = 0; v < vertex_count; ++v)
        if (!(isfinite(xyz[3 * (size_t)v]) && isfinite(xyz[3 * (size_t)v + 1]) &&
              isfinite(xyz[3 * (size_t)v + 2])))
            return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                                 "%s: vertex %u has a non-finite position", fn, v);
    for (uint32_t q = 0; q < quad_count; ++q)
        for (int k = 0; k < 4; ++k)
            if (quads[4 * (size_t)q + k] >= vertex_count)
                return rbc_set_error(RBC_ERR_BAD_MESH,
                                     "%s: quad %u corner %d is vertex %u; vertex_count is %u", fn,
                                     q, k, quads[4 * (size_t)q + k], vertex_count);
    char *tmp = dup_suffix(path, ".tmp");
    if (!tmp) return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: out of memory", fn);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        rbc_result rc = rbc_set_error(RBC_ERR_IO, "%s: cannot create %s: %s", fn, tmp,
                                      strerror(errno));
        free(tmp);
        return rc;
    }
    int ok = fprintf(f, "# rbcloth %s: %u vertices, %u quads\n", rbc_version_string(),
                     vertex_count, quad_count) > 0;
    /* %.9g round-trips every float exactly. */
    for (uint32_t v = 0; ok && v < vertex_count; ++v)
        ok = fprintf(f, "v %.9g %.9g %.9g\n", (double)xyz[3 * (size_t)v],
                     (double)xyz[3 * (size_t)v + 1], (double)xyz[3 * (size_t)v + 2]) > 0;
    for (uint32_t q = 0; ok && q < quad_count; ++q) {
        const uint32_t *c = quads + 4 * (size_t)q;
        ok = fprintf(f, "f %u %u %u %u\n", c[0] + 1, c[1] + 1, c[2] + 1, c[3] + 1) > 0;
    }
    ok = (fflush(f) == 0) && ok;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rbc_replace_file(tmp, path) != 0) {
        rbc_result rc = rbc_set_error(RBC_ERR_IO, "%s: writing %s failed: %s", fn, path,
                                      strerror(errno));
        remove(tmp);
        free(tmp);
        return rc;
    }
    free(tmp);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cache_def_init(rbc_cache_def *def, uint32_t struct_size) {
    rbc_cache_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.format = RBC_CACHE_PC2;
    d.start_frame = 0.0f;
    d.sample_rate = 1.0f;
    d.quads = NULL;
    d.quad_count = 0;
    d.frame_rate = 24.0f;
    return rbc_def_init_common(def, struct_size, &d, &rbc_sizes_cache_def, "rbc_cache_def_init");
}

/* The PC2 header: char[12] "POINTCACHE2\0", int32 version 1, int32 points,
 * float32 start frame, float32 sample rate, int32 samples (32 bytes). */
static int write_pc2_header(cache *c) {
    static const char magic[12] = "POINTCACHE2";
    return fseek(c->f, 0, SEEK_SET) == 0 && fwrite(magic, 1, 12, c->f) == 12 &&
           put_u32le(c->f, 1) && put_u32le(c->f, c->def.point_count) &&
           put_f32le(c->f, c->def.start_frame) && put_f32le(c->f, c->def.sample_rate) &&
           put_u32le(c->f, c->frames);
}

/* "<prefix>_0001.obj" (+ ".tmp") for frame k (0-based): malloc'd, or NULL. */
static char *objseq_name(const char *prefix, uint32_t k, int tmp) {
    size_t size = strlen(prefix) + 32;
    char *r = malloc(size);
    if (r) snprintf(r, size, "%s_%04u.obj%s", prefix, k + 1, tmp ? ".tmp" : "");
    return r;
}

static void objseq_remove_tmp(const cache *c, uint32_t first) {
    for (uint32_t k = first; k < c->frames; ++k) {
        char *t = objseq_name(c->path, k, 1);
        if (t) remove(t);
        free(t);
    }
}

static void cache_free(cache *c) {
    if (!c) return;
    if (c->f) fclose(c->f);
    if (c->tmp_path) remove(c->tmp_path);
    if (c->frames_path) remove(c->frames_path);
    if (c->def.format == RBC_CACHE_OBJ_SEQUENCE) objseq_remove_tmp(c, 0);
    free(c->path);
    free(c->tmp_path);
    free(c->frames_path);
    free(c->quads);
    free(c);
}

RBC_API rbc_result RBC_CALL rbc_cache_create(const rbc_cache_def *user_def, rbc_cache_id *out) {
    static const char fn[] = "rbc_cache_create";
    if (!out) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: out_cache is NULL", fn);
    *out = 0;
    if (!user_def) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: def is NULL", fn);
    if (!rbc_size_known(&rbc_sizes_cache_def, user_def->struct_size))
        return rbc_size_refused(&rbc_sizes_cache_def, user_def->struct_size, fn, "def");
    /* Fields the host's struct does not have take their defaults. */
    rbc_cache_def def;
    memset(&def, 0, sizeof def);
    def.frame_rate = 24.0f;
    memcpy(&def, user_def, user_def->struct_size);
    if (def.format != RBC_CACHE_PC2 && def.format != RBC_CACHE_MDD &&
        def.format != RBC_CACHE_OBJ_SEQUENCE)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: format %d is not an rbc_cache_format (PC2 1, MDD 2, "
                             "OBJ sequence 3)",
                             fn, (int)def.format);
    if (!def.path || !*def.path)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: path is empty", fn);
    if (def.point_count == 0)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: point_count is 0", fn);
    if (def.format == RBC_CACHE_MDD && !(isfinite(def.frame_rate) && def.frame_rate > 0.0f))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: frame_rate %g must be finite and > 0 (frames per second of "
                             "the MDD's times)",
                             fn, (double)def.frame_rate);
    if (!isfinite(def.start_frame) || !(isfinite(def.sample_rate) && def.sample_rate > 0.0f))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: start_frame %g and sample_rate %g must be finite, the rate > 0",
                             fn, (double)def.start_frame, (double)def.sample_rate);
    if (def.format != RBC_CACHE_OBJ_SEQUENCE) {
        def.quads = NULL;
        def.quad_count = 0;
    }
    if (def.quad_count && !def.quads)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: quads is NULL, quad_count is %u", fn,
                             def.quad_count);
    for (uint32_t q = 0; q < def.quad_count; ++q)
        for (int k = 0; k < 4; ++k)
            if (def.quads[4 * (size_t)q + k] >= def.point_count)
                return rbc_set_error(RBC_ERR_BAD_MESH,
                                     "%s: quad %u corner %d is vertex %u; point_count is %u", fn,
                                     q, k, def.quads[4 * (size_t)q + k], def.point_count);
    cache *c = calloc(1, sizeof *c);
    if (!c) return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: out of memory", fn);
    c->def = def;
    c->path = dup_suffix(def.path, "");
    if (def.format != RBC_CACHE_OBJ_SEQUENCE) c->tmp_path = dup_suffix(def.path, ".tmp");
    else c->tmp_path = objseq_name(def.path, 0, 1); /* probed below, then removed */
    if (def.format == RBC_CACHE_MDD) c->frames_path = dup_suffix(def.path, ".tmp.frames");
    if (def.quad_count) {
        c->quads = malloc(4 * sizeof(uint32_t) * (size_t)def.quad_count);
        if (c->quads) memcpy(c->quads, def.quads, 4 * sizeof(uint32_t) * (size_t)def.quad_count);
    }
    c->def.path = c->path;
    c->def.quads = c->quads;
    if (!c->path || !c->tmp_path || (def.format == RBC_CACHE_MDD && !c->frames_path) ||
        (def.quad_count && !c->quads)) {
        cache_free(c);
        return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: out of memory", fn);
    }
    const char *open_path = def.format == RBC_CACHE_MDD ? c->frames_path : c->tmp_path;
    c->f = fopen(open_path, "wb");
    if (!c->f) {
        rbc_result rc = rbc_set_error(RBC_ERR_IO, "%s: cannot create %s: %s", fn, open_path,
                                      strerror(errno));
        free(c->tmp_path); /* nothing was created: remove nothing */
        c->tmp_path = NULL;
        free(c->frames_path);
        c->frames_path = NULL;
        cache_free(c);
        return rc;
    }
    if (def.format == RBC_CACHE_OBJ_SEQUENCE) {
        /* The directory is writable; frames open their own files. */
        fclose(c->f);
        c->f = NULL;
        remove(c->tmp_path);
        free(c->tmp_path);
        c->tmp_path = NULL;
    } else if (def.format == RBC_CACHE_PC2 && !write_pc2_header(c)) {
        rbc_result rc = rbc_set_error(RBC_ERR_IO, "%s: cannot write %s: %s", fn, c->tmp_path,
                                      strerror(errno));
        cache_free(c);
        return rc;
    }
    if (rbc_reg_add(&g_caches, c, 0, out) != RBC_OK) {
        cache_free(c);
        return rbc_set_error(RBC_ERR_CAPACITY, "%s: %u caches are open already", fn,
                             RBC_MAX_CACHES);
    }
    return RBC_OK;
}

/* One frame of an OBJ sequence, complete in "<name>.tmp" (renamed by finish). */
static int write_obj_frame(const cache *c, const float *xyz, const char *tmp) {
    FILE *f = fopen(tmp, "wb");
    if (!f) return 0;
    int ok = fprintf(f, "# rbcloth %s: frame %u, %u vertices, %u quads\n", rbc_version_string(),
                     c->frames + 1, c->def.point_count, c->def.quad_count) > 0;
    /* %.9g round-trips every float exactly. */
    for (uint32_t v = 0; ok && v < c->def.point_count; ++v)
        ok = fprintf(f, "v %.9g %.9g %.9g\n", (double)xyz[3 * (size_t)v],
                     (double)xyz[3 * (size_t)v + 1], (double)xyz[3 * (size_t)v + 2]) > 0;
    for (uint32_t q = 0; ok && q < c->def.quad_count; ++q) {
        const uint32_t *k = c->quads + 4 * (size_t)q;
        ok = fprintf(f, "f %u %u %u %u\n", k[0] + 1, k[1] + 1, k[2] + 1, k[3] + 1) > 0;
    }
    ok = (fflush(f) == 0) && ok;
    ok = (fclose(f) == 0) && ok;
    return ok;
}

RBC_API rbc_result RBC_CALL rbc_cache_write_frame(rbc_cache_id id, const float *xyz) {
    static const char fn[] = "rbc_cache_write_frame";
    cache *c = rbc_reg_get(&g_caches, id, 0, fn);
    if (!c) return RBC_ERR_STALE_HANDLE;
    if (!xyz) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: xyz is NULL", fn);
    size_t count = 3 * (size_t)c->def.point_count;
    int ok;
    if (c->def.format == RBC_CACHE_OBJ_SEQUENCE) {
        char *tmp = objseq_name(c->path, c->frames, 1);
        if (!tmp) return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: out of memory", fn);
        ok = write_obj_frame(c, xyz, tmp);
        if (!ok) {
            rbc_result rc = rbc_set_error(RBC_ERR_IO, "%s: writing frame %u to %s failed: %s", fn,
                                          c->frames, tmp, strerror(errno));
            remove(tmp);
            free(tmp);
            return rc;
        }
        free(tmp);
    } else if (c->def.format == RBC_CACHE_MDD) {
        ok = 1;
        for (size_t k = 0; ok && k < count; ++k) ok = put_f32be(c->f, xyz[k]);
    } else if (host_is_little_endian()) {
        ok = fwrite(xyz, sizeof(float), count, c->f) == count;
    } else {
        ok = 1;
        for (size_t k = 0; ok && k < count; ++k) ok = put_f32le(c->f, xyz[k]);
    }
    if (!ok)
        return rbc_set_error(RBC_ERR_IO, "%s: writing frame %u to %s failed: %s", fn, c->frames,
                             c->frames_path ? c->frames_path : c->tmp_path, strerror(errno));
    c->frames++;
    return RBC_OK;
}

/* MDD: header and times into tmp_path, then the frames (already big-endian)
 * copied from frames_path. */
static int finish_mdd(cache *c) {
    int ok = fflush(c->f) == 0;
    ok = (fclose(c->f) == 0) && ok;
    c->f = NULL;
    if (!ok) return 0;
    FILE *in = fopen(c->frames_path, "rb");
    FILE *out = in ? fopen(c->tmp_path, "wb") : NULL;
    ok = in && out && put_u32be(out, c->frames) && put_u32be(out, c->def.point_count);
    for (uint32_t k = 0; ok && k < c->frames; ++k)
        /* seconds: Blender's modifier turns them back into frames at the scene's rate */
        ok = put_f32be(out, (float)(((double)c->def.start_frame +
                                     (double)k * c->def.sample_rate) / c->def.frame_rate));
    char buf[1 << 16];
    size_t n;
    while (ok && (n = fread(buf, 1, sizeof buf, in)) > 0) ok = fwrite(buf, 1, n, out) == n;
    ok = ok && !ferror(in);
    if (in) fclose(in);
    if (out) {
        ok = (fflush(out) == 0) && ok;
        ok = (fclose(out) == 0) && ok;
    }
    return ok;
}

/* OBJ sequence: rename every frame into place, in order. On a failure the frames
 * renamed so far stay (each is complete) and the rest are removed by cache_free. */
static int finish_objseq(cache *c) {
    for (uint32_t k = 0; k < c->frames; ++k) {
        char *t = objseq_name(c->path, k, 1), *d = objseq_name(c->path, k, 0);
        int ok = t && d && rbc_replace_file(t, d) == 0;
        free(t);
        free(d);
        if (!ok) {
            objseq_remove_tmp(c, k);
            c->frames = 0; /* nothing left for cache_free to remove */
            return 0;
        }
    }
    c->frames = 0;
    return 1;
}

static rbc_result cache_end(rbc_cache_id id, const char *fn, int keep) {
    cache *c = rbc_reg_get(&g_caches, id, 0, fn);
    if (!c) return RBC_ERR_STALE_HANDLE;
    rbc_reg_remove(&g_caches, id);
    rbc_result rc = RBC_OK;
    if (keep) {
        int ok;
        if (c->def.format == RBC_CACHE_OBJ_SEQUENCE) {
            ok = finish_objseq(c);
        } else if (c->def.format == RBC_CACHE_MDD) {
            ok = finish_mdd(c) && rbc_replace_file(c->tmp_path, c->path) == 0;
        } else {
            ok = write_pc2_header(c) && fflush(c->f) == 0;
            ok = (fclose(c->f) == 0) && ok;
            c->f = NULL;
            ok = ok && rbc_replace_file(c->tmp_path, c->path) == 0;
        }
        if (!ok)
            rc = rbc_set_error(RBC_ERR_IO, "%s: completing %s failed: %s", fn, c->path,
                               strerror(errno));
        else if (c->tmp_path) {
            free(c->tmp_path);
            c->tmp_path = NULL; /* renamed: nothing to remove */
        }
    }
    cache_free(c);
    return rc;
}

RBC_API rbc_result RBC_CALL rbc_cache_finish(rbc_cache_id id) {
    return cache_end(id, "rbc_cache_finish", 1);
}

RBC_API rbc_result RBC_CALL rbc_cache_destroy(rbc_cache_id id) {
    return cache_end(id, "rbc_cache_destroy", 0);
}
