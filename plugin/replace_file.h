/* replace_file.h -- rbc_replace_file(from, to): move a complete temporary file over
 * its destination, replacing a file already there, so a reader sees the old file or
 * the new one and never half of one. 0, or -1 with errno set (for the message).
 * POSIX: rename(), which does exactly that. Windows: rename() fails there when the
 * destination exists, so it is MoveFileExA with MOVEFILE_REPLACE_EXISTING (paths in
 * the ANSI code page, as fopen's); a destination that another process holds open
 * without FILE_SHARE_DELETE cannot be replaced (EACCES). */
#ifndef RBC_PLUGIN_REPLACE_FILE_H
#define RBC_PLUGIN_REPLACE_FILE_H
#include <errno.h>
#include <stdio.h>
#if defined(_WIN32)
#define WIN32_LEAN_AND_MEAN
#define NOMINMAX
#include <windows.h>

static inline int rbc_replace_file(const char *from, const char *to) {
    if (MoveFileExA(from, to, MOVEFILE_REPLACE_EXISTING)) return 0;
    switch (GetLastError()) {
    case ERROR_FILE_NOT_FOUND:
    case ERROR_PATH_NOT_FOUND: errno = ENOENT; break;
    case ERROR_ACCESS_DENIED:
    case ERROR_SHARING_VIOLATION:
    case ERROR_LOCK_VIOLATION: errno = EACCES; break;
    case ERROR_NOT_SAME_DEVICE: errno = EXDEV; break;
    case ERROR_DISK_FULL:
    case ERROR_HANDLE_DISK_FULL: errno = ENOSPC; break;
    default: errno = EIO; break;
    }
    return -1;
}
#else
static inline int rbc_replace_file(const char *from, const char *to) { return rename(from, to); }
#endif
#endif
