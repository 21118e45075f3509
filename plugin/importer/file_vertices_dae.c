/* file_vertices_dae.c -- a Collada file's <mesh> position lists in file order
 * (file_vertices.h).
 *
 * COLLADA 1.4/1.5: each <library_geometries>/<geometry>/<mesh> has one <vertices>
 * whose <input semantic="POSITION" source="#id"/> names a <source>; that source's
 * <technique_common><accessor source="#array" count stride offset> reads its
 * <float_array>: element i is values[offset + i*stride + k] for the accessor's
 * <param>s in order (a param without a name is skipped, as the specification says);
 * the first three named params are x, y, z. Elements are matched by local name
 * (either namespace). <asset><unit meter> and <asset><up_axis> of the root's asset.
 *
 * libxml2 reads the file with network access off (XML_PARSE_NONET), no DTD loading
 * and no entity substitution (no XML_PARSE_NOENT, XML_PARSE_DTDLOAD): an external
 * entity is never fetched (XXE); a document that declares entities at all is
 * refused (Collada needs none, and xmlNodeGetContent would expand internal ones);
 * libxml2's default limits stay on (no XML_PARSE_HUGE: depth 256; a float_array's
 * text is not limited by them: 44 MB, 2 million vertices, reads in 1.2 s). Its messages go to a handler that keeps the first
 * one for our error; nothing is printed. A file is Collada ("not this format"
 * otherwise) if "<COLLADA" (UTF-8 or UTF-16) is in its first 64 KiB and, once
 * parsed, its root element is COLLADA. */
#include "file_vertices.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <libxml/parser.h>
#include <libxml/tree.h>
#include <libxml/xmlerror.h>

typedef struct dae_ctx {
    char *err;
    size_t errcap;
    int failed;
    rbc_fv_builder b;
} dae_ctx;

static void dfail(dae_ctx *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void dfail(dae_ctx *c, const char *fmt, ...) {
    if (c->failed) return;
    c->failed = 1;
    if (!c->err || !c->errcap) return;
    char msg[600];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (char *p = msg; *p; ++p)
        if ((unsigned char)*p < 32) *p = ' ';
    snprintf(c->err, c->errcap, "Collada: %s", msg);
}

static int is_el(const xmlNode *n, const char *name) {
    return n && n->type == XML_ELEMENT_NODE && n->name && strcmp((const char *)n->name, name) == 0;
}

static const xmlNode *child_el(const xmlNode *n, const char *name) {
    for (const xmlNode *k = n ? n->children : NULL; k; k = k->next)
        if (is_el(k, name)) return k;
    return NULL;
}

/* An attribute's value, copied into buf (truncated), or NULL if absent. */
static const char *attr(const xmlNode *n, const char *name, char *buf, size_t cap) {
    xmlChar *v = xmlGetNoNsProp(n, (const xmlChar *)name);
    if (!v) return NULL;
    snprintf(buf, cap, "%s", (const char *)v);
    xmlFree(v);
    return buf;
}

/* A printable copy for messages. */
static const char *shown(const char *s, char *buf, size_t cap) {
    size_t k = 0;
    for (; s && *s && k + 1 < cap && k < 40; ++s)
        buf[k++] = ((unsigned char)*s >= 32 && (unsigned char)*s < 127) ? *s : '?';
    buf[k] = 0;
    return buf;
}

/* The element under root whose id is id (iterative, document order). */
static const xmlNode *find_id(const xmlNode *root, const char *id) {
    const xmlNode *n = root;
    while (n) {
        if (n->type == XML_ELEMENT_NODE) {
            xmlChar *v = xmlGetNoNsProp(n, (const xmlChar *)"id");
            int hit = v && strcmp((const char *)v, id) == 0;
            xmlFree(v);
            if (hit) return n;
        }
        if (n->children && n->type == XML_ELEMENT_NODE) {
            n = n->children;
            continue;
        }
        while (n && n != root && !n->next) n = n->parent;
        if (!n || n == root) return NULL;
        n = n->next;
    }
    return NULL;
}

/* "#id" resolved in scope first (the mesh), then the whole document. */
static const xmlNode *resolve(const xmlNode *scope, const xmlNode *doc_root, const char *ref) {
    if (!ref || ref[0] != '#' || !ref[1]) return NULL;
    const xmlNode *n = find_id(scope, ref + 1);
    return n ? n : find_id(doc_root, ref + 1);
}

static int parse_count(const char *s, unsigned long long *v) {
    if (!s) return 0;
    while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r') s++;
    if (*s < '0' || *s > '9') return 0;
    char *e;
    errno = 0;
    *v = strtoull(s, &e, 10);
    while (*e == ' ' || *e == '\t' || *e == '\n' || *e == '\r') e++;
    return !*e && errno == 0;
}

/* The last c in the n bytes at s (memrchr is a GNU extension). */
static const void *memrchr_compat(const char *s, char c, size_t n) {
    while (n--)
        if (s[n] == c) return s + n;
    return NULL;
}

/* The whitespace-separated numbers of a float_array: *vals malloc'd, *n of them. */
static int parse_floats(dae_ctx *c, const xmlNode *fa, const char *gname, double **vals, size_t *n) {
    *vals = NULL;
    *n = 0;
    xmlChar *text = xmlNodeGetContent(fa);
    if (!text) return 1;
    size_t cap = 0;
    const char *p = (const char *)text;
    char nb[64];
    for (;;) {
        while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r') p++;
        if (!*p) break;
        char *e;
        double v = strtod(p, &e);
        if (*e == ',') {
            /* A decimal comma ("21,920870": 3ds Max exporters under some locales),
             * which assimp's Collada parser reads as a point: so do we. */
            char tmp[128];
            size_t k = 0;
            while (p[k] && p[k] != ' ' && p[k] != '\t' && p[k] != '\n' && p[k] != '\r' && k + 1 < sizeof tmp) {
                tmp[k] = p[k] == ',' ? '.' : p[k];
                k++;
            }
            tmp[k] = 0;
            char *te;
            double w = strtod(tmp, &te);
            if (te == tmp + k && !memchr(p, '.', k) && memchr(p, ',', k) == memrchr_compat(p, ',', k)) {
                v = w;
                e = (char *)p + k;
            }
        }
        if (e == p || (*e && *e != ' ' && *e != '\t' && *e != '\n' && *e != '\r')) {
            char tok[48];
            size_t k = 0;
            while (p[k] && p[k] != ' ' && p[k] != '\t' && p[k] != '\n' && p[k] != '\r' && k < 24) {
                tok[k] = p[k];
                k++;
            }
            tok[k] = 0;
            dfail(c, "geometry '%s': float_array value %zu '%s' is not a number", shown(gname, nb, sizeof nb),
                  *n, shown(tok, tok, sizeof tok));
            xmlFree(text);
            free(*vals);
            *vals = NULL;
            return 0;
        }
        if (*n == cap) {
            size_t nc = cap ? 2 * cap : 256;
            double *q = realloc(*vals, nc * sizeof *q);
            if (!q) {
                dfail(c, "out of memory");
                xmlFree(text);
                free(*vals);
                *vals = NULL;
                return 0;
            }
            *vals = q;
            cap = nc;
        }
        (*vals)[(*n)++] = v;
        p = e;
    }
    xmlFree(text);
    return 1;
}

/* One <mesh>: its POSITION source through its accessor, appended as a list. */
static int read_mesh(dae_ctx *c, const xmlNode *root, const xmlNode *geom, const xmlNode *mesh) {
    char gname[256] = "", gid[128] = "", buf[256], nb[64], nb2[64];
    if (!attr(geom, "name", gname, sizeof gname)) gname[0] = 0; /* for messages */
    if (!attr(geom, "id", gid, sizeof gid)) gid[0] = 0;
    const char *label = gname[0] ? gname : gid;
    xmlChar *full = xmlGetNoNsProp(geom, (const xmlChar *)"name"); /* the name, whole */
    int begun = rbc_fv_begin_list(&c->b, full ? (const char *)full : "", full ? strlen((const char *)full) : 0);
    xmlFree(full);
    if (!begun) {
        dfail(c, "out of memory or over 2^32 vertices");
        return 0;
    }
    const xmlNode *verts = child_el(mesh, "vertices");
    if (!verts) {
        dfail(c, "geometry '%s': <mesh> without <vertices>", shown(label, nb, sizeof nb));
        return 0;
    }
    const char *ref = NULL;
    for (const xmlNode *k = verts->children; k; k = k->next)
        if (is_el(k, "input") && attr(k, "semantic", buf, sizeof buf) && strcmp(buf, "POSITION") == 0) {
            ref = attr(k, "source", buf, sizeof buf);
            break;
        }
    if (!ref) {
        dfail(c, "geometry '%s': <vertices> without a POSITION input", shown(label, nb, sizeof nb));
        return 0;
    }
    const xmlNode *src = resolve(mesh, root, ref);
    if (!is_el(src, "source")) {
        dfail(c, "geometry '%s': POSITION source '%s' %s", shown(label, nb, sizeof nb),
              shown(ref, nb2, sizeof nb2), src ? "is not a <source>" : "not found");
        return 0;
    }
    const xmlNode *acc = child_el(child_el(src, "technique_common"), "accessor");
    if (!acc) {
        dfail(c, "geometry '%s': source '%s' has no technique_common/accessor",
              shown(label, nb, sizeof nb), shown(ref, nb2, sizeof nb2));
        return 0;
    }
    unsigned long long count = 0, stride = 1, offset = 0;
    if (!parse_count(attr(acc, "count", buf, sizeof buf), &count)) {
        dfail(c, "geometry '%s': accessor count missing or not a number", shown(label, nb, sizeof nb));
        return 0;
    }
    if (attr(acc, "stride", buf, sizeof buf) && (!parse_count(buf, &stride) || stride == 0)) {
        dfail(c, "geometry '%s': accessor stride '%s' is not a positive number",
              shown(label, nb, sizeof nb), shown(buf, nb2, sizeof nb2));
        return 0;
    }
    if (attr(acc, "offset", buf, sizeof buf) && !parse_count(buf, &offset)) {
        dfail(c, "geometry '%s': accessor offset '%s' is not a number", shown(label, nb, sizeof nb),
              shown(buf, nb2, sizeof nb2));
        return 0;
    }
    /* Components: the first three named params (unnamed ones are skipped); no
     * params at all: the first three of each stride. */
    unsigned long long comp[3];
    int ncomp = 0, nparams = 0;
    for (const xmlNode *k = acc->children; k; k = k->next)
        if (is_el(k, "param")) {
            char pn[16];
            const char *nm = attr(k, "name", pn, sizeof pn);
            if (nm && nm[0] && ncomp < 3) comp[ncomp++] = (unsigned long long)nparams;
            nparams++;
        }
    if (nparams == 0) {
        for (int i = 0; i < 3; ++i) comp[i] = (unsigned long long)i;
        ncomp = 3;
    }
    if (ncomp < 3 || comp[2] >= stride) {
        dfail(c, "geometry '%s': position accessor has %s (stride %llu)", shown(label, nb, sizeof nb),
              ncomp < 3 ? "fewer than 3 named params" : "params past its stride", stride);
        return 0;
    }
    const char *aref = attr(acc, "source", buf, sizeof buf);
    const xmlNode *fa = aref ? resolve(src, root, aref) : child_el(src, "float_array");
    if (!is_el(fa, "float_array")) {
        dfail(c, "geometry '%s': accessor source '%s' %s", shown(label, nb, sizeof nb),
              aref ? shown(aref, nb2, sizeof nb2) : "(none)", fa ? "is not a <float_array>" : "not found");
        return 0;
    }
    double *vals;
    size_t n;
    if (!parse_floats(c, fa, label, &vals, &n)) return 0;
    unsigned long long declared;
    if (parse_count(attr(fa, "count", buf, sizeof buf), &declared) && declared != n) {
        dfail(c, "geometry '%s': float_array declares count %llu and holds %zu values",
              shown(label, nb, sizeof nb), declared, n);
        free(vals);
        return 0;
    }
    /* The last value read: offset + (count-1) stride + comp[2] < n, overflow-safe. */
    if (count > 0) {
        unsigned long long last = comp[2];
        int ok = offset < n && count - 1 <= (n - offset) / stride;
        if (ok) {
            last += offset + (count - 1) * stride;
            ok = last < n;
        }
        if (!ok) {
            dfail(c, "geometry '%s': accessor of %llu elements (stride %llu, offset %llu) reads past "
                  "its float_array of %zu values", shown(label, nb, sizeof nb), count, stride, offset, n);
            free(vals);
            return 0;
        }
    }
    if (count > UINT32_MAX || !rbc_fv_reserve(&c->b, (size_t)count * 3) ||
        c->b.n / 3 + count > UINT32_MAX) {
        dfail(c, "out of memory or over 2^32 vertices");
        free(vals);
        return 0;
    }
    for (unsigned long long i = 0; i < count; ++i)
        for (int k = 0; k < 3; ++k) c->b.xyz[c->b.n++] = vals[offset + i * stride + comp[k]];
    free(vals);
    return 1;
}

/* libxml2's messages: the first one kept (for a parse that fails), never printed. */
typedef struct xml_msgs {
    char first[300];
} xml_msgs;

static void on_xml_error(void *ud, xmlErrorPtr e) {
    xml_msgs *m = ud;
    if (!m || m->first[0] || !e || e->level < XML_ERR_ERROR) return;
    snprintf(m->first, sizeof m->first, "line %d: %s", e->line, e->message ? e->message : "error");
    size_t l = strlen(m->first);
    while (l && (m->first[l - 1] == '\n' || m->first[l - 1] == ' ')) m->first[--l] = 0;
    for (char *p = m->first; *p; ++p)
        if ((unsigned char)*p < 32) *p = ' ';
}
static void silent_generic(void *ctx, const char *msg, ...) {
    (void)ctx;
    (void)msg;
}

/* Whether the bytes say Collada at all: a "<COLLADA" (UTF-8 or UTF-16) early on. */
static int mentions_collada(const unsigned char *d, size_t n) {
    size_t lim = n < 65536 ? n : 65536;
    static const char a[] = "<COLLADA";
    for (size_t i = 0; i + 8 <= lim; ++i)
        if (memcmp(d + i, a, 8) == 0) return 1;
    for (size_t i = 0; i + 16 <= lim; ++i) {
        int hit = 1;
        for (size_t k = 0; k < 8 && hit; ++k) {
            unsigned char x = d[i + 2 * k], y = d[i + 2 * k + 1];
            hit = (x == (unsigned char)a[k] && y == 0) || (x == 0 && y == (unsigned char)a[k]);
        }
        if (hit) return 1;
    }
    return 0;
}

int rbc_dae_file_vertices(const char *path, rbc_file_vertices *out, char *err, size_t errcap) {
    memset(out, 0, sizeof *out);
    if (err && errcap) err[0] = 0;
    unsigned char *data;
    size_t size;
    if (!rbc_fv_read_file(path, &data, &size)) {
        if (err && errcap) snprintf(err, errcap, "Collada: cannot read the file: %s", strerror(errno));
        return -1;
    }
    if (!mentions_collada(data, size)) {
        free(data);
        return 0;
    }
    if (size > (size_t)INT32_MAX) {
        free(data);
        if (err && errcap) snprintf(err, errcap, "Collada: file over 2 GiB");
        return -1;
    }
    dae_ctx c;
    memset(&c, 0, sizeof c);
    c.err = err;
    c.errcap = errcap;
    xml_msgs msgs;
    memset(&msgs, 0, sizeof msgs);
    xmlGenericErrorFunc old_generic = xmlGenericError;
    void *old_generic_ctx = xmlGenericErrorContext;
    xmlStructuredErrorFunc old_structured = xmlStructuredError;
    void *old_structured_ctx = xmlStructuredErrorContext;
    xmlSetGenericErrorFunc(NULL, silent_generic);
    xmlParserCtxtPtr px = xmlNewParserCtxt();
    xmlDocPtr doc = NULL;
    if (px) {
        /* libxml2 2.9: without a handler of the context's own, its errors go to the
         * (thread's) structured handler, set for this parse only. */
        xmlSetStructuredErrorFunc(&msgs, on_xml_error);
        doc = xmlCtxtReadMemory(px, (const char *)data, (int)size, path, NULL,
                                XML_PARSE_NONET | XML_PARSE_NOERROR | XML_PARSE_NOWARNING |
                                    XML_PARSE_NOCDATA);
    }
    xmlSetStructuredErrorFunc(old_structured_ctx, old_structured);
    xmlSetGenericErrorFunc(old_generic_ctx, old_generic);
    free(data);
    int ret = 1;
    const xmlNode *root = doc ? xmlDocGetRootElement(doc) : NULL;
    if (!px) {
        dfail(&c, "out of memory");
        ret = -1;
    } else if (!doc) {
        dfail(&c, "not well-formed XML: %s", msgs.first[0] ? msgs.first : "parse failed");
        ret = -1;
    } else if (doc->intSubset && (doc->intSubset->entities || doc->intSubset->pentities)) {
        /* Collada needs no entities; a file that declares some is refused rather than
         * have xmlNodeGetContent expand them (billion laughs) -- external ones are
         * never loaded in any case (no XML_PARSE_NOENT / DTDLOAD, and NONET). */
        dfail(&c, "the file declares XML entities (refused: Collada needs none)");
        ret = -1;
    } else if (!is_el(root, "COLLADA")) {
        ret = 0;
    } else {
        const xmlNode *asset = child_el(root, "asset");
        char buf[64];
        const xmlNode *unit = child_el(asset, "unit");
        if (unit && attr(unit, "meter", buf, sizeof buf)) {
            char *e;
            double m = strtod(buf, &e);
            if (e != buf && isfinite(m) && m > 0) out->unit_metres = m;
        } else if (unit) {
            out->unit_metres = 1.0; /* <unit/> without meter: the schema's default */
        }
        out->up_axis = -1;
        const xmlNode *up = child_el(asset, "up_axis");
        if (up) {
            xmlChar *t = xmlNodeGetContent(up);
            if (t) {
                const char *s = (const char *)t;
                while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r') s++;
                if (s[0] >= 'X' && s[0] <= 'Z' && strncmp(s + 1, "_UP", 3) == 0) out->up_axis = s[0] - 'X';
                xmlFree(t);
            }
        }
        for (const xmlNode *lib = root->children; lib && !c.failed; lib = lib->next) {
            if (!is_el(lib, "library_geometries")) continue;
            for (const xmlNode *g = lib->children; g && !c.failed; g = g->next) {
                if (!is_el(g, "geometry")) continue;
                for (const xmlNode *m = g->children; m && !c.failed; m = m->next)
                    if (is_el(m, "mesh")) read_mesh(&c, root, g, m);
            }
        }
        if (c.failed) ret = -1;
    }
    if (ret == 1) {
        double um = out->unit_metres;
        int ua = out->up_axis;
        if (!rbc_fv_finish(&c.b, out)) {
            dfail(&c, "out of memory or over 2^32 vertices");
            ret = -1;
        } else {
            out->unit_metres = um;
            out->up_axis = ua;
        }
    }
    if (ret != 1) {
        rbc_fv_builder_free(&c.b);
        memset(out, 0, sizeof *out);
    }
    if (doc) xmlFreeDoc(doc);
    if (px) xmlFreeParserCtxt(px);
    return ret;
}
