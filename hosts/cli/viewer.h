/* viewer.h -- look at a simulated clip without other software: a PNG still of a
 * frame (software rasterizer, strain as colour), a self-contained HTML page that
 * plays the clip with WebGL, and an index page for a batch.
 *
 * Use: create, add every cloth and collider, then per frame (in frame order) give
 * each cloth its positions and each collider its pose, then write stills/pages.
 * Every function returns 0 on success and nonzero on failure, with a message in
 * err (when err is not NULL) naming what failed; nothing is printed.
 *
 * Strain colour (still, page and legend alike): per vertex, the largest relative
 * strain |len/L - 1| of the visible mesh edges at it (quad or triangle edges, each
 * once; L from the rest positions, edges with L = 0 skipped), mapped piecewise
 * linearly through the stops 0 light neutral, 2 % pale yellow, 10 % yellow-orange,
 * 30 % orange-red, >= 100 % red (cli_view_strain_colour).
 *
 * The still's camera (the page's with #fit=frame): it looks at the centre c of the
 * bounding box of the frame's cloth vertices from the direction
 * (cos el sin az, sin el, cos el cos az), az = 35 deg, el = 25 deg, y up, vertical
 * field of view 30 deg; its distance d = 1.1 r / sin(min(fov_y, fov_x) / 2) with r
 * the box's half diagonal, so the box's bounding sphere fits the image.
 */
#ifndef RBC_CLI_VIEWER_H
#define RBC_CLI_VIEWER_H

#include <stddef.h>
#include <stdint.h>

typedef struct cli_view cli_view; /* opaque */

typedef struct cli_view_cloth_def {
    const char *name;
    uint32_t vertex_count;
    const float *rest;     /* xyz per vertex: rest positions (strain reference) */
    uint32_t quad_count;   /* faces, 4 indices each (may be 0 if tris given) */
    const uint32_t *quads;
    uint32_t tri_count;    /* optional triangles (imported meshes), 3 indices */
    const uint32_t *tris;
} cli_view_cloth_def;

typedef struct cli_view_collider_def {
    /* An rbc_shape of abi/rbcloth.h: RBC_SHAPE_PLANE (1, the frame's y = 0, normal
     * +y), RBC_SHAPE_SPHERE (2), RBC_SHAPE_CAPSULE (3, axis from (0,-h,0) to (0,h,0),
     * h = half_extents[1]), RBC_SHAPE_BOX (4), RBC_SHAPE_TRIANGLE_MESH (5). */
    int shape;
    float radius;          /* sphere, capsule */
    float half_extents[3]; /* box; capsule uses half_extents[1] as half length along its local y */
    uint32_t mesh_vertex_count;
    const float *mesh_positions; /* triangle mesh, collider frame */
    uint32_t mesh_triangle_count;
    const uint32_t *mesh_triangles;
} cli_view_collider_def;

/* frame_dt: seconds between frames (the scene's dt); frame_count: frames that will
 * be added (at most; fewer may be). */
int cli_view_create(cli_view **out, const char *title, double frame_dt, uint32_t frame_count,
                    char *err, size_t errlen);
/* Budgets, before the first frame (defaults 256 MiB and 48 MiB): the float
 * positions kept in memory over all cloths, and the deflated data the page embeds.
 * Over either, every k-th frame is kept and the page says so. 0 keeps a budget. */
int cli_view_set_budget(cli_view *v, size_t memory_bytes, size_t page_bytes, char *err,
                        size_t errlen);
/* Cloths and colliders, all before the first frame; the def's arrays are copied. */
int cli_view_add_cloth(cli_view *v, const cli_view_cloth_def *def, char *err, size_t errlen);
int cli_view_add_collider(cli_view *v, const cli_view_collider_def *def, char *err,
                          size_t errlen);
/* Per frame, in frame order: each cloth's positions (xyz per vertex, same order as
 * rest) and each collider's pose (position xyz, unit quaternion xyzw), each exactly
 * once per frame, in any order within the frame. Errors: cli_view_last_error. */
int cli_view_frame_cloth(cli_view *v, uint32_t cloth, const float *xyz);
int cli_view_frame_collider(cli_view *v, uint32_t collider, const float pos[3],
                            const float quat[4]);
/* A quad removed (tearing, cuts) from the cloth's next frame on: call it before that
 * frame's cli_view_frame_cloth. A quad is removed once; quads only disappear. */
int cli_view_remove_quad(cli_view *v, uint32_t cloth, uint32_t quad);
/* The same from what rbc_cloth_get_quads reads: the quads that remain, 4 indices
 * each in creation order; every quad of the cloth not among them is removed. */
int cli_view_set_remaining_quads(cli_view *v, uint32_t cloth, const uint32_t *quads,
                                 size_t quad_count, char *err, size_t errlen);
/* Why the last cli_view_frame_cloth, cli_view_frame_collider or cli_view_remove_quad
 * failed ("" if none did). */
const char *cli_view_last_error(const cli_view *v);
/* Frames added so far (complete: every cloth and collider has them). */
uint32_t cli_view_frame_total(const cli_view *v);

/* A still of `frame` (0-based; with frames thinned, the kept frame at or before it).
 * width, height 0: 960 x 720. */
int cli_view_write_png(const cli_view *v, const char *path, uint32_t frame, uint32_t width,
                       uint32_t height, char *err, size_t errlen);
/* The player page (written to path.tmp, then renamed). Its URL hash takes
 * frame=N (show frame N), paused=1, ui=0 (canvas only), fit=frame (the still's
 * camera for the frame shown first; default: the clip's box). For tests, its
 * <div id="status"> carries data-ready (1 once drawn), data-error (webgl, inflate,
 * load), data-frame (frame shown), data-playing, data-frames, data-stride (1 frame
 * kept in data-stride), data-dt, and while playing data-play-start, data-play-frame,
 * data-tick (ms, performance.now()) and data-advanced (frames since play-start);
 * tests/viewer/browser_check.sh checks a page with headless Chromium. */
int cli_view_write_html(const cli_view *v, const char *path, char *err, size_t errlen);
void cli_view_destroy(cli_view *v);

/* Strain to colour (r, g, b in [0, 1]) as the still and the page draw it. */
void cli_view_strain_colour(float strain, float rgb[3]);

typedef struct cli_view_index_entry {
    const char *name, *page_href, *png_href, *status;
} cli_view_index_entry;
/* A batch's index page: one still per job with its name and status, linking to its
 * page. page_href, png_href and status may be NULL. */
int cli_view_write_index(const char *path, const char *title, const cli_view_index_entry *entries,
                         uint32_t count, char *err, size_t errlen);

#endif
