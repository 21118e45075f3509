/* script.h -- the viewer's scripted input (--script FILE): timed mouse and key events
 * and screenshots, so that a test drives the very code paths a user does.
 *
 * One event per line, "FRAME COMMAND ARGS", '#' starts a comment, blank lines are
 * skipped. FRAME is the 0-based frame the event happens at; lines must be in
 * non-decreasing frame order. Commands (x y: window pixels, origin top left):
 *   down X Y [left|right]   press a mouse button there (left: pick and drag, or cut
 *                           in cut mode; right: cut)
 *   move X Y                move the mouse there
 *   up                      release the button that is down
 *   key NAME                press a key: one character (b c p r s + -) or space,
 *                           escape, left, right, up, down, pageup, pagedown
 *   screenshot PATH         write the frame as drawn to PATH (PNG)
 *   state                   print the state line (see README.md) to stdout
 * Input events of frame N act before frame N is stepped and drawn; screenshot and
 * state see frame N as drawn.
 */
#ifndef RBC_VIEWER_SCRIPT_H
#define RBC_VIEWER_SCRIPT_H

#include <stddef.h>
#include <stdint.h>

typedef enum viewer_event_kind {
    VIEWER_EVENT_DOWN,
    VIEWER_EVENT_MOVE,
    VIEWER_EVENT_UP,
    VIEWER_EVENT_KEY,
    VIEWER_EVENT_SCREENSHOT,
    VIEWER_EVENT_STATE
} viewer_event_kind;

typedef struct viewer_event {
    uint32_t frame;
    viewer_event_kind kind;
    double x, y;
    /// DOWN: 0 left, 1 right.
    int button;
    /// KEY: a GLFW key code.
    int key;
    /// SCREENSHOT: malloc'd path.
    char *path;
    /// Line in the file, for messages.
    uint32_t line;
} viewer_event;

typedef struct viewer_script {
    viewer_event *events;
    size_t count;
} viewer_script;

/// Read a script. Returns 0, or -1 with "FILE:LINE: what was wrong" in err.
int viewer_script_load(const char *path, viewer_script *out, char *err, size_t err_size);
void viewer_script_free(viewer_script *script);

/// The GLFW key code of a script key NAME, or -1 if it names none.
int viewer_key_from_name(const char *name);

#endif
