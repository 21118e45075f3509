/* script.c -- see script.h. */
#include "script.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <GLFW/glfw3.h>

int viewer_key_from_name(const char *name) {
    static const struct {
        const char *name;
        int key;
    } named[] = {{"space", GLFW_KEY_SPACE},       {"escape", GLFW_KEY_ESCAPE},
                 {"left", GLFW_KEY_LEFT},         {"right", GLFW_KEY_RIGHT},
                 {"up", GLFW_KEY_UP},             {"down", GLFW_KEY_DOWN},
                 {"pageup", GLFW_KEY_PAGE_UP},    {"pagedown", GLFW_KEY_PAGE_DOWN}};
    for (size_t k = 0; k < sizeof named / sizeof named[0]; ++k)
        if (strcasecmp(name, named[k].name) == 0)
            return named[k].key;
    if (strlen(name) != 1)
        return -1;
    int c = toupper((unsigned char)name[0]);
    if (c >= 'A' && c <= 'Z')
        return GLFW_KEY_A + (c - 'A');
    if (c == '+' || c == '=')
        return GLFW_KEY_EQUAL;
    if (c == '-')
        return GLFW_KEY_MINUS;
    return -1;
}

/* A finite number that is the whole word. */
static int parse_number(const char *word, double *out) {
    if (!word)
        return -1;
    char *end;
    errno = 0;
    double v = strtod(word, &end);
    if (errno || end == word || *end || v != v || v > 1e9 || v < -1e9)
        return -1;
    *out = v;
    return 0;
}

void viewer_script_free(viewer_script *script) {
    for (size_t i = 0; script->events && i < script->count; ++i)
        free(script->events[i].path);
    free(script->events);
    script->events = NULL;
    script->count = 0;
}

int viewer_script_load(const char *path, viewer_script *out, char *err, size_t err_size) {
    memset(out, 0, sizeof *out);
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, err_size, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    size_t capacity = 0;
    char line[4096];
    uint32_t line_no = 0, last_frame = 0;
    int rc = 0;
    while (fgets(line, sizeof line, f)) {
        ++line_no;
        size_t len = strlen(line);
        if (len == sizeof line - 1 && line[len - 1] != '\n') {
            snprintf(err, err_size, "%s:%u: line longer than %zu characters", path, line_no,
                     sizeof line - 2);
            rc = -1;
            break;
        }
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        char *words[6] = {0};
        int n = 0;
        for (char *w = strtok(line, " \t\r\n"); w; w = strtok(NULL, " \t\r\n")) {
            if (n == 5) {
                n = 6;
                break;
            }
            words[n++] = w;
        }
        if (n == 0)
            continue;
        viewer_event e = {.line = line_no};
        double frame;
        if (parse_number(words[0], &frame) || frame < 0 || frame != (double)(uint32_t)frame) {
            snprintf(err, err_size, "%s:%u: '%s' is not a frame number (want FRAME COMMAND ...)",
                     path, line_no, words[0]);
            rc = -1;
            break;
        }
        e.frame = (uint32_t)frame;
        if (out->count && e.frame < last_frame) {
            snprintf(err, err_size, "%s:%u: frame %u comes after frame %u (events must be in frame "
                     "order)", path, line_no, e.frame, last_frame);
            rc = -1;
            break;
        }
        const char *cmd = words[1] ? words[1] : "";
        int want; /* arguments the command takes (DOWN: 2 or 3) */
        if (strcmp(cmd, "down") == 0) {
            e.kind = VIEWER_EVENT_DOWN, want = 2;
            if (n == 5) {
                want = 3;
                if (strcmp(words[4], "left") == 0)
                    e.button = 0;
                else if (strcmp(words[4], "right") == 0)
                    e.button = 1;
                else {
                    snprintf(err, err_size, "%s:%u: down: button '%s' is neither left nor right",
                             path, line_no, words[4]);
                    rc = -1;
                    break;
                }
            }
        } else if (strcmp(cmd, "move") == 0) {
            e.kind = VIEWER_EVENT_MOVE, want = 2;
        } else if (strcmp(cmd, "up") == 0) {
            e.kind = VIEWER_EVENT_UP, want = 0;
        } else if (strcmp(cmd, "key") == 0) {
            e.kind = VIEWER_EVENT_KEY, want = 1;
        } else if (strcmp(cmd, "screenshot") == 0) {
            e.kind = VIEWER_EVENT_SCREENSHOT, want = 1;
        } else if (strcmp(cmd, "state") == 0) {
            e.kind = VIEWER_EVENT_STATE, want = 0;
        } else {
            snprintf(err, err_size, "%s:%u: unknown command '%s' (down, move, up, key, screenshot, "
                     "state)", path, line_no, cmd);
            rc = -1;
            break;
        }
        if (n - 2 != want) {
            snprintf(err, err_size, "%s:%u: %s takes %s, not %d argument%s", path, line_no, cmd,
                     e.kind == VIEWER_EVENT_DOWN ? "X Y [left|right]"
                     : e.kind == VIEWER_EVENT_MOVE ? "X Y"
                     : e.kind == VIEWER_EVENT_KEY ? "a key name"
                     : e.kind == VIEWER_EVENT_SCREENSHOT ? "a PNG path" : "no argument",
                     n - 2, n - 2 == 1 ? "" : "s");
            rc = -1;
            break;
        }
        if (e.kind == VIEWER_EVENT_DOWN || e.kind == VIEWER_EVENT_MOVE) {
            if (parse_number(words[2], &e.x) || parse_number(words[3], &e.y)) {
                snprintf(err, err_size, "%s:%u: %s: '%s %s' are not pixel coordinates", path,
                         line_no, cmd, words[2], words[3]);
                rc = -1;
                break;
            }
        } else if (e.kind == VIEWER_EVENT_KEY) {
            if ((e.key = viewer_key_from_name(words[2])) < 0) {
                snprintf(err, err_size, "%s:%u: key: unknown key '%s' (a letter, + -, space, escape, "
                         "left, right, up, down, pageup, pagedown)", path, line_no, words[2]);
                rc = -1;
                break;
            }
        } else if (e.kind == VIEWER_EVENT_SCREENSHOT) {
            if (!(e.path = strdup(words[2]))) {
                snprintf(err, err_size, "%s:%u: out of memory", path, line_no);
                rc = -1;
                break;
            }
        }
        if (out->count == capacity) {
            size_t grown = capacity ? 2 * capacity : 32;
            viewer_event *events = realloc(out->events, grown * sizeof *events);
            if (!events) {
                free(e.path);
                snprintf(err, err_size, "%s:%u: out of memory", path, line_no);
                rc = -1;
                break;
            }
            out->events = events;
            capacity = grown;
        }
        out->events[out->count++] = e;
        last_frame = e.frame;
    }
    if (rc == 0 && ferror(f)) {
        snprintf(err, err_size, "%s: read error", path);
        rc = -1;
    }
    fclose(f);
    if (rc == 0 && out->count == 0) {
        snprintf(err, err_size, "%s: no events (a script needs at least one)", path);
        rc = -1;
    }
    if (rc)
        viewer_script_free(out);
    return rc;
}
