/* fsutil.h -- the few file-system helpers the CLI needs. */
#ifndef RBC_CLI_FSUTIL_H
#define RBC_CLI_FSUTIL_H

#include <stddef.h>

/// Create `path` and its missing parents (mkdir -p). Returns 0, or -1 with errno
/// set and a message in err.
int fs_mkdir_p(const char *path, char *err, size_t err_size);

/// malloc'd "dir/stem.ext" (no doubled '/'), or NULL when out of memory.
char *fs_path(const char *dir, const char *stem, const char *ext);

/// Write `size` bytes to `path` atomically: "<path>.tmp", then rename. Returns 0,
/// or -1 with a message in err (the temporary file is removed).
int fs_write_atomic(const char *path, const void *data, size_t size, char *err,
                    size_t err_size);

#endif
