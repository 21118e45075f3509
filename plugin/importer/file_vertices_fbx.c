/* file_vertices_fbx.c -- an FBX file's Geometry `Vertices` (control points) in file
 * order (file_vertices.h), and the helpers both readers share.
 *
 * Binary FBX (format as Blender's io_scene_fbx/parse_fbx.py and assimp's
 * FBXBinaryTokenizer.cpp read it): the 23-byte magic "Kaydara FBX Binary  \0\x1a\0",
 * a uint32 version, then node records: end offset (absolute), property count and
 * property list length -- uint32 before version 7500, uint64 from 7500 -- a uint8
 * name length and the name, the properties, the children, and when there are
 * children a null record (13 or 25 zero bytes). A null record ends the top level.
 * Properties: a type byte, then Y int16, C bool8, I int32, F float32, D float64,
 * L int64; S and R a uint32 length and bytes; arrays f d l i b c a uint32 element
 * count, uint32 encoding (0 raw, 1 zlib), uint32 byte length and the bytes. All
 * little-endian. Every node is parsed and bounded (its end within its parent's and
 * the file's, its properties within its property list), to a depth of
 * RBC_FBX_MAX_DEPTH; only Vertices arrays are decompressed.
 *
 * ASCII FBX: `Key: value, value, ... { children }`, `;` comments, "strings" without
 * escapes; FBX 7 arrays `Vertices: *N { a: v, v, ... }`, FBX 6.1 `Vertices: v,v,...`.
 *
 * What is taken: Objects/Geometry nodes whose type (second string property) is
 * "Mesh", one position list each (empty if it has no Vertices), named by its first
 * string property ("Name\x00\x01Geometry" binary, "Geometry::Name" ASCII); and FBX 6
 * Objects/Model nodes of type "Mesh" that hold a Vertices node themselves (FBX 6 has
 * no Geometry objects). GlobalSettings/Properties70 P "UnitScaleFactor" (centimetres
 * per unit) and "UpAxis"; FBX 6.1: Objects/GlobalSettings/Properties60 Property. */
#include "file_vertices.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#define RBC_FBX_MAX_DEPTH 64
/* zlib's deflate expands at most about 1032:1; an array that claims more than this
 * over its compressed bytes is refused before anything is allocated. */
#define RBC_ZLIB_MAX_RATIO 1100u

/* ---- shared helpers ----------------------------------------------------------- */

void rbc_file_vertices_free(rbc_file_vertices *v) {
    if (!v) return;
    if (v->list_name)
        for (uint32_t i = 0; i < v->list_count; ++i) free(v->list_name[i]);
    free(v->list_name);
    free(v->list_start);
    free(v->xyz);
    memset(v, 0, sizeof *v);
}

void rbc_fv_builder_free(rbc_fv_builder *b) {
    for (size_t i = 0; i < b->lists; ++i) free(b->name[i]);
    free(b->name);
    free(b->start);
    free(b->xyz);
    memset(b, 0, sizeof *b);
}

int rbc_fv_reserve(rbc_fv_builder *b, size_t more) {
    if (more > SIZE_MAX / sizeof(double) - b->n) return 0;
    size_t need = b->n + more;
    if (need <= b->cap) return 1;
    size_t cap = b->cap ? b->cap : 64;
    while (cap < need) cap = cap > SIZE_MAX / sizeof(double) / 2 ? need : cap * 2;
    double *p = realloc(b->xyz, cap * sizeof(double));
    if (!p) return 0;
    b->xyz = p;
    b->cap = cap;
    return 1;
}

int rbc_fv_begin_list(rbc_fv_builder *b, const char *name, size_t len) {
    if (b->n % 3) return 0;
    if (b->n / 3 > UINT32_MAX) return 0;
    if (b->lists == b->lists_cap) {
        size_t cap = b->lists_cap ? 2 * b->lists_cap : 8;
        if (cap > UINT32_MAX - 1) return 0;
        uint32_t *s = realloc(b->start, (cap + 1) * sizeof *s);
        if (!s) return 0;
        b->start = s;
        char **nm = realloc(b->name, cap * sizeof *nm);
        if (!nm) return 0;
        b->name = nm;
        b->lists_cap = cap;
    }
    char *copy = malloc(len + 1);
    if (!copy) return 0;
    /* Valid UTF-8 out, whatever came in: a NUL, a stray or overlong byte, a
     * surrogate or a cut-short sequence each become '?'. */
    const unsigned char *u = (const unsigned char *)name;
    size_t k = 0;
    for (size_t i = 0; i < len;) {
        unsigned c0 = u[i];
        size_t n = c0 < 0x80 ? 1 : (c0 >= 0xC2 && c0 <= 0xDF) ? 2 : (c0 >= 0xE0 && c0 <= 0xEF) ? 3
                 : (c0 >= 0xF0 && c0 <= 0xF4) ? 4 : 0;
        int ok = n > 0 && c0 != 0 && i + n <= len;
        for (size_t j = 1; ok && j < n; ++j) ok = (u[i + j] & 0xC0) == 0x80;
        if (ok && n == 3) {
            unsigned c1 = u[i + 1];
            ok = !(c0 == 0xE0 && c1 < 0xA0) && !(c0 == 0xED && c1 >= 0xA0);
        }
        if (ok && n == 4) {
            unsigned c1 = u[i + 1];
            ok = !(c0 == 0xF0 && c1 < 0x90) && !(c0 == 0xF4 && c1 >= 0x90);
        }
        if (!ok) {
            copy[k++] = '?';
            i++;
        } else {
            memcpy(copy + k, u + i, n);
            k += n;
            i += n;
        }
    }
    copy[k] = 0;
    b->name[b->lists] = copy;
    b->start[b->lists] = (uint32_t)(b->n / 3);
    b->lists++;
    return 1;
}

int rbc_fv_finish(rbc_fv_builder *b, rbc_file_vertices *out) {
    if (b->n % 3 || b->n / 3 > UINT32_MAX || b->lists > UINT32_MAX - 1) return 0;
    uint32_t *s = b->start;
    if (!s) {
        s = malloc(sizeof *s);
        if (!s) return 0;
    }
    s[b->lists] = (uint32_t)(b->n / 3);
    out->count = (uint32_t)(b->n / 3);
    out->xyz = b->xyz;
    if (!out->xyz) out->xyz = malloc(sizeof(double)); /* never NULL on success */
    out->list_count = (uint32_t)b->lists;
    out->list_start = s;
    out->list_name = b->name;
    if (!out->list_name) out->list_name = malloc(sizeof(char *));
    memset(b, 0, sizeof *b);
    if (!out->xyz || !out->list_name) {
        rbc_file_vertices_free(out);
        return 0;
    }
    return 1;
}

int rbc_fv_read_file(const char *path, unsigned char **data, size_t *size) {
    *data = NULL;
    *size = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    size_t cap = 1 << 16, n = 0;
    unsigned char *buf = malloc(cap + 1);
    if (!buf) {
        fclose(f);
        errno = ENOMEM;
        return 0;
    }
    for (;;) {
        if (n == cap) {
            if (cap > SIZE_MAX / 4) {
                free(buf);
                fclose(f);
                errno = EFBIG;
                return 0;
            }
            unsigned char *p = realloc(buf, 2 * cap + 1);
            if (!p) {
                free(buf);
                fclose(f);
                errno = ENOMEM;
                return 0;
            }
            buf = p;
            cap *= 2;
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) break;
    }
    int bad = ferror(f), saved = errno;
    fclose(f);
    if (bad) {
        free(buf);
        errno = saved ? saved : EIO;
        return 0;
    }
    buf[n] = 0;
    *data = buf;
    *size = n;
    return 1;
}

/* ---- FBX common state ----------------------------------------------------------- */

enum { K_OTHER, K_TOP, K_OBJECTS, K_GLOBAL, K_PROPS, K_PROP, K_MESH, K_VERTS, K_VERTS_A };

typedef struct fbx_frame {
    int kind;
    const unsigned char *name; /* the node's name, for messages */
    size_t name_len;
    const unsigned char *label; /* a mesh's name property, for messages */
    size_t label_len;
    /* K_MESH */
    int is_geometry, started, got_vertices;
    /* K_VERTS (ASCII): values of its "*N", -1 if none; first double of the list */
    long long declared;
    size_t first;
} fbx_frame;

typedef struct fbx_ctx {
    const unsigned char *d;
    size_t size;
    char *err;
    size_t errcap;
    int failed;
    rbc_fv_builder b;
    double usf;
    int have_usf;
    int up;
    fbx_frame stack[RBC_FBX_MAX_DEPTH + 2];
    int depth; /* frames in use; stack[0] is the top level */
} fbx_ctx;

/* Printable ASCII copy of at most max bytes (control and non-ASCII bytes as '?'). */
static void clean_copy(char *dst, size_t cap, const unsigned char *s, size_t n, size_t max) {
    size_t k = 0;
    if (!cap) return;
    for (size_t i = 0; i < n && i < max && k + 1 < cap; ++i)
        dst[k++] = (s[i] >= 32 && s[i] < 127) ? (char)s[i] : '?';
    if (n > max && k + 4 < cap) {
        memcpy(dst + k, "...", 3);
        k += 3;
    }
    dst[k] = 0;
}

/* "Objects/Geometry 'Plane'" for the open frames (and one more name, if given). */
static void node_path(const fbx_ctx *c, const unsigned char *extra, size_t extra_len, char *buf,
                      size_t cap) {
    size_t k = 0;
    buf[0] = 0;
    for (int i = 1; i <= c->depth + (extra ? 1 : 0) && i <= RBC_FBX_MAX_DEPTH + 1; ++i) {
        const unsigned char *nm = (i <= c->depth) ? c->stack[i].name : extra;
        size_t nl = (i <= c->depth) ? c->stack[i].name_len : extra_len;
        char part[96];
        clean_copy(part, 48, nm, nl, 40);
        if (i <= c->depth && c->stack[i].label) {
            char lab[48];
            clean_copy(lab, sizeof lab, c->stack[i].label, c->stack[i].label_len, 40);
            size_t pl = strlen(part);
            snprintf(part + pl, sizeof part - pl, " '%s'", lab);
        }
        int w = snprintf(buf + k, cap - k, "%s%s", k ? "/" : "", part);
        if (w < 0 || (size_t)w >= cap - k) break;
        k += (size_t)w;
        if (i > 8 && i < c->depth - 2) { /* deep paths: first levels, ..., last two */
            w = snprintf(buf + k, cap - k, "/...");
            if (w > 0 && (size_t)w < cap - k) k += (size_t)w;
            i = c->depth - 2;
        }
    }
}

static void fail(fbx_ctx *c, const unsigned char *extra, size_t extra_len, const char *fmt, ...) {
    if (c->failed) return;
    c->failed = 1;
    if (!c->err || !c->errcap) return;
    char path[512], msg[512];
    node_path(c, extra, extra_len, path, sizeof path);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (path[0])
        snprintf(c->err, c->errcap, "FBX: node %s: %s", path, msg);
    else
        snprintf(c->err, c->errcap, "FBX: %s", msg);
}

static int name_is(const unsigned char *s, size_t n, const char *lit) {
    size_t l = strlen(lit);
    return n == l && memcmp(s, lit, l) == 0;
}

/* The object name inside an FBX name property: binary "Name\x00\x01Class", ASCII
 * "Class::Name". */
static void object_name(const unsigned char *s, size_t n, const unsigned char **o, size_t *ol) {
    for (size_t i = 0; i + 1 < n; ++i)
        if (s[i] == 0 && s[i + 1] == 1) {
            *o = s;
            *ol = i;
            return;
        }
    for (size_t i = 0; i + 1 < n; ++i)
        if (s[i] == ':' && s[i + 1] == ':') {
            *o = s + i + 2;
            *ol = n - i - 2;
            return;
        }
    *o = s;
    *ol = n;
}

/* The kind of a node named nm under a frame of kind parent, given its first two
 * string properties (s0, s1; NULL if absent). */
static int child_kind(int parent, const unsigned char *nm, size_t nl, const unsigned char *s1,
                      size_t s1l) {
    switch (parent) {
    case K_TOP:
        if (name_is(nm, nl, "Objects")) return K_OBJECTS;
        if (name_is(nm, nl, "GlobalSettings")) return K_GLOBAL;
        return K_OTHER;
    case K_GLOBAL:
        if (name_is(nm, nl, "Properties70") || name_is(nm, nl, "Properties60")) return K_PROPS;
        return K_OTHER;
    case K_PROPS:
        if (name_is(nm, nl, "P") || name_is(nm, nl, "Property")) return K_PROP;
        return K_OTHER;
    case K_OBJECTS:
        if (name_is(nm, nl, "GlobalSettings")) return K_GLOBAL; /* FBX 6.1 puts it here */
        if ((name_is(nm, nl, "Geometry") || name_is(nm, nl, "Model")) && s1 &&
            name_is(s1, s1l, "Mesh"))
            return K_MESH;
        return K_OTHER;
    case K_MESH:
        return name_is(nm, nl, "Vertices") ? K_VERTS : K_OTHER;
    case K_VERTS:
        return name_is(nm, nl, "a") ? K_VERTS_A : K_OTHER;
    default:
        return K_OTHER;
    }
}

static void set_global(fbx_ctx *c, const unsigned char *pname, size_t pl, int have, double v) {
    if (!have || !pname) return;
    if (name_is(pname, pl, "UnitScaleFactor")) {
        c->usf = v;
        c->have_usf = 1;
    } else if (name_is(pname, pl, "UpAxis")) {
        c->up = (v == 0 || v == 1 || v == 2) ? (int)v : -1;
    }
}

/* A mesh frame's list, begun when first needed: a Geometry at once, an FBX 6 Model
 * at its Vertices. */
static int mesh_begin(fbx_ctx *c, fbx_frame *m) {
    if (m->started) return 1;
    const unsigned char *o = (const unsigned char *)"";
    size_t ol = 0;
    if (m->label) object_name(m->label, m->label_len, &o, &ol);
    if (!rbc_fv_begin_list(&c->b, (const char *)o, ol)) {
        fail(c, NULL, 0, "out of memory or over 2^32 vertices");
        return 0;
    }
    m->started = 1;
    return 1;
}

/* ---- binary ----------------------------------------------------------------- */

typedef struct fbx_prop {
    unsigned char type;
    size_t at;            /* offset of the payload (after type, and after an array's header) */
    size_t len;           /* payload bytes */
    uint32_t count, enc;  /* arrays */
} fbx_prop;

typedef struct fbx_bin {
    fbx_ctx *c;
    int v64;
    size_t sentinel, hdr;
} fbx_bin;

static uint32_t rd32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint64_t rd64(const unsigned char *p) { return (uint64_t)rd32(p) | (uint64_t)rd32(p + 4) << 32; }
static double rdd(const unsigned char *p) {
    uint64_t u = rd64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}
static double rdf(const unsigned char *p) {
    uint32_t u = rd32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return (double)f;
}

/* The numeric value of a scalar property (have = 0 if it is not one). */
static double prop_number(const fbx_ctx *c, const fbx_prop *p, int *have) {
    const unsigned char *q = c->d + p->at;
    *have = 1;
    switch (p->type) {
    case 'Y': return (double)(int16_t)(uint16_t)(q[0] | q[1] << 8);
    case 'C': return q[0] ? 1.0 : 0.0;
    case 'I': return (double)(int32_t)rd32(q);
    case 'L': return (double)(int64_t)rd64(q);
    case 'F': return rdf(q);
    case 'D': return rdd(q);
    default: *have = 0; return 0;
    }
}

/* Appends a Vertices property (an f or d array) to the current list. */
static int bin_vertices(fbx_bin *fb, const fbx_prop *p, const unsigned char *nm, size_t nl) {
    fbx_ctx *c = fb->c;
    nm = NULL; /* messages name the mesh; the text says "Vertices" */
    nl = 0;
    if (p->type != 'd' && p->type != 'f') {
        fail(c, nm, nl, "Vertices is of type '%c', not a double or float array",
             p->type >= 32 && p->type < 127 ? p->type : '?');
        return 0;
    }
    size_t es = p->type == 'd' ? 8 : 4;
    if (p->count % 3) {
        fail(c, nm, nl, "Vertices array of %u values, not a multiple of 3", p->count);
        return 0;
    }
    size_t raw = (size_t)p->count * es;
    const unsigned char *src = c->d + p->at;
    unsigned char *tmp = NULL;
    if (p->enc == 1 && raw > 0) {
        tmp = malloc(raw ? raw : 1);
        if (!tmp) {
            fail(c, nm, nl, "out of memory for a Vertices array of %u values", p->count);
            return 0;
        }
        uLongf got = (uLongf)raw;
        int zr = uncompress(tmp, &got, src, (uLong)p->len);
        if (zr != Z_OK || got != raw) {
            fail(c, nm, nl, "Vertices array at byte %zu: zlib data %s (%s)", p->at,
                 zr == Z_OK ? "decompresses to fewer bytes than its length" : "is corrupt",
                 zr == Z_BUF_ERROR ? "more data than its length, or cut short"
                 : zr == Z_DATA_ERROR ? "bad deflate stream"
                 : zr == Z_MEM_ERROR ? "out of memory" : zr == Z_OK ? "short" : "error");
            free(tmp);
            return 0;
        }
        src = tmp;
    }
    if (!rbc_fv_reserve(&c->b, p->count)) {
        free(tmp);
        fail(c, nm, nl, "out of memory for a Vertices array of %u values", p->count);
        return 0;
    }
    double *dst = c->b.xyz + c->b.n;
    for (uint32_t i = 0; i < p->count; ++i) dst[i] = es == 8 ? rdd(src + 8 * (size_t)i) : rdf(src + 4 * (size_t)i);
    c->b.n += p->count;
    free(tmp);
    if (c->b.n / 3 > UINT32_MAX) {
        fail(c, nm, nl, "over 2^32 vertices");
        return 0;
    }
    return 1;
}

#define MAX_KEPT_PROPS 8

/* One node record at *pos, which must end by limit. Returns 1 parsed (*pos past it),
 * 2 a null record (*pos past its end-offset field), 0 failed. */
static int bin_node(fbx_bin *fb, size_t *pos, size_t limit, int parent_kind) {
    fbx_ctx *c = fb->c;
    const unsigned char *d = c->d;
    size_t at = *pos, size = c->size;
    size_t of = fb->v64 ? 8 : 4;
    if (limit - at < of) {
        fail(c, NULL, 0, "truncated at byte %zu: a node record is cut short", size < limit ? size : limit);
        return 0;
    }
    uint64_t end = fb->v64 ? rd64(d + at) : rd32(d + at);
    if (end == 0) {
        *pos = at + of;
        return 2;
    }
    if (limit - at < fb->hdr) {
        fail(c, NULL, 0, "truncated at byte %zu: a node record header is cut short", limit);
        return 0;
    }
    uint64_t nprops = fb->v64 ? rd64(d + at + 8) : rd32(d + at + 4);
    uint64_t plen = fb->v64 ? rd64(d + at + 16) : rd32(d + at + 8);
    size_t nl = d[at + fb->hdr - 1];
    const unsigned char *nm = d + at + fb->hdr;
    if (nl > limit - at - fb->hdr) {
        fail(c, NULL, 0, "truncated at byte %zu: a node name is cut short", limit);
        return 0;
    }
    if (end > size) {
        fail(c, nm, nl, "ends at byte %llu, past the end of the file (%zu bytes): truncated",
             (unsigned long long)end, size);
        return 0;
    }
    if (end > limit || end < at + fb->hdr + nl) {
        fail(c, nm, nl, "end offset %llu outside its parent (bytes %zu to %zu)",
             (unsigned long long)end, at, limit);
        return 0;
    }
    size_t ps = at + fb->hdr + nl;
    if (plen > end - ps) {
        fail(c, nm, nl, "property list of %llu bytes runs past the node's end at byte %llu",
             (unsigned long long)plen, (unsigned long long)end);
        return 0;
    }
    size_t pe = ps + (size_t)plen;
    fbx_prop kept[MAX_KEPT_PROPS];
    size_t nkept = 0;
    size_t q = ps;
    for (uint64_t i = 0; i < nprops; ++i) {
        if (q >= pe) {
            fail(c, nm, nl, "property %llu of %llu at byte %zu: past the property list's end",
                 (unsigned long long)i, (unsigned long long)nprops, q);
            return 0;
        }
        fbx_prop p;
        memset(&p, 0, sizeof p);
        p.type = d[q++];
        size_t fixed = 0, es = 0;
        switch (p.type) {
        case 'Y': fixed = 2; break;
        case 'C': fixed = 1; break;
        case 'I': case 'F': fixed = 4; break;
        case 'D': case 'L': fixed = 8; break;
        case 'S': case 'R': break;
        case 'f': case 'i': es = 4; break;
        case 'd': case 'l': es = 8; break;
        case 'b': case 'c': es = 1; break;
        default:
            fail(c, nm, nl, "property %llu at byte %zu: unknown type byte 0x%02x",
                 (unsigned long long)i, q - 1, p.type);
            return 0;
        }
        if (fixed) {
            if (pe - q < fixed) goto short_prop;
            p.at = q;
            p.len = fixed;
        } else if (p.type == 'S' || p.type == 'R') {
            if (pe - q < 4) goto short_prop;
            uint32_t l = rd32(d + q);
            q += 4;
            if (l > pe - q) goto short_prop;
            p.at = q;
            p.len = l;
        } else {
            if (pe - q < 12) goto short_prop;
            p.count = rd32(d + q);
            p.enc = rd32(d + q + 4);
            uint32_t l = rd32(d + q + 8);
            q += 12;
            if (l > pe - q) goto short_prop;
            p.at = q;
            p.len = l;
            uint64_t raw = (uint64_t)p.count * es;
            if (p.enc == 0) {
                if (raw != l) {
                    fail(c, nm, nl, "array property at byte %zu: %u values of %zu bytes in %u bytes",
                         q - 13, p.count, es, l);
                    return 0;
                }
            } else if (p.enc == 1) {
                if (raw > (uint64_t)l * RBC_ZLIB_MAX_RATIO + 64) {
                    fail(c, nm, nl, "array property at byte %zu: %u values cannot come from %u "
                         "zlib bytes (absurd length)", q - 13, p.count, l);
                    return 0;
                }
            } else {
                fail(c, nm, nl, "array property at byte %zu: unknown encoding %u", q - 13, p.enc);
                return 0;
            }
        }
        q = p.at + p.len;
        if (nkept < MAX_KEPT_PROPS) kept[nkept++] = p;
        continue;
    short_prop:
        fail(c, nm, nl, "property %llu ('%c') truncated at byte %zu", (unsigned long long)i,
             p.type, pe);
        return 0;
    }
    if (q != pe) {
        fail(c, nm, nl, "properties end at byte %zu, the property list at byte %zu", q, pe);
        return 0;
    }

    /* What this node is: its first two string properties. */
    const fbx_prop *s0 = NULL, *s1 = NULL;
    for (size_t i = 0; i < nkept; ++i)
        if (kept[i].type == 'S') {
            if (!s0) s0 = &kept[i];
            else if (!s1) { s1 = &kept[i]; break; }
        }
    int kind = child_kind(parent_kind, nm, nl, s1 ? d + s1->at : NULL, s1 ? s1->len : 0);
    if (c->depth >= RBC_FBX_MAX_DEPTH) {
        fail(c, nm, nl, "nested deeper than %d levels", RBC_FBX_MAX_DEPTH);
        return 0;
    }
    fbx_frame *f = &c->stack[++c->depth];
    memset(f, 0, sizeof *f);
    f->kind = kind;
    f->name = nm;
    f->name_len = nl;
    if (kind == K_MESH) {
        if (s0) {
            f->label = d + s0->at;
            f->label_len = s0->len;
            const unsigned char *o;
            size_t ol;
            object_name(f->label, f->label_len, &o, &ol);
            f->label = o;
            f->label_len = ol;
        }
        f->is_geometry = name_is(nm, nl, "Geometry");
        if (f->is_geometry && !mesh_begin(c, f)) return 0;
    } else if (kind == K_PROP) {
        double v = 0;
        int have = 0;
        for (size_t i = 0; i < nkept && !have; ++i) v = prop_number(c, &kept[i], &have);
        set_global(c, s0 ? d + s0->at : NULL, s0 ? s0->len : 0, have, v);
    } else if (kind == K_VERTS) {
        fbx_frame *m = &c->stack[c->depth - 1];
        if (m->got_vertices) {
            fail(c, NULL, 0, "a second Vertices node");
            return 0;
        }
        m->got_vertices = 1;
        if (!nkept) {
            fail(c, NULL, 0, "Vertices without a value");
            return 0;
        }
        if (!mesh_begin(c, m)) return 0;
        c->depth--; /* messages name the mesh and "Vertices" */
        int ok = bin_vertices(fb, &kept[0], nm, nl);
        c->depth++;
        if (!ok) return 0;
    }

    /* Children, then the null record that ends them (as parse_fbx.py reads them). */
    size_t cp = pe;
    if (cp < end) {
        if (end - cp < fb->sentinel) {
            fail(c, NULL, 0, "%llu bytes after the properties, too few for a null record",
                 (unsigned long long)(end - cp));
            return 0;
        }
        while (cp < end - fb->sentinel) {
            int r = bin_node(fb, &cp, end - fb->sentinel, kind);
            if (r == 0) return 0;
            if (r == 2) {
                fail(c, NULL, 0, "a null record at byte %zu before the end of its children",
                     cp - of);
                return 0;
            }
        }
        for (size_t i = 0; i < fb->sentinel; ++i)
            if (d[cp + i]) {
                fail(c, NULL, 0, "children do not end with a null record at byte %zu", cp);
                return 0;
            }
        cp += fb->sentinel;
    }
    if (cp != end) {
        fail(c, NULL, 0, "contents end at byte %zu, the node at byte %llu", cp,
             (unsigned long long)end);
        return 0;
    }
    c->depth--;
    *pos = cp;
    return 1;
}

static int read_binary(fbx_ctx *c) {
    fbx_bin fb;
    if (c->size < 27) {
        fail(c, NULL, 0, "truncated at byte %zu: the header is 27 bytes", c->size);
        return 0;
    }
    uint32_t version = rd32(c->d + 23);
    fb.c = c;
    fb.v64 = version >= 7500;
    fb.sentinel = fb.v64 ? 25 : 13;
    fb.hdr = fb.v64 ? 25 : 13;
    size_t pos = 27;
    for (;;) {
        if (pos >= c->size) {
            fail(c, NULL, 0, "truncated at byte %zu: the top level has no end record", c->size);
            return 0;
        }
        int r = bin_node(&fb, &pos, c->size, K_TOP);
        if (r == 0) return 0;
        if (r == 2) break;
    }
    return 1;
}

/* ---- ASCII ------------------------------------------------------------------ */

enum { T_EOF, T_KEY, T_DATA, T_STRING, T_OPEN, T_CLOSE, T_COMMA, T_ERROR };

typedef struct fbx_tok {
    int type;
    const unsigned char *s; /* T_KEY without the ':'; T_STRING without the quotes */
    size_t n;
    size_t line;
} fbx_tok;

typedef struct fbx_lex {
    const unsigned char *p, *end;
    size_t line;
} fbx_lex;

static int is_space(unsigned char ch) { return ch == ' ' || ch == '\t' || ch == '\r' || ch == '\n'; }

static fbx_tok next_tok(fbx_lex *lx) {
    fbx_tok t;
    memset(&t, 0, sizeof t);
    for (;;) {
        while (lx->p < lx->end && is_space(*lx->p)) {
            if (*lx->p == '\n') lx->line++;
            lx->p++;
        }
        if (lx->p < lx->end && *lx->p == ';') {
            while (lx->p < lx->end && *lx->p != '\n') lx->p++;
            continue;
        }
        break;
    }
    t.line = lx->line;
    if (lx->p >= lx->end) {
        t.type = T_EOF;
        return t;
    }
    unsigned char ch = *lx->p;
    if (ch == '{' || ch == '}' || ch == ',') {
        t.type = ch == '{' ? T_OPEN : ch == '}' ? T_CLOSE : T_COMMA;
        t.s = lx->p++;
        t.n = 1;
        return t;
    }
    if (ch == '"') {
        const unsigned char *s = ++lx->p;
        while (lx->p < lx->end && *lx->p != '"') {
            if (*lx->p == '\n') lx->line++;
            lx->p++;
        }
        if (lx->p >= lx->end) {
            t.type = T_ERROR;
            return t;
        }
        t.type = T_STRING;
        t.s = s;
        t.n = (size_t)(lx->p - s);
        lx->p++;
        return t;
    }
    const unsigned char *s = lx->p;
    while (lx->p < lx->end && !is_space(*lx->p) && *lx->p != ',' && *lx->p != '{' &&
           *lx->p != '}' && *lx->p != '"' && *lx->p != ';' && *lx->p != ':')
        lx->p++;
    t.s = s;
    t.n = (size_t)(lx->p - s);
    if (lx->p < lx->end && *lx->p == ':') {
        lx->p++;
        t.type = T_KEY;
    } else if (t.n == 0) { /* a stray ':' cannot happen: it ends a key */
        t.type = T_ERROR;
        lx->p++;
    } else {
        t.type = T_DATA;
    }
    return t;
}

/* A number token, whole. strtod reads the file's buffer, which ends in a NUL; a
 * token ends at a separator (white space , { } " ; :), none of which continues a
 * number, so strtod stops at the token's end or before it. */
static int tok_number(const fbx_tok *t, double *v) {
    if (t->n == 0) return 0;
    char *e;
    *v = strtod((const char *)t->s, &e);
    return (const unsigned char *)e == t->s + t->n;
}

/* The element whose key was read and whose values are being read. */
typedef struct fbx_elem {
    int open; /* a key is pending */
    const unsigned char *name;
    size_t name_len;
    size_t line;
    int kind_hint; /* K_VERTS / K_VERTS_A known at the key: values go to the list */
    fbx_tok str[2];
    int nstr;
    double num;
    int have_num;
    long long star; /* "*N" */
    size_t values;  /* numbers appended (K_VERTS, K_VERTS_A) */
    size_t first;   /* b.n at the key */
} fbx_elem;

static void afail(fbx_ctx *c, size_t line, const char *fmt, ...) {
    if (c->failed) return;
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    char tmp[480];
    snprintf(tmp, sizeof tmp, "line %zu: %s", line, msg);
    fail(c, NULL, 0, "%s", tmp);
}

/* Ends a K_VERTS or K_VERTS_A element's values: a multiple of 3, as many as "*N". */
static int end_values(fbx_ctx *c, fbx_elem *e, long long declared) {
    if (declared >= 0 && (long long)e->values != declared) {
        afail(c, e->line, "Vertices declares *%lld values and holds %zu", declared, e->values);
        return 0;
    }
    if (e->values % 3) {
        afail(c, e->line, "Vertices holds %zu values, not a multiple of 3", e->values);
        return 0;
    }
    return 1;
}

/* The element's key and values are complete (a '{', a '}' or the next key follows):
 * handle what it says. With_children: a '{' follows, push its frame. */
static int finish_elem(fbx_ctx *c, fbx_elem *e, int with_children) {
    if (!e->open) return 1;
    e->open = 0;
    int parent = c->stack[c->depth].kind;
    int kind = child_kind(parent, e->name, e->name_len, e->nstr > 1 ? e->str[1].s : NULL,
                          e->nstr > 1 ? e->str[1].n : 0);
    if (kind == K_PROP) set_global(c, e->nstr ? e->str[0].s : NULL, e->nstr ? e->str[0].n : 0, e->have_num, e->num);
    if (kind == K_VERTS && !with_children && !end_values(c, e, -1)) return 0;
    if (kind == K_VERTS_A && !end_values(c, e, -1)) return 0;
    if (kind == K_VERTS_A) c->stack[c->depth].first += e->values; /* counted in the frame */
    if (!with_children) return 1;
    if (c->depth >= RBC_FBX_MAX_DEPTH) {
        afail(c, e->line, "nested deeper than %d levels", RBC_FBX_MAX_DEPTH);
        return 0;
    }
    fbx_frame *f = &c->stack[++c->depth];
    memset(f, 0, sizeof *f);
    f->kind = kind;
    f->name = e->name;
    f->name_len = e->name_len;
    f->declared = -1;
    if (kind == K_MESH) {
        if (e->nstr) {
            object_name(e->str[0].s, e->str[0].n, &f->label, &f->label_len);
        }
        f->is_geometry = name_is(e->name, e->name_len, "Geometry");
        if (f->is_geometry && !mesh_begin(c, f)) return 0;
    } else if (kind == K_VERTS) {
        f->declared = e->star;
        f->first = e->values; /* FBX 6 values before a '{' (none in practice) */
    }
    return 1;
}

static int read_ascii(fbx_ctx *c) {
    fbx_lex lx = {c->d, c->d + c->size, 1};
    if (c->size >= 3 && c->d[0] == 0xEF && c->d[1] == 0xBB && c->d[2] == 0xBF) lx.p += 3;
    fbx_elem e;
    memset(&e, 0, sizeof e);
    c->stack[0].kind = K_TOP;
    int objects_closed = 0;
    for (;;) {
        fbx_tok t = next_tok(&lx);
        if (c->failed) return 0;
        switch (t.type) {
        case T_ERROR:
            afail(c, t.line, "an unterminated string or a stray character");
            return 0;
        case T_EOF:
            if (!finish_elem(c, &e, 0)) return 0;
            if (c->depth > 0) {
                afail(c, t.line, "truncated: %d scopes still open at the end of the file", c->depth);
                return 0;
            }
            if (!objects_closed) {
                /* Every FBX has one; without it, a file cut short between two
                 * top-level scopes would read as a file without meshes. */
                afail(c, t.line, "no Objects section (truncated?)");
                return 0;
            }
            return 1;
        case T_KEY: {
            if (!finish_elem(c, &e, 0)) return 0;
            memset(&e, 0, sizeof e);
            e.open = 1;
            e.name = t.s;
            e.name_len = t.n;
            e.line = t.line;
            e.star = -1;
            e.first = c->b.n;
            int parent = c->stack[c->depth].kind;
            int k = child_kind(parent, t.s, t.n, NULL, 0);
            if (k == K_VERTS) {
                fbx_frame *m = &c->stack[c->depth];
                if (m->got_vertices) {
                    afail(c, t.line, "a second Vertices node");
                    return 0;
                }
                m->got_vertices = 1;
                if (!mesh_begin(c, m)) return 0;
                e.kind_hint = K_VERTS;
            } else if (k == K_VERTS_A) {
                e.kind_hint = K_VERTS_A;
            }
            break;
        }
        case T_COMMA:
            break;
        case T_STRING:
        case T_DATA: {
            if (!e.open) {
                afail(c, t.line, "a value without a key");
                return 0;
            }
            if (e.kind_hint) {
                if (t.type == T_DATA && t.n > 1 && t.s[0] == '*' && e.kind_hint == K_VERTS && e.values == 0 && e.star < 0) {
                    char *x;
                    char buf[32];
                    size_t l = t.n - 1 < sizeof buf - 1 ? t.n - 1 : sizeof buf - 1;
                    memcpy(buf, t.s + 1, l);
                    buf[l] = 0;
                    long long v = strtoll(buf, &x, 10);
                    if (*x || v < 0 || t.n - 1 >= sizeof buf) {
                        afail(c, t.line, "Vertices: bad array length '*%.*s'", (int)(t.n > 20 ? 20 : t.n - 1), t.s + 1);
                        return 0;
                    }
                    e.star = v;
                    break;
                }
                double v;
                if (t.type != T_DATA || !tok_number(&t, &v)) {
                    char shown[48];
                    clean_copy(shown, sizeof shown, t.s, t.n, 24);
                    afail(c, t.line, "Vertices: '%s' is not a number", shown);
                    return 0;
                }
                if (!rbc_fv_reserve(&c->b, 1)) {
                    afail(c, t.line, "out of memory");
                    return 0;
                }
                c->b.xyz[c->b.n++] = v;
                e.values++;
                if (c->b.n / 3 > UINT32_MAX) {
                    afail(c, t.line, "over 2^32 vertices");
                    return 0;
                }
                break;
            }
            if (t.type == T_STRING) {
                if (e.nstr < 2) e.str[e.nstr++] = t;
            } else if (!e.have_num) {
                double v;
                if (tok_number(&t, &v)) {
                    e.num = v;
                    e.have_num = 1;
                }
            }
            break;
        }
        case T_OPEN: {
            if (!e.open) {
                afail(c, t.line, "a '{' without a key");
                return 0;
            }
            if (!finish_elem(c, &e, 1)) return 0;
            break;
        }
        case T_CLOSE: {
            if (!finish_elem(c, &e, 0)) return 0;
            if (c->depth == 0) {
                afail(c, t.line, "a '}' that closes nothing");
                return 0;
            }
            fbx_frame *f = &c->stack[c->depth];
            if (f->kind == K_OBJECTS) objects_closed = 1;
            if (f->kind == K_VERTS) {
                /* FBX 7: "*N { a: ... }"; f->first counted the values of its a:. */
                fbx_elem tot;
                memset(&tot, 0, sizeof tot);
                tot.values = f->first;
                tot.line = t.line;
                if (!end_values(c, &tot, f->declared)) return 0;
            }
            c->depth--;
            memset(&e, 0, sizeof e);
            break;
        }
        }
    }
}

/* ---- entry ------------------------------------------------------------------ */

static const unsigned char k_magic[23] = "Kaydara FBX Binary  \0\x1a";

/* An ASCII FBX: after a BOM, white space and comments, "; FBX" began a comment, or
 * the first key is FBXHeaderExtension. */
static int looks_ascii_fbx(const unsigned char *d, size_t n) {
    size_t i = 0;
    if (n >= 3 && d[0] == 0xEF && d[1] == 0xBB && d[2] == 0xBF) i = 3;
    for (;;) {
        while (i < n && is_space(d[i])) i++;
        if (i < n && d[i] == ';') {
            size_t j = i + 1;
            while (j < n && d[j] == ' ') j++;
            if (n - j >= 3 && memcmp(d + j, "FBX", 3) == 0) return 1;
            while (i < n && d[i] != '\n') i++;
            continue;
        }
        break;
    }
    static const char key[] = "FBXHeaderExtension";
    size_t kl = sizeof key - 1;
    if (n - i > kl && memcmp(d + i, key, kl) == 0) {
        size_t j = i + kl;
        while (j < n && (d[j] == ' ' || d[j] == '\t')) j++;
        return j < n && d[j] == ':';
    }
    return 0;
}

int rbc_fbx_file_vertices(const char *path, rbc_file_vertices *out, char *err, size_t errcap) {
    memset(out, 0, sizeof *out);
    if (err && errcap) err[0] = 0;
    unsigned char *data;
    size_t size;
    if (!rbc_fv_read_file(path, &data, &size)) {
        if (err && errcap) snprintf(err, errcap, "FBX: cannot read the file: %s", strerror(errno));
        return -1;
    }
    int binary = 0;
    if (size >= 23 && memcmp(data, k_magic, 23) == 0) {
        binary = 1;
    } else if (size >= 18 && memcmp(data, k_magic, 18) == 0) {
        free(data);
        if (err && errcap)
            snprintf(err, errcap, "FBX: binary header damaged: bytes 18 to 22 are not \"  \\0\\x1a\\0\" "
                     "(the file was converted as text?)");
        return -1;
    } else if (size > 0 && size < 23 && memcmp(data, k_magic, size) == 0) {
        binary = 1; /* a cut-short header */
    } else if (!looks_ascii_fbx(data, size)) {
        free(data);
        return 0;
    }
    fbx_ctx *c = calloc(1, sizeof *c);
    if (!c) {
        free(data);
        if (err && errcap) snprintf(err, errcap, "FBX: out of memory");
        return -1;
    }
    c->d = data;
    c->size = size;
    c->err = err;
    c->errcap = errcap;
    c->up = -1;
    c->stack[0].kind = K_TOP;
    int ok = binary ? read_binary(c) : read_ascii(c);
    if (ok && !rbc_fv_finish(&c->b, out)) {
        fail(c, NULL, 0, "out of memory or over 2^32 vertices");
        ok = 0;
    }
    if (ok) {
        out->unit_metres = (c->have_usf && isfinite(c->usf) && c->usf > 0) ? c->usf / 100.0 : 0.0;
        out->up_axis = c->up;
    } else {
        if (!c->failed && err && errcap) snprintf(err, errcap, "FBX: unreadable");
        rbc_fv_builder_free(&c->b);
        memset(out, 0, sizeof *out);
    }
    free(c);
    free(data);
    return ok ? 1 : -1;
}
